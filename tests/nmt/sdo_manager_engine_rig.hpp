// The SDO manager engine (manager/sdo_manager_process.hpp) alone, for the tests that drive it
// through a fake of its port (sdo_manager_engine_test.cpp, sdo_manager_engine_spec_test.cpp):
// the fake master answers each SDO access the engine starts from the dictionaries of the
// devices on its "network" (a node without one is silent: the access times out), records every
// access in order, and says what the engine asked of error control.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <deque>
#include <map>
#include <optional>
#include <ostream>
#include <set>
#include <string>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/device_file.hpp"
#include "manager/sdo_manager_process.hpp"
#include "nmt_master_spec_test_rig.hpp"
#include "sdo_manager_spec_words.hpp"
#include "test_paths.hpp"

namespace nmt::engine_test {

using namespace std::chrono_literals;
using namespace cfg::literals;
using master_spec::le;
using master_spec::request_word;
using Kind = MasterEvent::Kind;

constexpr std::uint8_t kManager = 1;
constexpr std::uint32_t kInvalid = 0x80000000;
constexpr std::uint32_t kInUse = 0x40000000;  // 1F02h bit 30 (§7.2.3)

inline const cfg::DeviceDescription& device_file(const std::string& path) {
  static std::map<std::string, cfg::DeviceDescription> files;
  auto it = files.find(path);
  if (it != files.end()) return it->second;
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/" + path);
  EXPECT_TRUE(result.ok()) << path << ": " << result.diagnostics.format();
  return files.emplace(path, result.device.value_or(cfg::DeviceDescription{})).first->second;
}

/// One SDO access the engine started, as the fake port saw it.
struct Access {
  std::uint8_t node;
  std::uint16_t index;
  std::uint8_t sub;
  bool upload;
  std::uint32_t value;  ///< download
  bool operator==(const Access&) const = default;
};
inline std::ostream& operator<<(std::ostream& os, const Access& a) {
  // "node 120 write 0x1281 sub 1 = 0x680"
  os << "node " << int{a.node} << (a.upload ? " read " : " write ")
     << master_spec::hex_text(a.index) << " sub " << int{a.sub};
  if (!a.upload) os << " = " << master_spec::hex_text(a.value);
  return os;
}
inline Access read(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
  return {node, index, sub, true, 0};
}
inline Access write(std::uint8_t node, std::uint16_t index, std::uint8_t sub, std::uint32_t value) {
  return {node, index, sub, false, value};
}

/// The master as the engine sees it, and the devices its transfers reach.
class FakeMaster final : public SdoManagerPort {
 public:
  bool active = true;
  std::map<std::uint8_t, LocalDictionary> devices;
  std::vector<Access> accesses;
  std::deque<SdoManagerTransfer> pending;
  std::map<std::uint8_t, Duration> consumer;                ///< the master's 1016h entries
  std::map<std::uint8_t, std::optional<Duration>> watched;  ///< watch() calls
  std::vector<std::uint8_t> unwatched;

  bool master_active() const override { return active; }
  bool serves_sdo() const override { return true; }
  void start_transfer(SdoManagerTransfer t, TimePoint) override {
    accesses.push_back(
        {t.node, t.address.index, t.address.sub_index, t.upload,
         t.upload ? 0 : static_cast<std::uint32_t>(cfg::load_le(t.data, t.data.size()))});
    pending.push_back(std::move(t));
  }
  std::optional<Duration> consumer_time(cfg::NodeId node) const override {
    auto it = consumer.find(node);
    return it == consumer.end() ? std::nullopt : std::optional<Duration>(it->second);
  }
  void watch(cfg::NodeId node, std::optional<Duration> heartbeat, TimePoint) override {
    watched[node] = heartbeat;
  }
  void unwatch(cfg::NodeId node) override {
    watched.erase(node);
    unwatched.push_back(node);
  }

  /// The result of `t` as the device (or its absence) gives it.
  SdoResult answer(const SdoManagerTransfer& t, TimePoint now) {
    SdoResult r;
    r.node_id = t.node;
    r.address = t.address;
    r.upload = t.upload;
    auto it = devices.find(t.node);
    if (it == devices.end()) {
      r.abort = SdoAbort::Timeout;  // the client detected it
      return r;
    }
    r.abort = t.upload ? it->second.read(t.address.index, t.address.sub_index, r.data, now)
                       : it->second.write(t.address.index, t.address.sub_index, t.data, now);
    r.aborted_by_server = r.abort != SdoAbort::None;
    return r;
  }
};

/// The engine, its fake master and the devices, driven as a driver would.
class ManagerEngineRig {
 public:
  ManagerEngineRig() { settings.enabled = true; }

  /// Builds and installs the engine (settings may be changed before).
  SdoManagerProcess& engine() {
    if (!engine_) {
      engine_.emplace(dict, port, *cfg::NodeId::from(kManager), settings);
      engine_->install();
    }
    return *engine_;
  }
  void add_device(std::uint8_t node, const std::string& file) {
    auto d = LocalDictionary::from_device(device_file(file), *cfg::NodeId::from(node));
    ASSERT_TRUE(d.ok());
    port.devices.emplace(node, std::move(d).value());
  }
  void add_srd(std::uint8_t node) { add_device(node, "sdo_manager/srd.eds"); }
  /// Slaves 2 (1201h, 1202h) and 3 (default SDO only).
  void add_slaves() {
    add_device(2, "sdo_manager/slave_channels.eds");
    add_device(3, "master/slave.eds");
  }
  std::uint32_t at(std::uint8_t node, std::uint16_t index, std::uint8_t sub) {
    return static_cast<std::uint32_t>(
        port.devices.at(node).get_unsigned(index, sub).value_or(0xDEADBEEF));
  }
  std::uint32_t own(std::uint16_t index, std::uint8_t sub) {
    return static_cast<std::uint32_t>(dict.get_unsigned(index, sub).value_or(0xDEADBEEF));
  }

  /// Runs the engine as a driver would until nothing is due and no access waits: on_timer when
  /// due, each access answered after its response time (a silent node: the scan's or the SDO
  /// timeout).
  void run() {
    for (int i = 0; i < 100000; ++i) {
      auto due = engine().next_deadline();
      if (due && *due <= now) {
        engine().on_timer(now, out);
        continue;
      }
      if (port.pending.empty()) return;
      const auto t = port.pending.front();
      port.pending.pop_front();
      const auto result = port.answer(t, now);
      now += result.abort == SdoAbort::Timeout ? t.timeout : 1ms;
      engine().on_transfer_result(t.tag, result, now, out);
    }
    FAIL() << "the engine does not settle";
  }
  std::vector<MasterEvent> events_of(Kind kind, std::uint8_t node) const {
    std::vector<MasterEvent> found;
    for (const auto& e : out.events) {
      if (e.kind == kind && e.node_id == node) found.push_back(e);
    }
    return found;
  }
  /// The SRD sets 1F10h and sends 6E0h; true when the engine reported the registration.
  bool register_srd(std::uint8_t node, std::uint32_t request) {
    port.devices.at(node).set_unsigned(0x1F10, 0, request);
    EXPECT_TRUE(engine().on_frame(*from_candump("6E0#"), now, out));
    run();
    return !events_of(Kind::SrdRegistered, node).empty();
  }
  /// An expedited download of `value` to `index` sub 0 over the SRD's channel to the manager
  /// (its client entry `client`, as the manager wrote it); the frame the engine answers with.
  std::optional<CanFrame> srd_write(std::uint8_t node, std::uint16_t client, std::uint16_t index,
                                    std::uint32_t value) {
    // CiA 301 expedited download initiate, 4 bytes: 23h, index, sub, value (little-endian).
    std::vector<std::uint8_t> bytes{0x23, static_cast<std::uint8_t>(index & 0xFF),
                                    static_cast<std::uint8_t>(index >> 8U), 0};
    for (auto b : le(value, 4)) bytes.push_back(b);
    const CanFrame request = CanFrame::make(at(node, client, 1), bytes);
    const auto before = out.frames.size();
    EXPECT_TRUE(engine().on_frame(request, now, out));
    if (out.frames.size() != before + 1) return std::nullopt;
    return out.frames.back();
  }
  /// §7.2.2 over the SRD's channel 1281h, on client entry 1282h; runs the job.
  void connect(std::uint8_t srd, std::uint8_t slave) {
    const auto answer = srd_write(srd, 0x1281, 0x1F00, request_word(0x1282, srd, slave));
    ASSERT_TRUE(answer.has_value());
    ASSERT_EQ(answer->data[0], 0x60);  // download initiate response
    run();
    ASSERT_FALSE(events_of(Kind::SdoConnectionEstablished, srd).empty());
  }

  SdoManagerSettings settings{};
  LocalDictionary dict;  ///< the master's (empty unless a test fills it before engine())
  FakeMaster port;
  TimePoint now{};
  SdoManagerProcess::Output out;

 private:
  std::optional<SdoManagerProcess> engine_;
};

}  // namespace nmt::engine_test
