// The network scan (nmt::NetworkScanner under `cfgmgr scan`) on the simulated bus at 500 kbit/s,
// against the bounds issue 32 sets, in simulated time (exact, the same every run).
//
// BM_ScanNetwork: 127 node-IDs with N devices present (the sample drive and I/O modules,
// samples/network/*.dcf, at node-IDs spread over the range), each read in full (every entry
// cfg::entries_to_scan gives for its EDS). Bound: one SDO timeout (500 ms, the tool's default:
// what the absent node-IDs cost together) plus the air time of every frame of the scan
// (SimBusStats::busy_ns: each frame at its exact length, stuffing and intermission included).
// The requests are paced as the tool paces them with the bit rate known (97 % of the bus).
//
// BM_ReadDictionary: one device and its dictionary only (the probe and identity included): the
// sample drive (59 entries, strings by segmented upload) and bench::generate_dcf's device (PDOs
// and manufacturer records, expedited). Bound: the air time of its frames, request and answer
// one after the other (a device answers one request at a time, CiA 301 §7.2.4).
//
// Counters: sim_s, bound_s, ratio = sim / bound, frames, entries (read), absent.
// Run from a Release build: build-x/bench/bench_scan
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/device_scan.hpp"
#include "generated_dcf.hpp"
#include "nmt/manager/network_scanner.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"

namespace {

using namespace std::chrono_literals;
using Scanner = nmt::NetworkScanner;

constexpr std::uint32_t kBitrate = 500'000;
constexpr nmt::Duration kSdoTimeout = 500ms;

cfg::DeviceDescription read_or_die(const std::string& path) {
  auto r = cfg::read_device_file(path);
  if (!r.device) std::abort();
  return std::move(*r.device);
}

struct Result {
  double sim_s = 0;
  double busy_s = 0;
  std::uint64_t frames = 0;
  std::size_t entries = 0;
  std::size_t absent = 0;
  bool ok = false;
};

// Devices from `files` at `nodes`; the scanner asks `ask` and reads every entry of each found
// device's own file (the EDS a library match would give has the same entries).
Result scan(const std::vector<std::pair<const cfg::DeviceDescription*, unsigned>>& devices,
            const std::vector<cfg::NodeId>& ask) {
  nmt::SimBus bus(kBitrate);
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> nodes;
  std::map<unsigned, std::vector<cfg::ObjectAddress>> entries;
  for (const auto& [file, node] : devices) {
    nodes.push_back(std::make_unique<nmt::SimEngineNode<nmt::SimulatedDevice>>(
        nmt::SimulatedDevice::create(*file, static_cast<std::uint8_t>(node)).value()));
    bus.attach(*nodes.back());
    nodes.back()->apply(
        [](nmt::SimulatedDevice& d, nmt::TimePoint now, auto& out) { d.start(now, out); });
    entries[node] = cfg::entries_to_scan(*file);
  }
  bus.run_for(10ms);  // the boot-ups, as on a running machine
  nmt::ScanOptions options;
  options.sdo.timeout = kSdoTimeout;
  options.bitrate_bps = kBitrate;
  nmt::SimEngineNode<Scanner> scanner(options);
  bus.attach(scanner);
  Result result;
  scanner.set_event_handler([&](const Scanner::Event& e, nmt::TimePoint) {
    if (const auto* found = std::get_if<Scanner::NodeFound>(&e)) {
      scanner.apply([&](Scanner& s, nmt::TimePoint now, auto& out) {
        (void)s.read(found->node, entries[found->node.value()], now, out);
      });
    } else if (const auto* read = std::get_if<Scanner::EntryRead>(&e)) {
      result.entries += read->ok() ? 1 : 0;
    } else if (std::holds_alternative<Scanner::NodeAbsent>(e)) {
      ++result.absent;
    }
  });
  bus.reset_statistics();
  const nmt::TimePoint began = bus.now();
  scanner.apply([&](Scanner& s, nmt::TimePoint now, auto& out) { s.start(ask, now, out); });
  result.ok = bus.run_until([&] { return scanner.engine().finished(); }, began + 3600s);
  result.sim_s = std::chrono::duration<double>(bus.now() - began).count();
  const auto stats = bus.statistics();
  result.busy_s = static_cast<double>(stats.busy_ns) / 1e9;
  result.frames = stats.frames;
  return result;
}

void report(benchmark::State& state, const Result& r, double bound_s) {
  state.counters["sim_s"] = r.sim_s;
  state.counters["bound_s"] = bound_s;
  state.counters["ratio"] = r.sim_s / bound_s;
  state.counters["frames"] = static_cast<double>(r.frames);
  state.counters["entries"] = static_cast<double>(r.entries);
  state.counters["absent"] = static_cast<double>(r.absent);
}

void BM_ScanNetwork(benchmark::State& state) {
  const auto present = static_cast<unsigned>(state.range(0));
  const std::string samples = CANOPEN_SAMPLES_DIR;
  const auto drive = read_or_die(samples + "/network/drive_node3.dcf");
  const auto io = read_or_die(samples + "/network/io_module_node2.dcf");
  std::vector<std::pair<const cfg::DeviceDescription*, unsigned>> devices;
  for (unsigned i = 0; i < present; ++i) {
    devices.emplace_back(i % 2 == 0 ? &drive : &io, 2 + i * (125 / (present ? present : 1)));
  }
  std::vector<cfg::NodeId> all;
  for (unsigned n = 1; n <= 127; ++n)
    all.push_back(*cfg::NodeId::from(static_cast<std::uint8_t>(n)));
  Result r;
  for (auto _ : state) r = scan(devices, all);
  if (!r.ok) state.SkipWithError("the scan did not end");
  report(state, r, std::chrono::duration<double>(kSdoTimeout).count() + r.busy_s);
}
BENCHMARK(BM_ScanNetwork)
    ->Arg(4)
    ->Arg(16)
    ->ArgName("present")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

void BM_ReadDictionary(benchmark::State& state) {
  const std::string samples = CANOPEN_SAMPLES_DIR;
  const auto drive = read_or_die(samples + "/network/drive_node3.dcf");
  cfg::ReadOptions options;
  options.file_name = "generated.dcf";
  auto generated = cfg::parse_device_description(bench::generate_dcf(16, 32), options);
  if (!generated.device) std::abort();
  const cfg::DeviceDescription& device = state.range(0) == 0 ? drive : *generated.device;
  Result r;
  for (auto _ : state) r = scan({{&device, 5}}, {*cfg::NodeId::from(5)});
  if (!r.ok) state.SkipWithError("the scan did not end");
  report(state, r, r.busy_s);
}
BENCHMARK(BM_ReadDictionary)
    ->Arg(0)
    ->Arg(1)
    ->ArgName("generated")
    ->Unit(benchmark::kMillisecond)
    ->Iterations(1);

}  // namespace

BENCHMARK_MAIN();
