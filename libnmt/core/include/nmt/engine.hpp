// The one shape of every protocol engine in libnmt (SDO server and client, NMT slave, heartbeat
// producer and consumer, node and life guarding, EMCY, LSS master and slave, the slave node, the
// SDO requesting device, and the NMT master with its processes: its error control, the flying
// master, the SDO manager, the NMT command queue, Execute LSS). The configuration manager's
// objects are a process of the master without frames or timers of their own
// (ConfigurationStoreObjects, reached through the dictionary's hooks): they keep rules 5 and 6.
// Boot slave has timers but no frames of its own: the master hands it its node's error control
// messages as typed inputs (it updates 1F82h first) and reads its deadline after each call.
// This comment is the contract; the concept below checks its signatures at compile time, and
// each driver has one adapter that runs any engine (SimEngineNode in sim_bus.hpp, EngineRef in
// bus_event_loop.hpp).
//
// An engine is sans-I/O: it never reads a clock or touches a bus. It is fed
//   bool on_frame(const CanFrame& frame, TimePoint now, Output& out);  // a frame seen on the bus
//   void on_timer(TimePoint now, Output& out);                          // time has come
//   std::optional<TimePoint> next_deadline() const;                     // when to call on_timer
// and answers through one output type, Outbox<Event>: frames to send (in order) and events for
// the application (in the order they happened). `Event` is the engine's own event type (NoEvent
// when it has nothing to report).
//
// Rules every engine keeps and every driver relies on:
// 1. Time is a TimePoint (frame.hpp): microseconds since an epoch the driver chooses (simulated
//    time on the simulated bus, a monotonic clock on real buses), a std::chrono::time_point of
//    its own clock so it cannot be mixed up with a Duration (a timeout, a period). It never goes
//    back from one call to the next.
// 2. on_frame sees every frame of the bus, including those other engines of the same program
//    sent (drivers echo them; CAN nodes hear every frame). It returns true when the frame was
//    addressed to this engine (an SDO request for this server, an NMT command for this node),
//    false when the engine ignored it.
// 3. on_timer may be called at any time at or after next_deadline(), also early or twice:
//    the engine checks its own due times, so a spurious call changes nothing.
// 4. next_deadline() is nullopt when nothing is due; a time in the past (TimePoint{}) means
//    "as soon as possible". Any call may change it, so drivers read it after every call.
// 5. Calls of the engine's own API that start work (an SDO transfer, an emergency, a state
//    change, a power-on) take `TimePoint now, Output& out` as their last two parameters and,
//    before they return, put into `out` the frames and events the start causes at once: nothing
//    started through the API waits for a timer to reach the bus. Work that follows later is due
//    from next_deadline(); so is the one step CiA 301 puts between a device's power-on or reset
//    and its boot-up (initialisation), which ends at the next on_timer (due at `now`).
//    One verb, start: start(now, out) brings up a device (SlaveNode, SdoRequestingDevice,
//    NmtSlave, the fault wrappers; calling it again is a power cycle) or begins a process (the
//    NMT master, a boot slave process); start(..., now, out) begins one piece of work (an LSS
//    service, node guarding of a node); work with a verb of its own uses it (upload, download,
//    raise). There is no second verb for beginning (no power_on).
//    Could not start: the call returns cfg::Result<Id> (cfg::Status when the work has no id to
//    follow it by) whose error says why, and puts nothing into `out` (SdoRequestingDevice,
//    NmtMaster::boot_slave, SdoClient, NmtMaster::sdo_upload/sdo_download, the LssMaster
//    services, NodeGuardingMaster::start). Work that started and ended at once with an outcome
//    of its own protocol has started: the outcome is an event (a boot NMT slave process of a node
//    taken out of 1F81h while the master retries it ends with status A, CiA 302-2 §3.4 a).
//    Parameter writes are no starts and take no Output: HeartbeatProducer::set_period (1017h;
//    its first heartbeat is due at `now`, so it follows the SDO answer confirming the write),
//    HeartbeatConsumer::monitor (1016h; nothing is sent or reported at once) and
//    NodeGuardingMaster::guard (its first request is due at `now`: the NMT master's error
//    control, whose first request follows the NMT start and SDO requests of the same call).
//    LssSlave::start takes no `now, out` on purpose: an LSS slave never sends on its own
//    (nmt/lss/lss_slave.hpp).
// 6. Engines keep no reference to `out` or to a frame after a call returns; they only append,
//    and only to the `out` of the call they are in: what a dictionary hook reports goes into
//    the output of the call the access runs in (LocalDictionary's HookOutput), never into a
//    list kept for the next call.
// 7. Engines that contain engines (the slave node, the master) forward frames and time to them
//    and report their parts' events as their own event type. Test faults (latency, loss,
//    reboots) live in wrappers of the same shape (nmt/sim/fault_injection.hpp), never inside a
//    protocol engine.
#pragma once

#include <concepts>
#include <optional>
#include <type_traits>
#include <utility>
#include <vector>

#include "nmt/protocol/frame.hpp"

namespace nmt {

/// The event type of engines that report nothing but frames.
struct NoEvent {
  bool operator==(const NoEvent&) const = default;
};

/// What an engine call hands back: frames to send, in order, and events for the application.
/// The caller owns it, clears it between uses (or not: engines only append), and sends
/// `frames` in order.
template <class Event>
struct Outbox {
  std::vector<CanFrame> frames;
  std::vector<Event> events;

  void send(const CanFrame& frame) { frames.push_back(frame); }
  void report(Event event) { events.push_back(std::move(event)); }
  void clear() {
    frames.clear();
    events.clear();
  }
  bool empty() const { return frames.empty() && events.empty(); }
};

/// The engine contract above, as far as a compiler can check it.
template <class E>
concept Engine = requires(E& engine, const E& const_engine, const CanFrame& frame, TimePoint now,
                          Outbox<typename E::Event>& out) {
  typename E::Event;
  requires std::same_as<typename E::Output, Outbox<typename E::Event>>;
  { engine.on_frame(frame, now, out) } -> std::same_as<bool>;
  { engine.on_timer(now, out) } -> std::same_as<void>;
  { const_engine.next_deadline() } -> std::same_as<std::optional<TimePoint>>;
};

/// The earlier of two deadlines (nullopt: none), for engines made of engines.
inline std::optional<TimePoint> earliest(std::optional<TimePoint> a, std::optional<TimePoint> b) {
  if (!a) return b;
  if (!b) return a;
  return *a < *b ? a : b;
}

/// For engine drivers (EngineRef, SimEngineNode): returns what `call()` returns after running
/// `flush()` (send the call's frames, hand its events to the user's handler); when `call()`
/// throws, flushes what it put out before and lets its exception go on. `flush()` runs as plain
/// code, not from a destructor: an exception of the user's handler reaches the caller instead
/// of ending in std::terminate.
template <class Call, class Flush>
std::invoke_result_t<Call> call_then_flush(Call&& call, Flush&& flush) {
  using Result = std::invoke_result_t<Call>;
  auto guarded = [&]() -> Result {
    try {
      return std::forward<Call>(call)();
    } catch (...) {
      flush();
      throw;
    }
  };
  if constexpr (std::is_void_v<Result>) {
    guarded();
    flush();
  } else {
    Result result = guarded();
    flush();
    return std::forward<Result>(result);
  }
}

}  // namespace nmt
