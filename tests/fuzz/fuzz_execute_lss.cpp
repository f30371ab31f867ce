// libFuzzer target: the NMT master's Execute LSS (master/execute_lss.hpp: the start-up pass and
// the looks for unconfigured devices, over an LssProcedure) and up to four LSS slaves on a bus the
// input controls (lss_fuzz_harness.hpp), with a port whose slaves' LSS addresses the input
// chooses (some devices' addresses, some of nobody's, one node-ID for two addresses).
// Operations beyond the harness's: start(), watch(), stop(), the port's "may look" toggled.
// Checks: no crash; the harness's deadline checks; a pass or look that runs has a deadline, Off
// has none; pass_ended only ends a start()ed pass, once, not a stopped one; LssAssigned and
// LssFailed name the slave whose LSS address the device has, LssUnmatched one that no slave has;
// once the input ends and frames flow with time advancing, a pass or look ends within a bounded
// number of steps.
#include <cstdint>
#include <map>
#include <optional>
#include <vector>

#include "lss_fuzz_harness.hpp"
#include "master/execute_lss.hpp"

namespace {

using namespace std::chrono_literals;
using lss_fuzz::Input;
using Phase = nmt::ExecuteLssProcess::Phase;
using Kind = nmt::MasterEvent::Kind;

struct FuzzPort final : nmt::ExecuteLssPort {
  std::optional<cfg::NodeId> slave_with(const nmt::LssAddress& address) const override {
    for (const auto& [node, a] : slaves) {
      if (a == address) return node;
    }
    return std::nullopt;
  }
  std::vector<nmt::LssAddress> known_addresses() const override {
    std::vector<nmt::LssAddress> known;
    for (const auto& [node, a] : slaves) known.push_back(a);
    return known;
  }
  void pass_ended(nmt::TimePoint /*now*/, Output& /*out*/) override {
    // Only a start-up pass ends, once, and not after stop().
    check(pass_open);
    pass_open = false;
    ++passes_ended;
  }
  bool may_look() const override { return looking; }

  std::map<cfg::NodeId, nmt::LssAddress> slaves;
  bool pass_open = false;  ///< start() called, its pass not ended or stopped
  int passes_ended = 0;
  bool looking = true;
};

using ExecuteHarness = lss_fuzz::Harness<nmt::ExecuteLssProcess>;

void check_state(const ExecuteHarness& h) {
  const Phase phase = h.master.phase();
  if (phase == Phase::Off) check(!h.master.next_deadline().has_value());
  if (phase == Phase::Startup || phase == Phase::Probe || phase == Phase::Scan) {
    check(h.master.next_deadline().has_value());
  }
}

void check_events(const ExecuteHarness& h, const FuzzPort& port, std::size_t from) {
  for (std::size_t i = from; i < h.events.size(); ++i) {
    const auto& e = h.events[i];
    if (e.kind == Kind::LssAssigned || e.kind == Kind::LssFailed) {
      check(e.node_id.has_value() && e.lss_address.has_value());
      check(port.slave_with(*e.lss_address) == e.node_id);
    }
    if (e.kind == Kind::LssUnmatched) {
      check(e.lss_address.has_value() && !port.slave_with(*e.lss_address).has_value());
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Input in{data, size};
  const std::uint8_t setup = in.next();
  const std::uint8_t port_setup = in.next();
  FuzzPort port;
  // A look every 0, 20, 200 or 1000 ms (0: none after the pass).
  const nmt::Duration periods[] = {0ms, 20ms, 200ms, 1000ms};
  nmt::ExecuteLssProcess process(port, lss_fuzz::timing_from(setup), periods[port_setup & 3]);
  ExecuteHarness h(process);
  lss_fuzz::add_slaves(h, setup, in);
  // Which devices are a slave's, and which node-ID: a byte each (bit 0: a slave's; the rest its
  // node-ID, so two devices may name one node and the later one wins); and one slave whose
  // device is absent.
  for (const auto& slave : h.slaves) {
    const std::uint8_t b = in.next();
    if ((b & 1) == 0) continue;
    port.slaves[*cfg::NodeId::from(1 + (b >> 1) % 127)] = slave->address();
  }
  if ((port_setup & 4) != 0) {
    port.slaves[*cfg::NodeId::from(1 + (port_setup >> 3) % 127)] = lss_fuzz::address_from(in);
  }

  int starts = 0;
  lss_fuzz::run_ops(
      h, in,
      [&] {
        const std::uint8_t op = in.next();
        nmt::ExecuteLssProcess::Output out;
        switch (op % 4) {
          case 0:
            ++starts;
            port.pass_open = true;
            process.start(h.now, out);
            break;
          case 1:
            process.watch(h.now);
            break;
          case 2:
            port.pass_open = false;
            process.stop();
            break;
          default:
            port.looking = !port.looking;
            break;
        }
        h.take_master(out);
      },
      [&] {
        check_state(h);
        check(port.passes_ended <= starts);
      });

  // Frames flow and time runs: a pass or look ends (each finds at most four devices once).
  for (int guard = 0;
       !h.bus.empty() || (process.phase() != Phase::Idle && process.phase() != Phase::Off);
       ++guard) {
    check(guard < 100000);
    if (!h.bus.empty()) {
      h.deliver();
    } else {
      h.advance(1s);
    }
    check_state(h);
  }
  check(port.passes_ended <= starts);
  check_events(h, port, 0);
  return 0;
}
