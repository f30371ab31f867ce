// The NMT flying master's failover on the simulated bus: three masters
// (node 5 with priority 0, node 10 with the setting's priority, node 12 with priority 2) and
// two slaves at 500 kbit/s; once node 5 runs the network, its frames stop. Measured in simulated
// time:
//   reset_s     the active master's last frame (its heartbeat) to the first NMT command on the
//               bus after it (the standby masters' reset communication, CiA 302-2 §5.5.2)
//   failover_s  the active master's last frame to the first NMT command of the new active
//               master after its 71h (its NMT start-up's reset communication, §3.1 d)
//   predicted_s the spec's sum: heartbeat consumer time (2 x 1017h + 100 ms, nmt_master.hpp)
//               + 1F90h sub 2 (delay) + sub 1 (detection timeout) + the waiting time of node 10
//               (sub 3 x sub 4 + 10 x sub 5, §5.3)
// per set of 1F90h values and heartbeat periods (the arguments: see kSettings). The benchmark's
// time is the wall-clock time of the simulation (manual time).
// Run from a Release build: build-bench/bench/bench_flying_master
#include <benchmark/benchmark.h>

#include <array>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/device_file.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_index.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"

namespace {

using namespace std::chrono_literals;
using nmt::Duration;
using nmt::TimePoint;
namespace object = cfg::object;

/// One row of the figure: 1017h of every master and 1F90h sub 1-5 (ms), priority of node 10.
struct Setting {
  const char* name;
  std::uint16_t heartbeat_ms;
  std::uint16_t timeout_ms;
  std::uint16_t delay_ms;
  std::uint16_t priority_10;
  std::uint16_t priority_slot_ms;
  std::uint16_t node_slot_ms;
};
constexpr std::array<Setting, 5> kSettings{{
    {"defaults", 100, 100, 500, 1, 1500, 10},
    {"defaults,prio0", 100, 100, 500, 0, 1500, 10},
    {"hb250", 250, 100, 500, 1, 1500, 10},
    {"fast", 50, 50, 100, 1, 300, 2},
    {"fast,prio0", 50, 50, 100, 0, 300, 2},
}};

constexpr std::array<std::uint8_t, 2> kSlaves{2, 3};

cfg::DeviceDescription parse(const std::string& text) {
  auto read = cfg::parse_device_description(text);
  if (!read.device) throw std::runtime_error(read.diagnostics.format());
  return *read.device;
}

// A master DCF: heartbeat producer 1017h; every other object gets NmtMaster's defaults.
const cfg::DeviceDescription& master_dcf() {
  static const cfg::DeviceDescription dcf = parse(
      "[DeviceInfo]\nVendorName=Bench\n[OptionalObjects]\nSupportedObjects=1\n1=0x1017\n"
      "[1017]\nParameterName=Producer heartbeat time\nObjectType=0x7\nDataType=0x0006\n"
      "AccessType=rw\nDefaultValue=0\nPDOMapping=0\n");
  return dcf;
}
const cfg::DeviceDescription& slave_eds() {
  static const cfg::DeviceDescription eds = [] {
    auto read = cfg::read_device_file(std::string(CANOPEN_SAMPLES_DIR) + "/io_module.eds");
    if (!read.device) throw std::runtime_error(read.diagnostics.format());
    return *read.device;
  }();
  return eds;
}

void set(nmt::NmtMaster& master, std::uint16_t index, std::uint8_t sub, std::uint64_t value,
         std::size_t size) {
  std::vector<std::uint8_t> bytes(size);
  cfg::store_le(value, bytes, size);
  if (master.dictionary().write(index, sub, bytes, TimePoint{}) != nmt::SdoAbort::None) {
    throw std::runtime_error("write refused");
  }
}

struct Figure {
  double reset_s = 0;
  double failover_s = 0;
  double predicted_s = 0;
};

Figure failover(const Setting& s) {
  nmt::SimBus bus(500'000);
  std::vector<std::pair<TimePoint, nmt::CanFrame>> seen;
  bus.add_observer([&](const nmt::CanFrame& f, TimePoint t) { seen.emplace_back(t, f); });
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> slaves;
  for (const std::uint8_t node : kSlaves) {
    auto device = nmt::SimulatedDevice::create(slave_eds(), node);
    if (!device.ok()) throw std::runtime_error(device.error().message);
    slaves.push_back(
        std::make_unique<nmt::SimEngineNode<nmt::SimulatedDevice>>(std::move(device).value()));
    bus.attach(*slaves.back());
    slaves.back()->apply([](nmt::SimulatedDevice& d, TimePoint now,
                            nmt::SimulatedDevice::Output& out) { d.start(now, out); });
  }
  std::map<std::uint8_t, std::unique_ptr<nmt::SimEngineNode<nmt::NmtMaster>>> masters;
  const std::map<std::uint8_t, std::uint16_t> priorities{{5, 0}, {10, s.priority_10}, {12, 2}};
  for (const auto& [node, priority] : priorities) {
    auto created = nmt::NmtMaster::create(master_dcf(), cfg::NodeId::from(node).value());
    if (!created.ok()) throw std::runtime_error(created.error().message);
    auto m = std::make_unique<nmt::SimEngineNode<nmt::NmtMaster>>(std::move(created).value());
    auto& engine = m->engine();
    set(engine, object::kNmtStartup, 0,
        cfg::NmtStartup::kMaster | cfg::NmtStartup::kStartAllNodes | cfg::NmtStartup::kFlyingMaster,
        4);
    set(engine, object::kProducerHeartbeatTime, 0, s.heartbeat_ms, 2);
    for (const std::uint8_t slave : kSlaves) {
      set(engine, object::kSlaveAssignment, slave,
          cfg::SlaveAssignment::make(cfg::SlaveAssignment::kSlave |
                                     cfg::SlaveAssignment::kBootSlave)
              .value,
          4);
    }
    // Slot 4 before 5 or 5 before 4, whichever keeps sub 4 > 127 x sub 5 at every step.
    set(engine, object::kFlyingMasterParameters, 5, 1, 2);
    set(engine, object::kFlyingMasterParameters, 4, s.priority_slot_ms, 2);
    set(engine, object::kFlyingMasterParameters, 5, s.node_slot_ms, 2);
    set(engine, object::kFlyingMasterParameters, 1, s.timeout_ms, 2);
    set(engine, object::kFlyingMasterParameters, 2, s.delay_ms, 2);
    set(engine, object::kFlyingMasterParameters, 3, priority, 2);
    bus.attach(*m);
    m->apply(
        [](nmt::NmtMaster& e, TimePoint now, nmt::NmtMaster::Output& out) { e.start(now, out); });
    masters[node] = std::move(m);
  }
  const auto operational = [&] {
    return masters.at(5)->engine().startup_state() == nmt::StartupState::Operational;
  };
  if (!bus.run_until(operational, bus.now() + 30s)) throw std::runtime_error("no active master");
  bus.run_for(
      3s + Duration{1000 * (bus.now().time_since_epoch().count() % 97)});  // some heartbeat phase
  bus.detach(*masters.at(5));
  const auto died = bus.now();
  const auto new_master = [&] {
    return masters.at(10)->engine().startup_state() == nmt::StartupState::Operational;
  };
  if (!bus.run_until(new_master, bus.now() + 60s)) throw std::runtime_error("no takeover");
  TimePoint last{};
  for (const auto& [t, f] : seen) {
    if (t <= died && f.id == 0x705) last = t;
  }
  std::optional<TimePoint> reset;
  std::optional<TimePoint> won;
  std::optional<TimePoint> first_command;
  for (const auto& [t, f] : seen) {
    if (t <= died) continue;
    if (f.id == 0x000 && !reset) reset = t;
    if (f.id == nmt::FlyingMasterCobId::kMasterResponse && f.dlc == 2 && f.data[1] == 10 && !won) {
      won = t;
    }
    if (won && t >= *won && f.id == 0x000 && !first_command) first_command = t;
  }
  if (!reset || !first_command) throw std::runtime_error("frames missing");
  const auto seconds = [](Duration d) { return static_cast<double>(d.count()) / 1e6; };
  const Duration watch = 2 * std::chrono::milliseconds(s.heartbeat_ms) + 100ms;
  const Duration predicted = watch + std::chrono::milliseconds(s.delay_ms) +
                             std::chrono::milliseconds(s.timeout_ms) +
                             s.priority_10 * std::chrono::milliseconds(s.priority_slot_ms) +
                             10 * std::chrono::milliseconds(s.node_slot_ms);
  return {seconds(*reset - last), seconds(*first_command - last), seconds(predicted)};
}

void BM_FlyingMasterFailover(benchmark::State& state) {
  const auto& setting = kSettings.at(static_cast<std::size_t>(state.range(0)));
  Figure figure;
  for (auto _ : state) {
    const auto begin = std::chrono::steady_clock::now();
    figure = failover(setting);
    state.SetIterationTime(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count());
  }
  state.SetLabel(setting.name);
  state.counters["reset_s"] = figure.reset_s;
  state.counters["failover_s"] = figure.failover_s;
  state.counters["predicted_s"] = figure.predicted_s;
  state.counters["ratio"] = figure.failover_s / figure.predicted_s;
}

}  // namespace

BENCHMARK(BM_FlyingMasterFailover)
    ->DenseRange(0, static_cast<int>(kSettings.size()) - 1)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);

BENCHMARK_MAIN();
