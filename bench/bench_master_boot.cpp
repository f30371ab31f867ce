// The NMT master booting a full network on the simulated bus: 126 slaves
// with 100 configuration entries each at 500 kbit/s, every device answering 1 ms after a request.
// Node-IDs 1..126 are the slaves and the master is node 127: a master's own SDO server and NMT
// need a node-ID that no slave has, so 127 slaves and a master cannot share the 127 node-IDs.
//   BM_MasterBoot/hb:N/loss_per_1000:L
//                                first start-up: identity, 1020h differs, 100 writes, 1020h,
//                                1010h 'save', start error control (slaves' heartbeat every N ms,
//                                0: no heartbeat, no error control), start remote node; each
//                                frame on the bus is lost with probability L/1000 (occupies the
//                                bus, reaches nobody: SimBus::set_loss_rate, fixed seed kLossSeed,
//                                the fault `cfgmgr push --bus sim:?loss=` injects)
//   BM_MasterBootAllMatch/hb:N/loss_per_1000:L
//                                the next start-up of the same devices (power-cycled): every
//                                1020h matches 1F26h/1F27h, nothing is downloaded
// Counters: sim_s (simulated start() to StartupComplete), bound_s (the bus-time lower bound: the
// air time, nmt::frame_bits, of the frames the boot must exchange, built below from CiA 301 and
// CiA 302-2 independently of the engine), ratio = sim_s / bound_s, bus_load, frames (all frames
// in that time), required (the bound's frames), missing (required frames never seen), extra_*
// (frames seen beyond the required ones and their air time), lost (frames the loss took, not in
// frames; a lost required frame that is never repeated counts in missing), sdo_in_flight (mean
// number of SDO requests awaiting their response: how much the master overlaps the 1 ms response
// times). The benchmark's time is the wall-clock time of the simulated boot alone (manual time); a
// failed try of a slave's boot (retried, §3.3) is counted in boot_errors and the first one is the
// label. Run from a Release build: build-bench/bench/bench_master_boot; BENCH_MASTER_TRACE=FILE
// writes the frames and events of the boots to FILE (see write_trace).
//   --loss-seeds=FIRST-LAST [--loss-per-1000=L (10)] [--hb=N (0)]
//                                instead of the benchmarks: for each loss seed a first start-up and
//                                the second (all 1020h match) as
//                                BM_MasterBoot/BM_MasterBootAllMatch run them, one line per seed,
//                                then the ratios' distribution (min/median/p90/max), the failed
//                                tries and the slaves not configured (first) or not booted
//                                (second), summed over the seeds.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/object_index.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sim/fault_injection.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"

namespace {

using namespace std::chrono_literals;
using nmt::TimePoint;
namespace object = cfg::object;

constexpr std::uint32_t kBitrate = 500'000;
constexpr std::uint8_t kMasterId = 127;
constexpr std::uint8_t kSlaves = 126;
constexpr int kEntries = 100;
constexpr nmt::Duration kResponseTime = 1ms;
// The loss's PRNG seed: the same seed, the same frames lost (BENCH_LOSS_SEED overrides it).
constexpr std::uint64_t kLossSeed = 1;

// Identity of every slave (1000h, 1018h), checked by the master through 1F84h-1F88h; the
// vendor is the samples' fictitious one (samples/network/README.md).
constexpr std::uint32_t kDeviceType = 0x000F0191;  // CiA 401, digital and analog I/O
constexpr std::uint32_t kVendor = 0x7E57C0DE;
constexpr std::uint32_t kProduct = 0x00000401;
constexpr std::uint32_t kRevision = 0x00010002;
constexpr std::uint32_t serial_of(std::uint8_t node) {
  return 0x5E000000U + node;
}
// 1F26h/1F27h: the configuration's date and time (days since 1984, ms after midnight).
constexpr cfg::ConfigurationStamp kStamp{15'000, 43'200'000};

// Configuration entry k (0..99) of a node: 2000h+k sub 0, UNSIGNED32 for even k, UNSIGNED16 for
// odd k, values that differ per node and from the devices' defaults (0).
std::uint16_t entry_index(int k) {
  return static_cast<std::uint16_t>(object::kManufacturerAreaFirst + k);
}
std::size_t entry_size(int k) {
  return k % 2 == 0 ? 4 : 2;
}
std::uint32_t entry_value(std::uint8_t node, int k) {
  const std::uint32_t v = 0x00A50000U + (std::uint32_t{node} << 8) + static_cast<std::uint32_t>(k);
  return k % 2 == 0 ? v : (v & 0xFFFFU);
}

std::vector<std::uint8_t> le(std::uint64_t value, std::size_t size) {
  std::vector<std::uint8_t> out;
  cfg::append_le(out, value, size);
  return out;
}

// --- the devices ------------------------------------------------------------------------------

cfg::SubObject sub_object(std::uint8_t sub, cfg::DataType type, cfg::AccessType access,
                          std::uint64_t value) {
  cfg::SubObject s;
  s.sub_index = sub;
  s.data_type = static_cast<std::uint16_t>(type);
  s.access = access;
  s.default_value = std::to_string(value);
  return s;
}

void add_var(cfg::DeviceDescription& d, std::uint16_t index, cfg::DataType type,
             cfg::AccessType access, std::uint64_t value) {
  cfg::Object o;
  o.index = index;
  o.object_type = cfg::ObjectType::Var;
  o.subs.emplace(0, sub_object(0, type, access, value));
  d.objects.emplace(index, std::move(o));
}

// An ARRAY or RECORD of UNSIGNED32 entries 1..n with sub 0 = n.
void add_u32_array(cfg::DeviceDescription& d, std::uint16_t index, cfg::ObjectType type,
                   cfg::AccessType access, const std::vector<std::uint32_t>& values) {
  cfg::Object o;
  o.index = index;
  o.object_type = type;
  const auto n = static_cast<std::uint8_t>(values.size());
  o.subs.emplace(0, sub_object(0, cfg::DataType::Unsigned8, cfg::AccessType::Ro, n));
  for (std::uint8_t s = 1; s <= n; ++s) {
    o.subs.emplace(s, sub_object(s, cfg::DataType::Unsigned32, access, values[s - 1U]));
  }
  d.objects.emplace(index, std::move(o));
}

cfg::DeviceDescription slave_description(std::uint8_t node, std::uint16_t heartbeat_ms) {
  using cfg::AccessType;
  using cfg::DataType;
  cfg::DeviceDescription d;
  add_var(d, object::kDeviceType, DataType::Unsigned32, AccessType::Ro, kDeviceType);
  add_var(d, object::kErrorRegister, DataType::Unsigned8, AccessType::Ro, 0);
  add_u32_array(d, object::kStoreParameters, cfg::ObjectType::Array, AccessType::Rw, {1});
  add_u32_array(d, object::kRestoreDefaultParameters, cfg::ObjectType::Array, AccessType::Rw, {1});
  add_var(d, object::kProducerHeartbeatTime, DataType::Unsigned16, AccessType::Rw, heartbeat_ms);
  add_u32_array(d, object::kIdentity, cfg::ObjectType::Record, AccessType::Ro,
                {kVendor, kProduct, kRevision, serial_of(node)});
  add_u32_array(d, object::kVerifyConfiguration, cfg::ObjectType::Array, AccessType::Rw, {0, 0});
  for (int k = 0; k < kEntries; ++k) {
    add_var(d, entry_index(k), entry_size(k) == 4 ? DataType::Unsigned32 : DataType::Unsigned16,
            AccessType::Rw, 0);
  }
  return d;
}

using Device = nmt::Delayed<nmt::SimulatedDevice>;
using DeviceNode = nmt::SimEngineNode<Device>;

// The slaves on one bus; they stay (with what they saved) across boots.
struct Network {
  nmt::SimBus bus{kBitrate};
  std::vector<std::unique_ptr<DeviceNode>> slaves;

  explicit Network(std::uint16_t heartbeat_ms) {
    for (std::uint8_t node = 1; node <= kSlaves; ++node) {
      auto device = nmt::SimulatedDevice::create(slave_description(node, heartbeat_ms), node);
      if (!device.ok()) throw std::runtime_error(device.error().message);
      // Every frame a device sends leaves kResponseTime after what caused it.
      slaves.push_back(std::make_unique<DeviceNode>(kResponseTime, std::move(device).value()));
      bus.attach(*slaves.back());
    }
    power_cycle();
  }
  // Power on (again): unsaved values are lost, the boot-up follows; then let the boot-ups pass.
  void power_cycle() {
    for (auto& slave : slaves) {
      slave->apply([](Device& d, TimePoint now, Device::Output& out) {
        d.discard();
        d.engine().start(now, out);
      });
    }
    bus.run_for(50ms);
  }
};

// --- the master ---------------------------------------------------------------------------------

class Configurations final : public nmt::ConfigurationSource {
 public:
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override {
    std::vector<cfg::ObjectWrite> writes;
    writes.reserve(kEntries);
    for (int k = 0; k < kEntries; ++k) {
      writes.push_back({entry_index(k), 0, le(entry_value(node, k), entry_size(k))});
    }
    return writes;
  }
};

// Writes a value of the master's own dictionary as an SDO write would (checked).
void set(nmt::NmtMaster& master, std::uint16_t index, std::uint8_t sub, std::uint64_t value) {
  const nmt::DictionaryEntry* entry = master.dictionary().entry(index, sub);
  if (entry == nullptr || !entry->fixed_size()) {
    throw std::runtime_error("master has no " + cfg::to_string(cfg::ObjectAddress{index, sub}));
  }
  const auto abort =
      master.dictionary().write(index, sub, le(value, *entry->fixed_size()), TimePoint{});
  if (abort != nmt::SdoAbort::None) {
    throw std::runtime_error("master refuses " + cfg::to_string(cfg::ObjectAddress{index, sub}));
  }
}

// CiA 302-2 §6: master (1F80h bit 0) that starts each slave once it booted (bits 1 and 3 = 0);
// every slave mandatory and booted by the master (1F81h bits 0, 2, 3), its identity checked
// (1F84h-1F88h), its configuration verified (1F26h/1F27h) and its heartbeat consumed (1016h,
// 1.5 heartbeat periods).
nmt::NmtMaster make_master(std::uint16_t heartbeat_ms) {
  nmt::MasterOptions options;
  options.pacing.bitrate = kBitrate;
  options.configurations = std::make_shared<Configurations>();
  auto created = nmt::NmtMaster::create(cfg::DeviceDescription{},
                                        cfg::NodeId::from(kMasterId).value(), options);
  if (!created.ok()) throw std::runtime_error(created.error().message);
  nmt::NmtMaster master = std::move(created).value();
  set(master, object::kNmtStartup, 0, cfg::NmtStartup::kMaster);
  for (std::uint8_t node = 1; node <= kSlaves; ++node) {
    set(master, object::kSlaveAssignment, node,
        cfg::SlaveAssignment::make(cfg::SlaveAssignment::kSlave | cfg::SlaveAssignment::kBootSlave |
                                   cfg::SlaveAssignment::kMandatory)
            .value);
    set(master, object::kDeviceTypeIdentification, node, kDeviceType);
    set(master, object::kVendorIdentification, node, kVendor);
    set(master, object::kProductCode, node, kProduct);
    set(master, object::kRevisionNumber, node, kRevision);
    set(master, object::kSerialNumber, node, serial_of(node));
    set(master, object::kExpectedConfigurationDate, node, kStamp.days);
    set(master, object::kExpectedConfigurationTime, node, kStamp.ms);
    if (heartbeat_ms != 0) {
      set(master, object::kConsumerHeartbeatTime, node,
          std::uint32_t{node} << 16 | (heartbeat_ms * 3U / 2U));
    }
  }
  return master;
}

// --- the bound ----------------------------------------------------------------------------------

nmt::CanFrame frame(std::uint32_t id, const std::vector<std::uint8_t>& bytes) {
  return nmt::CanFrame::make(id, bytes);
}

// CiA 301 §7.2.4.3.3-6: expedited upload request 40h, its response 43h/4Bh (4/2 bytes,
// size indicated), expedited download request 23h/2Bh, its response 60h; 8 data bytes each.
std::vector<std::uint8_t> sdo(std::uint8_t command, std::uint16_t index, std::uint8_t sub,
                              std::uint32_t data = 0, std::size_t size = 4) {
  std::vector<std::uint8_t> out{command};
  cfg::append_le(out, index, 2);
  out.push_back(sub);
  cfg::append_le(out, data, size);
  out.resize(8, 0);
  return out;
}

struct Required {
  std::vector<nmt::CanFrame> frames;
  void upload(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
    frames.push_back(frame(0x600U + node, sdo(0x40, index, sub)));
    frames.push_back(frame(0x580U + node, sdo(0x43, index, sub, value)));
  }
  void download(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value,
                std::size_t size) {
    frames.push_back(frame(0x600U + node, sdo(size == 4 ? 0x23 : 0x2B, index, sub, value, size)));
    frames.push_back(frame(0x580U + node, sdo(0x60, index, sub)));
  }
};

// The frames a boot must exchange, whatever the master does between them.
Required required_frames(bool download, std::uint16_t heartbeat_ms) {
  Required r;
  r.frames.push_back(frame(0x700U + kMasterId, {0x00}));  // the master's boot-up (CiA 301)
  r.frames.push_back(frame(0x000, {0x82, 0x00}));         // §3.1 d) reset communication, all
  for (std::uint8_t node = 1; node <= kSlaves; ++node) {
    r.frames.push_back(frame(0x700U + node, {0x00}));     // boot-up
    r.upload(node, object::kDeviceType, 0, kDeviceType);  // §3.4 c), d)
    r.upload(node, object::kIdentity, 1, kVendor);        // §3.4 e): 1F85h-1F88h are set
    r.upload(node, object::kIdentity, 2, kProduct);
    r.upload(node, object::kIdentity, 3, kRevision);
    r.upload(node, object::kIdentity, 4, serial_of(node));
    if (download) {
      // §3.5 b), c): sub 1 (date) differs, which already decides.
      r.upload(node, object::kVerifyConfiguration, 1, 0);
      for (int k = 0; k < kEntries; ++k) {
        r.download(node, entry_index(k), 0, entry_value(node, k), entry_size(k));
      }
      r.download(node, object::kVerifyConfiguration, 1, kStamp.days, 4);
      r.download(node, object::kVerifyConfiguration, 2, kStamp.ms, 4);
      r.download(node, object::kStoreParameters, 1, cfg::kSaveSignature, 4);
    } else {
      r.upload(node, object::kVerifyConfiguration, 1, kStamp.days);  // both must match
      r.upload(node, object::kVerifyConfiguration, 2, kStamp.ms);
    }
    // §4.1: one heartbeat of the pre-operational slave ends start error control.
    if (heartbeat_ms != 0) r.frames.push_back(frame(0x700U + node, {0x7F}));
    r.frames.push_back(frame(0x000, {0x01, node}));  // §3.4 l) start remote node
  }
  return r;
}

std::uint64_t air_bits(const std::vector<nmt::CanFrame>& frames) {
  std::uint64_t bits = 0;
  for (const auto& f : frames) bits += nmt::frame_bits(f).total();
  return bits;
}

// --- one boot -----------------------------------------------------------------------------------

struct Seen {
  nmt::CanFrame frame;
  TimePoint at;
};

struct BootResult {
  double sim_s = 0;
  double wall_s = 0;
  double bus_load = 0;  ///< air time of the boot's frames / sim_s
  std::vector<Seen> seen;
  std::string error;
  std::size_t booted = 0;
  std::size_t configured = 0;
  std::size_t boot_errors = 0;  ///< tries that failed and were repeated
  std::string first_boot_error;
  std::uint64_t lost = 0;  ///< frames the loss rate took during the boot
};

// BENCH_MASTER_TRACE=FILE: the frames (time in us, candump) and the master's events (except
// step and state changes) of each boot go to FILE, the last boot's remaining.
void write_trace(const std::vector<Seen>& seen, const std::vector<std::string>& events) {
  const char* path = std::getenv("BENCH_MASTER_TRACE");
  if (path == nullptr) return;
  std::ofstream out(path);
  for (const auto& s : seen)
    out << s.at.time_since_epoch().count() << ' ' << nmt::to_candump(s.frame) << '\n';
  for (const auto& e : events) out << e << '\n';
}

BootResult boot(Network& net, std::uint16_t heartbeat_ms) {
  BootResult result;
  nmt::SimEngineNode<nmt::NmtMaster> master(make_master(heartbeat_ms));
  net.bus.attach(master);
  std::optional<TimePoint> complete_at;
  std::vector<std::string> events;
  master.set_event_handler([&](const nmt::MasterEvent& e, TimePoint now) {
    using Kind = nmt::MasterEvent::Kind;
    if (e.kind != Kind::BootStepChanged && e.kind != Kind::SlaveStateChanged) {
      events.push_back("event " + std::to_string(now.time_since_epoch().count()) + ' ' +
                       nmt::describe(e));
    }
    if (e.kind == Kind::StartupComplete) complete_at = now;
    if (e.kind == Kind::SlaveBooted) {
      ++result.booted;
      if (e.configured) ++result.configured;
    }
    // A failed try is tried again (§3.3); only the end of NMT start-up ends the boot.
    if (e.kind == Kind::BootError) {
      ++result.boot_errors;
      if (result.first_boot_error.empty()) result.first_boot_error = nmt::describe(e);
    }
    if ((e.kind == Kind::StartupHalted || (e.kind == Kind::BootError && e.final)) &&
        result.error.empty()) {
      result.error = nmt::describe(e);
    }
  });
  const auto observer = net.bus.add_observer([&](const nmt::CanFrame& f, TimePoint at) {
    result.seen.push_back({f, at});
  });
  result.seen.reserve(40'000);
  const std::uint64_t dropped0 = net.bus.statistics().frames_dropped;
  const TimePoint t0 = net.bus.now();
  const auto wall0 = std::chrono::steady_clock::now();
  master.apply(
      [](nmt::NmtMaster& m, TimePoint now, nmt::NmtMaster::Output& out) { m.start(now, out); });
  net.bus.run_until([&] { return complete_at || !result.error.empty(); }, t0 + 600s);
  result.lost = net.bus.statistics().frames_dropped - dropped0;
  result.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  if (!complete_at && result.error.empty()) result.error = "start-up did not complete in 600 s";
  // The last start remote node commands are queued when start-up completes: the boot ends when
  // they are on the bus. Frames after that moment are not the boot's.
  net.bus.run_for(20ms);
  net.bus.remove_observer(observer);
  write_trace(result.seen, events);
  if (!complete_at) return result;
  TimePoint end = *complete_at;
  std::erase_if(result.seen, [&](const Seen& s) {
    const bool start_command = s.frame.id == 0 && s.frame.dlc == 2 && s.frame.data[0] == 0x01;
    if (s.at <= *complete_at) return false;
    if (start_command) end = std::max(end, s.at);
    return !start_command;
  });
  result.sim_s = static_cast<double>((end - t0).count()) / 1e6;
  std::uint64_t bits = 0;
  for (const auto& s : result.seen) bits += nmt::frame_bits(s.frame).total();
  result.bus_load = static_cast<double>(bits) / kBitrate / result.sim_s;
  return result;  // the master's node detaches itself
}

// Matches the frames seen against the required ones (heartbeats by COB-ID: any state byte).
struct Accounting {
  std::size_t missing = 0;
  std::size_t extra_sdo = 0;
  std::size_t extra_error_control = 0;
  std::size_t extra_other = 0;
  std::uint64_t extra_bits = 0;
};

bool is_heartbeat(const nmt::CanFrame& f) {
  return f.id > 0x700 && f.id <= 0x77F && f.dlc == 1 && f.data[0] != 0;
}

Accounting account(const Required& required, const std::vector<Seen>& seen) {
  std::map<std::string, std::size_t> wanted;
  for (const auto& f : required.frames) {
    ++wanted[is_heartbeat(f) ? "hb" + std::to_string(f.id) : nmt::to_candump(f)];
  }
  Accounting a;
  for (const auto& s : seen) {
    const auto key =
        is_heartbeat(s.frame) ? "hb" + std::to_string(s.frame.id) : nmt::to_candump(s.frame);
    auto it = wanted.find(key);
    if (it != wanted.end() && it->second > 0) {
      --it->second;
      continue;
    }
    a.extra_bits += nmt::frame_bits(s.frame).total();
    if (s.frame.id >= 0x581 && s.frame.id <= 0x67F) {
      ++a.extra_sdo;
    } else if (s.frame.id >= 0x701 && s.frame.id <= 0x77F) {
      ++a.extra_error_control;
    } else {
      ++a.extra_other;
    }
  }
  for (const auto& [key, count] : wanted) a.missing += count;
  return a;
}

// Mean number of SDO requests awaiting their response over the boot: the sum of the times from
// each request's end of frame to its response's, divided by the boot time.
double sdo_in_flight(const std::vector<Seen>& seen, double sim_s) {
  std::map<std::uint32_t, TimePoint> open;  // by node: the pending request's time
  double busy_s = 0;
  for (const auto& s : seen) {
    if (s.frame.id >= 0x601 && s.frame.id <= 0x67F) {
      open[s.frame.id - 0x600] = s.at;
    } else if (s.frame.id >= 0x581 && s.frame.id <= 0x5FF) {
      auto it = open.find(s.frame.id - 0x580);
      if (it == open.end()) continue;
      busy_s += static_cast<double>((s.at - it->second).count()) / 1e6;
      open.erase(it);
    }
  }
  return sim_s > 0 ? busy_s / sim_s : 0;
}

void report(benchmark::State& state, const BootResult& r, const Required& required) {
  const double bound_s = static_cast<double>(air_bits(required.frames)) / kBitrate;
  const Accounting a = account(required, r.seen);
  state.counters["sim_s"] = r.sim_s;
  state.counters["bound_s"] = bound_s;
  state.counters["ratio"] = r.sim_s / bound_s;
  state.counters["bus_load"] = r.bus_load;
  state.counters["frames"] = static_cast<double>(r.seen.size());
  state.counters["required"] = static_cast<double>(required.frames.size());
  state.counters["missing"] = static_cast<double>(a.missing);
  state.counters["extra_sdo"] = static_cast<double>(a.extra_sdo);
  state.counters["extra_ec"] = static_cast<double>(a.extra_error_control);
  state.counters["extra_other"] = static_cast<double>(a.extra_other);
  state.counters["extra_air_s"] = static_cast<double>(a.extra_bits) / kBitrate;
  state.counters["lost"] = static_cast<double>(r.lost);
  state.counters["sdo_in_flight"] = sdo_in_flight(r.seen, r.sim_s);
  state.counters["configured"] = static_cast<double>(r.configured);
  state.counters["boot_errors"] = static_cast<double>(r.boot_errors);
  if (!r.first_boot_error.empty()) state.SetLabel("first boot error: " + r.first_boot_error);
}

// A first start-up on a new network with frame loss `loss` (PRNG seed `seed`) and, when
// `second_start_up`, after it and a power cycle of the devices the start-up when every 1020h
// matches (the loss PRNG going on): the last boot's result.
BootResult boot_case(std::uint16_t heartbeat_ms, double loss, std::uint64_t seed,
                     bool second_start_up, BootResult* first = nullptr) {
  Network net(heartbeat_ms);
  // After the devices' power-on boot-ups: the loss hits the boot alone.
  net.bus.set_loss_rate(loss, seed);
  BootResult r = boot(net, heartbeat_ms);
  if (second_start_up && r.error.empty()) {
    if (first != nullptr) *first = r;
    net.power_cycle();
    r = boot(net, heartbeat_ms);
  }
  return r;
}

// One boot per iteration on a new network; `second_start_up`: the boot after a first one and a
// power cycle of the devices, when every 1020h matches.
void master_boot(benchmark::State& state, bool second_start_up) {
  const auto heartbeat_ms = static_cast<std::uint16_t>(state.range(0));
  const double loss = static_cast<double>(state.range(1)) / 1000;
  const char* seed_text = std::getenv("BENCH_LOSS_SEED");
  const std::uint64_t seed =
      seed_text != nullptr ? std::strtoull(seed_text, nullptr, 10) : kLossSeed;
  const Required required = required_frames(!second_start_up, heartbeat_ms);
  for (auto _ : state) {
    BootResult r = boot_case(heartbeat_ms, loss, seed, second_start_up);
    if (!r.error.empty()) {
      state.SkipWithError(r.error.c_str());
      return;
    }
    state.SetIterationTime(r.wall_s);
    report(state, r, required);
  }
}

void BM_MasterBoot(benchmark::State& state) {
  master_boot(state, false);
}
void BM_MasterBootAllMatch(benchmark::State& state) {
  master_boot(state, true);
}

// hb: the slaves' heartbeat period in ms (0: none, and no error control); loss_per_1000: the
// frame loss (field conditions: 1 % loss, 100 ms heartbeats; not both: with 1016h at
// 1.5 heartbeat periods one lost heartbeat is a heartbeat event, and the boot rightly fails).
void boot_arguments(benchmark::internal::Benchmark* b) {
  b->ArgNames({"hb", "loss_per_1000"})
      ->Args({1000, 0})
      ->Args({0, 0})
      ->Args({100, 0})
      ->Args({0, 10})
      ->UseManualTime()
      ->Unit(benchmark::kMillisecond)
      ->Iterations(3);
}
BENCHMARK(BM_MasterBoot)->Apply(boot_arguments);
BENCHMARK(BM_MasterBootAllMatch)->Apply(boot_arguments);

// --- many loss seeds (--loss-seeds) -------------------------------------------------------------

struct SeedArguments {
  std::uint64_t first = 0;
  std::uint64_t last = 0;
  unsigned loss_per_1000 = 10;
  std::uint16_t heartbeat_ms = 0;
};

// The value of `--name=VALUE` in `arg`, or nullopt.
std::optional<std::string_view> flag_value(std::string_view arg, std::string_view name) {
  if (arg.substr(0, name.size()) != name || arg.size() <= name.size() || arg[name.size()] != '=') {
    return std::nullopt;
  }
  return arg.substr(name.size() + 1);
}

// The --loss-seeds arguments, or nullopt when there are none (the benchmarks run).
std::optional<SeedArguments> seed_arguments(int argc, char** argv) {
  std::optional<SeedArguments> a;
  SeedArguments parsed;
  for (int i = 1; i < argc; ++i) {
    const std::string_view arg = argv[i];
    if (const auto v = flag_value(arg, "--loss-seeds")) {
      const std::string text(*v);
      const auto dash = text.find('-');
      parsed.first = std::strtoull(text.substr(0, dash).c_str(), nullptr, 10);
      parsed.last = dash == std::string::npos
                        ? parsed.first
                        : std::strtoull(text.substr(dash + 1).c_str(), nullptr, 10);
      a = parsed;
    } else if (const auto l = flag_value(arg, "--loss-per-1000")) {
      parsed.loss_per_1000 =
          static_cast<unsigned>(std::strtoul(std::string(*l).c_str(), nullptr, 10));
    } else if (const auto h = flag_value(arg, "--hb")) {
      parsed.heartbeat_ms =
          static_cast<std::uint16_t>(std::strtoul(std::string(*h).c_str(), nullptr, 10));
    }
  }
  if (a) {
    a->loss_per_1000 = parsed.loss_per_1000;
    a->heartbeat_ms = parsed.heartbeat_ms;
  }
  return a;
}

// min / median / p90 / max of `values` (nearest rank).
std::string distribution(std::vector<double> values) {
  if (values.empty()) return "none";
  std::sort(values.begin(), values.end());
  const auto rank = [&](double q) {
    const auto i = static_cast<std::size_t>(std::ceil(q * static_cast<double>(values.size())));
    return values[std::clamp<std::size_t>(i, 1, values.size()) - 1];
  };
  char text[128];
  std::snprintf(text, sizeof text, "min %.3f  median %.3f  p90 %.3f  max %.3f", values.front(),
                rank(0.5), rank(0.9), values.back());
  return text;
}

int run_seeds(const SeedArguments& a) {
  const double loss = a.loss_per_1000 / 1000.0;
  const double first_bound_s =
      static_cast<double>(air_bits(required_frames(true, a.heartbeat_ms).frames)) / kBitrate;
  const double second_bound_s =
      static_cast<double>(air_bits(required_frames(false, a.heartbeat_ms).frames)) / kBitrate;
  std::vector<double> first_ratios;
  std::vector<double> second_ratios;
  std::size_t failed_tries = 0;
  std::size_t unconfigured = 0;
  std::size_t not_booted = 0;
  std::size_t failed_boots = 0;
  std::printf("hb:%u loss_per_1000:%u, bounds %.3f s / %.3f s\n", a.heartbeat_ms, a.loss_per_1000,
              first_bound_s, second_bound_s);
  std::printf("seed  first_s  ratio  tries_failed configured | second_s  ratio  tries_failed\n");
  for (std::uint64_t seed = a.first; seed <= a.last; ++seed) {
    BootResult first;
    BootResult second = boot_case(a.heartbeat_ms, loss, seed, true, &first);
    const bool second_ran = first.error.empty() && first.sim_s > 0;
    if (!second_ran) first = std::exchange(second, BootResult{});  // the first failed: no second
    const bool failed = !first.error.empty() || !second_ran || !second.error.empty();
    if (failed) ++failed_boots;
    // A failed start-up has no boot time: only its failed tries and slaves count.
    if (first.error.empty()) first_ratios.push_back(first.sim_s / first_bound_s);
    failed_tries += first.boot_errors;
    unconfigured += kSlaves - first.configured;
    if (second_ran) {
      if (second.error.empty()) second_ratios.push_back(second.sim_s / second_bound_s);
      failed_tries += second.boot_errors;
      not_booted += kSlaves - second.booted;
    }
    std::printf("%4llu  %7.3f  %5.3f  %12zu %10zu | %8.3f  %5.3f  %12zu %s\n",
                static_cast<unsigned long long>(seed), first.sim_s, first.sim_s / first_bound_s,
                first.boot_errors, first.configured, second.sim_s, second.sim_s / second_bound_s,
                second.boot_errors,
                first.error.empty() ? second.error.c_str() : first.error.c_str());
    std::fflush(stdout);
  }
  std::printf("first start-up ratio:  %s\n", distribution(first_ratios).c_str());
  std::printf("second start-up ratio: %s\n", distribution(second_ratios).c_str());
  std::printf(
      "seeds %llu-%llu: failed tries %zu, slaves not configured %zu (first), not booted %zu "
      "(second), failed start-ups %zu\n",
      static_cast<unsigned long long>(a.first), static_cast<unsigned long long>(a.last),
      failed_tries, unconfigured, not_booted, failed_boots);
  return failed_boots == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (const auto seeds = seed_arguments(argc, argv)) return run_seeds(*seeds);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
