// The NMT command queue of the NMT master: the NMT module control services it requests, in the
// order it requested them, at least the NMT inhibit time apart (CiA 302-2 §6.1, object 102Ah).
// Private to the library.
//
// An engine of the shape of nmt/engine.hpp. Its port is the smallest there is: the master
// queues (command, node) with queue() and tells it 102Ah's value with set_inhibit_time(); the
// queue answers with frames (CiA 301 §7.2.8.3.1: COB-ID 000h, byte 0 the command specifier,
// byte 1 the node-ID, 0 for all nodes) and one event per command sent, from which the master
// updates what it knows of the slaves' states. A queued command is due at once (engine.hpp rule
// 5, second form: work made due at `now`), or when the inhibit time since the last one ends.
//
// Order on the bus is output order: the master runs the queue after its parts of a call and
// before it hands out the SDO requests of the call, so a reset reaches a slave before the
// request that follows it (nmt_master.cpp, settle()). The queue itself only appends.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <optional>
#include <utility>

#include "nmt/engine.hpp"
#include "nmt/slave/nmt_slave.hpp"

namespace nmt {

class NmtCommandQueue {
 public:
  /// A command that left (its frame is in the same Output, in the same order).
  struct Sent {
    NmtCommand command;
    NmtTarget target;
    bool operator==(const Sent&) const = default;
  };
  using Event = Sent;
  using Output = Outbox<Event>;

  /// 102Ah in the engine's units (multiples of 100 µs); 0: no inhibit time.
  void set_inhibit_time(Duration inhibit) { inhibit_ = inhibit; }
  Duration inhibit_time() const { return inhibit_; }

  /// Queues `command` for `target`; due at once unless the inhibit time runs.
  void queue(NmtCommand command, NmtTarget target) { queue_.emplace_back(command, target); }
  std::size_t size() const { return queue_.size(); }
  bool empty() const { return queue_.empty(); }

  /// The queue takes no frames (an NMT command of another master is the master's concern).
  bool on_frame(const CanFrame& /*frame*/, TimePoint /*now*/, Output& /*out*/) { return false; }
  /// Sends the due commands, in order, each at least the inhibit time after the one before.
  void on_timer(TimePoint now, Output& out);
  /// Nothing queued: nullopt; else when the inhibit time allows the next (TimePoint{}: now).
  std::optional<TimePoint> next_deadline() const;

 private:
  bool inhibited(TimePoint now) const {
    return inhibit_.count() > 0 && last_ && now < *last_ + inhibit_;
  }

  std::deque<std::pair<NmtCommand, NmtTarget>> queue_;
  std::optional<TimePoint> last_;  ///< when the last command left
  Duration inhibit_{0};
};

static_assert(Engine<NmtCommandQueue>);

}  // namespace nmt
