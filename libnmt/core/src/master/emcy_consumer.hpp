// The NMT master's emergency consumer (CiA 301 §7.2.7): the EMCY of every node it watches, on
// the COB-ID it was given (the master's 1028h sub node-ID, CiA 301 §7.5.2.30, else the slave's
// 1014h from its DCF, else 80h + node-ID), decoded and reported per node. Bounded: per node and
// error code at most `max_per_window` messages are reported in a window of `window` from the
// first; the rest are counted, and one Flood event with the count follows when the window ends
// (or at the node's error reset, which also ends its windows). An engine (engine.hpp) of its
// own, tested alone in tests/nmt/emcy_consumer_test.cpp; private to the library.
#pragma once

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <optional>

#include "cfg/cob_id.hpp"
#include "cfg/node_id.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/emcy.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// What the consumer reports.
struct EmcyConsumerEvent {
  enum class Kind : std::uint8_t {
    Emergency,  ///< an EMCY of `node` (error code 0000h: error reset or no error)
    Flood,      ///< `suppressed` EMCYs of `node` with `emcy.error_code` were not reported in the
                ///< window that began at `window_began`; `emcy` is the last of them
  };
  Kind kind = Kind::Emergency;
  cfg::NodeId node;
  Emergency emcy{};
  TimePoint at{};
  /// Emergency with code 0000h: the node had reported an error before (since its last reset):
  /// this ends it.
  bool ends_error = false;
  std::uint32_t suppressed = 0;  ///< Flood: how many
  TimePoint window_began{};      ///< Flood
  bool operator==(const EmcyConsumerEvent&) const = default;
};

/// The consumer's bound (MasterOptions::emcy).
struct EmcyConsumerSettings {
  /// Per node and error code, at most this many reported per window (>= 1).
  unsigned max_per_window = 5;
  std::chrono::milliseconds window{1000};
};

class EmcyConsumer {
 public:
  using Event = EmcyConsumerEvent;
  using Output = Outbox<Event>;

  using Settings = EmcyConsumerSettings;

  explicit EmcyConsumer(Settings settings = {}) : settings_(settings) {}

  /// Consumes the EMCY of `node` on `cob_id` (replacing an earlier one); an invalid COB-ID (bit
  /// 31 set) consumes nothing for the node.
  void consume(cfg::NodeId node, cfg::CobId cob_id);
  /// Stops consuming everything (counts kept).
  void clear();
  /// The COB-ID consumed for `node`; nullopt when none.
  std::optional<cfg::CobId> cob_id(cfg::NodeId node) const;

  /// An 8-byte frame on a consumed COB-ID is an EMCY: reported (or counted, see the top).
  /// Other frames are not looked at (false).
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  /// Ends the windows that are over: a Flood event for each that suppressed any.
  void on_timer(TimePoint now, Output& out);
  /// Ends every open window now, over or not: a Flood event for each that suppressed any (the
  /// driver stops: a count not said now would be lost).
  void end_windows(TimePoint now, Output& out);
  /// The end of the earliest window that suppressed something; nullopt when none.
  std::optional<TimePoint> next_deadline() const;

  /// EMCYs received from `node` (reported or not) since construction.
  std::uint64_t received(cfg::NodeId node) const { return received_[node.value()]; }

 private:
  struct Window {
    TimePoint began{};
    unsigned reported = 0;
    std::uint32_t suppressed = 0;
    Emergency last{};
  };
  void end_window(cfg::NodeId node, std::uint16_t code, Window& w, TimePoint now, Output& out);

  Settings settings_;
  std::array<std::optional<cfg::CobId>, 128> cob_ids_{};
  std::array<std::uint64_t, 128> received_{};
  std::array<bool, 128> in_error_{};
  /// Open windows by (node << 16 | code).
  std::map<std::uint32_t, Window> windows_;
};
static_assert(Engine<EmcyConsumer>);

}  // namespace nmt
