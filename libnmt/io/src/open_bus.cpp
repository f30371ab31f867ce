// nmt::open_bus (bus.hpp): picks the driver by the URL's scheme.
#include <cerrno>
#include <chrono>
#include <string>
#include <string_view>

#include "nmt/io/bus.hpp"
#include "nmt/io/socketcan_bus.hpp"
#include "nmt/io/udp_bus.hpp"

namespace nmt {

namespace {
constexpr std::string_view kAcceptedForms =
    "accepted: socketcan:IFNAME (e.g. socketcan:can0), udp://GROUP:PORT[?iface=ADDR&ttl=N] "
    "(e.g. udp://239.74.163.2:43113)";

constexpr std::string_view kUdp = "udp://";
constexpr std::string_view kSocketCan = "socketcan:";
}  // namespace

TimePoint wall_clock_now() {
  return TimePoint{
      std::chrono::duration_cast<Duration>(std::chrono::system_clock::now().time_since_epoch())};
}

SendResult::Status send_status_of_errno(int error_number) {
  switch (error_number) {
    case ENOBUFS:  // the interface's queue (qdisc) is full: net/can/af_can.c can_send
    case EAGAIN:   // the socket's send buffer is full (EWOULDBLOCK is the same number on Linux)
      return SendResult::Status::QueueFull;
    case ENODEV:  // the interface was removed (a USB adapter unplugged)
    case ENXIO:
    case ENETDOWN:  // the interface is down (ip link set ... down)
      return SendResult::Status::InterfaceGone;
    default:
      return SendResult::Status::Failed;
  }
}

SendResult Bus::try_send(const CanFrame& frame) {
  auto sent = send(frame);
  if (sent) return {};
  return {SendResult::Status::Failed, sent.error().message};
}

cfg::Status check_bus_url(std::string_view url) {
  if (url.substr(0, kUdp.size()) == kUdp) {
    auto parsed = parse_udp_url(url);
    if (!parsed) return parsed.error();
    return {};
  }
  if (url.substr(0, kSocketCan.size()) == kSocketCan) {
    const std::string_view name = url.substr(kSocketCan.size());
    // Linux interface names: 1..15 bytes (IFNAMSIZ - 1), no '/', ':' or whitespace.
    const bool valid = !name.empty() && name.size() < 16 &&
                       name.find_first_of("/ \t\n:") == std::string_view::npos;
    if (!valid) {
      return cfg::Error{"bad bus URL '" + std::string(url) +
                        "': expected an interface name of 1 to 15 characters after "
                        "'socketcan:'; " +
                        std::string(kAcceptedForms)};
    }
    return {};
  }
  return cfg::Error{"unknown bus URL '" + std::string(url) + "'; " + std::string(kAcceptedForms)};
}

cfg::Result<std::unique_ptr<Bus>> open_bus(std::string_view url) {
  if (auto syntax = check_bus_url(url); !syntax) return syntax.error();
  if (url.substr(0, kUdp.size()) == kUdp) return open_udp_bus(url);
  const std::string name(url.substr(kSocketCan.size()));
  auto bus = open_socketcan_bus(name);
  if (!bus) return cfg::Error{"cannot open bus '" + std::string(url) + "': " + bus.error().message};
  return bus;
}

}  // namespace nmt
