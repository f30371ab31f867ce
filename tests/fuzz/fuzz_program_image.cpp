// libFuzzer target: the program version texts of the project file (NodeXProgramVersion=),
// --program-version and cfgmgr program-image (cfg::parse_program_version), and the version
// trailer of an image (DSP 302 §9; cfg/program_image.hpp).
// Input: byte 0 even: the rest is a version text; odd: the rest is an image payload.
// Checks the promises of cfg/program_image.hpp: no crash; an accepted version has a time below
// 24 h; an image stamped with a version carries exactly that version, grows by the trailer at
// most, and stamping it again gives the same bytes.
#include <cstdint>
#include <cstdlib>
#include <span>
#include <string_view>
#include <vector>

#include "cfg/program_image.hpp"

namespace {

void check(bool condition) {
  if (!condition) std::abort();
}

void check_stamp(std::span<const std::uint8_t> payload, cfg::ProgramVersion version) {
  const auto image = cfg::with_program_trailer(payload, version);
  check(image.size() == payload.size() + cfg::kProgramTrailerSize ||
        (cfg::program_image_version(payload) && image.size() == payload.size()));
  check(cfg::program_image_version(image) == version);
  check(cfg::with_program_trailer(image, version) == image);
  check(!cfg::to_string(version).empty());
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const std::span<const std::uint8_t> rest(data + 1, size - 1);
  if (data[0] % 2 == 0) {
    const std::string_view text(reinterpret_cast<const char*>(rest.data()), rest.size());
    auto parsed = cfg::parse_program_version(text);
    if (!parsed) {
      check(!parsed.error().message.empty());
      return 0;
    }
    check(parsed->time_ms < 24U * 60U * 60U * 1000U);
    check_stamp({}, *parsed);
    return 0;
  }
  // An image as it comes: its trailer, if any, read; stamped with a version from its first bytes.
  (void)cfg::program_image_version(rest);
  cfg::ProgramVersion version;
  if (rest.size() >= 2) version = {rest[0] * 100U, rest[1] * 1000U};
  check_stamp(rest, version);
  return 0;
}
