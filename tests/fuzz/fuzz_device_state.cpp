// libFuzzer target: arbitrary text to nmt::parse_device_state (a simulated device's saved
// values, nmt/sim/device_state.hpp). Checks its promises: no crash; accepted text formats
// (format_device_state) to a text that parses back to the same values.
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "nmt/sim/device_state.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const cfg::NodeId node = *cfg::NodeId::from(5);
  const auto parsed = nmt::parse_device_state(text, "fuzz", node);
  if (!parsed) return 0;
  const auto again = nmt::parse_device_state(nmt::format_device_state(node, *parsed), "fuzz", node);
  if (!again || *again != *parsed) std::abort();
  return 0;
}
