// nmt::NetworkScanner alone on the simulated bus, against SimulatedDevices built from
// tests/data/network/nodes/io_node2.dcf (1018h: vendor ABCh, product 401h, revision 00010002h,
// serial 0; 1017h = 1000 ms). Times are simulated and exact.
#include "nmt/manager/network_scanner.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <variant>
#include <vector>

#include "cfg/device_file.hpp"
#include "device_text_support.hpp"
#include "nmt/protocol/frame_bits.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"
#include "test_paths.hpp"

namespace {

using namespace std::chrono_literals;
using Scanner = nmt::NetworkScanner;

cfg::NodeId id(unsigned n) {
  return *cfg::NodeId::from(static_cast<std::uint8_t>(n));
}

std::vector<cfg::NodeId> all_node_ids() {
  std::vector<cfg::NodeId> ids;
  for (unsigned n = 1; n <= 127; ++n) ids.push_back(id(n));
  return ids;
}

// A bus with devices built from `dcf` at `nodes` and the scanner; the scanner's frames and
// events are recorded with their times.
struct ScanRig {
  explicit ScanRig(const cfg::DeviceDescription& dcf, std::vector<unsigned> nodes,
                   nmt::ScanOptions options = default_options())
      : bus(500'000), scanner(options) {
    for (unsigned n : nodes) {
      devices.push_back(std::make_unique<nmt::SimEngineNode<nmt::SimulatedDevice>>(
          nmt::SimulatedDevice::create(dcf, static_cast<std::uint8_t>(n)).value()));
      bus.attach(*devices.back());
    }
    bus.attach(scanner);
    scanner.set_event_handler([this](const Scanner::Event& e, nmt::TimePoint now) {
      events.push_back({e, now});
      if (const auto* found = std::get_if<Scanner::NodeFound>(&e)) on_found(*found, now);
    });
    bus.set_filter([this](const nmt::CanFrame& f, nmt::TimePoint now) {
      if (f.id >= 0x600 && f.id <= 0x67F) requests.push_back({f, now});
      if (f.id == 0x000) ++nmt_commands;
      return filter ? filter(f, now) : nmt::FrameFate::deliver();
    });
  }
  static nmt::ScanOptions default_options() {
    nmt::ScanOptions o;
    o.sdo.timeout = 100ms;
    return o;
  }
  void power_on() {
    for (auto& d : devices) {
      d->apply(
          [](nmt::SimulatedDevice& dev, nmt::TimePoint now, auto& out) { dev.start(now, out); });
    }
  }
  void scan(std::vector<cfg::NodeId> nodes, nmt::TimePoint until = nmt::TimePoint{} + 60s) {
    scanner.apply([&](Scanner& s, nmt::TimePoint now, auto& out) { s.start(nodes, now, out); });
    bus.run_until([this] { return scanner.engine().finished(); }, until);
    finished_at = bus.now();
  }
  template <class T>
  std::vector<T> all() const {
    std::vector<T> out;
    for (const auto& [e, at] : events) {
      if (const auto* t = std::get_if<T>(&e)) out.push_back(*t);
    }
    return out;
  }

  nmt::SimBus bus;
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> devices;
  nmt::SimEngineNode<Scanner> scanner;
  std::vector<std::pair<Scanner::Event, nmt::TimePoint>> events;
  std::vector<std::pair<nmt::CanFrame, nmt::TimePoint>> requests;
  nmt::SimBus::Filter filter;
  // What the application reads of a found device (none by default).
  std::map<unsigned, std::vector<cfg::ObjectAddress>> entries;
  nmt::TimePoint finished_at{};
  std::size_t nmt_commands = 0;

 private:
  void on_found(const Scanner::NodeFound& found, nmt::TimePoint) {
    const auto list = entries[found.node.value()];
    scanner.apply([&](Scanner& s, nmt::TimePoint now, auto& out) {
      EXPECT_TRUE(s.read(found.node, list, now, out));
    });
  }
};

cfg::DeviceDescription io_node2() {
  auto r =
      cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/network/nodes/io_node2.dcf");
  EXPECT_TRUE(r.ok()) << r.diagnostics.format();
  return r.device.value_or(cfg::DeviceDescription{});
}

TEST(NetworkScanner, FindsTheDevicesAndTheAbsentNodeIdsCostOneTimeoutInAll) {
  // Two devices among 127 node-IDs: 125 probes go unanswered; all were asked at once, so the
  // scan ends one SDO timeout (100 ms) after the last probe, not 125 timeouts later.
  ScanRig rig(io_node2(), {2, 5});
  rig.power_on();
  rig.scan(all_node_ids());
  EXPECT_TRUE(rig.scanner.engine().finished());
  const auto found = rig.all<Scanner::NodeFound>();
  ASSERT_EQ(found.size(), 2U);
  EXPECT_EQ(found[0].node, 2);
  EXPECT_EQ(found[1].node, 5);
  EXPECT_EQ(rig.all<Scanner::NodeAbsent>().size(), 125U);
  // 127 probes of 1 frame each (at most 135 bits: 8 data bytes and stuffing) at 500 kbit/s
  // take at most 34.3 ms of bus; the scan ends within a timeout of that.
  const nmt::Duration took = rig.finished_at - nmt::TimePoint{};
  EXPECT_GE(took, 100ms);
  EXPECT_LE(took, 100ms + 35ms);
}

TEST(NetworkScanner, ReportsTheIdentityObjectAsTheDeviceHoldsIt) {
  // CiA 301 §7.5.2.23: 1018h sub 1-4; io_node2.dcf's values.
  ScanRig rig(io_node2(), {2});
  rig.power_on();
  rig.scan({id(2)});
  const auto found = rig.all<Scanner::NodeFound>();
  ASSERT_EQ(found.size(), 1U);
  const auto device_type = rig.devices[0]->engine().node().dictionary().get_unsigned(0x1000, 0);
  ASSERT_TRUE(device_type.has_value());
  const cfg::DeviceIdentity expected{.device_type = static_cast<std::uint32_t>(*device_type),
                                     .vendor_id = 0xABC,
                                     .product_code = 0x401,
                                     .revision_number = 0x00010002,
                                     .serial_number = 0};
  EXPECT_EQ(found[0].identity, expected);
  EXPECT_EQ(found[0].skipped, 0U);
  // No stored EDS in io_node2.dcf: 1022h is refused, 1021h never asked.
  EXPECT_FALSE(found[0].stored_eds_format.has_value());
  EXPECT_FALSE(found[0].stored_eds.has_value());
  for (const auto& [f, at] : rig.requests) {
    EXPECT_NE(nmt::to_candump(f).substr(0, 12), "602#4021100") << "1021h asked";
  }
}

TEST(NetworkScanner, ReadsTheEntriesTheApplicationNamesAndReportsEachValue) {
  ScanRig rig(io_node2(), {2});
  rig.entries[2] = {{0x1017, 0}, {0x2000, 0}, {0x1018, 1}};
  rig.power_on();
  rig.scan({id(2)});
  const auto read = rig.all<Scanner::EntryRead>();
  ASSERT_EQ(read.size(), 3U);
  EXPECT_EQ(read[0].address, (cfg::ObjectAddress{0x1017, 0}));
  EXPECT_EQ(read[0].data, (std::vector<std::uint8_t>{0xE8, 0x03}));  // 1000 ms
  EXPECT_EQ(read[2].data, (std::vector<std::uint8_t>{0xBC, 0x0A, 0x00, 0x00}));
  const auto scanned = rig.all<Scanner::NodeScanned>();
  ASSERT_EQ(scanned.size(), 1U);
  EXPECT_EQ(scanned[0].read, 3U);
  EXPECT_EQ(scanned[0].skipped, 0U);
}

TEST(NetworkScanner, AnEntryTheDeviceRefusesIsSkippedAndCountedNeverFatal) {
  ScanRig rig(io_node2(), {2});
  rig.entries[2] = {{0x1017, 0}, {0x6000, 1}, {0x1017, 0}};  // 6000h: not in the dictionary
  rig.power_on();
  rig.scan({id(2)});
  const auto read = rig.all<Scanner::EntryRead>();
  ASSERT_EQ(read.size(), 3U);
  EXPECT_EQ(read[1].abort, nmt::SdoAbort::ObjectDoesNotExist);  // 0602 0000, CiA 301
  EXPECT_EQ(read[1].attempts, 1U) << "an abort is the device's answer: not asked again";
  EXPECT_TRUE(read[2].ok());
  const auto scanned = rig.all<Scanner::NodeScanned>();
  ASSERT_EQ(scanned.size(), 1U);
  EXPECT_EQ(scanned[0].read, 2U);
  EXPECT_EQ(scanned[0].skipped, 1U);
}

TEST(NetworkScanner, SendsOnlySdoUploadRequests) {
  // The scan only reads: every frame it sends is an SDO request of an upload (CiA 301
  // §7.2.4.3: initiate 40h, segment 60h/70h, block A0h/A2h/A3h) or the abort 80h of an overdue
  // one; no download (2xh), no NMT command (000h).
  ScanRig rig(io_node2(), {2, 3});
  rig.entries[2] = {{0x1017, 0}, {0x1008, 0}, {0x2000, 0}};
  rig.entries[3] = {{0x1017, 0}};
  rig.power_on();
  rig.scan(all_node_ids());
  ASSERT_FALSE(rig.requests.empty());
  for (const auto& [f, at] : rig.requests) {
    const std::uint8_t ccs = f.data[0] >> 5;
    EXPECT_TRUE(ccs == 2 || ccs == 3 || ccs == 4 || ccs == 5) << nmt::to_candump(f);
  }
  EXPECT_EQ(rig.nmt_commands, 0U);
}

TEST(NetworkScanner, ALostAnswerOfADeviceWhoseBootUpWasSeenIsAskedAgain) {
  // The device's boot-up (702h#00) tells the scan it is there: its lost probe answer is asked
  // again after the timeout.
  ScanRig rig(io_node2(), {2});
  bool dropped = false;
  rig.filter = [&dropped](const nmt::CanFrame& f, nmt::TimePoint) {
    if (f.id == 0x582 && !dropped) {
      dropped = true;
      return nmt::FrameFate::drop();
    }
    return nmt::FrameFate::deliver();
  };
  rig.power_on();
  rig.scan({id(2)});
  EXPECT_EQ(rig.all<Scanner::NodeFound>().size(), 1U);
  EXPECT_EQ(rig.all<Scanner::NodeAbsent>().size(), 0U);
}

TEST(NetworkScanner, ASilentNodeIdIsProbedOnceAndAHeartbeatLaterBringsANewProbe) {
  // The device is there but its boot-up and first answer are lost: after one timeout it is
  // taken as absent; its heartbeat (1017h = 1000 ms) then brings one more probe, which finds it.
  ScanRig rig(io_node2(), {2});
  int answers_dropped = 0;
  rig.filter = [&](const nmt::CanFrame& f, nmt::TimePoint now) {
    if (f.id == 0x702 && now < nmt::TimePoint{} + 500ms) return nmt::FrameFate::drop();
    if (f.id == 0x582 && answers_dropped == 0) {
      ++answers_dropped;
      return nmt::FrameFate::drop();
    }
    return nmt::FrameFate::deliver();
  };
  rig.power_on();
  // Scan runs until the heartbeat at 1 s has brought the second probe and its identity.
  rig.scanner.apply([&](Scanner& s, nmt::TimePoint now, auto& out) {
    const std::vector<cfg::NodeId> nodes{id(2)};
    s.start(nodes, now, out);
  });
  rig.bus.run_until([&] { return !rig.all<Scanner::NodeFound>().empty(); }, nmt::TimePoint{} + 3s);
  const auto absent = rig.all<Scanner::NodeAbsent>();
  ASSERT_EQ(absent.size(), 1U);
  std::size_t probes = 0;
  for (const auto& [f, at] : rig.requests) probes += nmt::to_candump(f) == "602#4000100000000000";
  EXPECT_EQ(probes, 2U);
  EXPECT_EQ(rig.all<Scanner::NodeFound>().size(), 1U);
}

TEST(NetworkScanner, ReadsTheEdsTheDeviceStoresIn1021h) {
  // CiA 301 §7.5.2.20/21: 1022h = 0 (ISO 10646, not compressed) and the file in 1021h.
  auto dcf = io_node2();
  const std::string text =
      cfg::write_device_description(dcf, {}) +
      "\n[1021]\nParameterName=Store EDS\nObjectType=0x7\nDataType=0x000F\nAccessType=ro\n"
      "PDOMapping=0\n\n[1022]\nParameterName=Storage format\nObjectType=0x7\nDataType=0x0006\n"
      "AccessType=ro\nDefaultValue=0\nPDOMapping=0\n";
  auto read = test_support::parse_text(text, cfg::ReadMode::Tolerant, "stored.dcf");
  ASSERT_TRUE(read.device) << read.diagnostics.format();
  ScanRig rig(*read.device, {2});
  const std::string eds(300, 'e');  // 43 segments' worth: a segmented or block upload
  rig.power_on();                   // the dictionary at its defaults, then the stored file
  ASSERT_TRUE(rig.devices[0]->engine().node().dictionary().set_max_size(0x1021, 0, 4096));
  ASSERT_TRUE(rig.devices[0]->engine().node().dictionary().set_bytes(
      0x1021, 0, std::vector<std::uint8_t>(eds.begin(), eds.end())));
  rig.scan({id(2)});
  const auto found = rig.all<Scanner::NodeFound>();
  ASSERT_EQ(found.size(), 1U);
  EXPECT_EQ(found[0].stored_eds_format, 0);
  ASSERT_TRUE(found[0].stored_eds.has_value());
  EXPECT_EQ(std::string(found[0].stored_eds->begin(), found[0].stored_eds->end()), eds);
}

TEST(NetworkScanner, PacedRequestsLeaveTheBusShareTheOptionsAllow) {
  // At half the bus: 127 probes and the answers they ask for take 2 x 127 frames; spread over
  // twice their air time, the last probe leaves no earlier than about 2 x 127 x 111 bits /
  // (500 kbit/s x 0.5) = 113 ms after the first.
  auto options = ScanRig::default_options();
  options.bitrate_bps = 500'000;
  options.bus_load_limit = 0.5;
  ScanRig rig(io_node2(), {}, options);
  rig.scan(all_node_ids());
  // The probes (upload initiate 40h); the aborts of the overdue ones (80h) come after.
  std::vector<std::pair<nmt::CanFrame, nmt::TimePoint>> probes;
  for (const auto& r : rig.requests) {
    if (r.first.data[0] == 0x40) probes.push_back(r);
  }
  ASSERT_EQ(probes.size(), 127U);
  double bits = 0;
  for (std::size_t i = 0; i + 1 < probes.size(); ++i) {
    bits += 2.0 * nmt::frame_bits(probes[i].first).total();
  }
  const double share_s = bits / (500'000 * 0.5);
  const double spread_s =
      std::chrono::duration<double>(probes.back().second - probes.front().second).count();
  EXPECT_GE(spread_s, share_s * 0.99);
  EXPECT_LE(spread_s, share_s * 1.05 + 0.001);
  EXPECT_EQ(rig.all<Scanner::NodeAbsent>().size(), 127U);
}

TEST(NetworkScanner, ReadIsRefusedForANodeTheScanDidNotFind) {
  Scanner scanner;
  Scanner::Output out;
  EXPECT_FALSE(scanner.read(id(4), {{0x1017, 0}}, nmt::TimePoint{}, out));
  EXPECT_TRUE(out.empty());
}

}  // namespace
