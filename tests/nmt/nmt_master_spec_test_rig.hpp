// The rig of the NmtMasterSpec tests (nmt_master_spec_test*.cpp): an NmtMaster, simulated slaves,
// an SDO "tool" talking to the master's SDO server and a spare node for foreign frames, all on
// one 500 kbit/s simulated bus with simulated time. Written from the public headers only
// (nmt/master/nmt_master.hpp, cfg/master_objects.hpp, nmt/sim/sim_bus.hpp,
// nmt/sim/simulated_device.hpp).
//
// Device files, written for these tests (tests/data/master/):
// - master.dcf: the CANopen manager at node 1; 1F80h = 01h; nodes 2 and 3 assigned with
//   1F81h = 05h (slave, boot slave); 1F84h = 000F0191h and 1F85h = 0000ABCDh for both; every
//   other CiA 302-2 §6 object at its default. Tests change ParameterValue before start.
// - slave.eds: 1000h = 000F0191h, 1018h = 0000ABCDh / 00000042h / 00020003h / 00001234h,
//   1017h = 0, 1020h = 0/0, 1F52h = 15000 days / 3 600 000 ms, 2000h = 10 (U16), 2001h (string),
//   2002h (DOMAIN), RPDO1/TPDO1.
// With MASTER_SPEC_DUMP=1 in the environment each rig prints its frames and events when it ends.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <functional>
#include <initializer_list>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/config_manager.hpp"
#include "cfg/device_file.hpp"
#include "cfg/master_objects.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/master_host.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "started.hpp"
#include "test_paths.hpp"

namespace nmt::master_spec {

using namespace std::chrono_literals;
using namespace cfg::literals;

constexpr cfg::NodeId kMaster = 1_node;
// slave.eds identity.
constexpr std::uint32_t kDeviceType = 0x000F0191;
constexpr std::uint32_t kVendor = 0x0000ABCD;
constexpr std::uint32_t kProduct = 0x00000042;
constexpr std::uint32_t kRevision = 0x00020003;
constexpr std::uint32_t kSerial = 0x00001234;
constexpr std::uint32_t kSoftwareDate = 15000;
constexpr std::uint32_t kSoftwareTime = 3'600'000;

// 1F81h byte 0 (CiA 302-2 §6.3, Tables 19-25).
using Assign = cfg::SlaveAssignment;
constexpr std::uint8_t kSlave = Assign::kSlave;
constexpr std::uint8_t kBoot = Assign::kBootSlave;
constexpr std::uint8_t kMandatory = Assign::kMandatory;
constexpr std::uint8_t kKeepAlive = Assign::kKeepAlive;
constexpr std::uint8_t kVerifySoftware = Assign::kVerifySoftware;
constexpr std::uint8_t kUpdateSoftware = Assign::kUpdateSoftware;
constexpr std::uint8_t kRestore = Assign::kRestore;
using Startup = cfg::NmtStartup;

// "071#PPNN": DSP 302 §5.5.1.1 / §5.5.1.3, data byte 0 the priority level, byte 1 the node-ID.
inline std::string reply_71(std::uint16_t priority, std::uint8_t node) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  std::string text = "071#";
  for (unsigned byte : {unsigned{priority} & 0xFFU, unsigned{node}}) {
    text += kDigits[byte >> 4U];
    text += kDigits[byte & 0xFU];
  }
  return text;
}

inline cfg::DeviceDescription load_file(const std::string& name) {
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/master/" + name);
  EXPECT_TRUE(result.ok()) << result.diagnostics.format();
  return result.device.value_or(cfg::DeviceDescription{});
}
inline const cfg::DeviceDescription& master_dcf() {
  static const cfg::DeviceDescription dcf = load_file("master.dcf");
  return dcf;
}
inline const cfg::DeviceDescription& slave_eds() {
  static const cfg::DeviceDescription eds = load_file("slave.eds");
  return eds;
}

inline std::string hex_text(std::uint64_t value) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  std::string text;
  do {
    text.insert(text.begin(), kDigits[value & 0xF]);
    value >>= 4;
  } while (value != 0);
  return "0x" + text;
}

// Sets ParameterValue of an entry the file has (the DCF way of configuring a device).
inline void set_value(cfg::DeviceDescription& description, std::uint16_t index, std::uint8_t sub,
                      std::uint64_t value) {
  auto* entry = description.sub(index, sub);
  ASSERT_NE(entry, nullptr) << "no " << std::hex << index << " sub " << int{sub} << " in the file";
  entry->parameter_value = hex_text(value);
}

inline std::vector<std::uint8_t> le(std::uint64_t value, std::size_t size) {
  std::vector<std::uint8_t> bytes(size);
  for (std::size_t i = 0; i < size; ++i) bytes[i] = static_cast<std::uint8_t>(value >> (8 * i));
  return bytes;
}
inline cfg::ObjectWrite write_of(std::uint16_t index, std::uint8_t sub, std::uint64_t value,
                                 std::size_t size) {
  return {index, sub, le(value, size)};
}
inline std::uint64_t value_of(std::span<const std::uint8_t> bytes) {
  std::uint64_t v = 0;
  for (std::size_t i = 0; i < bytes.size() && i < 8; ++i) v |= std::uint64_t{bytes[i]} << (8 * i);
  return v;
}

// Configurations and program images by node, as the configuration manager would hand them out.
class TestConfigurations : public ConfigurationSource {
 public:
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override {
    auto it = writes.find(node.value());
    if (it == writes.end()) return std::nullopt;
    return it->second;
  }
  std::optional<std::vector<std::uint8_t>> program(cfg::NodeId node) const override {
    auto it = programs.find(node.value());
    if (it == programs.end()) return std::nullopt;
    return it->second;
  }
  std::map<std::uint8_t, std::vector<cfg::ObjectWrite>> writes;
  std::map<std::uint8_t, std::vector<std::uint8_t>> programs;
};

// Device faults (nmt/sim/fault_injection.hpp) for one scenario.
inline DeviceFaults fault(const std::function<void(DeviceFaults&)>& set) {
  DeviceFaults faults;
  set(faults);
  return faults;
}
inline DeviceFaults absent_device() {
  return fault([](DeviceFaults& f) { f.absent = true; });
}
inline DeviceFaults failing(std::uint16_t index, std::optional<std::uint8_t> sub, SdoAbort code,
                            bool on_read, bool on_write) {
  InjectedAbort abort;
  abort.index = index;
  abort.sub_index = sub;
  abort.code = code;
  abort.on_read = on_read;
  abort.on_write = on_write;
  return fault([&](DeviceFaults& f) { f.sdo_aborts.push_back(abort); });
}
/// The device answers SDO reads (uploads) of the object with `code`.
inline DeviceFaults failing_read(std::uint16_t index, std::optional<std::uint8_t> sub,
                                 SdoAbort code) {
  return failing(index, sub, code, true, false);
}
/// The device answers SDO writes (downloads) of the object with `code`.
inline DeviceFaults failing_write(std::uint16_t index, std::optional<std::uint8_t> sub,
                                  SdoAbort code) {
  return failing(index, sub, code, false, true);
}

struct Seen {
  TimePoint at;
  CanFrame frame;
  std::string text() const { return to_candump(frame); }
};

// SDO request frames of CiA 301 §7.2.4.3 (ccs in bits 7-5 of byte 0; index LE; sub-index).
inline bool addresses(const CanFrame& f, std::uint16_t index, std::uint8_t sub) {
  return !f.rtr && f.dlc == 8 && f.data[1] == (index & 0xFF) && f.data[2] == (index >> 8) &&
         f.data[3] == sub;
}
// Initiate download (ccs 1) or block download initiate (ccs 6, cs 0).
inline bool is_download_initiate(const CanFrame& f) {
  const unsigned ccs = f.data[0] >> 5U;
  return ccs == 1 || (ccs == 6 && (f.data[0] & 1U) == 0);
}
// Initiate upload (ccs 2) or block upload initiate (ccs 5, cs 0).
inline bool is_upload_initiate(const CanFrame& f) {
  const unsigned ccs = f.data[0] >> 5U;
  return ccs == 2 || (ccs == 5 && (f.data[0] & 3U) == 0);
}

class MasterRig {
 public:
  MasterRig() {
    bus.attach(tool_);
    bus.attach(other_);
    tool_.set_event_handler([this](const SdoResult& r, TimePoint) { results_[r.id] = r; });
    bus.add_observer([this](const CanFrame& f, TimePoint t) { seen.push_back({t, f}); });
    options.configurations = configurations;
  }
  ~MasterRig() {
    if (std::getenv("MASTER_SPEC_DUMP") == nullptr) return;
    for (const auto& s : seen)
      std::cerr << s.at.time_since_epoch().count() << "us " << s.text() << "\n";
    for (const auto& e : events)
      std::cerr << "EVENT " << e.at.time_since_epoch().count() << "us " << describe(e) << "\n";
  }
  MasterRig(const MasterRig&) = delete;
  MasterRig& operator=(const MasterRig&) = delete;

  // --- configuration before start ------------------------------------------------------------
  /// 1F81h sub `node` (CiA 302-2 §6.3).
  void assign(std::uint8_t node, std::uint8_t flags, std::uint8_t retry_factor = 0,
              std::uint16_t guard_time_ms = 0) {
    set_value(master, 0x1F81, node, Assign::make(flags, retry_factor, guard_time_ms).value);
  }
  void startup(std::uint32_t value) { set_value(master, 0x1F80, 0, value); }
  /// 1016h sub `entry` = consumer of `node` with `time_ms` (CiA 301 §7.5.2.33).
  void consume_heartbeat(std::uint8_t entry, std::uint8_t node, std::uint16_t time_ms) {
    set_value(master, 0x1016, entry, std::uint32_t{node} << 16U | time_ms);
  }

  /// A slave from slave.eds (or `eds`) at `node`, off until start().
  SimulatedDevice& add_slave(std::uint8_t node, DeviceFaults faults = {},
                             const cfg::DeviceDescription& eds = slave_eds(),
                             SlaveNodeOptions slave_options = {}) {
    auto device = SimulatedDevice::create(eds, node, std::move(faults), slave_options);
    EXPECT_TRUE(device.ok()) << (device.ok() ? "" : device.error().message);
    auto& slot = slaves_[node];
    if (slot) bus.detach(*slot);
    slot = std::make_unique<SimEngineNode<SimulatedDevice>>(std::move(device).value());
    bus.attach(*slot);
    return slot->engine();
  }
  SimulatedDevice& slave(std::uint8_t node) { return slaves_.at(node)->engine(); }
  void start(std::uint8_t node) {
    slaves_.at(node)->apply(
        [](SimulatedDevice& d, TimePoint now, SimulatedDevice::Output& out) { d.start(now, out); });
  }
  void power_on_slaves() {
    for (auto& [node, slot] : slaves_) start(node);
  }
  /// Takes a slave off the bus (it keeps its state, sends and hears nothing).
  void unplug(std::uint8_t node) { bus.detach(*slaves_.at(node)); }
  void set_faults(std::uint8_t node, DeviceFaults faults) {
    slave(node).set_faults(std::move(faults));
  }

  /// Builds the master from `master` and `options`, attaches it and starts it at the bus time.
  NmtMaster& start_master() {
    auto created = NmtMaster::create(master, kMaster, options);
    EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
    if (!created.ok()) throw std::runtime_error("NmtMaster::create failed");
    master_ = std::make_unique<SimEngineNode<NmtMaster>>(std::move(created).value());
    // The rig is the driver (as cfgmgr master is): entries are written after the call; the tests
    // call enter_operational() themselves.
    host = std::make_unique<MasterHost>(
        master_->engine(), [this](const MasterHost::Call& call) { master_->apply(call); });
    host->set_enters_operational(false);
    master_->set_event_handler([this](const MasterEvent& e, TimePoint) {
      events.push_back(e);
      if (persist_entries) host->on_event(e);
    });
    bus.attach(*master_);
    started_at = bus.now();
    master_->apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
    return master_->engine();
  }
  /// The usual scene: slaves on at 0, the master 50 ms later.
  NmtMaster& power_on_network() {
    power_on_slaves();
    bus.run_for(50ms);
    return start_master();
  }
  /// The scene of most tests: node 2 from slave.eds, node 3 with `faults3` (and `eds3`,
  /// `options3`), powered on as power_on_network() does.
  NmtMaster& two_slaves(DeviceFaults faults3 = {}, const cfg::DeviceDescription& eds3 = slave_eds(),
                        SlaveNodeOptions options3 = {}) {
    add_slave(2);
    add_slave(3, std::move(faults3), eds3, options3);
    return power_on_network();
  }
  /// Node 3's boot error in that scene (nullopt when it booted first, or nothing within 20 s).
  std::optional<BootError> boot_error_of_3(DeviceFaults faults3 = {},
                                           const cfg::DeviceDescription& eds3 = slave_eds()) {
    two_slaves(std::move(faults3), eds3);
    auto ended = [](const MasterEvent& e) {
      return e.node_id == 3 &&
             (e.kind == MasterEvent::Kind::BootError || e.kind == MasterEvent::Kind::SlaveBooted);
    };
    if (!run_until_event(ended, 20s)) return std::nullopt;
    for (const auto& e : events) {
      if (ended(e)) return e.error;
    }
    return std::nullopt;
  }
  /// Every value written to (index, sub) by the tool is refused with an abort that CiA 302-2
  /// §6.2-§6.5 allow for reserved values (0800 0000h or 0609 0030h).
  void expect_writes_refused(std::uint16_t index, std::uint8_t sub,
                             std::initializer_list<std::uint64_t> values, std::size_t size) {
    for (std::uint64_t value : values) {
      const SdoAbort code = tool_write_u(index, sub, value, size);
      EXPECT_TRUE(code == SdoAbort::General || code == SdoAbort::ValueRangeExceeded)
          << hex_text(index) << " sub " << int{sub} << " = " << hex_text(value) << ": " << code;
    }
  }
  NmtMaster& engine() { return master_->engine(); }
  /// Runs an API call of the master at the bus time.
  template <class Fn>
  decltype(auto) call(Fn&& fn) {
    return master_->apply(std::forward<Fn>(fn));
  }

  void run_for(Duration d) { bus.run_for(d); }
  /// Runs until an event matching `pred` was reported (true) or `limit` passed (false).
  bool run_until_event(const std::function<bool(const MasterEvent&)>& pred, Duration limit) {
    std::size_t checked = 0;
    auto found = [&] {
      for (; checked < events.size(); ++checked) {
        if (pred(events[checked])) return true;
      }
      return false;
    };
    const bool ok = bus.run_until(found, bus.now() + limit);
    return ok || found();
  }
  /// Power-cycles slave `node` and runs until the master reports it booted again (SlaveBooted
  /// after the power cycle): the time of the power cycle, nullopt when no boot came in `limit`.
  std::optional<TimePoint> reboot_until_booted(std::uint8_t node, Duration limit) {
    const TimePoint reboot = bus.now();
    start(node);
    const bool booted = run_until_event(
        [&](const MasterEvent& e) {
          return e.kind == MasterEvent::Kind::SlaveBooted && e.node_id == node && e.at > reboot;
        },
        limit);
    if (!booted) return std::nullopt;
    return reboot;
  }
  bool run_until_kind(MasterEvent::Kind kind, Duration limit,
                      std::optional<std::uint8_t> node = {}) {
    return run_until_event(
        [&](const MasterEvent& e) { return e.kind == kind && (!node || e.node_id == *node); },
        limit);
  }

  // --- observation ---------------------------------------------------------------------------
  std::vector<MasterEvent> events_of(MasterEvent::Kind kind,
                                     std::optional<std::uint8_t> node = {}) const {
    std::vector<MasterEvent> out;
    for (const auto& e : events) {
      if (e.kind == kind && (!node || e.node_id == *node)) out.push_back(e);
    }
    return out;
  }
  std::vector<MasterEvent> boot_errors(std::uint8_t node) const {
    return events_of(MasterEvent::Kind::BootError, node);
  }
  std::vector<MasterEvent> booted(std::uint8_t node) const {
    return events_of(MasterEvent::Kind::SlaveBooted, node);
  }
  /// Frames on `id` seen at or after `from`.
  std::vector<Seen> on_id(std::uint32_t id, TimePoint from = TimePoint{}) const {
    std::vector<Seen> out;
    for (const auto& s : seen) {
      if (s.at >= from && !s.frame.extended && s.frame.id == id) out.push_back(s);
    }
    return out;
  }
  /// NMT commands (COB-ID 000h) as candump text, in bus order, from `from` on.
  std::vector<std::string> nmt(TimePoint from = TimePoint{}) const {
    std::vector<std::string> out;
    for (const auto& s : on_id(kNmtCobId, from)) out.push_back(s.text());
    return out;
  }
  std::vector<Seen> nmt_seen(TimePoint from = TimePoint{}) const { return on_id(kNmtCobId, from); }
  std::size_t count_nmt(std::string_view text, TimePoint from = TimePoint{}) const {
    auto all = nmt(from);
    return static_cast<std::size_t>(std::count(all.begin(), all.end(), text));
  }
  /// SDO requests the master sent to `node`.
  std::vector<Seen> requests_to(std::uint8_t node, TimePoint from = TimePoint{}) const {
    return on_id(0x600U + node, from);
  }
  /// Initiated downloads (expedited, segmented or block) of (index, sub) to `node`.
  std::vector<Seen> downloads_of(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                                 TimePoint from = TimePoint{}) const {
    std::vector<Seen> out;
    for (const auto& s : requests_to(node, from)) {
      if (is_download_initiate(s.frame) && addresses(s.frame, index, sub)) out.push_back(s);
    }
    return out;
  }
  std::vector<Seen> all_downloads(std::uint8_t node, TimePoint from = TimePoint{}) const {
    std::vector<Seen> out;
    for (const auto& s : requests_to(node, from)) {
      if (is_download_initiate(s.frame)) out.push_back(s);
    }
    return out;
  }
  std::vector<Seen> uploads_of(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                               TimePoint from = TimePoint{}) const {
    std::vector<Seen> out;
    for (const auto& s : requests_to(node, from)) {
      if (is_upload_initiate(s.frame) && addresses(s.frame, index, sub)) out.push_back(s);
    }
    return out;
  }
  /// The value the device holds now (unchecked read of its dictionary).
  std::optional<std::uint64_t> device_value(std::uint8_t node, std::uint16_t index,
                                            std::uint8_t sub) {
    return slave(node).node().dictionary().get_unsigned(index, sub);
  }

  // --- the tool: an SDO client of the master's server (600h/580h + master node-ID) -----------
  SdoResult tool_write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data,
                       SdoTransferOptions transfer = {}) {
    auto id = tool_.apply([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
      return c.download(index, sub, std::move(data), now, out, transfer);
    });
    return finish(test_support::started(id));
  }
  /// Starts a write of the tool and returns at once (tool_result() tells when it ended).
  SdoClient::TransferId tool_begin_write(std::uint16_t index, std::uint8_t sub,
                                         std::vector<std::uint8_t> data,
                                         SdoTransferOptions transfer = {}) {
    return test_support::started(
        tool_.apply([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
          return c.download(index, sub, std::move(data), now, out, transfer);
        }));
  }
  /// The result of a transfer of the tool; nullopt while it runs.
  std::optional<SdoResult> tool_result(SdoClient::TransferId id) const {
    const auto it = results_.find(id);
    if (it == results_.end()) return std::nullopt;
    return it->second;
  }
  SdoAbort tool_write_u(std::uint16_t index, std::uint8_t sub, std::uint64_t value,
                        std::size_t size) {
    return tool_write(index, sub, le(value, size)).abort;
  }
  SdoResult tool_read(std::uint16_t index, std::uint8_t sub, SdoTransferOptions transfer = {}) {
    auto id = tool_.apply([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
      return c.upload(index, sub, now, out, transfer);
    });
    return finish(test_support::started(id));
  }
  std::optional<std::uint64_t> tool_read_u(std::uint16_t index, std::uint8_t sub) {
    auto r = tool_read(index, sub);
    if (!r.ok()) return std::nullopt;
    return value_of(r.data);
  }

  /// A frame from a node that is neither master nor slave (another device on the bus).
  void send_foreign(std::string_view candump) {
    auto f = from_candump(candump);
    ASSERT_TRUE(f.has_value()) << candump;
    bus.send(other_, *f);
  }

  SimBus bus{500'000};
  cfg::DeviceDescription master = master_dcf();
  MasterOptions options;
  std::shared_ptr<TestConfigurations> configurations = std::make_shared<TestConfigurations>();
  std::vector<Seen> seen;
  std::vector<MasterEvent> events;
  /// MasterEvent::PersistEntry (a manager with a store directory): the rig's host writes the
  /// entry at once and calls entry_persisted() (or gives it to the host's writer); false leaves
  /// that to the test.
  bool persist_entries = true;
  /// The driver's duties (nmt/master/master_host.hpp), from start_master() on.
  std::unique_ptr<MasterHost> host;
  TimePoint started_at{};

 private:
  SdoResult finish(SdoClient::TransferId id) {
    bus.run_until([&] { return results_.count(id) != 0; }, bus.now() + 10s);
    auto it = results_.find(id);
    EXPECT_TRUE(it != results_.end()) << "SDO transfer of the tool did not finish";
    if (it == results_.end()) return SdoResult{};
    auto r = it->second;
    results_.erase(it);
    return r;
  }

  std::map<std::uint8_t, std::unique_ptr<SimEngineNode<SimulatedDevice>>> slaves_;
  std::unique_ptr<SimEngineNode<NmtMaster>> master_;
  SimEngineNode<SdoClient> tool_{SdoClientConfig::for_node(kMaster)};
  FunctionNode other_;
  std::map<SdoClient::TransferId, SdoResult> results_;
};

/// CiA 302-2 §6.2/§6.4/§6.5: "abort code: 0800 0000h or 0609 0030h".
inline bool is_value_abort(SdoAbort code) {
  return code == SdoAbort::General || code == SdoAbort::ValueRangeExceeded;
}

inline std::ostream& operator<<(std::ostream& os, const Seen& s) {
  return os << s.at.time_since_epoch().count() << "us " << s.text();
}

}  // namespace nmt::master_spec

namespace nmt {
inline std::ostream& operator<<(std::ostream& os, const MasterEvent& e) {
  return os << e.at.time_since_epoch().count() << "us " << to_string(e.kind) << " node "
            << (e.node_id ? int{e.node_id->value()} : 0) << ": " << describe(e);
}
}  // namespace nmt
