// IPv4 addresses as the udp:// URL (udp_url.cpp) and the UDP bus's sockets (udp_bus.cpp) use
// them: in network byte order, as in in_addr. Private to libnmt/io.
#pragma once

#include <arpa/inet.h>
#include <netinet/in.h>

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace nmt::detail {

/// A dotted-quad address, or nullopt when `text` is not one.
inline std::optional<std::uint32_t> parse_ipv4(std::string_view text) {
  std::string s(text);
  in_addr a{};
  if (inet_pton(AF_INET, s.c_str(), &a) != 1) return std::nullopt;
  return a.s_addr;
}

/// The dotted-quad text of an address.
inline std::string ipv4_text(std::uint32_t address_be) {
  in_addr a{};
  a.s_addr = address_be;
  std::array<char, INET_ADDRSTRLEN> buf{};
  inet_ntop(AF_INET, &a, buf.data(), buf.size());
  return buf.data();
}

/// RFC 5771: IPv4 multicast is 224.0.0.0/4.
inline bool is_ipv4_multicast(std::uint32_t address_be) {
  return (ntohl(address_be) >> 28) == 0xE;
}

}  // namespace nmt::detail
