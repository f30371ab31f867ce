// A virtual CAN bus over IPv4 UDP multicast that interoperates with python-can's `udp_multicast`
// interface (python-can 4.1: can/interfaces/udp_multicast). Every member of the group hears every
// frame; there is no arbitration, no acknowledgement and no guaranteed delivery or order.
//
// Wire format: one python-can MessagePack map per datagram (nmt/io/udp_datagram.hpp).
//
// URL: `udp://[GROUP][:PORT][?iface=ADDR&ttl=N]`, default `udp://239.74.163.2:43113`.
//   GROUP  an IPv4 multicast address (224.0.0.0/4). IPv6 is not supported.
//   PORT   UDP port, 1..65535. Groups on the same port are kept apart (we bind to the group),
//          but python-can binds to the port on every address and hears all groups on it.
//   iface  the IPv4 address of the local interface to send and join on. Default 127.0.0.1:
//          the bus stays on this machine. Give the address of a LAN interface to reach other
//          machines (then also raise ttl if the group must cross routers).
//   ttl    IPv4 multicast time to live, 1..255, default 1 (never leaves the local link).
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/result.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/udp_datagram.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// Where and how a UdpBus joins its group. All addresses are dotted-quad IPv4 text.
struct UdpBusOptions {
  std::string group = "239.74.163.2";  ///< python-can's DEFAULT_GROUP_IPv4
  std::uint16_t port = 43113;          ///< python-can's default port
  std::string interface_address = "127.0.0.1";
  std::uint8_t ttl = 1;
  /// Longest total time send() waits for room in the socket's send buffer before failing.
  Duration send_timeout = std::chrono::milliseconds(1000);
  /// Requested receive buffer (SO_RCVBUF), bytes; the kernel caps it at net.core.rmem_max.
  int receive_buffer_bytes = 4 << 20;
};

/// Parses a `udp://` URL (see the top of this file). Fails with a message naming the URL and the
/// accepted form.
cfg::Result<UdpBusOptions> parse_udp_url(std::string_view url);
/// The URL that parse_udp_url() turns back into `options` (query only for non-defaults).
std::string to_udp_url(const UdpBusOptions& options);

/// What a UdpBus has dropped, for diagnostics.
struct UdpBusCounters {
  std::uint64_t own_datagrams = 0;  ///< our own frames, looped back by the kernel and dropped
  std::uint64_t rejected = 0;       ///< datagrams decode_udp_datagram() refused (skipped)
  std::uint64_t send_waits = 0;     ///< times send() found the send buffer full and waited
};

/// One member of a multicast group. Owns two sockets: one bound to the group's port that joins
/// the group (receive), and one with an ephemeral port that sends, so our own looped-back
/// datagrams are recognised by their source address and dropped. Not thread-safe: one event loop
/// owns it.
class UdpBus final : public Bus {
 public:
  /// Opens both sockets and joins the group. Fails with a message on an invalid address, a
  /// `interface_address` that is not a local IPv4 address, or any socket error.
  static cfg::Result<std::unique_ptr<UdpBus>> open(const UdpBusOptions& options);
  ~UdpBus() override;
  UdpBus(const UdpBus&) = delete;
  UdpBus& operator=(const UdpBus&) = delete;

  /// Sends one datagram to the group. Refuses frames python-can would reject (see
  /// encode_udp_datagram); error frames may be sent (python-can carries them too). Waits up to
  /// `send_timeout` for buffer space, then fails.
  cfg::Status send(const CanFrame& frame) override;
  /// One sendto without waiting: QueueFull when the send buffer is full, Refused for a frame
  /// python-can would reject.
  SendResult try_send(const CanFrame& frame) override;
  /// Waits up to `timeout` for a frame from another member, skipping our own datagrams and
  /// malformed ones (counted in counters()). The timestamp is the kernel's receive time
  /// (SO_TIMESTAMPNS), StampClock::Realtime: microseconds since the Unix epoch, taken when the
  /// datagram reached the socket, not when it was read. Fails only on a socket error.
  cfg::Result<std::optional<ReceivedFrame>> receive(Duration timeout) override;
  /// The URL that opens an equivalent bus (to_udp_url).
  std::string url() const override;
  int readable_fd() const override { return receive_fd_; }

  /// The receive socket, for an event loop that polls several sources. Stays owned by the bus.
  int native_handle() const { return receive_fd_; }
  const UdpBusCounters& counters() const { return counters_; }
  /// Why the last rejected datagram was refused; empty if none was.
  const std::string& last_rejection() const { return last_rejection_; }

 private:
  UdpBus(UdpBusOptions options, int receive_fd, int send_fd);

  UdpBusOptions options_;
  int receive_fd_;
  int send_fd_;
  std::uint32_t group_be_ = 0;        ///< group address, network byte order
  std::uint32_t own_address_be_ = 0;  ///< send socket's local address, network byte order
  std::uint16_t own_port_be_ = 0;     ///< send socket's local port, network byte order
  UdpBusCounters counters_;
  std::string last_rejection_;
};

/// Opens a UdpBus from a `udp://` URL (parse_udp_url + UdpBus::open).
cfg::Result<std::unique_ptr<Bus>> open_udp_bus(std::string_view url);

}  // namespace nmt
