// libFuzzer target: arbitrary bytes to the variables-file reader of cfgmgr build --variables
// (cfg/dynamic_channels.hpp), then dynamic index assignment into the two segments of the CiA DSP
// 302 §8.4 example plus an output segment. Checks: no crash or hang; what the reader accepts has
// names and fixed-size types; every allocated variable lies in its segment's range, at sub-index
// 01h..FEh, and at the offset the §8.2 formula gives.
// Seeds: tests/fuzz/seeds/network_variables/.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string_view>

#include "cfg/data_type.hpp"
#include "cfg/dynamic_channels.hpp"

namespace {

[[noreturn]] void fail(const char* what) {
  std::fprintf(stderr, "fuzz_network_variables: %s\n", what);
  std::abort();
}

cfg::DynamicChannels segments() {
  cfg::DynamicChannels c;
  c.segments.push_back({0x0005, cfg::SegmentDirection::Ro, 0x7001, 0x7017, 0, {}, 4096, {}});
  c.segments.push_back({0x0001, cfg::SegmentDirection::Ro, 0x7018, 0x7018, 4096, 1, 64, {}});
  c.segments.push_back({0x0006, cfg::SegmentDirection::Rww, 0x7100, 0x7101, 0, {}, 300, {}});
  c.segments.push_back({0x0007, cfg::SegmentDirection::Wo, 0x7200, 0x7200, 0, {}, 20, {}});
  return c;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  auto vars = cfg::parse_network_variables(text, "fuzz.csv");
  if (!vars) return 0;
  for (const auto& v : *vars) {
    if (v.name.empty()) fail("a variable without a name was accepted");
    const cfg::DataTypeInfo* info = cfg::find_data_type(v.data_type);
    if (info == nullptr || info->size_bytes == 0) fail("a type without a fixed size was accepted");
  }
  static const cfg::DynamicChannels channels = segments();
  auto allocated = cfg::allocate_variables(channels, *vars);
  if (!allocated) return 0;
  if (allocated->size() != vars->size()) fail("not every variable was allocated");
  for (const auto& a : *allocated) {
    const cfg::DynamicSegment& s = channels.segments.at(a.segment);
    if (a.address.index < s.first_index || a.address.index > s.last_index) fail("index outside");
    if (a.address.sub_index == 0 || a.address.sub_index > 0xFE) fail("sub-index outside 01h-FEh");
    if (a.position >= cfg::capacity(s)) fail("beyond MaxCnt");
    if (a.pp_bit_offset != cfg::process_picture_bit_offset(s, a.position)) fail("offset formula");
  }
  return 0;
}
