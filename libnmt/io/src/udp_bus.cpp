// python-can compatible UDP multicast bus: the sockets. The datagram codec is udp_datagram.cpp,
// the udp:// URL udp_url.cpp. Facts about the peer come from python-can 4.1's
// can/interfaces/udp_multicast/bus.py.
#include "nmt/io/udp_bus.hpp"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

#include "ipv4_address.hpp"
#include "kernel_time.hpp"

namespace nmt {

namespace {

using detail::ipv4_text;
using detail::is_ipv4_multicast;
using detail::parse_ipv4;
using detail::to_timespec;

// python-can receives with a 4096-byte buffer (GeneralPurposeUdpMulticastBus.max_buffer);
// anything longer is not a frame it could have sent.
constexpr std::size_t kMaxDatagram = 4096;

std::string errno_text(int error) {
  return std::strerror(error);
}

// Owns a file descriptor while UdpBus::open() sets the sockets up.
class Fd {
 public:
  explicit Fd(int fd) : fd_(fd) {}
  ~Fd() {
    if (fd_ >= 0) ::close(fd_);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  int get() const { return fd_; }
  int release() { return std::exchange(fd_, -1); }

 private:
  int fd_;
};

}  // namespace

// ---- the bus -----------------------------------------------------------------------------------

UdpBus::UdpBus(UdpBusOptions options, int receive_fd, int send_fd)
    : options_(std::move(options)), receive_fd_(receive_fd), send_fd_(send_fd) {}

UdpBus::~UdpBus() {
  ::close(receive_fd_);
  ::close(send_fd_);
}

cfg::Result<std::unique_ptr<UdpBus>> UdpBus::open(const UdpBusOptions& options) {
  const std::string where = to_udp_url(options);
  auto fail = [&](std::string_view what, int error) {
    return cfg::Error{where + ": " + std::string(what) + ": " + errno_text(error)};
  };
  auto group = parse_ipv4(options.group);
  if (!group || !is_ipv4_multicast(*group)) {
    return cfg::Error{where + ": group '" + options.group + "' is not an IPv4 multicast address"};
  }
  auto iface = parse_ipv4(options.interface_address);
  if (!iface) {
    return cfg::Error{where + ": iface '" + options.interface_address + "' is not an IPv4 address"};
  }
  if (options.port == 0 || options.ttl == 0) {
    return cfg::Error{where + ": port and ttl must be > 0"};
  }

  // Receive socket. python-can binds its own socket to the port with SO_REUSEADDR, so we do the
  // same (plus SO_REUSEPORT) to share the port with it and with other members on this host.
  Fd rx(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (rx.get() < 0) return fail("cannot create a UDP socket", errno);
  const int one = 1;
  if (setsockopt(rx.get(), SOL_SOCKET, SO_REUSEADDR, &one, sizeof one) != 0 ||
      setsockopt(rx.get(), SOL_SOCKET, SO_REUSEPORT, &one, sizeof one) != 0) {
    return fail("cannot share the port (SO_REUSEADDR/SO_REUSEPORT)", errno);
  }
  // A bigger buffer rides out bursts (an SDO block transfer is 127 frames back to back). The
  // kernel silently caps the request at net.core.rmem_max, which is fine.
  (void)setsockopt(rx.get(), SOL_SOCKET, SO_RCVBUF, &options.receive_buffer_bytes,
                   sizeof options.receive_buffer_bytes);
  // SO_TIMESTAMPNS (socket(7)): the kernel's receive time comes with each datagram, so a datagram
  // that waited in the socket while the process was stopped keeps the time it arrived
  // (bus_event_loop.hpp, "Time").
  if (setsockopt(rx.get(), SOL_SOCKET, SO_TIMESTAMPNS, &one, sizeof one) != 0) {
    return fail("cannot enable receive timestamps (SO_TIMESTAMPNS)", errno);
  }
  // Binding to the group address (not INADDR_ANY) makes the kernel deliver only datagrams sent
  // to this group, so groups sharing a port stay apart for us.
  sockaddr_in bind_address{};
  bind_address.sin_family = AF_INET;
  bind_address.sin_port = htons(options.port);
  bind_address.sin_addr.s_addr = *group;
  if (::bind(rx.get(), reinterpret_cast<const sockaddr*>(&bind_address), sizeof bind_address) !=
      0) {
    return fail("cannot bind to the group's port", errno);
  }
  ip_mreq membership{};
  membership.imr_multiaddr.s_addr = *group;
  membership.imr_interface.s_addr = *iface;
  if (setsockopt(rx.get(), IPPROTO_IP, IP_ADD_MEMBERSHIP, &membership, sizeof membership) != 0) {
    const int error = errno;
    if (error == ENODEV || error == EADDRNOTAVAIL) {
      return cfg::Error{where + ": cannot join the group on " + options.interface_address +
                        " (not the address of a local interface?): " + errno_text(error)};
    }
    return fail("cannot join the group", error);
  }

  // Send socket, separate so its ephemeral port tells our looped-back datagrams apart.
  Fd tx(::socket(AF_INET, SOCK_DGRAM | SOCK_CLOEXEC, 0));
  if (tx.get() < 0) return fail("cannot create a UDP socket", errno);
  in_addr out_interface{};
  out_interface.s_addr = *iface;
  const int ttl = options.ttl;
  if (setsockopt(tx.get(), IPPROTO_IP, IP_MULTICAST_IF, &out_interface, sizeof out_interface) !=
      0) {
    return fail("cannot send on " + options.interface_address + " (IP_MULTICAST_IF)", errno);
  }
  if (setsockopt(tx.get(), IPPROTO_IP, IP_MULTICAST_TTL, &ttl, sizeof ttl) != 0 ||
      setsockopt(tx.get(), IPPROTO_IP, IP_MULTICAST_LOOP, &one, sizeof one) != 0) {
    return fail("cannot set multicast TTL/loopback", errno);
  }
  sockaddr_in local{};
  local.sin_family = AF_INET;
  local.sin_addr.s_addr = *iface;
  if (::bind(tx.get(), reinterpret_cast<const sockaddr*>(&local), sizeof local) != 0) {
    return fail("cannot bind the send socket to " + options.interface_address, errno);
  }
  socklen_t local_size = sizeof local;
  if (getsockname(tx.get(), reinterpret_cast<sockaddr*>(&local), &local_size) != 0) {
    return fail("cannot read the send socket's address", errno);
  }

  auto bus = std::unique_ptr<UdpBus>(new UdpBus(options, rx.release(), tx.release()));
  bus->options_.group = ipv4_text(*group);
  bus->options_.interface_address = ipv4_text(*iface);
  bus->group_be_ = *group;
  bus->own_address_be_ = local.sin_addr.s_addr;
  bus->own_port_be_ = local.sin_port;
  return bus;
}

SendResult UdpBus::try_send(const CanFrame& frame) {
  using Status = SendResult::Status;
  const auto now = std::chrono::system_clock::now().time_since_epoch();
  // python-can stamps with time.time(): seconds since the Unix epoch as a float.
  const double timestamp_s = std::chrono::duration<double>(now).count();
  auto datagram = encode_udp_datagram(frame, timestamp_s);
  if (!datagram) {
    return {Status::Refused,
            url() + ": cannot send " + to_candump(frame) + ": " + datagram.error().message};
  }
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(options_.port);
  to.sin_addr.s_addr = group_be_;
  for (;;) {
    const ssize_t n =
        ::sendto(send_fd_, datagram->data(), datagram->size(), MSG_DONTWAIT | MSG_NOSIGNAL,
                 reinterpret_cast<const sockaddr*>(&to), sizeof to);
    if (n == static_cast<ssize_t>(datagram->size())) return {};
    if (n >= 0) return {Status::Failed, url() + ": short send of " + to_candump(frame)};
    const int error = errno;
    if (error == EINTR) continue;
    return {send_status_of_errno(error),
            url() + ": cannot send " + to_candump(frame) + ": " + errno_text(error)};
  }
}

cfg::Status UdpBus::send(const CanFrame& frame) {
  const auto deadline = std::chrono::steady_clock::now() + options_.send_timeout;
  for (;;) {
    auto attempt = try_send(frame);
    if (attempt.status == SendResult::Status::Sent) return {};
    if (attempt.status != SendResult::Status::QueueFull) return cfg::Error{attempt.message};
    // Buffer full: wait for room, but never past the deadline. ENOBUFS does not wake poll(), so
    // wait at most 10 ms at a time and retry.
    ++counters_.send_waits;
    const auto left =
        std::chrono::duration_cast<Duration>(deadline - std::chrono::steady_clock::now());
    if (left <= Duration::zero()) {
      return cfg::Error{url() + ": cannot send " + to_candump(frame) + ": send buffer full for " +
                        std::to_string(options_.send_timeout.count() / 1000) + " ms"};
    }
    pollfd p{send_fd_, POLLOUT, 0};
    const timespec wait = to_timespec(std::min<Duration>(left, std::chrono::milliseconds(10)));
    (void)::ppoll(&p, 1, &wait, nullptr);
  }
}

cfg::Result<std::optional<ReceivedFrame>> UdpBus::receive(Duration timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  std::array<std::uint8_t, kMaxDatagram> buffer;
  for (;;) {
    sockaddr_in from{};
    // recvmsg for the receive time (SO_TIMESTAMPNS, a control message). MSG_TRUNC: the return
    // value is the datagram's real length even when it did not fit.
    iovec iov{buffer.data(), buffer.size()};
    alignas(cmsghdr) std::array<char, CMSG_SPACE(sizeof(timespec))> control{};
    msghdr msg{};
    msg.msg_name = &from;
    msg.msg_namelen = sizeof from;
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control.data();
    msg.msg_controllen = control.size();
    const ssize_t n = ::recvmsg(receive_fd_, &msg, MSG_DONTWAIT | MSG_TRUNC);
    if (n >= 0) {
      TimePoint received_at = wall_clock_now();  // without a stamp: as old as now
      for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
        if (c->cmsg_level == SOL_SOCKET && c->cmsg_type == SO_TIMESTAMPNS) {
          timespec ts{};
          std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
          received_at = detail::from_timespec(ts);
        }
      }
      if (from.sin_port == own_port_be_ && from.sin_addr.s_addr == own_address_be_) {
        ++counters_.own_datagrams;  // IP_MULTICAST_LOOP hands every member its own datagrams
        continue;
      }
      if (static_cast<std::size_t>(n) > buffer.size()) {
        ++counters_.rejected;
        last_rejection_ = "datagram of " + std::to_string(n) + " bytes is longer than " +
                          std::to_string(kMaxDatagram);
        continue;
      }
      auto frame = decode_udp_datagram({buffer.data(), static_cast<std::size_t>(n)});
      if (!frame) {
        ++counters_.rejected;
        last_rejection_ = frame.error().message;
        continue;
      }
      return std::optional<ReceivedFrame>(ReceivedFrame{*frame, received_at, StampClock::Realtime});
    }
    const int error = errno;
    if (error == EINTR) continue;
    if (error != EAGAIN && error != EWOULDBLOCK) {
      return cfg::Error{url() + ": receive failed: " + errno_text(error)};
    }
    const auto left =
        std::chrono::duration_cast<Duration>(deadline - std::chrono::steady_clock::now());
    if (left <= Duration::zero()) return std::optional<ReceivedFrame>{};
    pollfd p{receive_fd_, POLLIN, 0};
    const timespec wait = to_timespec(left);
    if (::ppoll(&p, 1, &wait, nullptr) < 0 && errno != EINTR) {
      return cfg::Error{url() + ": waiting for a frame failed: " + errno_text(errno)};
    }
  }
}

std::string UdpBus::url() const {
  return to_udp_url(options_);
}

cfg::Result<std::unique_ptr<Bus>> open_udp_bus(std::string_view url) {
  auto options = parse_udp_url(url);
  if (!options) return options.error();
  auto bus = UdpBus::open(*options);
  if (!bus) return bus.error();
  return std::unique_ptr<Bus>(std::move(*bus));
}

}  // namespace nmt
