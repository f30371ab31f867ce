// The real-time event loop driving simulated devices over an nmt::Bus. A fake bus with a fake
// clock makes the timing exact: receive(timeout) advances the clock to the next scripted frame or
// by the timeout. Expected bytes: boot-up and heartbeat per spec/002; the SDO expedited upload
// response `43 idx sub data` per CiA 301 §7.2.4.3.6 (public description).
#include <gtest/gtest.h>

#include "cfg/device_file.hpp"
#include "fake_clock_bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/sdo/sdo.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "nmt/slave/slave_node.hpp"
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

cfg::DeviceDescription sim_eds() {
  auto r = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sim_device.eds");
  EXPECT_TRUE(r.device.has_value()) << r.diagnostics.format();
  return r.device.value_or(cfg::DeviceDescription{});
}

SimulatedDevice device_with_heartbeat(std::uint8_t node, const char* ms) {
  auto eds = sim_eds();
  eds.sub(0x1017, 0)->default_value = ms;
  auto d = SimulatedDevice::create(eds, node);
  EXPECT_TRUE(d.ok()) << (d.ok() ? "" : d.error().message);
  return std::move(d).value();
}

TEST(BusEventLoop, DeviceBootsAndProducesHeartbeatOnTime) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  auto device = device_with_heartbeat(2, "100");
  EngineRef ref(device);
  loop.add(ref);
  power_on_at(device, loop.now());
  ASSERT_TRUE(loop.run_until(TimePoint{1000ms + 1us}).ok());
  ASSERT_EQ(bus.sent_at.size(), 11u);
  EXPECT_EQ(bus.sent_at[0], std::make_pair(TimePoint{}, std::string("702#00")));
  for (std::size_t i = 1; i < bus.sent_at.size(); ++i) {
    EXPECT_EQ(bus.sent_at[i].first, TimePoint{std::chrono::milliseconds(100 * i)});
    EXPECT_EQ(bus.sent_at[i].second, "702#7F");
  }
}

TEST(BusEventLoop, ReceivedNmtCommandChangesHeartbeatState) {
  FakeClockBus bus;
  bus.arrive(TimePoint{250ms}, "000#0102");
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  auto device = device_with_heartbeat(2, "100");
  EngineRef ref(device);
  loop.add(ref);
  power_on_at(device, loop.now());
  ASSERT_TRUE(loop.run_until(TimePoint{450ms}).ok());
  std::vector<std::string> frames;
  for (const auto& [t, f] : bus.sent_at) frames.push_back(f);
  EXPECT_EQ(frames, (std::vector<std::string>{"702#00", "702#7F", "702#7F", "702#05", "702#05"}));
  EXPECT_EQ(loop.frames_received(), 1u);
}

TEST(BusEventLoop, AnswersSdoRequestFromTheBus) {
  FakeClockBus bus;
  bus.arrive(TimePoint{10ms}, "602#4000100000000000");  // upload 1000h sub 0
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  auto device = device_with_heartbeat(2, "0");
  EngineRef ref(device);
  loop.add(ref);
  power_on_at(device, loop.now());
  ASSERT_TRUE(loop.run_until(TimePoint{20ms}).ok());
  ASSERT_EQ(bus.sent_at.size(), 2u);
  // 1000h = 0x000F0191 (sim_device.eds), 4 bytes expedited: command byte 43h.
  EXPECT_EQ(bus.sent_at[1], std::make_pair(TimePoint{10ms}, std::string("582#4300100091010F00")));
}

TEST(BusEventLoop, EnginesOfOneLoopHearEachOther) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  auto device = device_with_heartbeat(4, "0");
  SdoClient client(SdoClientConfig::for_node(*cfg::NodeId::from(4)));
  std::optional<SdoResult> result;
  EngineRef device_ref(device);
  EngineRef client_ref(client, [&](const SdoResult& r, TimePoint) { result = r; });
  loop.add(device_ref);
  loop.add(client_ref);
  power_on_at(device, loop.now());
  ASSERT_TRUE(loop.run_until(TimePoint{1ms}).ok());  // boot-up
  // The request goes out from apply() at once; the device hears it through the loop's echo.
  ASSERT_TRUE(client_ref
                  .apply([](SdoClient& c, TimePoint now, SdoClient::Output& out) {
                    return c.upload(0x1018, 1, now, out);
                  })
                  .ok());
  ASSERT_TRUE(loop.run_until(TimePoint{5ms}).ok());
  const SdoResult* r = result ? &*result : nullptr;
  ASSERT_NE(r, nullptr);
  ASSERT_TRUE(r->ok()) << r->abort;
  EXPECT_EQ(r->data, (std::vector<std::uint8_t>{0xDE, 0xC0, 0x57, 0x7E}));  // 0x7E57C0DE
  // Both sides' frames went to the bus too.
  ASSERT_EQ(bus.sent_at.size(), 3u);
  EXPECT_EQ(bus.sent_at[1].second, "604#4018100100000000");
  EXPECT_EQ(bus.sent_at[2].second, "584#43181001DEC0577E");
}

TEST(BusEventLoop, SlaveNodeWithoutFaultsRunsOnTheLoopAndReportsItsEvents) {
  // The slave node as an embedder puts it on a real bus: no fault wrapper, events to a handler.
  FakeClockBus bus;
  bus.arrive(TimePoint{10ms}, "603#2B17100064000000");  // 1017h = 100 ms
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  auto node = SlaveNode::create(sim_eds(), cfg::NodeId::from(3).value());
  ASSERT_TRUE(node.ok()) << node.error().message;
  std::vector<std::string> events;
  EngineRef ref(**node, [&](const SlaveEvent& e, TimePoint) {
    events.push_back(std::string(to_string(e.kind)) + ": " + e.text);
  });
  loop.add(ref);
  power_on_at(**node, loop.now());
  ASSERT_TRUE(loop.run_until(TimePoint{150ms}).ok());
  std::vector<std::pair<TimePoint, std::string>> expected{
      {TimePoint{}, "703#00"},                    // boot-up (CiA 301 §7.2.8.3.2.4)
      {TimePoint{10ms}, "583#6017100000000000"},  // download confirmed
      {TimePoint{10ms}, "703#7F"},                // the producer starts at once
      {TimePoint{110ms}, "703#7F"}};              // then every 100 ms
  EXPECT_EQ(bus.sent_at, expected);
  EXPECT_EQ(events,
            (std::vector<std::string>{"boot: boot-up", "sdo-write: 1017h sub 00h = 2 byte(s)"}));
}

TEST(BusEventLoop, StopRequestEndsRun) {
  FakeClockBus bus;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  auto device = device_with_heartbeat(2, "100");
  EngineRef ref(device);
  loop.add(ref);
  power_on_at(device, loop.now());
  loop.set_observer([&](const CanFrame& f, TimePoint, BusEventLoop::Direction) {
    if (to_candump(f) == "702#7F") loop.request_stop();
  });
  ASSERT_TRUE(loop.run().ok());
  EXPECT_EQ(bus.now, TimePoint{100ms});
  EXPECT_TRUE(loop.stop_requested());
}

TEST(BusEventLoop, WaitsAreBoundedByMaxWait) {
  FakeClockBus bus;
  BusEventLoopOptions options;
  options.max_wait = 20ms;
  BusEventLoop loop(bus, options, [&] { return bus.now; });
  ASSERT_TRUE(loop.run_until(TimePoint{100ms}).ok());
  // Nothing is due: the loop waits in steps of max_wait (between them it only looks at the
  // queue, with a zero timeout).
  EXPECT_EQ(bus.waits, std::vector<Duration>(5, 20ms));
}

// The transmit path survives a real controller: a send error that is not fatal is
// reported and retried; the loop goes on and nothing is lost or reordered.
TEST(BusEventLoop, SendFailureIsReportedAndRetriedWhileTheRunGoesOn) {
  FakeClockBus bus;
  bus.fail_sends = true;
  BusEventLoop loop(bus, {}, [&] { return bus.now; });
  std::vector<BusEvent> reported;
  loop.set_bus_event_handler([&](const BusEvent& e, TimePoint) { reported.push_back(e); });
  auto device = device_with_heartbeat(2, "100");
  EngineRef ref(device);
  loop.add(ref);
  power_on_at(device, loop.now());
  ASSERT_TRUE(loop.run_for(1s).ok());
  ASSERT_FALSE(reported.empty());
  EXPECT_EQ(reported[0].kind, BusEvent::Kind::SendFailed);
  EXPECT_EQ(to_candump(reported[0].frame), "702#00");
  EXPECT_NE(reported[0].text.find("transmit queue full"), std::string::npos) << reported[0].text;
  EXPECT_EQ(loop.counters().send_failures, reported.size());
  EXPECT_GE(loop.counters().queued, 10U);  // the boot-up and the heartbeats of that second
  bus.fail_sends = false;
  ASSERT_TRUE(loop.run_for(2s).ok());
  ASSERT_GE(bus.sent_at.size(), 11U);
  EXPECT_EQ(bus.sent_at[0].second, "702#00");  // in order: the boot-up first
  for (std::size_t i = 1; i < bus.sent_at.size(); ++i) EXPECT_EQ(bus.sent_at[i].second, "702#7F");
  EXPECT_EQ(loop.counters().queued, 0U);
}

}  // namespace
}  // namespace nmt
