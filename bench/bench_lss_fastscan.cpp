// LSS Fastscan (CiA 305) of N unconfigured devices at 500 kbit/s on the simulated bus: the bus
// time of `LssProcedure::scan` (find each device by Fastscan, give it a node-ID, store it) against
// the frame bound of the scan.
//
// The frame bound, counted from the protocol as nmt/lss/lss_procedure.hpp describes it: per device
// the Fastscan reset (BitCheck 80h), then per part of the LSS address (vendor-ID, product code,
// revision, serial number) 32 bit queries and a confirmation, 1 + 4 x 33 = 133 requests; then
// configure node-ID, store configuration and switch state global to waiting, 3 more: 136 per
// device. Before them one switch state global of all devices, after them the reset nobody
// answers: 136 N + 2 requests (tests/nmt/lss_procedure_test.cpp checks this count). Each is an
// 8-byte standard frame, 111 bits on the wire before stuffing (SOF to CRC 98, delimiters, ACK
// and EOF 10, intermission 3): 222 us at 500 kbit/s. The bound counts the master's requests
// only, sent back to back; the devices' answers and the time a Fastscan step waits for them
// (LssMasterOptions::scan_step, `cfgmgr lss --scan-step`) come on top.
//
// Counters: sim_s the simulated time of the scan, bound_s the frame bound, ratio sim / bound,
// requests the master's frames (= 136 N + 2), frames all frames on the bus, load the bus load.
// Args: N devices, scan step in microseconds (10000 = the engine's default of 10 ms).
// Run from a Release build: build-x/bench/bench_lss_fastscan
#include <benchmark/benchmark.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <random>
#include <set>
#include <vector>

#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/lss/lss_procedure.hpp"
#include "nmt/lss/lss_slave.hpp"
#include "nmt/sim/sim_bus.hpp"

namespace {

using namespace std::chrono_literals;

constexpr std::uint32_t kBitrate = 500'000;
constexpr double kBitsPerRequest = 111.0;  // 8-byte standard frame before stuffing

void BM_LssFastscan(benchmark::State& state) {
  const auto n = static_cast<int>(state.range(0));
  const auto step = nmt::Duration(state.range(1));
  double sim_s = 0;
  std::uint64_t requests = 0;
  nmt::SimBusStats stats;
  for (auto _ : state) {
    state.PauseTiming();
    nmt::SimBus bus(kBitrate);
    nmt::LssMasterOptions options;
    options.scan_step = step;
    nmt::SimEngineNode<nmt::LssProcedure> master(options);
    bus.attach(master);
    // One product, random serial numbers (a batch of new devices), the same every run.
    std::mt19937 rng(static_cast<std::uint32_t>(n));
    std::set<nmt::LssAddress> addresses;
    while (static_cast<int>(addresses.size()) < n) {
      addresses.insert(
          nmt::LssAddress{0x0000019A, 0x00020001, 0x00010000, static_cast<std::uint32_t>(rng())});
    }
    std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::LssSlave>>> slaves;
    for (const auto& a : addresses) {
      slaves.push_back(
          std::make_unique<nmt::SimEngineNode<nmt::LssSlave>>(a, nmt::lss::kUnconfigured));
      auto* raw = slaves.back().get();
      raw->set_event_handler([raw](const nmt::LssSlaveEvent& e, nmt::TimePoint) {
        if (e.kind == nmt::LssSlaveEvent::Kind::NodeIdActivate) {
          raw->engine().activate_pending_node_id();
        }
      });
      bus.attach(*raw);
    }
    std::uint64_t sent = 0;
    bus.add_observer([&sent](const nmt::CanFrame& f, nmt::TimePoint) {
      sent += f.id == nmt::lss::kMasterCobId ? 1 : 0;
    });
    std::uint32_t assigned = 0;
    master.set_event_handler([&assigned](const nmt::LssProcedureEvent& e, nmt::TimePoint) {
      assigned += e.kind == nmt::LssProcedureEvent::Kind::Assigned ? 1 : 0;
    });
    state.ResumeTiming();
    std::uint8_t next = 1;
    const nmt::TimePoint start = bus.now();
    (void)master.apply([&next](auto& m, auto t, auto& o) {
      return m.scan([&next](const nmt::LssAddress&) { return cfg::NodeId::from(next++); }, t, o);
    });
    if (!bus.run_until([&master] { return !master.engine().busy(); }, nmt::TimePoint{36000s}) ||
        assigned != static_cast<std::uint32_t>(n)) {
      state.SkipWithError("the scan did not configure every device");
      return;
    }
    sim_s = static_cast<double>((bus.now() - start).count()) / 1e6;
    requests = sent;
    stats = bus.statistics();
  }
  const double bound_s =
      static_cast<double>(136 * n + 2) * kBitsPerRequest / static_cast<double>(kBitrate);
  state.counters["sim_s"] = sim_s;
  state.counters["bound_s"] = bound_s;
  state.counters["ratio"] = sim_s / bound_s;
  state.counters["requests"] = static_cast<double>(requests);
  state.counters["frames"] = static_cast<double>(stats.frames);
  state.counters["load"] = stats.load();
}
BENCHMARK(BM_LssFastscan)
    ->ArgsProduct({{1, 10, 50, 126}, {10000, 1000}})
    ->ArgNames({"devices", "step_us"})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

// Scan with known addresses (LssProcedure::scan's `targets`, what Execute LSS runs): `targets`
// known addresses of one product, of which every `stride`-th has its device on the bus, out of the
// box (the others absent: the project describes more devices than are connected), plus
// `configured` more devices with their node-IDs whose addresses are targets too, listed first
// (a push --lss of a network in which one device was replaced). Counters: sim_s the simulated
// time of the scan, frames all frames on the bus, assigned the devices given a node-ID.
// Args: targets, stride (1: all present; 0: none), configured, scan step in microseconds.
void BM_LssKnownAddresses(benchmark::State& state) {
  const auto targets = static_cast<int>(state.range(0));
  const auto stride = static_cast<int>(state.range(1));
  const auto configured = static_cast<int>(state.range(2));
  const auto step = nmt::Duration(state.range(3));
  double sim_s = 0;
  std::uint32_t assigned = 0;
  int present = 0;
  nmt::SimBusStats stats;
  for (auto _ : state) {
    state.PauseTiming();
    nmt::SimBus bus(kBitrate);
    nmt::LssMasterOptions options;
    options.scan_step = step;
    nmt::SimEngineNode<nmt::LssProcedure> master(options);
    bus.attach(master);
    std::vector<nmt::LssAddress> known;
    std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::LssSlave>>> slaves;
    auto add = [&](const nmt::LssAddress& a, std::uint8_t node_id) {
      slaves.push_back(std::make_unique<nmt::SimEngineNode<nmt::LssSlave>>(a, node_id));
      auto* raw = slaves.back().get();
      raw->set_event_handler([raw](const nmt::LssSlaveEvent& e, nmt::TimePoint) {
        if (e.kind == nmt::LssSlaveEvent::Kind::NodeIdActivate) {
          raw->engine().activate_pending_node_id();
        }
      });
      bus.attach(*raw);
    };
    for (int i = 0; i < configured; ++i) {
      const nmt::LssAddress a{0x0000019A, 0x00020001, 0x00010000, 0x10000000U + i};
      known.push_back(a);
      add(a, static_cast<std::uint8_t>(1 + i));
    }
    present = 0;
    for (int i = 0; i < targets; ++i) {
      const nmt::LssAddress a{0x0000019A, 0x00020001, 0x00010000, 0x20000000U + 7U * i};
      known.push_back(a);
      if (stride != 0 && i % stride == 0) {
        add(a, nmt::lss::kUnconfigured);
        ++present;
      }
    }
    assigned = 0;
    master.set_event_handler([&assigned](const nmt::LssProcedureEvent& e, nmt::TimePoint) {
      assigned += e.kind == nmt::LssProcedureEvent::Kind::Assigned ? 1 : 0;
    });
    state.ResumeTiming();
    std::uint8_t next = static_cast<std::uint8_t>(configured + 1);
    const nmt::TimePoint start = bus.now();
    (void)master.apply([&](auto& m, auto t, auto& o) {
      return m.scan([&next](const nmt::LssAddress&) { return cfg::NodeId::from(next++); }, t, o,
                    known);
    });
    if (!bus.run_until([&master] { return !master.engine().busy(); }, nmt::TimePoint{36000s}) ||
        assigned != static_cast<std::uint32_t>(present)) {
      state.SkipWithError("the scan did not configure every device");
      return;
    }
    sim_s = static_cast<double>((bus.now() - start).count()) / 1e6;
    stats = bus.statistics();
  }
  state.counters["sim_s"] = sim_s;
  state.counters["frames"] = static_cast<double>(stats.frames);
  state.counters["assigned"] = assigned;
}
BENCHMARK(BM_LssKnownAddresses)
    ->Args({126, 1, 0, 10000})    // all present (bench_push --lss)
    ->Args({126, 2, 0, 10000})    // every other absent
    ->Args({126, 13, 0, 10000})   // 10 present, 116 absent among them
    ->Args({126, 126, 0, 10000})  // the first present, 125 absent after it
    ->Args({1, 1, 125, 10000})    // 125 configured, then one new device
    ->ArgNames({"targets", "stride", "configured", "step_us"})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
