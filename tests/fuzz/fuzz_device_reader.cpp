// libFuzzer target: arbitrary bytes to the CiA 306 reader in both modes, then the writer on the
// model. Checks the promises of cfg/device_file.hpp: no crash or hang on any input; the mode
// changes diagnostics, never the model; reading the writer's output gives canonical_form() of the
// model; writing that again, or canonical_form() of the model, gives the same bytes.
// Seeds: tests/fuzz/seeds/device_reader/ (small files written for this project), with the
// dictionary seeds/device_reader/cia306.dict (use -dict=...).
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <string_view>

#include "cfg/device_file.hpp"

namespace {

[[noreturn]] void fail(const char* what) {
  std::fprintf(stderr, "fuzz_device_reader: %s\n", what);
  std::abort();
}

void round_trip(const cfg::DeviceDescription& device, cfg::FileKind kind, cfg::LineEnding ending) {
  cfg::WriteOptions options;
  options.kind = kind;
  options.line_ending = ending;
  const std::string written = cfg::write_device_description(device, options);
  const cfg::ReadResult back = cfg::parse_device_description(written);
  if (!back.device) fail("the writer's output does not read back");
  if (!(*back.device == cfg::canonical_form(device, options))) {
    fail("parse(write(m)) != canonical_form(m)");
  }
  if (cfg::write_device_description(*back.device, options) != written) {
    fail("writing the re-read model changes the bytes");
  }
  // The writer takes texts it finds canonical as they are and makes the others canonical; both
  // ways must give what canonical_form() stores.
  if (cfg::write_device_description(cfg::canonical_form(device, options), options) != written) {
    fail("write(canonical_form(m)) != write(m)");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const cfg::ReadResult tolerant =
      cfg::parse_device_description(text, {cfg::ReadMode::Tolerant, "fuzz.eds"});
  const cfg::ReadResult strict =
      cfg::parse_device_description(text, {cfg::ReadMode::Strict, "fuzz.eds"});
  (void)tolerant.diagnostics.format();
  if (tolerant.device.has_value() != strict.device.has_value()) fail("modes disagree on model");
  if (!tolerant.device) return 0;
  if (!(*tolerant.device == *strict.device)) fail("modes give different models");
  if (strict.diagnostics.size() < tolerant.diagnostics.count(cfg::Severity::Warning)) {
    // Every tolerant warning is a strict error (plus strict-only findings), up to the cap.
    if (strict.diagnostics.size() < 5000) fail("strict mode reports less than tolerant mode");
  }
  round_trip(*tolerant.device, cfg::FileKind::Dcf, cfg::LineEnding::Crlf);
  round_trip(*tolerant.device, cfg::FileKind::Eds, cfg::LineEnding::Lf);
  return 0;
}
