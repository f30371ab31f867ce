// Simulated bus and SDO on it: how fast the simulation runs in wall time, and how close a block
// transfer comes to the bus's theoretical limit in simulated time.
//   BM_FrameBits               cost of the exact frame length (CRC-15 + stuffing) per frame
//   BM_SimBusEvents            scheduler + bus events processed per second of CPU time
//   BM_SdoExpeditedTransfers   complete expedited downloads (request + response) per wall second
//   BM_SdoBlockDownload1MiB    1 MiB block download at 1 Mbit/s: simulated time compared with
//                              the time the data bits alone need at 1 Mbit/s (ratio counter)
//   BM_SdoSegmentedDownload1MiB  the same with segmented transfer, for comparison
// Run from a Release build: build-x/bench/bench_sim_bus
#include <benchmark/benchmark.h>

#include <memory>
#include <stdexcept>
#include <vector>

#include "cfg/object_dictionary.hpp"
#include "nmt/sdo/sdo.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace {

using namespace std::chrono_literals;
using nmt::TimePoint;

// A node sending one 8-byte frame every `period`.
class Talker : public nmt::SimNode {
 public:
  Talker(std::uint32_t id, nmt::Duration period) : id_(id), period_(period) {}
  void start(TimePoint at) { set_timer(at); }
  void on_frame(const nmt::CanFrame&, TimePoint) override { ++received; }
  void on_timer(TimePoint now) override {
    const std::uint8_t bytes[8] = {1, 2, 3, 4, 5, 6, 7, 8};
    send(nmt::CanFrame::make(id_, bytes));
    set_timer(now + period_);
  }
  std::uint64_t received = 0;

 private:
  std::uint32_t id_;
  nmt::Duration period_;
};

void BM_SimBusEvents(benchmark::State& state) {
  const auto nodes = static_cast<std::size_t>(state.range(0));
  nmt::SimBus bus(1'000'000);
  std::vector<std::unique_ptr<Talker>> talkers;
  for (std::size_t i = 0; i < nodes; ++i) {
    // Periods chosen so the bus runs at about 50 % load.
    talkers.push_back(std::make_unique<Talker>(static_cast<std::uint32_t>(0x180 + i),
                                               std::chrono::microseconds(250 * nodes)));
    bus.attach(*talkers.back());
    talkers.back()->start(TimePoint{nmt::Duration{static_cast<std::int64_t>(i * 13)}});
  }
  const auto events_before = bus.events_processed();
  for (auto _ : state) bus.run_for(10ms);
  const auto events = bus.events_processed() - events_before;
  state.counters["events/s"] =
      benchmark::Counter(static_cast<double>(events), benchmark::Counter::kIsRate);
  state.counters["sim_speedup"] = benchmark::Counter(
      static_cast<double>(state.iterations()) * 0.010, benchmark::Counter::kIsRate);
  state.counters["bus_load"] = bus.statistics().load();
}
BENCHMARK(BM_SimBusEvents)->Arg(2)->Arg(10)->Arg(50)->Unit(benchmark::kMillisecond);

// Exact bit length of one frame (CRC-15 and stuffing over the real bits): the bus model's cost
// per frame.
void BM_FrameBits(benchmark::State& state) {
  const std::uint8_t bytes[8] = {0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00};
  auto frame = nmt::CanFrame::make(0x605, bytes);
  for (auto _ : state) {
    benchmark::DoNotOptimize(frame);
    benchmark::DoNotOptimize(nmt::frame_bits(frame));
    frame.data[7]++;
  }
}
BENCHMARK(BM_FrameBits);

cfg::DeviceDescription bench_device() {
  cfg::DeviceDescription d;
  auto add = [&](std::uint16_t index, cfg::DataType type, std::optional<std::string> value) {
    cfg::Object o;
    o.index = index;
    o.object_type = type == cfg::DataType::Domain ? cfg::ObjectType::Domain : cfg::ObjectType::Var;
    cfg::SubObject s;
    s.data_type = static_cast<std::uint16_t>(type);
    s.access = cfg::AccessType::Rw;
    s.default_value = std::move(value);
    o.subs.emplace(0, s);
    d.objects.emplace(index, o);
  };
  add(0x1017, cfg::DataType::Unsigned16, "0");
  add(0x2000, cfg::DataType::Domain, std::nullopt);
  return d;
}

struct Rig {
  nmt::SimBus bus{1'000'000};
  nmt::LocalDictionary dict =
      nmt::LocalDictionary::from_device(bench_device(), *cfg::NodeId::from(5)).value();
  nmt::SimEngineNode<nmt::SdoServer> server{dict,
                                            nmt::SdoServerConfig::for_node(*cfg::NodeId::from(5))};
  nmt::SimEngineNode<nmt::SdoClient> client{nmt::SdoClientConfig::for_node(*cfg::NodeId::from(5))};
  nmt::SdoResult result;  // the last transfer's
  Rig() {
    bus.attach(server);
    bus.attach(client);
    client.set_event_handler([this](const nmt::SdoResult& r, nmt::TimePoint) { result = r; });
  }
  nmt::SdoResult run(bool upload, std::vector<std::uint8_t> data, nmt::SdoTransferOptions o) {
    const auto started =
        client.apply([&](nmt::SdoClient& c, nmt::TimePoint now, nmt::SdoClient::Output& out) {
          return upload ? c.upload(0x2000, 0, now, out, o)
                        : c.download(0x2000, 0, std::move(data), now, out, o);
        });
    if (!started) throw std::runtime_error(started.error().message);
    bus.run_until_idle();
    return result;
  }
};

void BM_SdoExpeditedTransfers(benchmark::State& state) {
  Rig rig;
  std::uint16_t value = 0;
  bool all_ok = true;
  const auto start = rig.bus.now();
  for (auto _ : state) {
    ++value;
    rig.result = {};
    const auto started =
        rig.client.apply([&](nmt::SdoClient& c, nmt::TimePoint now, nmt::SdoClient::Output& out) {
          return c.download(
              0x1017, 0, {static_cast<std::uint8_t>(value), static_cast<std::uint8_t>(value >> 8)},
              now, out);
        });
    rig.bus.run_until_idle();
    all_ok = all_ok && started.ok() && rig.result.ok() && rig.result.id != 0;
  }
  if (!all_ok) state.SkipWithError("a transfer failed");
  state.counters["transfers/s"] =
      benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.counters["sim_us/transfer"] = static_cast<double>((rig.bus.now() - start).count()) /
                                      static_cast<double>(state.iterations());
}
BENCHMARK(BM_SdoExpeditedTransfers);

void transfer_1mib(benchmark::State& state, nmt::SdoMode mode) {
  constexpr std::size_t kSize = std::size_t{1} << 20;
  std::vector<std::uint8_t> data(kSize);
  for (std::size_t i = 0; i < kSize; ++i) data[i] = static_cast<std::uint8_t>(i * 31 + (i >> 9));
  double sim_s = 0;
  double load = 0;
  std::uint64_t frames = 0;
  for (auto _ : state) {
    Rig rig;
    nmt::SdoTransferOptions o;
    o.mode = mode;
    rig.bus.reset_statistics();
    auto r = rig.run(false, data, o);
    if (!r.ok()) {
      state.SkipWithError("transfer failed");
      return;
    }
    sim_s = static_cast<double>((r.finished - r.started).count()) / 1e6;
    load = rig.bus.statistics().load();
    frames = rig.bus.statistics().frames;
  }
  // The data bits alone at 1 Mbit/s: 8 * 2^20 bits = 8.389 s.
  const double data_bits_s = static_cast<double>(kSize) * 8 / 1e6;
  state.counters["sim_s"] = sim_s;
  state.counters["data_bits_s"] = data_bits_s;
  state.counters["ratio"] = sim_s / data_bits_s;
  state.counters["bus_load"] = load;
  state.counters["frames"] = static_cast<double>(frames);
}

void BM_SdoBlockDownload1MiB(benchmark::State& state) {
  transfer_1mib(state, nmt::SdoMode::Block);
}
BENCHMARK(BM_SdoBlockDownload1MiB)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_SdoSegmentedDownload1MiB(benchmark::State& state) {
  transfer_1mib(state, nmt::SdoMode::Auto);
}
BENCHMARK(BM_SdoSegmentedDownload1MiB)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
