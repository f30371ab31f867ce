// The SocketCAN driver. Reviewed line by line against the kernel's
// Documentation/networking/can.rst (cited below as "can.rst, <section title>"); where the
// behaviour comes from the kernel source or from measurement instead, the comment says so.
#include "nmt/io/socketcan_bus.hpp"

#include <fcntl.h>
#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <vector>

#include "kernel_time.hpp"

namespace nmt {
namespace {

using std::chrono::duration_cast;
using std::chrono::microseconds;
using std::chrono::steady_clock;

std::string errno_text(int err) {
  return std::strerror(err);
}

cfg::Error failure(const std::string& interface_name, const std::string& what, int err) {
  return cfg::Error{"socketcan:" + interface_name + ": " + what + ": " + errno_text(err)};
}

Duration remaining(steady_clock::time_point deadline) {
  return std::max(Duration::zero(), duration_cast<microseconds>(deadline - steady_clock::now()));
}

// The kernel stamps received frames with CLOCK_REALTIME (can.rst, "How to use SocketCAN": "set
// automatically at the reception of a CAN frame"; socket(7), SO_TIMESTAMPNS: a struct timespec).
// It is passed on as it is, StampClock::Realtime: BusEventLoop moves it onto its own clock.
using detail::from_timespec;
using detail::to_timespec;

// can.rst, "RAW socket option CAN_RAW_FILTER", "CAN Filter Usage Optimisation": CAN_EFF_FLAG
// in the mask makes the frame format matter (without it a filter for SFF 0x123 also passes
// EFF 0xXXXXX123); CAN_RTR_FLAG in the mask makes the RTR bit matter. The id mask is limited
// to the format's id bits so flag bits of the caller's mask cannot leak in.
can_filter to_kernel_filter(const CanFilter& f) {
  const canid_t id_bits = f.extended ? CAN_EFF_MASK : CAN_SFF_MASK;
  can_filter k{};
  k.can_id = (f.id & id_bits) | (f.extended ? CAN_EFF_FLAG : 0u) | (f.rtr ? CAN_RTR_FLAG : 0u);
  k.can_mask = (f.mask & id_bits) | CAN_EFF_FLAG | (f.rtr ? CAN_RTR_FLAG : 0u);
  return k;
}

}  // namespace

std::optional<CanFrame> decode_socketcan_frame(std::uint32_t can_id, std::uint8_t len,
                                               std::span<const std::uint8_t> data) {
  // can.rst, "How to use SocketCAN": `len` is the payload length 0..CAN_MAX_DLEN for a
  // Classical CAN frame, not a DLC code.
  if (len > CAN_MAX_DLEN || data.size() < len) return std::nullopt;
  CanFrame f;
  f.dlc = len;
  if ((can_id & CAN_ERR_FLAG) != 0) {
    // can.rst, "Network Problem Notifications" and linux/can/error.h: an error message frame
    // carries the error class bits in can_id (under CAN_ERR_MASK) and details in data[0..7].
    // It is shown as candump shows it: 8 hex digits, hence `extended`.
    f.error = true;
    f.extended = true;
    f.id = can_id & CAN_ERR_MASK;
    std::copy_n(data.begin(), len, f.data.begin());
    return f;
  }
  f.extended = (can_id & CAN_EFF_FLAG) != 0;
  f.rtr = (can_id & CAN_RTR_FLAG) != 0;
  f.id = can_id & (f.extended ? CAN_EFF_MASK : CAN_SFF_MASK);
  // A remote frame has a DLC but carries no data; its data bytes are left zero.
  if (!f.rtr) std::copy_n(data.begin(), len, f.data.begin());
  return f;
}

SocketCanBus::SocketCanBus(Private /*unused*/, int fd, std::string interface_name,
                           const SocketCanOptions& options)
    : fd_(fd), interface_name_(std::move(interface_name)), options_(options) {}

SocketCanBus::~SocketCanBus() {
  ::close(fd_);
}

cfg::Result<std::unique_ptr<SocketCanBus>> SocketCanBus::open(const std::string& interface_name,
                                                              const SocketCanOptions& options) {
  // ifr_name holds IFNAMSIZ bytes including the terminating NUL.
  if (interface_name.empty() || interface_name.size() >= IFNAMSIZ) {
    return cfg::Error{"socketcan:" + interface_name + ": interface names are 1 to " +
                      std::to_string(IFNAMSIZ - 1) + " characters"};
  }
  // can.rst, "How to use SocketCAN": socket(PF_CAN, SOCK_RAW, CAN_RAW). Non-blocking, so that
  // neither a read nor a write can hang the event loop: waiting is done with poll below.
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_NONBLOCK | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    const int err = errno;
    return failure(interface_name,
                   "cannot open a CAN_RAW socket (does the kernel have CAN support? "
                   "modprobe can-raw)",
                   err);
  }
  // From here the object owns fd and closes it on every failure path.
  auto bus = std::make_unique<SocketCanBus>(Private{}, fd, interface_name, options);

  // can.rst, "How to use SocketCAN": the interface index comes from SIOCGIFINDEX. Index 0
  // would bind to all CAN interfaces, which a name never gives.
  ifreq ifr{};
  std::memcpy(ifr.ifr_name, interface_name.data(), interface_name.size());
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
    const int err = errno;
    return failure(interface_name, "no such network interface", err);
  }

  // can.rst, "RAW Protocol Sockets with can_filters": the defaults at bind time are one filter
  // receiving everything, no error frames, loopback on, own frames not received. The options
  // "may be changed before or after binding"; set before, so no frame slips in unfiltered.
  if (auto st = bus->set_error_mask(options.error_mask); !st) return st.error();
  const int own = options.receive_own_frames ? 1 : 0;
  if (::setsockopt(fd, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &own, sizeof own) < 0) {
    const int err = errno;
    return failure(interface_name, "cannot set CAN_RAW_RECV_OWN_MSGS", err);
  }
  // Loopback stays on (the default): other applications on this host, e.g. candump, see the
  // frames we send (can.rst, "Local Loopback of Sent Frames").
  //
  // SO_TIMESTAMPNS delivers the receive time with each frame as a control message (socket(7));
  // the stamp SIOCGSTAMPNS would return, without a second system call per frame. The event loop
  // judges frames by it (bus_event_loop.hpp, "Time"): a frame that waited in the socket while the
  // process was stopped keeps the time it arrived.
  const int on = 1;
  if (::setsockopt(fd, SOL_SOCKET, SO_TIMESTAMPNS, &on, sizeof on) < 0) {
    const int err = errno;
    return failure(interface_name, "cannot enable SO_TIMESTAMPNS", err);
  }
  // A bigger receive buffer keeps what arrives while the process is stopped (a scheduler
  // hiccup must cost no frame); the
  // kernel silently caps the request at net.core.rmem_max, which is fine.
  (void)::setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &options.receive_buffer_bytes,
                     sizeof options.receive_buffer_bytes);
  // SO_RXQ_OVFL (socket(7)): the count of frames dropped for a full receive buffer comes with
  // each frame, so a reader that falls behind is visible rather than silent.
  if (::setsockopt(fd, SOL_SOCKET, SO_RXQ_OVFL, &on, sizeof on) < 0) {
    const int err = errno;
    return failure(interface_name, "cannot enable SO_RXQ_OVFL", err);
  }

  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  // The kernel refuses to bind to an interface that is not of type ARPHRD_CAN (ENODEV).
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) < 0) {
    const int err = errno;
    return failure(interface_name, "cannot bind (is it a CAN interface?)", err);
  }
  return bus;
}

cfg::Result<std::unique_ptr<Bus>> open_socketcan_bus(const std::string& interface_name) {
  auto bus = SocketCanBus::open(interface_name);
  if (!bus) return bus.error();
  return std::unique_ptr<Bus>(std::move(bus).value());
}

std::string SocketCanBus::url() const {
  return "socketcan:" + interface_name_;
}

SendResult SocketCanBus::try_send(const CanFrame& frame) {
  using Status = SendResult::Status;
  if (frame.error) {
    return {Status::Refused, url() + ": error frames are reported by the driver, not sent"};
  }
  if (frame.dlc > CAN_MAX_DLEN) {
    return {Status::Refused, url() + ": a classic CAN frame carries at most 8 data bytes, not " +
                                 std::to_string(frame.dlc)};
  }
  const std::uint32_t max_id = frame.extended ? CanFrame::kMaxExtendedId : CanFrame::kMaxStandardId;
  if (frame.id > max_id) {
    return {Status::Refused, url() + ": identifier " + std::to_string(frame.id) +
                                 " is out of range for " +
                                 (frame.extended ? "an extended" : "a standard") + " frame"};
  }
  // can.rst, "How to use SocketCAN": a struct can_frame with the EFF/RTR flags in can_id and
  // the payload length in len. A remote frame carries its DLC in len and no data.
  can_frame raw{};
  raw.can_id = frame.id | (frame.extended ? CAN_EFF_FLAG : 0u) | (frame.rtr ? CAN_RTR_FLAG : 0u);
  raw.len = frame.dlc;
  if (!frame.rtr) std::copy_n(frame.data.begin(), frame.dlc, raw.data);
  for (;;) {
    const ssize_t n = ::write(fd_, &raw, sizeof raw);
    if (n == static_cast<ssize_t>(sizeof raw)) return {};
    if (n >= 0) {
      // can.rst: a raw socket takes whole frames; a short write would be a kernel bug.
      return {Status::Failed,
              url() + ": short write of a CAN frame (" + std::to_string(n) + " bytes)"};
    }
    const int err = errno;
    if (err == EINTR) continue;
    // A full transmit queue is not in can.rst. Measured and in the kernel source
    // (net/can/af_can.c can_send): when the interface's queueing discipline is full, write()
    // fails with ENOBUFS; EAGAIN when the socket's send buffer is full.
    return {send_status_of_errno(err),
            url() + ": cannot send " + to_candump(frame) + ": " + errno_text(err)};
  }
}

cfg::Status SocketCanBus::send(const CanFrame& frame) {
  // ENOBUFS comes while the socket still reports POLLOUT (its send buffer has room), so poll
  // alone would spin: after each refusal we also sleep a backoff (50 us doubling to 2 ms).
  // EAGAIN (send buffer full) is the case poll(POLLOUT) covers. The total wait is bounded by
  // send_timeout; the frame is then reported as not sent.
  const auto deadline = steady_clock::now() + options_.send_timeout;
  Duration backoff{50};
  for (;;) {
    auto attempt = try_send(frame);
    if (attempt.status == SendResult::Status::Sent) return {};
    if (attempt.status != SendResult::Status::QueueFull) return cfg::Error{attempt.message};
    const Duration left = remaining(deadline);
    if (left == Duration::zero()) {
      return cfg::Error{url() + ": transmit queue full for " +
                        std::to_string(options_.send_timeout.count() / 1000) +
                        " ms; frame not sent: " + to_candump(frame)};
    }
    ++queue_full_waits_;
    pollfd pfd{fd_, POLLOUT, 0};
    const timespec poll_wait = to_timespec(left);
    if (::ppoll(&pfd, 1, &poll_wait, nullptr) < 0 && errno != EINTR) {
      const int poll_err = errno;
      return failure(interface_name_, "poll for transmit room failed", poll_err);
    }
    const timespec sleep_for = to_timespec(std::min(backoff, remaining(deadline)));
    ::nanosleep(&sleep_for, nullptr);
    backoff = std::min(backoff * 2, Duration{2000});
  }
}

cfg::Result<std::optional<ReceivedFrame>> SocketCanBus::receive(Duration timeout) {
  const auto deadline = steady_clock::now() + std::max(timeout, Duration::zero());
  for (;;) {
    pollfd pfd{fd_, POLLIN, 0};
    const timespec wait = to_timespec(remaining(deadline));
    const int ready = ::ppoll(&pfd, 1, &wait, nullptr);
    if (ready < 0) {
      const int err = errno;
      if (err == EINTR) continue;
      return failure(interface_name_, "poll for frames failed", err);
    }
    if (ready == 0) return std::optional<ReceivedFrame>{};
    if ((pfd.revents & (POLLERR | POLLNVAL)) != 0 && (pfd.revents & POLLIN) == 0) {
      int err = 0;
      socklen_t len = sizeof err;
      ::getsockopt(fd_, SOL_SOCKET, SO_ERROR, &err, &len);
      return failure(interface_name_, "socket error", err != 0 ? err : EIO);
    }

    // can.rst, "How to use SocketCAN": read a struct can_frame; recvmsg instead of read(2) to
    // get the timestamp and drop count as control messages.
    can_frame raw{};
    iovec iov{&raw, sizeof raw};
    alignas(cmsghdr) char control[CMSG_SPACE(sizeof(timespec)) + CMSG_SPACE(sizeof(std::uint32_t))];
    msghdr msg{};
    msg.msg_iov = &iov;
    msg.msg_iovlen = 1;
    msg.msg_control = control;
    msg.msg_controllen = sizeof control;
    const ssize_t n = ::recvmsg(fd_, &msg, MSG_DONTWAIT);
    if (n < 0) {
      const int err = errno;
      if (err == EINTR || err == EAGAIN) continue;  // woken without a frame: wait again
      return failure(interface_name_, "cannot receive", err);
    }
    // can.rst: the "paranoid check" for an incomplete frame. CAN FD frames (CANFD_MTU) are not
    // delivered because CAN_RAW_FD_FRAMES stays off (can.rst, "RAW Socket Option
    // CAN_RAW_FD_FRAMES": "only CAN_MTU is allowed (default)").
    if (n != static_cast<ssize_t>(sizeof raw) || (msg.msg_flags & MSG_TRUNC) != 0) {
      return cfg::Error{url() + ": incomplete CAN frame (" + std::to_string(n) + " bytes)"};
    }

    std::optional<TimePoint> stamp;
    for (cmsghdr* c = CMSG_FIRSTHDR(&msg); c != nullptr; c = CMSG_NXTHDR(&msg, c)) {
      if (c->cmsg_level != SOL_SOCKET) continue;
      if (c->cmsg_type == SO_TIMESTAMPNS) {
        timespec ts{};
        std::memcpy(&ts, CMSG_DATA(c), sizeof ts);
        stamp = from_timespec(ts);
      } else if (c->cmsg_type == SO_RXQ_OVFL) {
        std::memcpy(&receive_overflows_, CMSG_DATA(c), sizeof receive_overflows_);
      }
    }

    auto frame = decode_socketcan_frame(raw.can_id, raw.len, std::span(raw.data));
    if (!frame) {
      return cfg::Error{url() + ": received a frame with length " + std::to_string(raw.len) +
                        " (more than 8 bytes)"};
    }
    // Without a stamp (the kernel always sends one once enabled) the frame is as old as now.
    return std::optional<ReceivedFrame>{
        ReceivedFrame{*frame, stamp.value_or(wall_clock_now()), StampClock::Realtime}};
  }
}

cfg::Status SocketCanBus::set_filters(std::span<const CanFilter> filters) {
  // can.rst, "RAW socket option CAN_RAW_FILTER": 0..n filters, OR'ed; zero filters
  // (NULL, 0) disable reception. The kernel caps the count at CAN_RAW_FILTER_MAX.
  if (filters.size() > CAN_RAW_FILTER_MAX) {
    return cfg::Error{url() + ": at most " + std::to_string(CAN_RAW_FILTER_MAX) +
                      " receive filters, not " + std::to_string(filters.size())};
  }
  std::vector<can_filter> kernel;
  kernel.reserve(filters.size());
  for (const auto& f : filters) kernel.push_back(to_kernel_filter(f));
  const void* data = kernel.empty() ? nullptr : kernel.data();
  const auto size = static_cast<socklen_t>(kernel.size() * sizeof(can_filter));
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, data, size) < 0) {
    const int err = errno;
    return failure(interface_name_, "cannot set receive filters", err);
  }
  return {};
}

cfg::Status SocketCanBus::accept_all_frames() {
  // can.rst, "RAW Protocol Sockets with can_filters": the bind-time default is "exactly one
  // filter receiving everything", i.e. can_id 0 with mask 0 (the rcvlist_all entry in procfs).
  const can_filter all{0, 0};
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, &all, sizeof all) < 0) {
    const int err = errno;
    return failure(interface_name_, "cannot set receive filters", err);
  }
  return {};
}

cfg::Status SocketCanBus::set_error_mask(std::uint32_t error_mask) {
  // can.rst, "RAW Socket Option CAN_RAW_ERR_FILTER": error classes from linux/can/error.h;
  // CAN_ERR_MASK registers for every error condition. Bits outside it are not classes.
  const can_err_mask_t mask = error_mask & CAN_ERR_MASK;
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, sizeof mask) < 0) {
    const int err = errno;
    return failure(interface_name_, "cannot set the error frame mask", err);
  }
  return {};
}

}  // namespace nmt
