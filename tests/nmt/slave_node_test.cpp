// The slave node with no faults, driven frame by frame as a master would drive a real device
// (no bus, no wrapper). Device file: tests/data/sim_device.eds (written for these tests: 1000h =
// 000F0191h, 1014h = $NODEID+80h). Frames as candump strings; bytes from CiA 301: SDO expedited
// upload/download (§7.2.4.3), boot-up and heartbeat `7xx#SS` (§7.2.8.3.2), guarding toggle
// (§7.2.8.3.2.1), EMCY (§7.2.7.3.1).
#include "nmt/slave/slave_node.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

// Powers `device` on at `now` (nothing it reports at power-on is looked at here).
template <class Device>
void power_on_at(Device& device, TimePoint now) {
  typename Device::Output out;
  device.start(now, out);
}

using namespace std::chrono_literals;
using namespace cfg::literals;

static_assert(Engine<SlaveNode>);

constexpr cfg::NodeId kNode = 2_node;

cfg::DeviceDescription sim_eds() {
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sim_device.eds");
  EXPECT_TRUE(result.device.has_value()) << result.diagnostics.format();
  return result.device.value_or(cfg::DeviceDescription{});
}

// A node and what it answered to the last call, as candump strings.
struct Driver {
  std::unique_ptr<SlaveNode> node;
  std::vector<std::string> sent;
  std::vector<SlaveEvent> events;

  explicit Driver(SlaveNodeOptions options = {}) {
    auto created = SlaveNode::create(sim_eds(), kNode, std::move(options));
    EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
    node = std::move(created).value();
  }
  void take(SlaveNode::Output& out) {
    sent.clear();
    for (const auto& f : out.frames) sent.push_back(to_candump(f));
    events = std::move(out.events);
  }
  bool frame(std::string_view candump, TimePoint now) {
    auto f = from_candump(candump);
    EXPECT_TRUE(f.has_value()) << candump;
    SlaveNode::Output out;
    const bool taken = node->on_frame(f.value_or(CanFrame{}), now, out);
    take(out);
    return taken;
  }
  void timer(TimePoint now) {
    SlaveNode::Output out;
    node->on_timer(now, out);
    take(out);
  }
  void boot(TimePoint now = TimePoint{}) {
    power_on_at(*node, now);
    timer(now);
  }
};

TEST(SlaveNode, IsSilentUntilPoweredOnThenBootsWithBootUpMessage) {
  Driver d;
  EXPECT_FALSE(d.node->powered());
  EXPECT_FALSE(d.node->next_deadline().has_value());
  EXPECT_FALSE(d.frame("602#4000100000000000", TimePoint{}));
  EXPECT_TRUE(d.sent.empty());

  power_on_at(*d.node, TimePoint{5ms});
  EXPECT_EQ(d.node->state(), NmtState::Initialising);
  EXPECT_EQ(d.node->next_deadline(), TimePoint{5ms});  // initialisation ends at once
  d.timer(TimePoint{5ms});
  EXPECT_EQ(d.sent, std::vector<std::string>{"702#00"});  // CiA 301 §7.2.8.3.2.4
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0].kind, SlaveEvent::Kind::Boot);
  EXPECT_EQ(d.events[0].at, TimePoint{5ms});
  EXPECT_EQ(d.node->state(), NmtState::PreOperational);
}

TEST(SlaveNode, AnswersAnExpeditedUploadOfTheDeviceType) {
  Driver d;
  d.boot();
  // CiA 301 §7.2.4.3.4: initiate upload 40h; response 43h = expedited, size indicated, 4 bytes.
  EXPECT_TRUE(d.frame("602#4000100000000000", TimePoint{1ms}));
  EXPECT_EQ(d.sent, std::vector<std::string>{"582#4300100091010F00"});
  EXPECT_FALSE(d.frame("603#4000100000000000", TimePoint{2ms}));  // another node's SDO
  EXPECT_TRUE(d.sent.empty());
}

TEST(SlaveNode, WriteEventsCarryTheTimeOfTheWrite) {
  Driver d;
  d.boot();
  // 2000h (UNSIGNED16 filter time) = 5: expedited download of 2 bytes (2Bh), answered 60h.
  EXPECT_TRUE(d.frame("602#2B00200005000000", TimePoint{7ms}));
  EXPECT_EQ(d.sent, std::vector<std::string>{"582#6000200000000000"});
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0].kind, SlaveEvent::Kind::SdoWrite);
  EXPECT_EQ(d.events[0].at, TimePoint{7ms});
  EXPECT_EQ(d.events[0].text, "2000h sub 00h = 2 byte(s)");
}

TEST(SlaveNode, HeartbeatStartsAtOnceWhen1017IsWrittenAndFollowsTheState) {
  Driver d;
  d.boot();
  EXPECT_TRUE(d.frame("602#2B17100064000000", TimePoint{10ms}));  // 1017h = 100 ms
  EXPECT_EQ(d.sent, std::vector<std::string>{"582#6017100000000000"});
  // CiA 301 §7.2.8.3.2.2: a non-zero producer time starts the protocol at once.
  EXPECT_EQ(d.node->next_deadline(), TimePoint{10ms});
  d.timer(TimePoint{10ms});
  EXPECT_EQ(d.sent, std::vector<std::string>{"702#7F"});
  EXPECT_EQ(d.node->next_deadline(), TimePoint{110ms});
  EXPECT_TRUE(d.frame("000#0102", TimePoint{50ms}));  // start
  ASSERT_EQ(d.events.size(), 1u);
  EXPECT_EQ(d.events[0].text, "start: pre-operational -> operational");
  d.timer(TimePoint{110ms});
  EXPECT_EQ(d.sent, std::vector<std::string>{"702#05"});
}

TEST(SlaveNode, AnswersGuardingWhileNoHeartbeatIsProduced) {
  Driver d;
  d.boot();
  EXPECT_TRUE(d.frame("702#R1", TimePoint{1ms}));
  EXPECT_EQ(d.sent, std::vector<std::string>{"702#7F"});
  EXPECT_TRUE(d.frame("702#R1", TimePoint{2ms}));
  EXPECT_EQ(d.sent, std::vector<std::string>{"702#FF"});  // toggle bit alternates
}

TEST(SlaveNode, ResetNodeRestoresAndBootsAgainFromTheTimer) {
  Driver d;
  d.boot();
  ASSERT_TRUE(d.frame("602#2B00200005000000", TimePoint{1ms}));
  EXPECT_TRUE(d.frame("000#8102", TimePoint{2ms}));
  EXPECT_TRUE(d.sent.empty());
  EXPECT_EQ(d.node->state(), NmtState::Initialising);
  EXPECT_EQ(d.node->dictionary().get_unsigned(0x2000, 0), 10u);  // the file's value again
  EXPECT_EQ(d.node->next_deadline(), TimePoint{2ms});
  d.timer(TimePoint{2ms});
  EXPECT_EQ(d.sent, std::vector<std::string>{"702#00"});
}

TEST(SlaveNode, RaisedEmergencyGoesOutOnTheEmcyCobIdOfTheFile) {
  Driver d;
  SlaveNode::Output out;
  d.node->raise_emergency(emcy_code::kGeneric, 0, TimePoint{}, out);
  EXPECT_TRUE(out.frames.empty());  // not powered: nothing
  d.boot();
  d.node->raise_emergency(emcy_code::kGeneric, error_register::kTemperature, TimePoint{1ms}, out);
  ASSERT_EQ(out.frames.size(), 1u);
  // 1014h = $NODEID+80h; error register = temperature | generic (CiA 301 §7.5.2.2).
  EXPECT_EQ(to_candump(out.frames[0]), "082#0010090000000000");
  ASSERT_EQ(out.events.size(), 1u);
  EXPECT_EQ(out.events[0].kind, SlaveEvent::Kind::Emergency);
  EXPECT_EQ(d.node->dictionary().get_unsigned(0x1001, 0), 0x09u);
}

TEST(SlaveNode, SdoServerTimeoutIsAnOption) {
  // A segmented download (initiate 21h with size 40) left without segments is aborted after the
  // server timeout with 0504 0000 (CiA 301 §7.2.4.3.17 abort, Table 22 SDO protocol timed out).
  SlaveNodeOptions options;
  options.sdo_server_timeout = 500ms;
  Driver d(options);
  d.boot();
  ASSERT_TRUE(d.frame("602#2101200028000000", TimePoint{}));
  EXPECT_EQ(d.sent, std::vector<std::string>{"582#6001200000000000"});
  EXPECT_EQ(d.node->next_deadline(), TimePoint{500ms});
  d.timer(TimePoint{500ms});
  EXPECT_EQ(d.sent, std::vector<std::string>{"582#8001200000000405"});
}

}  // namespace
}  // namespace nmt
