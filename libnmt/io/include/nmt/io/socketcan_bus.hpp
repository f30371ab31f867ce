// The Linux SocketCAN driver: a CAN_RAW socket bound to one interface (can0, vcan0, ...).
// Behaviour follows the kernel's Documentation/networking/can.rst; the .cpp cites its sections.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>

#include "cfg/result.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// One receive filter. A frame passes when `(frame.id & mask) == (id & mask)` and its frame
/// format (standard or extended) is `extended`; with `rtr` set only remote frames pass, otherwise
/// data and remote frames both pass. Error frames are not filtered here (see `error_mask`).
struct CanFilter {
  std::uint32_t id = 0;
  std::uint32_t mask = 0;  ///< identifier bits that must match; 0 accepts every id
  bool extended = false;
  bool rtr = false;
};

struct SocketCanOptions {
  /// Longest total time send() waits while the interface's transmit queue is full (ENOBUFS)
  /// before it gives up with an error. The frame is never dropped silently.
  Duration send_timeout = std::chrono::milliseconds(1000);
  /// Error classes (CAN_ERR_* bits of linux/can/error.h) reported as error frames; all by
  /// default, 0 for none.
  std::uint32_t error_mask = 0x1FFFFFFF;
  /// Also receive the frames this socket sent itself (CAN_RAW_RECV_OWN_MSGS).
  bool receive_own_frames = false;
  /// Requested receive buffer (SO_RCVBUF), bytes, as UdpBusOptions: frames that arrive while
  /// the process is stopped wait there (and keep their receive time) rather than being dropped
  /// (receive_overflows()). The kernel caps it at net.core.rmem_max (212992 by default).
  int receive_buffer_bytes = 4 << 20;
};

/// A CAN_RAW socket on one interface. Owns the socket and closes it on destruction.
/// Not thread-safe: one event loop owns it.
class SocketCanBus final : public Bus {
 public:
  /// Opens the socket and binds it to `interface_name`. Fails with a message when the kernel
  /// has no CAN support, the interface does not exist, or it is not a CAN interface.
  static cfg::Result<std::unique_ptr<SocketCanBus>> open(const std::string& interface_name,
                                                         const SocketCanOptions& options = {});
  ~SocketCanBus() override;
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  /// Sends a data or remote frame (standard or extended id, 0..8 bytes). When the transmit
  /// queue is full it polls for room and retries for up to `send_timeout` in total. Fails on
  /// an invalid frame (error flag set, id out of range, dlc > 8), a timeout or a socket error.
  cfg::Status send(const CanFrame& frame) override;
  /// One write without waiting: QueueFull on ENOBUFS/EAGAIN, InterfaceGone on ENODEV, ENXIO,
  /// ENETDOWN, Refused for a frame send() would refuse.
  SendResult try_send(const CanFrame& frame) override;
  /// Waits up to `timeout` for a frame. Error frames come back with `error` set, `extended`
  /// set and `id` holding the error class bits (as candump prints them); data bytes 0..7 hold
  /// the details (linux/can/error.h). The timestamp is the kernel's receive time
  /// (SO_TIMESTAMPNS), StampClock::Realtime: microseconds since the Unix epoch, taken when the
  /// frame reached the socket, not when it was read.
  cfg::Result<std::optional<ReceivedFrame>> receive(Duration timeout) override;
  /// "socketcan:" followed by the interface name.
  std::string url() const override;
  int readable_fd() const override { return fd_; }

  /// Replaces the receive filters (CAN_RAW_FILTER). A frame passes when any filter accepts
  /// it; an empty list receives no data or remote frames at all (as the kernel does).
  cfg::Status set_filters(std::span<const CanFilter> filters);
  /// Back to the default: every data and remote frame passes.
  cfg::Status accept_all_frames();
  /// Which error classes are reported (CAN_RAW_ERR_FILTER); 0 turns error frames off.
  cfg::Status set_error_mask(std::uint32_t error_mask);

  /// The socket, for an event loop that polls several sources. Stays owned by this object.
  int native_handle() const { return fd_; }

  /// How often send() found the transmit queue full and waited before retrying (diagnostics).
  std::uint64_t queue_full_waits() const { return queue_full_waits_; }
  /// Frames the kernel dropped because this socket's receive buffer was full, as last reported
  /// with a received frame (SO_RXQ_OVFL). Non-zero means the reader did not keep up.
  std::uint32_t receive_overflows() const { return receive_overflows_; }

 private:
  struct Private {
    explicit Private() = default;
  };

 public:
  /// Use open(); public only so that open() can use std::make_unique.
  SocketCanBus(Private, int fd, std::string interface_name, const SocketCanOptions& options);

 private:
  int fd_;
  std::string interface_name_;
  SocketCanOptions options_;
  std::uint64_t queue_full_waits_ = 0;
  std::uint32_t receive_overflows_ = 0;
};

/// Opens `interface_name` with default options (see SocketCanBus::open).
cfg::Result<std::unique_ptr<Bus>> open_socketcan_bus(const std::string& interface_name);

/// Turns a raw SocketCAN frame (the `can_id` word with its EFF/RTR/ERR flags, the length and
/// up to 8 data bytes) into a CanFrame. Used by the driver and exposed so the decoding of flags
/// and error frames can be tested without a CAN interface. nullopt when `len` > 8.
std::optional<CanFrame> decode_socketcan_frame(std::uint32_t can_id, std::uint8_t len,
                                               std::span<const std::uint8_t> data);

}  // namespace nmt
