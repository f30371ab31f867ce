// The NMT master's boot NMT slave engines, one per node-ID 1..127 (BootSlaveProcess), with the
// start-up's boot-up gate they share (boot_up_gate.hpp) and the index of their deadlines. Every
// call of an engine goes through with(), which files the engine's new deadline, so that
// next_deadline() and on_timer() need no scan of 127 engines and no caller can forget the
// index. Private to the library.
#pragma once

#include <array>
#include <optional>
#include <span>
#include <type_traits>
#include <utility>
#include <vector>

#include "master/boot_slave_process.hpp"
#include "master/boot_up_gate.hpp"
#include "nmt/protocol/deadline_queue.hpp"

namespace nmt {

class BootSlaveSet {
 public:
  using Output = BootSlaveProcess::Output;

  BootSlaveSet(BootSlavePort& port, const BootSlaveProcess::Options& options);
  // The engines hold a reference to gate_: the set stays where it was built.
  BootSlaveSet(const BootSlaveSet&) = delete;
  BootSlaveSet& operator=(const BootSlaveSet&) = delete;

  /// The engine of `node`, to read.
  const BootSlaveProcess& operator[](cfg::NodeId node) const { return engines_[node.value() - 1U]; }
  /// Every engine, node-ID 1 first.
  std::span<const BootSlaveProcess> all() const { return engines_; }

  /// Calls `call(engine)` on the engine of `node` and files its deadline; returns what `call`
  /// returns.
  template <class Call>
  decltype(auto) with(cfg::NodeId node, Call&& call) {
    auto& engine = engines_[node.value() - 1U];
    if constexpr (std::is_void_v<std::invoke_result_t<Call, BootSlaveProcess&>>) {
      std::forward<Call>(call)(engine);
      track(node);
    } else {
      auto result = std::forward<Call>(call)(engine);
      track(node);
      return result;
    }
  }

  BootUpGate& gate() { return gate_; }
  const BootUpGate& gate() const { return gate_; }
  /// Opens the gate for the boots waiting at it once every one of them saw its boot-up, or at
  /// once when `quiet` (the paced quiet time passed, BootUpGate::kQuiet).
  void open_gate(TimePoint now, Output& out, bool quiet = false);

  /// The gate's quiet time, then the due engines in node-ID order (as the events have always
  /// come).
  void on_timer(TimePoint now, Output& out);
  /// The earliest of the gate's and the engines' deadlines.
  std::optional<TimePoint> next_deadline() const;

 private:
  void track(cfg::NodeId node);

  BootUpGate gate_;
  std::vector<BootSlaveProcess> engines_;
  /// The engines' deadlines, earliest first, and each one's as the index holds it.
  DeadlineQueue<cfg::NodeId> deadlines_;
  std::array<std::optional<TimePoint>, 128> deadline_of_{};
};

}  // namespace nmt
