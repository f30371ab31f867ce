// `cfgmgr push` as a whole process (start to exit) on the simulated bus: a
// generated network of 126 slaves (node-IDs 1..126; the master is 127) x 100 configuration
// values at 500 kbit/s, each device answering 1 ms after a request (sim:?latency_ms=1), no
// heartbeats. Run 1 downloads into fresh devices and saves (state=DIR keeps what they saved);
// run 2 is the same push again: every 1020h matches, every node is skipped. "1 % loss": the
// first push without state= with each frame lost with probability 0.01 (sim:?loss=0.01&seed=1,
// the same frames lost in every run; conditions as in the field).
// "--lss": instead, the push --lss of the same network whose 126 devices all come out
// of the box without node-ID (sim:?unconfigured=1-126, every DCF with LSS_Supported=1 and a
// serial number of its own): Execute LSS gives each its node-ID, then the usual first push. Its
// bound adds the LSS frames the protocol needs when the master knows every device's address
// (nmt/lss/lss_procedure.hpp, scan with targets), requests and the answers CiA 305 requires, each
// at its exact length: one switch to waiting, identify non-configured remote slave (4Ch) and
// every device's answer (50h); per device switch state selective (40h-43h) and its answer (44h),
// inquire node-ID (5Eh) and its answer, configure node-ID and store configuration with theirs,
// the switch to waiting (12); the Fastscan reset nobody answers after: 13 N + 3. (Issue 34's
// before: 8 N + 2 requests, the Fastscan confirmation's, answers not counted; before the targeted
// scan a blind Fastscan's, 136 N + 2: 1 + 4 x 33 requests to find each device.)
//   cmake --build build-bench --target bench_push && build-bench/bench/bench_push [RUNS] [--lss]
// Per run: bus time (the report's elapsed_s, simulated), the lower bound (air time,
// nmt::frame_bits, of the frames CiA 301/302-2 require, built here from the network's own
// download plans, not from what the master sends), their ratio, the frames the trace holds,
// the wall-clock time of the process and its peak RSS (wait4 ru_maxrss).
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "../tests/tools/generated_network.hpp"
#include "cfg/bytes.hpp"
#include "cfg/download_order.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/network.hpp"
#include "cfg/object_index.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "process_runner.hpp"

namespace {

namespace fs = std::filesystem;
namespace object = cfg::object;

constexpr std::uint32_t kBitrate = 500'000;
constexpr std::uint8_t kMasterId = 127;

struct Run {
  double bus_s = 0;
  double wall_s = 0;
  double cpu_s = 0;  ///< user + system time of the process
  long max_rss_kib = 0;
  std::size_t frames = 0;
  int exit_code = -1;
};

std::string slurp(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

Run push(const std::vector<std::string>& arguments, const fs::path& dir) {
  std::vector<std::string> args = {CANOPEN_CFGMGR, "push"};
  args.insert(args.end(), arguments.begin(), arguments.end());
  const fs::path json = dir / "report.json";
  const fs::path trace = dir / "trace.log";
  for (const std::string& a :
       {std::string("--json"), json.string(), std::string("--candump"), trace.string()}) {
    args.push_back(a);
  }
  const bench::ProcessSample sample = bench::run_process(args);
  Run run;
  run.wall_s = sample.wall_ms / 1e3;
  run.cpu_s = sample.cpu_ms / 1e3;
  run.max_rss_kib = sample.max_rss_kib;
  run.exit_code = sample.exit_code;
  const std::string report = slurp(json);
  const auto at = report.find("\"elapsed_s\": ");
  if (at != std::string::npos) run.bus_s = std::strtod(report.c_str() + at + 13, nullptr);
  const std::string log = slurp(trace);
  run.frames = static_cast<std::size_t>(std::count(log.begin(), log.end(), '\n'));
  return run;
}

// --- the bound ----------------------------------------------------------------------------------

// CiA 301 §7.2.4.3.3-6: expedited upload request 40h, its response 43h (4 bytes indicated),
// expedited download request 2Fh/2Bh/23h (1/2/4 bytes), its response 60h; 8 data bytes each.
std::vector<std::uint8_t> sdo(std::uint8_t command, std::uint16_t index, std::uint8_t sub,
                              std::span<const std::uint8_t> data = {}) {
  std::vector<std::uint8_t> out{command};
  cfg::append_le(out, index, 2);
  out.push_back(sub);
  out.insert(out.end(), data.begin(), data.end());
  out.resize(8, 0);
  return out;
}

struct Required {
  std::vector<nmt::CanFrame> frames;
  void add(std::uint32_t id, const std::vector<std::uint8_t>& bytes) {
    frames.push_back(nmt::CanFrame::make(id, bytes));
  }
  void upload(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
    std::vector<std::uint8_t> v;
    cfg::append_le(v, value, 4);
    add(0x600U + node, sdo(0x40, index, sub));
    add(0x580U + node, sdo(0x43, index, sub, v));
  }
  void download(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                std::span<const std::uint8_t> data) {
    // Values of 1..4 bytes go expedited (all of this network's).
    add(0x600U + node, sdo(static_cast<std::uint8_t>(0x23 | (4 - data.size()) << 2 | 1 << 1 | 1),
                           index, sub, data));
    add(0x580U + node, sdo(0x60, index, sub));
  }
  double seconds() const {
    std::uint64_t bits = 0;
    for (const auto& f : frames) bits += nmt::frame_bits(f).total();
    return static_cast<double>(bits) / kBitrate;
  }
};

// The frames a push of `network` must exchange, whatever the master does between them: the
// master's boot-up and reset communication (CiA 302-2 §3.1 d), per slave its boot-up, the
// identity uploads the derived master checks (1000h, 1018h sub 1-3: 1F84h-1F87h are set, 1F88h
// is not, §3.4 c-e), 1020h sub 1 (first run: it differs, which decides; second: sub 1 and 2,
// §3.5 b-c), the download plan (§3.5 d) with 1020h sub 1/2 and 1010h sub 1 'save' after it
// (first run), and its start (000#01nn, §3.1 h: the derived master starts each slave).
Required required_frames(const cfg::Network& network, const generated::NetworkSpec& spec,
                         bool download) {
  Required r;
  r.add(0x700U + kMasterId, {0x00});
  r.add(0x000, {0x82, 0x00});
  for (const auto& node : network.nodes) {
    const std::uint8_t id = node.node_id.value();
    r.add(0x700U + id, {0x00});
    r.upload(id, object::kDeviceType, 0, spec.identity.device_type);
    r.upload(id, object::kIdentity, 1, spec.identity.vendor_id);
    r.upload(id, object::kIdentity, 2, spec.identity.product_code);
    r.upload(id, object::kIdentity, 3, spec.identity.revision);
    const std::vector<std::uint8_t> stamp(4, 0);  // the bound counts bits; any 4 bytes
    if (download) {
      r.upload(id, object::kVerifyConfiguration, 1, 0);
      for (const auto& w : cfg::order_for_download(node.writes).writes) {
        r.download(id, w.index, w.sub_index, w.data);
      }
      r.download(id, object::kVerifyConfiguration, 1, stamp);
      r.download(id, object::kVerifyConfiguration, 2, stamp);
      std::vector<std::uint8_t> save;
      cfg::append_le(save, cfg::kSaveSignature, 4);
      r.download(id, object::kStoreParameters, 1, save);
    } else {
      r.upload(id, object::kVerifyConfiguration, 1, 0);
      r.upload(id, object::kVerifyConfiguration, 2, 0);
    }
    r.add(0x000, {0x01, id});
  }
  return r;
}

void print(const char* what, const std::vector<Run>& runs, const Required& bound) {
  std::vector<double> wall;
  std::vector<double> cpu;
  for (const auto& r : runs) {
    wall.push_back(r.wall_s);
    cpu.push_back(r.cpu_s);
  }
  const auto [min_wall, max_wall] = std::minmax_element(wall.begin(), wall.end());
  const Run& r = runs.front();
  std::printf(
      "%-9s bus %.3f s  bound %.3f s (%zu frames)  ratio %.3f  frames %zu  wall median %.3f s "
      "(min %.3f, max %.3f)  CPU median %.3f s  peak RSS %ld KiB  exit %d  (%zu runs)\n",
      what, r.bus_s, bound.seconds(), bound.frames.size(), r.bus_s / bound.seconds(), r.frames,
      bench::median(wall), *min_wall, *max_wall, bench::median(cpu), r.max_rss_kib, r.exit_code,
      runs.size());
}

}  // namespace

// The LSS frames a scan of the network's new devices of known addresses needs (see the top),
// 8 data bytes each, as CiA 305 lays them out (nmt/lss/lss.hpp).
void add_lss_frames(Required& r, const cfg::Network& network, const generated::NetworkSpec& spec) {
  auto frame = [&r](std::uint32_t id, nmt::lss::Cs cs, std::uint32_t value = 0) {
    r.frames.push_back(nmt::lss::make_frame(id, cs, value));
  };
  using nmt::lss::Cs;
  constexpr std::uint32_t kM = nmt::lss::kMasterCobId;
  constexpr std::uint32_t kS = nmt::lss::kSlaveCobId;
  frame(kM, Cs::SwitchStateGlobal);
  frame(kM, Cs::IdentifyNonConfigured);
  for (std::size_t i = 0; i < network.nodes.size(); ++i) frame(kS, Cs::IdentifyNonConfiguredAnswer);
  for (const auto& node : network.nodes) {
    const std::uint8_t id = node.node_id.value();
    frame(kM, Cs::SwitchSelectiveVendor, spec.identity.vendor_id);
    frame(kM, Cs::SwitchSelectiveProduct, spec.identity.product_code);
    frame(kM, Cs::SwitchSelectiveRevision, spec.identity.revision);
    frame(kM, Cs::SwitchSelectiveSerial, generated::lss_serial(id));
    frame(kS, Cs::SwitchSelectiveAnswer);
    frame(kM, Cs::InquireNodeId);
    frame(kS, Cs::InquireNodeId, nmt::lss::kUnconfigured);
    frame(kM, Cs::ConfigureNodeId, id);
    frame(kS, Cs::ConfigureNodeId);
    frame(kM, Cs::StoreConfiguration);
    frame(kS, Cs::StoreConfiguration);
    frame(kM, Cs::SwitchStateGlobal);
  }
  r.frames.push_back(nmt::lss::make_fastscan(0, nmt::lss::kFastscanReset, 0, 0));
}

int main(int argc, char** argv) {
  const bool lss = argc > 2 && std::string(argv[2]) == "--lss";
  const int runs = argc > 1 ? std::max(1, static_cast<int>(std::strtol(argv[1], nullptr, 10))) : 5;
  const fs::path dir = fs::temp_directory_path() / ("bench_push_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  generated::NetworkSpec spec;
  spec.values = 100;
  spec.pdos = 0;
  spec.lss = lss;
  const std::string cpj = generated::write_network(dir / "net", spec);
  auto loaded = cfg::load_network(cpj, {});
  if (!loaded.ok()) {
    std::fprintf(stderr, "bench_push: the generated network does not load\n");
    return 1;
  }
  const cfg::Network& network = *loaded.network;
  std::printf(
      "network: %zu slaves, %zu configuration entries each (node 1), 500 kbit/s, "
      "latency 1 ms\n",
      network.nodes.size(), network.nodes.front().writes.size());
  if (lss) {
    // Every device out of the box; the first push after it (Execute LSS, then the boot).
    std::vector<Run> step10;
    std::vector<Run> step1;
    const std::vector<std::string> args = {cpj, "--bus", "sim:?latency_ms=1&unconfigured=1-126",
                                           "--lss"};
    for (int i = 0; i < runs; ++i) {
      step10.push_back(push(args, dir));
      auto fast = args;
      fast.insert(fast.end(), {"--lss-scan-step", "1"});
      step1.push_back(push(fast, dir));
    }
    Required bound = required_frames(network, spec, true);
    add_lss_frames(bound, network, spec);
    print("--lss", step10, bound);
    print("step 1 ms", step1, bound);
    fs::remove_all(dir);
    return 0;
  }
  const std::string state = (dir / "state").string();
  const std::vector<std::string> args = {cpj, "--bus", "sim:?latency_ms=1&state=" + state};
  const std::vector<std::string> stateless = {cpj, "--bus", "sim:?latency_ms=1"};
  const std::vector<std::string> lossy = {cpj, "--bus", "sim:?latency_ms=1&loss=0.01&seed=1"};
  std::vector<Run> plain;
  std::vector<Run> lost;
  std::vector<Run> first;
  std::vector<Run> second;
  for (int i = 0; i < runs; ++i) {
    plain.push_back(push(stateless, dir));
    fs::remove_all(state);
    first.push_back(push(args, dir));
    second.push_back(push(args, dir));
    lost.push_back(push(lossy, dir));
  }
  // Without state= the devices keep nothing, so no file is written (each save is one
  // fsync'd file per node with state=).
  print("no state", plain, required_frames(network, spec, true));
  print("first", first, required_frames(network, spec, true));
  print("second", second, required_frames(network, spec, false));
  // The trace holds the frames delivered; the lost ones took the bus too but are not in it.
  print("1 % loss", lost, required_frames(network, spec, true));
  std::printf("second / first bus time: 1 / %.1f\n", first.front().bus_s / second.front().bus_s);
  fs::remove_all(dir);
  return 0;
}
