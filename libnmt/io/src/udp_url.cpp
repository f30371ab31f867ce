// The udp:// URL of the python-can compatible UDP multicast bus (nmt/io/udp_bus.hpp): parse and
// print. The options are python-can 4.1's (can/interfaces/udp_multicast/bus.py).
#include <charconv>
#include <string>
#include <string_view>

#include "ipv4_address.hpp"
#include "nmt/io/udp_bus.hpp"

namespace nmt {

namespace {

using detail::ipv4_text;
using detail::is_ipv4_multicast;
using detail::parse_ipv4;

constexpr std::string_view kUrlForm =
    "expected udp://GROUP:PORT[?iface=ADDR&ttl=N] with an IPv4 multicast GROUP, e.g. "
    "udp://239.74.163.2:43113";
const UdpBusOptions kDefaults{};
cfg::Error url_error(std::string_view url, std::string_view reason) {
  return cfg::Error{"bad bus URL '" + std::string(url) + "': " + std::string(reason) + "; " +
                    std::string(kUrlForm)};
}

template <class T>
std::optional<T> parse_decimal(std::string_view text) {
  T value{};
  auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc{} || end != text.data() + text.size() || text.empty()) return std::nullopt;
  return value;
}

}  // namespace

cfg::Result<UdpBusOptions> parse_udp_url(std::string_view url) {
  constexpr std::string_view kScheme = "udp://";
  if (url.substr(0, kScheme.size()) != kScheme) return url_error(url, "not a udp:// URL");
  UdpBusOptions options;
  std::string_view rest = url.substr(kScheme.size());
  std::string_view query;
  if (auto q = rest.find('?'); q != std::string_view::npos) {
    query = rest.substr(q + 1);
    rest = rest.substr(0, q);
  }
  if (!rest.empty() && rest.back() == '/') rest.remove_suffix(1);
  if (!rest.empty() && rest.front() == '[') {
    return url_error(url, "IPv6 groups are not supported (IPv4 only)");
  }
  std::string_view group_text = rest;
  if (auto colon = rest.find(':'); colon != std::string_view::npos) {
    group_text = rest.substr(0, colon);
    auto port = parse_decimal<std::uint16_t>(rest.substr(colon + 1));
    if (!port || *port == 0) {
      return url_error(
          url, "port '" + std::string(rest.substr(colon + 1)) + "' is not a number in 1..65535");
    }
    options.port = *port;
  }
  if (!group_text.empty()) {
    auto group = parse_ipv4(group_text);
    if (!group) {
      return url_error(url, "group '" + std::string(group_text) + "' is not an IPv4 address");
    }
    if (!is_ipv4_multicast(*group)) {
      return url_error(url, "group '" + std::string(group_text) +
                                "' is not a multicast address (224.0.0.0 to 239.255.255.255)");
    }
    options.group = ipv4_text(*group);
  }
  while (!query.empty()) {
    auto amp = query.find('&');
    std::string_view item = query.substr(0, amp);
    query = amp == std::string_view::npos ? std::string_view{} : query.substr(amp + 1);
    auto eq = item.find('=');
    std::string_view key = item.substr(0, eq);
    std::string_view value =
        eq == std::string_view::npos ? std::string_view{} : item.substr(eq + 1);
    if (key == "iface") {
      auto address = parse_ipv4(value);
      if (!address) {
        return url_error(
            url, "iface '" + std::string(value) + "' is not the IPv4 address of a local interface");
      }
      options.interface_address = ipv4_text(*address);
    } else if (key == "ttl") {
      auto ttl = parse_decimal<unsigned>(value);
      if (!ttl || *ttl < 1 || *ttl > 255) {
        return url_error(url, "ttl '" + std::string(value) + "' is not a number in 1..255");
      }
      options.ttl = static_cast<std::uint8_t>(*ttl);
    } else {
      return url_error(url, "unknown option '" + std::string(key) + "' (known: iface, ttl)");
    }
  }
  return options;
}

std::string to_udp_url(const UdpBusOptions& options) {
  std::string url = "udp://" + options.group + ":" + std::to_string(options.port);
  char sep = '?';
  if (options.interface_address != kDefaults.interface_address) {
    url += sep + std::string("iface=") + options.interface_address;
    sep = '&';
  }
  if (options.ttl != kDefaults.ttl) url += sep + std::string("ttl=") + std::to_string(options.ttl);
  return url;
}

}  // namespace nmt
