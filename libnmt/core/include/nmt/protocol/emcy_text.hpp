// The words of an emergency (CiA 301 §7.2.7.3): the error code's class and, where known, the
// code itself (CiA 301 Table 21, "emergency error codes"), the device profile's codes for CiA 402
// drives and CiA 401 I/O modules, and the bits of the error register (1001h, §7.5.2.2). For the
// sentence a person reads (nmt/master/master_event_text.hpp); a program reads the numbers.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace nmt {

/// The device profile an EMCY's code is read in: the low 16 bits of 1000h (CiA 301 §7.5.2.1).
inline constexpr std::uint16_t kProfileDrives = 402;  ///< CiA 402 (1000h = 0x....0192)
inline constexpr std::uint16_t kProfileIo = 401;      ///< CiA 401 (1000h = 0x....0191)

/// The words of `code` as CiA 301 Table 21 has them: the code's own where the table lists it
/// ("CAN in error passive mode" for 8120h), else its class's ("voltage" for 3xxxh); for codes
/// of a class only the profile or the manufacturer defines ("device specific" for FFxxh).
std::string_view emcy_code_words(std::uint16_t code);
/// The words a device profile gives `code` (CiA 402 for drives, CiA 401 for I/O), by the low 16
/// bits of `device_type` (1000h); nullopt when the profile is another, or it has no words for
/// the code that we know.
std::optional<std::string_view> emcy_profile_words(std::uint16_t code, std::uint32_t device_type);
/// "8130h life guard error or heartbeat error"; where `device_type` names a profile that has
/// words for the code, the profile's first: "8611h following error (CiA 402); monitoring".
std::string describe_emcy_code(std::uint16_t code, std::optional<std::uint32_t> device_type);
/// The set bits of the error register in words, in bit order: "generic, communication"; "none"
/// for 00h.
std::string describe_error_register(std::uint8_t error_register);

}  // namespace nmt
