// nmt::open_bus (bus.hpp): picks the driver by the URL's scheme.
#include <string>
#include <string_view>

#include "nmt/bus.hpp"
#include "nmt/socketcan_bus.hpp"
#include "nmt/udp_bus.hpp"

namespace nmt {

namespace {
constexpr std::string_view kAcceptedForms =
    "accepted: socketcan:IFNAME (e.g. socketcan:can0), udp://GROUP:PORT[?iface=ADDR&ttl=N] "
    "(e.g. udp://239.74.163.2:43113)";
}  // namespace

cfg::Result<std::unique_ptr<Bus>> open_bus(std::string_view url) {
  constexpr std::string_view kSocketCan = "socketcan:";
  if (url.substr(0, 6) == "udp://") return open_udp_bus(url);
  if (url.substr(0, kSocketCan.size()) == kSocketCan) {
    const std::string_view name = url.substr(kSocketCan.size());
    // Linux interface names: 1..15 bytes (IFNAMSIZ - 1), no '/', no whitespace.
    const bool valid = !name.empty() && name.size() < 16 &&
                       name.find_first_of("/ \t\n:") == std::string_view::npos;
    if (!valid) {
      return cfg::Error{"bad bus URL '" + std::string(url) +
                        "': expected an interface name of 1 to 15 characters after "
                        "'socketcan:'; " +
                        std::string(kAcceptedForms)};
    }
    auto bus = open_socketcan_bus(std::string(name));
    if (!bus)
      return cfg::Error{"cannot open bus '" + std::string(url) + "': " + bus.error().message};
    return bus;
  }
  return cfg::Error{"unknown bus URL '" + std::string(url) + "'; " + std::string(kAcceptedForms)};
}

}  // namespace nmt
