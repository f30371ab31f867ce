// The version of an application program (DSP 302 §9: "date: number of days since January 1,
// 1984", "time: number of milliseconds after midnight", as 1F52h sub 1/2 of a slave and 1F53h/
// 1F54h sub N of the master hold it), and the convention by which our tools and simulated devices
// learn the version an image carries.
//
// DSP 302 §9 leaves the image format to the manufacturer ("The program data are manufacturer
// specific"). Ours, a choice of this project, documented in the README ("Software update"): an
// image may end in a 12-byte version trailer
//
//   date_days  UNSIGNED32 little endian   (1F52h sub 1)
//   time_ms    UNSIGNED32 little endian   (1F52h sub 2)
//   magic      4 bytes "CPV1"
//
// A real device ignores it (its bytes are part of the manufacturer's image); a simulated device
// reports it in 1F52h once the image is started. `cfgmgr program-image` appends it.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/result.hpp"

namespace cfg {

/// Version of an application program: 1F52h sub 1/2, 1F53h/1F54h sub N (DSP 302 §9).
struct ProgramVersion {
  std::uint32_t date_days = 0;  ///< days since 1 January 1984 (1F52h sub 1, 1F53h)
  std::uint32_t time_ms = 0;    ///< milliseconds after midnight (1F52h sub 2, 1F54h)
  bool operator==(const ProgramVersion&) const = default;
};

/// Size of the version trailer and its magic, the last 4 bytes of an image that has one.
inline constexpr std::size_t kProgramTrailerSize = 12;
inline constexpr std::string_view kProgramTrailerMagic = "CPV1";

/// The version in the trailer of `image`, nullopt when it does not end in one.
std::optional<ProgramVersion> program_image_version(std::span<const std::uint8_t> image);

/// `payload` with a trailer for `version` appended. A payload that already ends in a trailer
/// gets it replaced, so that re-stamping an image does not grow it.
std::vector<std::uint8_t> with_program_trailer(std::span<const std::uint8_t> payload,
                                               ProgramVersion version);

/// A version from text, for command lines and project files:
///   "YYYY-MM-DD" or "YYYY-MM-DDTHH:MM[:SS[.mmm]]" (also with a space instead of T), or
///   "DAYS,MS" (the numbers 1F53h/1F54h hold, decimal or 0x hex).
/// Dates before 1984-01-01, times of 24 h and more, and numbers over UNSIGNED32 are errors.
Result<ProgramVersion> parse_program_version(std::string_view text);

/// "2026-11-27 08:15:00.000 (1F52h 15671, 29700000)": the date and time for people, and the
/// numbers as the objects hold them.
std::string to_string(ProgramVersion version);

}  // namespace cfg
