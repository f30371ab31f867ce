// The NMT master (CiA 302-2) in this process, driven by BusEventLoop over the UDP multicast bus,
// boots three slaves written with python-can alone (tests/io/python/master_slaves.py: NMT,
// expedited SDO server, heartbeat, 1010h 'save'). Runs, like the other UdpBus.* tests, only in
// the private network namespace of the ctest test io_udp_bus_netns; elsewhere it skips.
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/object_index.hpp"
#include "multicast_netns.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/io/udp_bus.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/slave/local_dictionary.hpp"
#include "python_peer.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
namespace object = cfg::object;

constexpr std::uint16_t kPort = 47020;  // one port per test (python-can binds to the port)
constexpr std::uint8_t kMasterId = 127;
const std::vector<std::uint8_t> kNodes = {2, 3, 4};
// 1F26h/1F27h: the configuration's date and time (days since 1984, ms after midnight).
constexpr cfg::ConfigurationStamp kStamp{15'000, 43'200'000};

std::vector<std::uint8_t> le(std::uint64_t value, std::size_t size) {
  std::vector<std::uint8_t> out;
  cfg::append_le(out, value, size);
  return out;
}

// What the master downloads to each node: 2000h (UNSIGNED32), 2001h (UNSIGNED16), 2002h
// (UNSIGNED8), as master_slaves.py declares them.
std::vector<cfg::ObjectWrite> configuration_of(std::uint8_t node) {
  return {{0x2000, 0, le(0xC0DE0000U + node, 4)},
          {0x2001, 0, le(0x1000U + node, 2)},
          {0x2002, 0, le(node, 1)}};
}

class Configurations final : public ConfigurationSource {
 public:
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override {
    return configuration_of(node);
  }
};

void set(NmtMaster& master, std::uint16_t index, std::uint8_t sub, std::uint64_t value) {
  const DictionaryEntry* entry = master.dictionary().entry(index, sub);
  ASSERT_NE(entry, nullptr) << cfg::to_string(cfg::ObjectAddress{index, sub});
  ASSERT_TRUE(entry->fixed_size().has_value());
  EXPECT_EQ(master.dictionary().write(index, sub, le(value, *entry->fixed_size()), TimePoint{}),
            SdoAbort::None)
      << cfg::to_string(cfg::ObjectAddress{index, sub});
}

// CiA 302-2 §6: a master (1F80h bit 0) that starts each slave when it booted (bits 1, 3 = 0);
// the slaves mandatory and booted by it (1F81h bits 0, 2, 3), vendor-ID checked (1F85h),
// configuration verified (1F26h/1F27h) and heartbeat consumed (1016h: 500 ms; the peers send
// one every 100 ms).
NmtMaster make_master() {
  MasterOptions options;
  options.configurations = std::make_shared<Configurations>();
  auto created =
      NmtMaster::create(cfg::DeviceDescription{}, cfg::NodeId::from(kMasterId).value(), options);
  EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
  NmtMaster master = std::move(created).value();
  set(master, object::kNmtStartup, 0, cfg::NmtStartup::kMaster);
  for (const std::uint8_t node : kNodes) {
    set(master, object::kSlaveAssignment, node,
        cfg::SlaveAssignment::make(cfg::SlaveAssignment::kSlave | cfg::SlaveAssignment::kBootSlave |
                                   cfg::SlaveAssignment::kMandatory)
            .value);
    set(master, object::kVendorIdentification, node, 0x7E57C0DE);
    set(master, object::kExpectedConfigurationDate, node, kStamp.days);
    set(master, object::kExpectedConfigurationTime, node, kStamp.ms);
    set(master, object::kConsumerHeartbeatTime, node, std::uint32_t{node} << 16 | 500U);
  }
  return master;
}

std::string hex_bytes(const std::vector<std::uint8_t>& bytes) {
  std::string out;
  for (const auto b : bytes) out += cfg::hex_digits(b, 2);
  return out;
}

std::string index_text(std::uint16_t index, std::uint8_t sub) {
  return cfg::hex_digits(index, 4) + " " + cfg::hex_digits(sub, 2);
}

// The peer's lines about `node`, in order, without the node-ID: "WRITE 2000 00 ..." etc.
std::vector<std::string> lines_of(const std::vector<std::string>& lines, std::uint8_t node) {
  std::vector<std::string> out;
  const std::string tag = " " + std::to_string(node);
  for (const auto& line : lines) {
    const auto space = line.find(' ');
    if (space == std::string::npos) continue;
    const auto rest = line.substr(space);
    if (rest == tag || rest.rfind(tag + " ", 0) == 0) {
      out.push_back(line.substr(0, space) + rest.substr(tag.size()));
    }
  }
  return out;
}

std::ptrdiff_t position(const std::vector<std::string>& lines, const std::string& line) {
  const auto it = std::find(lines.begin(), lines.end(), line);
  return it == lines.end() ? -1 : it - lines.begin();
}

TEST(UdpBus, MasterBootsPythonCanSlaves) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  std::vector<std::string> args = {test_support::kUdpTestGroup, std::to_string(kPort), "20"};
  for (const auto node : kNodes) args.push_back(std::to_string(node));
  test_support::PythonPeer peer(test_support::python_script("master_slaves.py"), args);
  ASSERT_EQ(peer.read_line(), "READY");

  UdpBusOptions bus_options;
  bus_options.port = kPort;
  auto bus = UdpBus::open(bus_options);
  ASSERT_TRUE(bus.ok()) << bus.error().message;
  BusEventLoop loop(**bus);
  std::vector<std::string> sent;
  std::vector<std::string> received;
  loop.set_observer([&](const CanFrame& f, TimePoint, BusEventLoop::Direction d) {
    (d == BusEventLoop::Direction::Sent ? sent : received).push_back(to_candump(f));
  });

  NmtMaster master = make_master();
  std::vector<MasterEvent> events;
  bool complete = false;
  EngineRef<NmtMaster> engine(master, [&](const MasterEvent& e, TimePoint) {
    events.push_back(e);
    if (e.kind == MasterEvent::Kind::StartupComplete ||
        e.kind == MasterEvent::Kind::StartupHalted) {
      complete = e.kind == MasterEvent::Kind::StartupComplete;
      loop.request_stop();
    }
  });
  loop.add(engine);
  engine.apply([](NmtMaster& m, TimePoint now, NmtMaster::Output& out) { m.start(now, out); });
  auto status = loop.run_for(10s);
  ASSERT_TRUE(status.ok()) << status.error().message;
  for (const auto& e : events) {
    EXPECT_NE(e.kind, MasterEvent::Kind::BootError) << describe(e);
  }
  ASSERT_TRUE(complete) << "NMT start-up did not complete within 10 s";
  // Heartbeats of the started slaves come in (100 ms period).
  loop.clear_stop();
  status = loop.run_for(400ms);
  ASSERT_TRUE(status.ok()) << status.error().message;
  ASSERT_TRUE((*bus)->send(*from_candump("7FF#")).ok());  // the peer's end
  const auto lines = peer.read_all();
  EXPECT_EQ(peer.finish(), 0);
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines.back(), "END");

  // CiA 301: the master's own boot-up (77Fh); CiA 302-2 §3.1 d): no slave is keep-alive, so the
  // first NMT command is one reset communication for all nodes (000#8200); both before any SDO.
  const auto first_sdo = std::find_if(sent.begin(), sent.end(),
                                      [](const std::string& f) { return f.rfind("6", 0) == 0; });
  EXPECT_NE(std::find(sent.begin(), first_sdo, "77F#00"), first_sdo);
  const auto first_nmt = std::find_if(sent.begin(), sent.end(),
                                      [](const std::string& f) { return f.rfind("000#", 0) == 0; });
  ASSERT_NE(first_nmt, sent.end());
  EXPECT_EQ(*first_nmt, "000#8200");
  EXPECT_LT(first_nmt, first_sdo);
  for (const auto node : kNodes) {
    SCOPED_TRACE("node " + std::to_string(node));
    const auto seen = lines_of(lines, node);
    // The peers heard the reset communication and answered with a boot-up.
    EXPECT_GE(position(seen, "NMT 82"), 0);
    // §3.4 c)-e): 1000h and, since 1F85h is set, 1018h sub 1; §3.5 b): 1020h.
    EXPECT_GE(position(seen, "READ " + index_text(object::kDeviceType, 0)), 0);
    EXPECT_GE(position(seen, "READ " + index_text(object::kIdentity, 1)), 0);
    EXPECT_GE(position(seen, "READ " + index_text(object::kVerifyConfiguration, 1)), 0);
    // §3.5 d): the configuration, then 1020h sub 1/2 = 1F26h/1F27h and 1010h sub 1 'save'
    // (DSP 302 §6.3: 1020h last, so that a broken download is not taken as configured).
    std::vector<std::string> writes;
    for (const auto& line : seen) {
      if (line.rfind("WRITE ", 0) == 0) writes.push_back(line);
    }
    std::vector<std::string> expected;
    for (const auto& w : configuration_of(node)) {
      expected.push_back("WRITE " + index_text(w.index, w.sub_index) + " " + hex_bytes(w.data));
    }
    expected.push_back("WRITE 1020 01 " + hex_bytes(le(kStamp.days, 4)));
    expected.push_back("WRITE 1020 02 " + hex_bytes(le(kStamp.ms, 4)));
    expected.push_back("WRITE 1010 01 73617665");  // "save", CiA 301 §7.5.2.13
    EXPECT_EQ(writes, expected);
    // §3.4 l): start remote node for this node (000#01nn), after its configuration was saved.
    const auto saved = position(seen, "SAVE");
    const auto started = position(seen, "NMT 01");
    EXPECT_GE(saved, 0);
    EXPECT_GT(started, saved);
    EXPECT_NE(std::find(sent.begin(), sent.end(), "000#01" + cfg::hex_digits(node, 2)), sent.end());
    // The slave's heartbeat says operational (05h) afterwards, and the master knows it.
    const std::string operational = cfg::hex_digits(0x700U + node, 3) + "#05";
    EXPECT_NE(std::find(received.begin(), received.end(), operational), received.end());
    EXPECT_EQ(master.known_state(cfg::NodeId::from(node).value()),
              KnownState::in(NmtState::Operational));
    const auto booted = std::find_if(events.begin(), events.end(), [&](const MasterEvent& e) {
      return e.kind == MasterEvent::Kind::SlaveBooted && e.node_id == node;
    });
    ASSERT_NE(booted, events.end());
    EXPECT_TRUE(booted->configured);
  }
}

}  // namespace
}  // namespace nmt
