// libFuzzer target: an LSS master (nmt/lss_master.hpp) and up to four LSS slaves
// (nmt/lss_slave.hpp) on a bus the input controls: frames are delivered or lost, frames of any
// content are injected on 7E5h and 7E4h, services start, time advances.
// Input: byte 0 the master's timing and the number of slaves, then per slave its LSS address
// (from a few bytes, so addresses share parts and differ in few bits) and whether it has a
// node-ID; the rest are operations. Checks: no crash; a running service always has a deadline
// and after on_timer() at a time at or past it the deadline is gone or later (a driver never
// spins); slaves ask for no timer; once the input ends and frames flow with time advancing,
// the master ends its service within a bounded number of steps.
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <memory>
#include <vector>

#include "../support/fuzz_support.hpp"
#include "nmt/lss_master.hpp"
#include "nmt/lss_slave.hpp"

namespace {

using nmt::CanFrame;
using nmt::TimePoint;
using namespace std::chrono_literals;

using fuzz_support::Input;

struct Queued {
  CanFrame frame;
  int sender;  // -1 master, else slave index, -2 injected
};

struct Harness {
  nmt::LssMaster master;
  std::vector<std::unique_ptr<nmt::LssSlave>> slaves;
  std::deque<Queued> bus;
  TimePoint now{};

  explicit Harness(nmt::LssMasterOptions o) : master(o) {}

  void take_master(nmt::LssMaster::Output& out) {
    for (const auto& f : out.frames) bus.push_back({f, -1});
    out.clear();
  }
  void check_master_deadline() { check(master.busy() == master.next_deadline().has_value()); }
  void deliver() {
    if (bus.empty()) return;
    const Queued q = bus.front();
    bus.pop_front();
    if (q.sender != -1) {
      nmt::LssMaster::Output out;
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
    check_master_deadline();
  }
  void advance(nmt::Duration limit) {
    TimePoint t = now + limit;
    if (auto d = master.next_deadline(); d && *d < t) t = *d;
    if (t > now) now = t;
    if (auto d = master.next_deadline(); d && *d <= now) {
      nmt::LssMaster::Output out;
      master.on_timer(now, out);
      take_master(out);
      const auto after = master.next_deadline();
      check(!after || *after > now);
    }
    check_master_deadline();
  }
};

nmt::LssAddress address_from(Input& in) {
  const std::uint8_t a = in.next();
  const std::uint8_t b = in.next();
  return {0x100u + (a & 0x03), 0x20u + (a >> 2 & 0x03), 1u << (a >> 4 & 0x0F), 0xCAFE0000u | b};
}

void start_service(Harness& h, Input& in) {
  const std::uint8_t op = in.next();
  nmt::LssMaster::Output out;
  switch (op % 12) {
    case 0:
      h.master.switch_state_global(static_cast<nmt::LssState>(op >> 4 & 1), h.now, out);
      break;
    case 1:
      h.master.switch_state_selective(address_from(in), h.now, out);
      break;
    case 2:
      h.master.configure_node_id(in.next(), h.now, out);
      break;
    case 3:
      h.master.configure_bit_timing(in.next() % 12, h.now, out, in.next() % 2);
      break;
    case 4:
      h.master.activate_bit_timing(in.next() % 50, h.now, out);
      break;
    case 5:
      h.master.store_configuration(h.now, out);
      break;
    case 6:
      h.master.inquire(static_cast<nmt::LssService>(in.next() % 16), h.now, out);
      break;
    case 7: {
      const auto a = address_from(in);
      h.master.identify_remote_slaves({a.vendor_id, a.product_code, 0, a.revision, 0, a.serial},
                                      h.now, out);
      break;
    }
    case 8:
      h.master.identify_non_configured(h.now, out);
      break;
    case 9:
      h.master.fastscan(h.now, out);
      break;
    case 10:
      h.master.fastscan(h.now, out, address_from(in));
      break;
    default: {
      const std::uint8_t pick = in.next();
      h.master.scan(
          [pick](const nmt::LssAddress& a) -> std::optional<std::uint8_t> {
            const auto id = static_cast<std::uint8_t>((a.serial + pick) & 0xFF);
            if (id & 0x80) return std::nullopt;  // skipped
            return id;                           // 0 and others the device refuses included
          },
          h.now, out);
      break;
    }
  }
  h.take_master(out);
  h.check_master_deadline();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Input in{data, size};
  const std::uint8_t setup = in.next();
  nmt::LssMasterOptions options;
  options.timeout = std::chrono::milliseconds(1 + (setup & 0x0F) * 10);
  options.scan_step = std::chrono::milliseconds(1 + (setup >> 4 & 0x03) * 5);
  options.store = (setup & 0x40) != 0;
  Harness h(options);
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
        start_service(h, in);
        break;
      case 7:
        h.advance(std::chrono::milliseconds(op >> 3));
        break;
    }
  }

  // Frames flow and time runs: the service ends (a scan finds each of at most four devices
  // once, and every device it finds gets a node-ID or is looked past).
  for (int guard = 0; h.master.busy() || !h.bus.empty(); ++guard) {
    check(guard < 100000);
    if (!h.bus.empty()) {
      h.deliver();
    } else {
      h.advance(1s);
    }
  }
  check(!h.master.next_deadline().has_value());
  return 0;
}
