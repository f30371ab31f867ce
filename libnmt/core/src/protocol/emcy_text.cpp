#include "nmt/protocol/emcy_text.hpp"

#include <array>
#include <utility>

#include "cfg/hex.hpp"

namespace nmt {
namespace {

struct CodeWords {
  std::uint16_t code;
  std::string_view words;
};

// CiA 301 v4.2 §7.2.7.3.2 Table 21 (emergency error codes), as CANopenNode's CO_Emergency.h
// (CO_EM_errorCodes) and openCANopen's cia302-error-codes.h list it. The spec is not in
// ../shared/spec; those two agree on every code here. Note 8230h is "DAM MPDO" and 8240h
// "unexpected SYNC data length" there.
constexpr std::array kCia301 = {
    CodeWords{0x0000, "error reset or no error"},
    CodeWords{0x1000, "generic error"},
    CodeWords{0x6100, "internal software"},
    CodeWords{0x6200, "user software"},
    CodeWords{0x6300, "data set"},
    CodeWords{0x8100, "communication"},
    CodeWords{0x8110, "CAN overrun (objects lost)"},
    CodeWords{0x8120, "CAN in error passive mode"},
    CodeWords{0x8130, "life guard error or heartbeat error"},
    CodeWords{0x8140, "recovered from bus off"},
    CodeWords{0x8150, "CAN-ID collision"},
    CodeWords{0x8200, "protocol error"},
    CodeWords{0x8210, "PDO not processed due to length error"},
    CodeWords{0x8220, "PDO length exceeded"},
    CodeWords{0x8230, "DAM MPDO not processed, destination object not available"},
    CodeWords{0x8240, "unexpected SYNC data length"},
    CodeWords{0x8250, "RPDO timeout"},
};

// CiA 402 (IEC 61800-7-201) drive codes, the most common, as openCANopen's
// cia402-error-codes.h names them (the class of the code first where the profile's table
// has the code under a heading).
constexpr std::array kCia402 = {
    CodeWords{0x2310, "continuous over-current (device output side)"},
    CodeWords{0x2320, "short circuit or earth leakage (device output side)"},
    CodeWords{0x3110, "mains over-voltage"},
    CodeWords{0x3120, "mains under-voltage"},
    CodeWords{0x3130, "mains phase failure"},
    CodeWords{0x3210, "DC link over-voltage"},
    CodeWords{0x3220, "DC link under-voltage"},
    CodeWords{0x4210, "excess temperature device"},
    CodeWords{0x4310, "excess temperature drive"},
    CodeWords{0x5530, "EEPROM"},
    CodeWords{0x6010, "reset by watchdog"},
    CodeWords{0x6320, "parameter error"},
    CodeWords{0x7121, "motor blocked"},
    CodeWords{0x7305, "incremental sensor 1 fault"},
    CodeWords{0x7310, "speed"},
    CodeWords{0x7320, "position"},
    CodeWords{0x8611, "following error"},
    CodeWords{0x8612, "reference limit"},
};

// CiA 401 I/O module codes, as CANopenNode's CO_Emergency.h has them (CO_EMC401_*).
constexpr std::array kCia401 = {
    CodeWords{0x2310, "current at outputs too high (overload)"},
    CodeWords{0x2320, "short circuit at outputs"},
    CodeWords{0x2330, "load dump at outputs"},
    CodeWords{0x3110, "input voltage too high"},
    CodeWords{0x3120, "input voltage too low"},
    CodeWords{0x3210, "internal voltage too high"},
    CodeWords{0x3220, "internal voltage too low"},
    CodeWords{0x3310, "output voltage too high"},
    CodeWords{0x3320, "output voltage too low"},
};

template <std::size_t N>
std::optional<std::string_view> lookup(const std::array<CodeWords, N>& table, std::uint16_t code) {
  for (const auto& entry : table) {
    if (entry.code == code) return entry.words;
  }
  return std::nullopt;
}

}  // namespace

std::string_view emcy_code_words(std::uint16_t code) {
  if (auto words = lookup(kCia301, code)) return *words;
  // The classes of Table 21: the high byte for FFxxh and F0xxh, else the high nibble, with
  // the current, voltage and temperature sub-classes of the high byte.
  switch (code >> 8) {
    case 0xFF:
      return "device specific";
    case 0xF0:
      return "additional functions";
    case 0x21:
      return "current, device input side";
    case 0x22:
      return "current inside the device";
    case 0x23:
      return "current, device output side";
    case 0x31:
      return "mains voltage";
    case 0x32:
      return "voltage inside the device";
    case 0x33:
      return "output voltage";
    case 0x41:
      return "ambient temperature";
    case 0x42:
      return "device temperature";
    case 0x50:
      return "device hardware";
    case 0x61:
      return "internal software";
    case 0x62:
      return "user software";
    case 0x63:
      return "data set";
    case 0x81:
      return "communication";
    case 0x82:
      return "protocol error";
    default:
      break;
  }
  switch (code >> 12) {
    case 0x0:
      return "error reset or no error";
    case 0x1:
      return "generic error";
    case 0x2:
      return "current";
    case 0x3:
      return "voltage";
    case 0x4:
      return "temperature";
    case 0x5:
      return "device hardware";
    case 0x6:
      return "device software";
    case 0x7:
      return "additional modules";
    case 0x8:
      return "monitoring";
    case 0x9:
      return "external error";
    default:
      return "additional functions or device specific";
  }
}

std::optional<std::string_view> emcy_profile_words(std::uint16_t code, std::uint32_t device_type) {
  switch (device_type & 0xFFFFU) {
    case kProfileDrives:
      return lookup(kCia402, code);
    case kProfileIo:
      return lookup(kCia401, code);
    default:
      return std::nullopt;
  }
}

std::string describe_emcy_code(std::uint16_t code, std::optional<std::uint32_t> device_type) {
  std::string text = cfg::hex_digits(code, 4) + "h ";
  if (device_type) {
    if (auto profile = emcy_profile_words(code, *device_type)) {
      text += std::string(*profile) + " (CiA " + std::to_string(*device_type & 0xFFFFU) + "); ";
    }
  }
  text += emcy_code_words(code);
  return text;
}

std::string describe_error_register(std::uint8_t error_register) {
  // CiA 301 §7.5.2.2 Table 47: the bits of 1001h.
  static constexpr std::array<std::string_view, 8> kBits = {
      "generic",       "current",
      "voltage",       "temperature",
      "communication", "device profile specific",
      "reserved",      "manufacturer specific"};
  if (error_register == 0) return "none";
  std::string text;
  for (unsigned bit = 0; bit < 8; ++bit) {
    if ((error_register & (1U << bit)) == 0) continue;
    if (!text.empty()) text += ", ";
    text += kBits[bit];
  }
  return text;
}

}  // namespace nmt
