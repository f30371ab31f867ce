// nmt::ConfigurationVerifier on the simulated bus against a SimulatedDevice built from a DCF:
// tests/data/network/nodes/io_node2.dcf (README there: heartbeat 1000 ms, 2000h = 0x12). The
// writes compared are the DCF's configured values as the configuration manager downloads them
// (cfg::concise_writes_from_dcf); CiA 301 §7.2.4.3 uploads read them back.
#include "nmt/manager/configuration_verifier.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "test_paths.hpp"

namespace {

using namespace std::chrono_literals;

cfg::DeviceDescription io_node2() {
  auto r =
      cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/network/nodes/io_node2.dcf");
  EXPECT_TRUE(r.ok()) << r.diagnostics.format();
  return r.device.value_or(cfg::DeviceDescription{});
}

std::vector<cfg::ObjectWrite> writes_of(const cfg::DeviceDescription& dcf) {
  cfg::Diagnostics d;
  auto w = cfg::concise_writes_from_dcf(dcf, {}, d);
  EXPECT_TRUE(w.has_value()) << d.format();
  return w.value_or(std::vector<cfg::ObjectWrite>{});
}

// One device (node 2) built from `device_dcf` and the verifier reading `writes` from it.
std::vector<nmt::VerifyResult> verify(const cfg::DeviceDescription& device_dcf,
                                      const std::vector<cfg::ObjectWrite>& writes,
                                      nmt::SimBus::Filter filter = {}, std::uint8_t node = 2) {
  nmt::SimBus bus(500'000);
  if (filter) bus.set_filter(std::move(filter));
  nmt::SimEngineNode<nmt::SimulatedDevice> device(
      nmt::SimulatedDevice::create(device_dcf, 2).value());
  bus.attach(device);
  device.apply([](nmt::SimulatedDevice& d, nmt::TimePoint now, auto& out) { d.start(now, out); });
  nmt::VerifyOptions options;
  options.sdo.timeout = 100ms;
  nmt::SimEngineNode<nmt::ConfigurationVerifier> reader(options);
  bus.attach(reader);
  std::vector<nmt::VerifyResult> out;
  reader.set_event_handler(
      [&out](const nmt::VerifyResult& r, nmt::TimePoint) { out.push_back(r); });
  reader.apply([&](nmt::ConfigurationVerifier& v, nmt::TimePoint now, auto& o) {
    v.verify(*cfg::NodeId::from(node), writes, now, o);
  });
  bus.run_until([&reader] { return reader.engine().pending() == 0; }, nmt::TimePoint{} + 10s);
  EXPECT_EQ(reader.engine().pending(), 0U);
  return out;
}

TEST(ConfigurationVerifier, ADeviceConfiguredAsItsDcfHasNoDifference) {
  const auto dcf = io_node2();
  const auto writes = writes_of(dcf);
  ASSERT_FALSE(writes.empty());
  const auto results = verify(dcf, writes);
  ASSERT_EQ(results.size(), writes.size());
  for (const auto& r : results) {
    EXPECT_TRUE(r.same()) << cfg::to_string(r.address);
  }
}

// The device's DCF says 1017h = 500 where the description says 1000 (io_node2.dcf): that entry,
// and only that one, differs, with both values' bytes (UNSIGNED16 little-endian).
TEST(ConfigurationVerifier, AValueTheDeviceHasOtherwiseIsADifferenceWithBothValues) {
  const auto description = io_node2();
  auto device = description;
  device.sub(0x1017, 0)->parameter_value = "500";
  const auto results = verify(device, writes_of(description));
  std::vector<nmt::VerifyResult> differ;
  for (const auto& r : results) {
    if (!r.same()) differ.push_back(r);
  }
  ASSERT_EQ(differ.size(), 1U);
  EXPECT_EQ(differ[0].node_id, 2);
  EXPECT_EQ(differ[0].address, (cfg::ObjectAddress{0x1017, 0}));
  EXPECT_TRUE(differ[0].read());
  EXPECT_EQ(differ[0].expected, (std::vector<std::uint8_t>{0xE8, 0x03}));  // 1000
  EXPECT_EQ(differ[0].actual, (std::vector<std::uint8_t>{0xF4, 0x01}));    // 500
}

// A download that writes an entry twice leaves the last value (cfg::order_for_download): that
// is what the device must have.
TEST(ConfigurationVerifier, AnEntryWrittenTwiceIsComparedWithItsLastWrite) {
  const auto dcf = io_node2();
  const std::vector<cfg::ObjectWrite> writes = {{0x1017, 0, {0x00, 0x00}},
                                                {0x1017, 0, {0xE8, 0x03}}};
  const auto results = verify(dcf, writes);
  ASSERT_EQ(results.size(), 1U);
  EXPECT_TRUE(results[0].same());
}

// An upload whose response is lost times out (0504 0000) and is made again.
TEST(ConfigurationVerifier, ALostResponseIsReadAgain) {
  const auto dcf = io_node2();
  bool dropped = false;
  const auto results =
      verify(dcf, {{0x1017, 0, {0xE8, 0x03}}}, [&dropped](const nmt::CanFrame& f, nmt::TimePoint) {
        if (f.id == 0x582 && !dropped) {
          dropped = true;
          return nmt::FrameFate::drop();
        }
        return nmt::FrameFate::deliver();
      });
  ASSERT_EQ(results.size(), 1U);
  EXPECT_TRUE(results[0].same());
  EXPECT_EQ(results[0].attempts, 2U);
}

// No device at node 9: every upload times out, 1 + retries (2) times, and is reported failed.
// No device at node 9: its first upload times out once (100 ms) and the node is unreachable;
// its other entries are not asked (issue 33: an absent node costs one timeout, not 3 per entry).
TEST(ConfigurationVerifier, ANodeThatNeverAnswersIsUnreachableAfterOneTimeout) {
  nmt::TimePoint last{};
  const auto results = verify(
      io_node2(), {{0x1017, 0, {0xE8, 0x03}}, {0x2000, 0, {0x12}}, {0x1017, 0, {0xE8, 0x03}}},
      [&last](const nmt::CanFrame& f, nmt::TimePoint now) {
        if (f.id == 0x609) last = now;
        return nmt::FrameFate::deliver();
      },
      9);
  ASSERT_EQ(results.size(), 2U);  // 1017h twice is one entry
  EXPECT_EQ(results[0].node_id, 9);
  EXPECT_EQ(results[0].abort, nmt::SdoAbort::Timeout);
  EXPECT_EQ(results[0].attempts, 1U);
  EXPECT_TRUE(results[0].unreachable);
  EXPECT_EQ(results[1].attempts, 0U) << "never asked";
  EXPECT_TRUE(results[1].unreachable);
  // The request and its abort: nothing after the one timeout.
  EXPECT_LE(last - nmt::TimePoint{}, std::chrono::milliseconds(101));
}

// A device whose boot-up was seen (702h#00 when it powers on) is there: its lost first answer
// is asked again, not taken for absence.
TEST(ConfigurationVerifier, ALostFirstAnswerOfAHeardDeviceIsAskedAgain) {
  bool dropped = false;
  const auto results = verify(io_node2(), {{0x1017, 0, {0xE8, 0x03}}, {0x2000, 0, {0x12}}},
                              [&dropped](const nmt::CanFrame& f, nmt::TimePoint) {
                                if (f.id == 0x582 && !dropped) {
                                  dropped = true;
                                  return nmt::FrameFate::drop();
                                }
                                return nmt::FrameFate::deliver();
                              });
  ASSERT_EQ(results.size(), 2U);
  // The repetition queues behind 2000h: 1017h ends second.
  EXPECT_EQ(results[1].address, (cfg::ObjectAddress{0x1017, 0}));
  EXPECT_TRUE(results[1].same());
  EXPECT_EQ(results[1].attempts, 2U);
  EXPECT_FALSE(results[1].unreachable);
  EXPECT_TRUE(results[0].same());
}

}  // namespace
