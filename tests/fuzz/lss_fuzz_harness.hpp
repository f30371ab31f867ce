// What fuzz_lss and fuzz_execute_lss share: an LSS master side (the LssMaster, or the NMT
// master's Execute LSS that runs one) and up to four LSS slaves (nmt/lss/lss_slave.hpp) on a bus
// the input controls: frames are delivered or lost, frames of any content are injected on 7E5h and
// 7E4h, time advances. Each target adds its own starts (start_op) and checks.
// Input: byte 0 the LSS timing and the number of slaves, then per slave its LSS address (from a
// few bytes, so addresses share parts and differ in few bits) and whether it has a node-ID; the
// rest are operations (run_ops).
// Checks: no crash; after on_timer() at a time at or past the master's deadline the deadline is
// gone or later (a driver never spins); slaves ask for no timer.
#pragma once

#include <cstdint>
#include <deque>
#include <memory>
#include <span>
#include <vector>

#include "../support/fuzz_support.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/lss/lss_slave.hpp"

namespace lss_fuzz {

using fuzz_support::Input;
using nmt::CanFrame;
using nmt::TimePoint;

struct Queued {
  CanFrame frame;
  int sender;  // -1 master, else slave index, -2 injected
};

/// The bus, the slaves and the master side `M` (an engine of the shape of nmt/engine.hpp).
template <class M>
struct Harness {
  M& master;
  std::vector<std::unique_ptr<nmt::LssSlave>> slaves;
  std::deque<Queued> bus;
  TimePoint now{};
  std::vector<typename M::Event> events;  ///< what the master side reported, in order

  explicit Harness(M& m) : master(m) {}

  void take_master(typename M::Output& out) {
    for (const auto& f : out.frames) bus.push_back({f, -1});
    for (auto& e : out.events) events.push_back(std::move(e));
    out.clear();
  }
  void deliver() {
    if (bus.empty()) return;
    const Queued q = bus.front();
    bus.pop_front();
    if (q.sender != -1) {
      typename M::Output out;
      master.on_frame(q.frame, now, out);
      take_master(out);
    }
    for (std::size_t i = 0; i < slaves.size(); ++i) {
      if (static_cast<int>(i) == q.sender) continue;
      nmt::LssSlave::Output out;
      slaves[i]->on_frame(q.frame, now, out);
      for (const auto& f : out.frames) bus.push_back({f, static_cast<int>(i)});
      for (const auto& e : out.events) {
        if (e.kind == nmt::LssSlaveEvent::Kind::NodeIdActivate) {
          slaves[i]->activate_pending_node_id();
        }
      }
      check(!slaves[i]->next_deadline().has_value());
    }
  }
  void advance(nmt::Duration limit) {
    TimePoint t = now + limit;
    if (auto d = master.next_deadline(); d && *d < t) t = *d;
    if (t > now) now = t;
    if (auto d = master.next_deadline(); d && *d <= now) {
      typename M::Output out;
      master.on_timer(now, out);
      take_master(out);
      const auto after = master.next_deadline();
      check(!after || *after > now);
    }
  }
};

inline nmt::LssAddress address_from(Input& in) {
  const std::uint8_t a = in.next();
  const std::uint8_t b = in.next();
  return {0x100u + (a & 0x03), 0x20u + (a >> 2 & 0x03), 1u << (a >> 4 & 0x0F), 0xCAFE0000u | b};
}

/// The LSS timing of byte 0 of the input.
inline nmt::LssMasterOptions timing_from(std::uint8_t setup) {
  nmt::LssMasterOptions options;
  options.timeout = std::chrono::milliseconds(1 + (setup & 0x0F) * 10);
  options.scan_step = std::chrono::milliseconds(1 + (setup >> 4 & 0x03) * 5);
  options.store = (setup & 0x40) != 0;
  return options;
}

/// The slaves of the input (after byte 0 `setup`).
template <class M>
void add_slaves(Harness<M>& h, std::uint8_t setup, Input& in) {
  const int slaves = 1 + (setup >> 7) * 3;
  for (int i = 0; i < slaves; ++i) {
    const auto a = address_from(in);
    const std::uint8_t node = in.next();
    nmt::LssSlaveOptions so;
    so.store_supported = (node & 0x80) == 0;
    h.slaves.push_back(std::make_unique<nmt::LssSlave>(
        a, (node & 0x40) != 0 ? static_cast<std::uint8_t>(1 + node % 127) : nmt::lss::kUnconfigured,
        so));
  }
}

/// The operations of the rest of the input: `start_op()` for a start (it reads its own bytes),
/// `invariant()` after each operation.
template <class M, class Start, class Invariant>
void run_ops(Harness<M>& h, Input& in, Start start_op, Invariant invariant) {
  while (!in.empty()) {
    const std::uint8_t op = in.next();
    switch (op & 0x07) {
      case 0:
      case 1:
      case 2:
        h.deliver();
        break;
      case 3:
        if (!h.bus.empty()) h.bus.pop_front();  // lost
        break;
      case 4: {  // a frame from nowhere: an LSS frame of any content, sometimes short
        std::uint8_t bytes[8];
        for (auto& b : bytes) b = in.next();
        const std::uint32_t id = (op & 0x08) != 0 ? nmt::lss::kMasterCobId : nmt::lss::kSlaveCobId;
        const std::size_t dlc = (op & 0x10) != 0 ? 8 : in.next() % 9;
        h.bus.push_front({CanFrame::make(id, std::span(bytes, dlc)), -2});
        break;
      }
      case 5:
      case 6:
        start_op();
        break;
      case 7:
        h.advance(std::chrono::milliseconds(op >> 3));
        break;
    }
    invariant();
  }
}

}  // namespace lss_fuzz
