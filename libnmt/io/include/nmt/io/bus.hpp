// One bus interface for real-time CAN drivers (SocketCAN, UDP multicast). The simulated bus
// (sim_bus.hpp) runs on simulated time and connects protocol engines directly.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "cfg/result.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// The clock a received frame's timestamp is on.
enum class StampClock : std::uint8_t {
  /// CLOCK_REALTIME (wall_clock_now()): the kernel's receive time, which the SocketCAN and UDP
  /// drivers deliver (SO_TIMESTAMPNS). BusEventLoop moves it onto its own clock.
  Realtime,
  /// The clock of the BusEventLoop that reads the bus: buses that share the loop's clock, such
  /// as the scripted buses of tests.
  Loop,
};

struct ReceivedFrame {
  CanFrame frame;
  /// When the frame arrived: for the real drivers the kernel stamped it as it came off the wire
  /// (or the network), before it waited in the socket for the program to read it.
  TimePoint timestamp;
  StampClock clock = StampClock::Loop;
};

/// Microseconds since the Unix epoch (std::chrono::system_clock, i.e. CLOCK_REALTIME): the clock
/// of the kernel's receive stamps and the default trace clock.
TimePoint wall_clock_now();

/// What one attempt to send a frame did (Bus::try_send).
struct SendResult {
  enum class Status : std::uint8_t {
    Sent,       ///< the driver took the frame
    QueueFull,  ///< the transmit queue is full (ENOBUFS, EAGAIN): back-pressure, try again later
    Failed,     ///< another error the interface may recover from: try again later
    Refused,    ///< the driver can never send this frame (invalid for it): do not retry
    InterfaceGone,  ///< the interface vanished or went down (ENODEV, ENXIO, ENETDOWN)
  };
  Status status = Status::Sent;
  std::string message;  ///< why, for every status but Sent
};

/// The status of a failed send(2)/write(2) on a socket by its errno: QueueFull for ENOBUFS,
/// EAGAIN/EWOULDBLOCK; InterfaceGone for ENODEV, ENXIO, ENETDOWN; Failed for anything else.
SendResult::Status send_status_of_errno(int error_number);

/// A CAN bus driver. Not thread-safe: one event loop owns it.
class Bus {
 public:
  virtual ~Bus() = default;
  /// Sends a frame. When the driver's transmit queue is full it waits (up to a bounded time)
  /// rather than dropping; fails with a message only when the frame could not be sent.
  virtual cfg::Status send(const CanFrame& frame) = 0;
  /// Tries once to send a frame without waiting; BusEventLoop's transmit path, which keeps
  /// the frames in order and retries itself. The default calls send() (Sent or Failed).
  virtual SendResult try_send(const CanFrame& frame);
  /// Waits up to `timeout` of wall time for a frame. nullopt when none arrived in time. With a
  /// zero timeout it only looks at what is already queued, which BusEventLoop relies on to read
  /// every queued frame before it fires timers.
  virtual cfg::Result<std::optional<ReceivedFrame>> receive(Duration timeout) = 0;
  /// The URL the bus was opened with, e.g. "socketcan:can0".
  virtual std::string url() const = 0;
  /// A file descriptor poll(2) reports readable (POLLIN) when receive() may have a frame, so
  /// that BusEventLoop can wait on it together with its own wake-up descriptor (post()); -1
  /// (the default): none, the loop waits in receive() (a posted function then runs within
  /// BusEventLoopOptions::max_wait).
  virtual int readable_fd() const { return -1; }
};

/// Opens a bus by URL: `socketcan:IFNAME`, `udp://GROUP:PORT` (default
/// udp://239.74.163.2:43113). Fails with a message naming the URL and the reason.
cfg::Result<std::unique_ptr<Bus>> open_bus(std::string_view url);

/// Checks a bus URL's syntax without opening anything (the rules open_bus applies), so that a
/// tool can tell a mistyped URL (a usage error) from a bus that cannot be opened.
cfg::Status check_bus_url(std::string_view url);

}  // namespace nmt
