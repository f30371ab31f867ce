// libFuzzer target: the whole NMT master engine (nmt::NmtMaster) with flying master (1F80h bit 5)
// and SDO manager on, a configuration manager, three simulated slaves (nodes 2 and 3 assigned by
// tests/data/master/master.dcf, node 4 unassigned), an SDO requesting device at node 126 and a
// tool's SDO client on the master's default SDO, on a small bus model whose frames take 250 us
// each, in order. The input drives frames, time and the peers.
//
// Input format:
//   byte 0 (setup): bit 0 master 1017h = 100 ms (else 0); bit 1 slaves 2/3 mandatory;
//     bit 2 node 4 assigned too; bit 3 slaves keep alive; bits 4-5 1F90h sub 3 (priority 0..2,
//     3 taken as 2); bit 6 slaves produce heartbeats (1017h 50 ms); bit 7 1F89h boot time 2 s.
//   then operations, one byte `op` each, with operands from the bytes that follow:
//     00-1F  advance time by (op + 1) ms
//     20-3F  advance time by (op - 1F) x 100 ms
//     40-5F  raw frame: 2 bytes id (11 bits), op & 0x0F = DLC (0..15, data up to 8), bit 4: RTR;
//            then min(DLC, 8) data bytes
//     60-7F  templated frame (op & 0x1F, k = next byte): see frame_template()
//     80-9F  tool: SDO download to the master: object table[op & 0x0F], next byte sub, next
//            byte n, then n bytes of data (repeated to n x 16 bytes when op bit 4 is set)
//     A0-AF  tool: SDO upload from the master: object table[op & 0x0F], next byte sub
//     B0-BF  peer: power on (op 0-4 for slaves 2, 3, 4, the SRD), 5-9 unplug, A-E plug back
//     C0-CF  SRD: 1F10h = (0x1280 + next byte % 3) << 16 | 1 (| 8 with op bit 0), then 6E0h
//     D0-DF  application: boot_slave(k), enter_operational, request_nmt, request_guarding,
//            sdo_upload/sdo_download to a slave (op & 7 selects, k = next byte)
//     E0-FF  run until the master's next deadline (at most 2 s ahead)
// Checks (abort with a message, never an assert): no crash; the time of every master event is
// the time of the call that reported it, never earlier than the last one; after every call the
// master has a next deadline while it has work (below), and never needs to be called again at
// the same instant for ever (on_timer at now leaves next_deadline() after now within 1000
// calls); memory stays bounded: every call's output, the configuration manager's stored bytes
// (cfg::ConfigManagerLimits), the SDO manager's tables and the frames waiting on the bus.
// "Work" (nmt/master/nmt_master.hpp): the flying master negotiating (StartupState::Negotiating), or
// a slave in a boot step that waits for the bus (a boot-up, an SDO answer, a heartbeat, the retry
// time) while no SDO manager connection holds that slave's default SDO (its boot then waits
// for the release, which the SRD's error control brings).
#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "../support/fuzz_support.hpp"
#include "cfg/config_manager.hpp"
#include "cfg/device_file.hpp"
#include "cfg/master_objects.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/sim/simulated_device.hpp"

namespace {

// Powers `device` on at `now` (nothing it reports at power-on is looked at here).
template <class Device>
void power_on_at(Device& device, nmt::TimePoint now) {
  typename Device::Output out;
  device.start(now, out);
}

using nmt::CanFrame;
using nmt::Duration;
using nmt::TimePoint;
using namespace std::chrono_literals;

[[noreturn]] void fail(const char* what, int line, long long at) {
  std::fprintf(stderr, "fuzz_nmt_master: check failed at line %d (t = %lld us): %s\n", line, at,
               what);
  std::abort();
}
#define check_at_time(condition, at)                                               \
  do {                                                                             \
    if (!(condition)) fail(#condition, __LINE__, (at).time_since_epoch().count()); \
  } while (false)

constexpr std::uint8_t kMasterId = 1;
constexpr std::uint8_t kSrdId = 126;
constexpr Duration kFrameTime = 250us;
// Bounds of one run, so every input ends quickly.
constexpr std::size_t kMaxDeliveries = 60'000;
constexpr std::size_t kMaxQueuedFrames = 20'000;
constexpr std::size_t kMaxOutputPerCall = 4'096;
constexpr int kMaxCallsAtOneInstant = 1'000;

cfg::DeviceDescription load(const char* name) {
  auto read = cfg::read_device_file(std::string(CANOPEN_FUZZ_DATA_DIR) + "/master/" + name);
  if (!read.device) {
    std::fprintf(stderr, "fuzz_nmt_master: cannot read %s\n", name);
    std::abort();
  }
  return *read.device;
}

std::vector<std::uint8_t> le(std::uint64_t value, std::size_t size) {
  std::vector<std::uint8_t> bytes(size);
  for (std::size_t i = 0; i < size; ++i) bytes[i] = static_cast<std::uint8_t>(value >> (8 * i));
  return bytes;
}

using fuzz_support::Input;

// The objects the tool reads and writes (index; the sub-index comes from the input).
constexpr std::array<std::uint16_t, 16> kObjects = {0x1F22, 0x1F20, 0x1F25, 0x1F82, 0x1F83, 0x1F80,
                                                    0x1F00, 0x1F01, 0x1F02, 0x1017, 0x1016, 0x1F81,
                                                    0x1F26, 0x1F23, 0x1F90, 0x102A};

// One participant of the bus: an engine with its own output.
struct Peer {
  virtual ~Peer() = default;
  virtual void frame(const CanFrame& f, TimePoint now) = 0;
  virtual void timer(TimePoint now) = 0;
  virtual std::optional<TimePoint> deadline() const = 0;
  virtual std::vector<CanFrame> take() = 0;
  bool plugged = true;
};

template <class E>
struct EnginePeer : Peer {
  E* engine;
  typename E::Output out;
  explicit EnginePeer(E& e) : engine(&e) {}
  void frame(const CanFrame& f, TimePoint now) override { engine->on_frame(f, now, out); }
  void timer(TimePoint now) override { engine->on_timer(now, out); }
  std::optional<TimePoint> deadline() const override { return engine->next_deadline(); }
  std::vector<CanFrame> take() override {
    if constexpr (std::is_same_v<E, nmt::SdoClient>) {
      // The tool's results, with FUZZ_TRACE (see Harness::trace).
      if (std::getenv("FUZZ_TRACE") != nullptr) {
        for (const auto& r : out.events) {
          std::fprintf(stderr, "tool: %s %04Xh sub %02Xh: %08X\n", r.upload ? "read" : "write",
                       r.address.index, r.address.sub_index, static_cast<unsigned>(r.abort));
        }
      }
    }
    auto frames = std::move(out.frames);
    out.clear();
    return frames;
  }
};

struct Harness {
  std::shared_ptr<cfg::ConfigManager> manager = std::make_shared<cfg::ConfigManager>();
  std::optional<nmt::NmtMaster> master;
  std::vector<nmt::SimulatedDevice> devices;  // 2, 3, 4, the SRD
  nmt::SdoClient tool{nmt::SdoClientConfig::for_node(*cfg::NodeId::from(kMasterId))};
  std::vector<std::unique_ptr<Peer>> peers;  // [0] the master, devices, the tool
  struct Queued {
    CanFrame frame;
    std::size_t sender;
  };
  std::deque<Queued> wire;
  TimePoint now{};
  TimePoint bus_free{};
  TimePoint last_event{};
  std::size_t deliveries = 0;
  // FUZZ_TRACE=1 in the environment prints the master's events (to see what a seed reaches).
  const bool trace = std::getenv("FUZZ_TRACE") != nullptr;

  nmt::NmtMaster& m() { return *master; }

  // --- checks after every call of the master ---
  void after_master_call(nmt::NmtMaster::Output& out) {
    check_at_time(out.frames.size() <= kMaxOutputPerCall, now);
    check_at_time(out.events.size() <= kMaxOutputPerCall, now);
    for (const auto& e : out.events) {
      if (trace)
        std::fprintf(stderr, "%lld us %s\n",
                     static_cast<long long>(e.at.time_since_epoch().count()),
                     nmt::describe(e).c_str());
      check_at_time(e.at == now, now);  // reported by the call at `now`
      check_at_time(e.at >= last_event, now);
      last_event = e.at;
    }
    for (const auto& f : out.frames) wire.push_back({f, 0});
    out.clear();
    check_at_time(!has_work() || m().next_deadline().has_value(), now);
    check_at_time(manager->value_bytes() <= manager->limits().max_total_bytes, now);
    // Texts are held deflated: at most zlib's bound over their size (compressBound: about
    // 0.03 % + 13 bytes per entry).
    const auto total = manager->limits().max_total_bytes;
    check_at_time(manager->stored_bytes() <= total + total / 256 + 127 * 3 * 64, now);
    check_at_time(m().sdo_connections().size() <= 4 * 254, now);
    check_at_time(m().registered_srds().size() <= 127, now);
  }

  bool default_sdo_held(std::uint8_t node) const {
    for (const auto& srd : master->registered_srds()) {
      if (srd.all_default_sdos) return true;
    }
    for (const auto& c : master->sdo_connections()) {
      if (c.server == node && c.server_index == 0x1200) return true;
    }
    return false;
  }

  bool has_work() const {
    using S = nmt::BootStep;
    if (master->startup_state() == nmt::StartupState::Negotiating) return true;
    for (std::uint8_t node = 2; node <= 4; ++node) {
      const auto id = *cfg::NodeId::from(node);
      switch (master->boot_step(id)) {
        case S::AwaitBootUp:
        case S::Identify:
        case S::CheckNmtState:
        case S::CheckSoftware:
        case S::UpdateSoftware:
        case S::VerifyConfiguration:
        case S::Restore:
        case S::Download:
        case S::Save:
        case S::StartErrorControl:
        case S::RetryWait:
          if (!default_sdo_held(node)) return true;
          break;
        default:
          break;
      }
    }
    return false;
  }

  // --- the bus ---
  void collect(std::size_t index) {
    if (index == 0) return;  // the master's output is checked in after_master_call
    for (auto& f : peers[index]->take()) {
      if (peers[index]->plugged) wire.push_back({f, index});
    }
  }
  void deliver(const Queued& q) {
    ++deliveries;
    for (std::size_t i = 0; i < peers.size(); ++i) {
      if (i == q.sender || !peers[i]->plugged) continue;
      if (i == 0) {
        auto& p = static_cast<EnginePeer<nmt::NmtMaster>&>(*peers[0]);
        p.frame(q.frame, now);
        after_master_call(p.out);
      } else {
        peers[i]->frame(q.frame, now);
        collect(i);
      }
    }
  }
  void fire_timers() {
    for (std::size_t i = 0; i < peers.size(); ++i) {
      int calls = 0;
      while (true) {
        const auto due = peers[i]->deadline();
        if (!due || *due > now) break;
        check_at_time(++calls <= kMaxCallsAtOneInstant, now);  // next_deadline() never leaves `now`
        peers[i]->timer(now);
        if (i == 0) {
          after_master_call(static_cast<EnginePeer<nmt::NmtMaster>&>(*peers[0]).out);
        } else {
          collect(i);
        }
      }
    }
  }
  bool exhausted() const { return deliveries >= kMaxDeliveries; }
  // Runs frames and timers in time order up to `until`.
  void run_until(TimePoint until) {
    fire_timers();
    while (!exhausted()) {
      check_at_time(wire.size() <= kMaxQueuedFrames, now);
      std::optional<TimePoint> next;
      if (!wire.empty()) next = std::max(now, bus_free) + kFrameTime;
      for (const auto& p : peers) next = nmt::earliest(next, p->deadline());
      if (!next || *next > until) break;
      const bool frame_first = !wire.empty() && *next == std::max(now, bus_free) + kFrameTime;
      if (*next > now) now = *next;
      if (frame_first) {
        const auto q = wire.front();
        wire.pop_front();
        bus_free = now;
        deliver(q);
      }
      fire_timers();
    }
    if (until > now) now = until;
    fire_timers();
  }
  void send_foreign(const CanFrame& f) { wire.push_back({f, peers.size()}); }
};

CanFrame make(std::uint32_t id, std::initializer_list<std::uint8_t> data) {
  CanFrame f;
  f.id = id;
  f.dlc = static_cast<std::uint8_t>(data.size());
  std::copy(data.begin(), data.end(), f.data.begin());
  return f;
}

// Frames of the protocols the master takes part in, so the fuzzer reaches them with few bytes.
CanFrame frame_template(std::uint8_t which, std::uint8_t k, Input& in) {
  const std::uint8_t node = static_cast<std::uint8_t>(1 + k % 127);
  switch (which) {
    case 0:
      return make(0x700 + node, {0x00});  // boot-up
    case 1:
      return make(0x700 + node, {0x05});  // heartbeat: operational
    case 2:
      return make(0x700 + node, {0x7F});  // heartbeat: pre-operational
    case 3:
      return make(0x700 + node, {0x04});  // heartbeat: stopped
    case 4:
      return make(0x6E0, {});  // Dynamic SDO Request
    case 5:
      return make(0x71, {static_cast<std::uint8_t>(k % 4), in.next()});  // master response
    case 6:
      return make(0x72, {});  // negotiation
    case 7:
      return make(0x73, {});  // detection
    case 8:
      return make(0x74, {});
    case 9:
      return make(0x75, {});
    case 10:
      return make(0x76, {});  // force
    case 11:
      return make(0x000, {in.next(), static_cast<std::uint8_t>(k)});  // NMT command
    case 12: {  // an SDO response from node k (580h + k): 8 bytes from the input
      CanFrame f = make(0x580 + node, {});
      f.dlc = 8;
      for (auto& b : f.data) b = in.next();
      return f;
    }
    case 13: {  // an SDO request to the master (601h): 8 bytes from the input
      CanFrame f = make(0x600 + kMasterId, {});
      f.dlc = 8;
      for (auto& b : f.data) b = in.next();
      return f;
    }
    case 14: {  // an SDO request to an SRD channel in the manager's pool (680h..6DFh)
      CanFrame f = make(0x680 + k % 0x60, {});
      f.dlc = 8;
      for (auto& b : f.data) b = in.next();
      return f;
    }
    case 15: {  // guarding reply (RTR answer) of node k with toggle
      return make(0x700 + node, {static_cast<std::uint8_t>(in.next() & 0xFF)});
    }
    default: {  // a guarding request (RTR) for node k
      CanFrame f = make(0x700 + node, {});
      f.rtr = true;
      return f;
    }
  }
}

void add_entry(nmt::LocalDictionary& dict, std::uint16_t index, std::uint8_t sub,
               cfg::DataType type, std::uint64_t value) {
  nmt::DictionaryEntry e;
  e.index = index;
  e.sub_index = sub;
  e.name = "fuzz entry";
  e.data_type = static_cast<std::uint16_t>(type);
  e.basic_type = type;
  e.access =
      sub == 0 && index >= 0x1200 && index <= 0x12FF ? cfg::AccessType::Const : cfg::AccessType::Rw;
  e.bytes = le(value, cfg::data_type_info(type).size_bytes);
  dict.insert(e);
}

// DSP 302 §7: what an SRD has (1F10h, 1F11h, client entries 1280h-1282h, not valid).
void make_srd(nmt::LocalDictionary& dict) {
  using T = cfg::DataType;
  add_entry(dict, 0x1F10, 0, T::Unsigned32, 0);
  add_entry(dict, 0x1F11, 0, T::Unsigned16, 0);
  for (std::uint16_t index = 0x1280; index <= 0x1282; ++index) {
    add_entry(dict, index, 0, T::Unsigned8, 3);
    add_entry(dict, index, 1, T::Unsigned32, 0x80000000);
    add_entry(dict, index, 2, T::Unsigned32, 0x80000000);
    add_entry(dict, index, 3, T::Unsigned8, 0);
  }
}

void write_value(nmt::LocalDictionary& dict, std::uint16_t index, std::uint8_t sub,
                 std::uint64_t value, std::size_t size) {
  (void)dict.write(index, sub, le(value, size), TimePoint{});
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto master_dcf = load("master.dcf");
  static const auto slave_eds = load("slave.eds");
  Input in{data, size};
  const std::uint8_t setup = in.next();

  Harness h;
  h.devices.reserve(4);
  nmt::MasterOptions options;
  options.manager = h.manager;
  options.sdo_manager.enabled = true;
  options.sdo_manager.channels = 4;
  options.sdo_manager.scan_timeout = 5ms;
  options.sdo.timeout = 50ms;
  options.boot.retry_interval = 300ms;
  options.boot.boot_up_wait = 100ms;
  options.boot.reboot_timeout = 500ms;
  options.sdo_manager.srd_guard_time = 200ms;
  options.sdo.block_threshold = 16;
  // Bounds small enough for the input to reach them (nmt_master.hpp: memory a peer can make the
  // master use); the checks hold the master to them.
  h.manager->set_limits({.max_entry_bytes = 3000, .max_total_bytes = 12000});
  options.sdo_manager.max_queued_requests = 4;
  options.nmt.max_queued_requests = 8;
  auto created = nmt::NmtMaster::create(master_dcf, *cfg::NodeId::from(kMasterId), options);
  if (!created.ok()) std::abort();
  h.master.emplace(std::move(created).value());
  auto& dict = h.m().dictionary();
  using Startup = cfg::NmtStartup;
  using Assign = cfg::SlaveAssignment;
  write_value(dict, 0x1F80, 0, Startup::kMaster | Startup::kStartAllNodes | Startup::kFlyingMaster,
              4);
  write_value(dict, 0x1017, 0, (setup & 0x01) ? 100 : 0, 2);
  std::uint8_t flags = Assign::kSlave | Assign::kBootSlave;
  if (setup & 0x02) flags |= Assign::kMandatory;
  if (setup & 0x08) flags |= Assign::kKeepAlive;
  for (std::uint8_t node = 2; node <= ((setup & 0x04) ? 4 : 3); ++node) {
    write_value(dict, 0x1F81, node, Assign::make(flags, 0, 0).value, 4);
  }
  write_value(dict, 0x1F90, 3, std::min(2, (setup >> 4) & 3), 2);
  if (setup & 0x80) write_value(dict, 0x1F89, 0, 2000, 4);

  for (const std::uint8_t node : {std::uint8_t{2}, std::uint8_t{3}, std::uint8_t{4}, kSrdId}) {
    auto device = nmt::SimulatedDevice::create(slave_eds, node);
    if (!device.ok()) std::abort();
    h.devices.push_back(std::move(device).value());
    auto& d = h.devices.back().node().dictionary();
    if (setup & 0x40) write_value(d, 0x1017, 0, 50, 2);
    if (node == kSrdId) make_srd(d);
  }
  h.peers.push_back(std::make_unique<EnginePeer<nmt::NmtMaster>>(h.m()));
  for (auto& d : h.devices)
    h.peers.push_back(std::make_unique<EnginePeer<nmt::SimulatedDevice>>(d));
  h.peers.push_back(std::make_unique<EnginePeer<nmt::SdoClient>>(h.tool));
  const std::size_t tool_peer = h.peers.size() - 1;
  auto& tool_out = static_cast<EnginePeer<nmt::SdoClient>&>(*h.peers[tool_peer]).out;
  auto& master_out = static_cast<EnginePeer<nmt::NmtMaster>&>(*h.peers[0]).out;

  h.m().start(h.now, master_out);
  h.after_master_call(master_out);

  nmt::SdoTransferOptions tool_options;
  tool_options.timeout = 200ms;
  while (!in.empty() && !h.exhausted()) {
    const std::uint8_t op = in.next();
    if (op < 0x20) {
      h.run_until(h.now + std::chrono::milliseconds(op + 1));
    } else if (op < 0x40) {
      h.run_until(h.now + std::chrono::milliseconds(100 * (op - 0x1F)));
    } else if (op < 0x60) {
      CanFrame f;
      f.id = (std::uint32_t{in.next()} << 8 | in.next()) & 0x7FF;
      f.dlc = static_cast<std::uint8_t>(std::min(op & 0x0F, 8));
      f.rtr = (op & 0x10) != 0;
      for (std::size_t i = 0; i < f.dlc; ++i) f.data[i] = in.next();
      h.send_foreign(f);
    } else if (op < 0x80) {
      const std::uint8_t k = in.next();
      h.send_foreign(frame_template(op & 0x1F, k, in));
    } else if (op < 0xA0) {
      const auto index = kObjects[op & 0x0F];
      const std::uint8_t sub = in.next();
      const std::size_t n = in.next();
      std::vector<std::uint8_t> bytes;
      for (std::size_t i = 0; i < n; ++i) bytes.push_back(in.next());
      if (op & 0x10) {
        const auto once = bytes;
        for (int r = 1; r < 16; ++r) bytes.insert(bytes.end(), once.begin(), once.end());
      }
      auto options_now = tool_options;
      options_now.mode = (n & 1) ? nmt::SdoMode::Block : nmt::SdoMode::Auto;
      check(h.tool.download(index, sub, std::move(bytes), h.now, tool_out, options_now).ok());
      h.collect(tool_peer);
    } else if (op < 0xB0) {
      check(h.tool.upload(kObjects[op & 0x0F], in.next(), h.now, tool_out, tool_options).ok());
      h.collect(tool_peer);
    } else if (op < 0xC0) {
      const unsigned which = op & 0x0F;
      if (which < 5) {
        if (which < 4) power_on_at(h.devices[which], h.now);
      } else if (which < 10) {
        if (which - 5 < 4) h.peers[1 + which - 5]->plugged = false;
      } else if (which < 15) {
        if (which - 10 < 4) h.peers[1 + which - 10]->plugged = true;
      }
    } else if (op < 0xD0) {
      auto& srd = h.devices[3];
      const std::uint32_t index = 0x1280 + in.next() % 3;
      srd.node().dictionary().set_unsigned(0x1F10, 0, index << 16 | 1 | ((op & 1) ? 8 : 0));
      h.send_foreign(make(0x6E0, {}));
    } else if (op < 0xE0) {
      const std::uint8_t k = in.next();
      const auto node = *cfg::NodeId::from(static_cast<std::uint8_t>(1 + k % 127));
      // Sub-index 80h of 1F82h/1F83h addresses all nodes; the others name `node`.
      const auto target = k == 0x80 ? nmt::NmtTarget::all_nodes() : nmt::NmtTarget(node);
      // Engine rule 5: an application transfer that cannot start (to the master's own node-ID)
      // puts nothing into the output.
      const std::size_t frames_before = master_out.frames.size();
      const std::size_t events_before = master_out.events.size();
      const auto transfer = [&](const cfg::Result<nmt::NmtMaster::TransferId>& id) {
        check(id.ok() == (node != h.m().node_id()));
        if (!id.ok()) {
          check(master_out.frames.size() == frames_before);
          check(master_out.events.size() == events_before);
        }
      };
      switch (op & 7) {
        case 0:
          static_cast<void>(h.m().boot_slave(node, h.now, master_out));
          break;
        case 1:
          h.m().enter_operational(h.now, master_out);
          break;
        case 2:
          // Reserved bytes and sub-indices end where bytes enter (nmt_request_from_byte, the
          // 1F82h write); 1F82h writes of the fuzzed SDO frames reach them.
          if (const auto request = nmt::nmt_request_from_byte(in.next())) {
            h.m().request_nmt(target, *request, h.now, master_out);
          }
          break;
        case 3:
          h.m().request_guarding(target, (op & 8) != 0, h.now, master_out);
          break;
        case 4:
          transfer(h.m().sdo_upload(node, 0x1000, 0, h.now, master_out));
          break;
        case 5:
          transfer(h.m().sdo_download(node, 0x2000, 0, le(in.next(), 2), h.now, master_out));
          break;
        case 6:
          h.m().configuration_done(node, (op & 8) != 0, h.now, master_out);
          break;
        default:
          transfer(h.m().sdo_download(node, 0x2002, 0, std::vector<std::uint8_t>(k, 0x5A), h.now,
                                      master_out));
      }
      h.after_master_call(master_out);
    } else {
      const auto due = h.m().next_deadline();
      const auto limit = h.now + 2s;
      h.run_until(due && *due < limit ? std::max(*due, h.now) : limit);
    }
  }
  // The input ended: let the network run a little, the checks still apply.
  h.run_until(h.now + 3s);
  return 0;
}
