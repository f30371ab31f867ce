// Bus traces: recording CAN traffic in files other tools read.
//  - candump log (`candump -l` format): `(1700000000.123456) can0 123#DEADBEEF`, one frame a
//    line; read by can-utils (canplayer, log2asc, ...) and python-can (can.LogReader).
//  - pcap with link type LINKTYPE_CAN_SOCKETCAN (227), written with libpcap; read by Wireshark
//    and tshark (which decode CANopen with `-d can.subdissector,canopen`).
// Any bus can be traced: wrap a real driver in TracingBus, or give the simulated bus an observer
// made by trace_observer() (sim.add_observer(nmt::trace_observer(writer))); this room does not
// depend on the simulation.
#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>

#include "cfg/result.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// A file that records frames. Not thread-safe. The file is complete when the writer is flushed
/// or destroyed.
class TraceWriter {
 public:
  virtual ~TraceWriter() = default;
  /// Records `frame` seen at `timestamp`, microseconds since an epoch the caller chooses: the
  /// Unix epoch gives real dates, simulated time gives offsets from the start of the
  /// simulation. Fails on a negative timestamp, a frame with dlc > 8, or an I/O error. Failures
  /// are sticky: after the first, nothing more is written and status() keeps it.
  virtual cfg::Status write(const CanFrame& frame, TimePoint timestamp) = 0;
  /// Pushes buffered frames to the file.
  virtual cfg::Status flush() = 0;
  /// Success, or the first failure of write() or flush().
  virtual cfg::Status status() const = 0;
  /// The file being written.
  virtual const std::filesystem::path& path() const = 0;
};

/// Creates (truncates) a candump log at `path`. `channel` is the interface name written on every
/// line (1 to 15 characters without white space, as a Linux interface name).
cfg::Result<std::unique_ptr<TraceWriter>> open_candump_log(const std::filesystem::path& path,
                                                           const std::string& channel = "can0");
/// Creates (truncates) a pcap file at `path` with link type LINKTYPE_CAN_SOCKETCAN. Each record
/// is the 16-byte Linux `struct can_frame`: the CAN id in network byte order with the EFF
/// (0x80000000), RTR (0x40000000) and ERR (0x20000000) flags, the length, three zero bytes and
/// eight data bytes (zero past the length).
cfg::Result<std::unique_ptr<TraceWriter>> open_pcap(const std::filesystem::path& path);
/// Picks the format by extension: `.log` candump log (channel can0), `.pcap` pcap. Fails with a
/// message naming the accepted extensions otherwise.
cfg::Result<std::unique_ptr<TraceWriter>> open_trace(const std::filesystem::path& path);

/// A Bus that records every frame it sends (once the inner bus accepted it) and every frame it
/// receives into a trace, stamped with `clock` at the moment of the call (one clock for both
/// directions keeps the trace in order; the inner driver's receive timestamps are passed through
/// unchanged to the caller). Tracing never makes a bus operation fail: a trace failure is kept
/// in trace().status().
class TracingBus final : public Bus {
 public:
  /// Owns both `inner` and `trace`; neither may be null.
  TracingBus(std::unique_ptr<Bus> inner, std::unique_ptr<TraceWriter> trace,
             std::function<TimePoint()> clock = wall_clock_now);

  cfg::Status send(const CanFrame& frame) override;
  /// The inner bus's try_send; a frame it took is traced.
  SendResult try_send(const CanFrame& frame) override;
  cfg::Result<std::optional<ReceivedFrame>> receive(Duration timeout) override;
  /// The inner bus's URL.
  std::string url() const override;
  /// The inner bus's.
  int readable_fd() const override { return inner_->readable_fd(); }

  Bus& inner() { return *inner_; }
  TraceWriter& trace() { return *trace_; }

 private:
  std::unique_ptr<Bus> inner_;
  std::unique_ptr<TraceWriter> trace_;
  std::function<TimePoint()> clock_;
};

/// A frame observer that writes every frame with the time it is given, e.g. for the simulated
/// bus: `sim.add_observer(trace_observer(writer))` records every frame receivers see at its
/// simulated delivery time. `writer` is not owned and must outlive the observer; failures stay
/// in writer.status().
std::function<void(const CanFrame&, TimePoint)> trace_observer(TraceWriter& writer);

}  // namespace nmt
