// NmtMaster against CiA 302-2 §3.5 check configuration (1F26h/1F27h against the slave's 1020h,
// download, 1020h and 1010h 'save'), the restore of 1F81h bit 7 / 1F8Ah, the PDO-safe download
// order and block transfer, and the boot-up handler's reconfiguration of a replaced device
// (§4.3). Written from the public headers; the rig is nmt_master_spec_test_rig.hpp.
//
// Signatures: 1010h 'save' = 65766173h, 1011h 'load' = 64616F6Ch (CiA 301 §7.5.2.13/14, the
// constants of cfg/master_objects.hpp). 1020h sub 1 = date, sub 2 = time (DSP 302 §6.3).
#include <gtest/gtest.h>

#include "nmt_master_spec_test_rig.hpp"

namespace nmt::master_spec {
namespace {

using Kind = MasterEvent::Kind;

constexpr std::uint32_t kConfDate = 0x00003A99;  // days since 1984
constexpr std::uint32_t kConfTime = 0x01234567;  // ms after midnight

// The configuration of node 3 in these tests: a manufacturer value, the heartbeat and a string.
std::vector<cfg::ObjectWrite> node3_configuration() {
  const std::string name = "left axis";
  return {write_of(0x2000, 0, 25, 2),
          write_of(0x1017, 0, 100, 2),
          {0x2001, 0, std::vector<std::uint8_t>(name.begin(), name.end())}};
}

// 1F26h/1F27h sub 3 (the configuration date and time the master expects of node 3) and the
// configuration the master downloads when 1020h differs.
void expect_configuration_of_3(MasterRig& rig) {
  set_value(rig.master, 0x1F26, 3, kConfDate);
  set_value(rig.master, 0x1F27, 3, kConfTime);
  rig.configurations->writes[3] = node3_configuration();
}
// slave.eds with 1020h holding that date and time, as a device configured and saved earlier.
cfg::DeviceDescription configured_slave_eds() {
  auto eds = slave_eds();
  set_value(eds, 0x1020, 1, kConfDate);
  set_value(eds, 0x1020, 2, kConfTime);
  return eds;
}

std::uint32_t data_u32(const CanFrame& f) {
  return static_cast<std::uint32_t>(value_of(std::span<const std::uint8_t>(f.data.data() + 4, 4)));
}

// §3.5 a-c: "If the values equals the process shall finish with status OK" - no download.
TEST(NmtMasterSpec, MatchingVerifyConfigurationSkipsTheDownload) {
  MasterRig rig;
  expect_configuration_of_3(rig);
  rig.two_slaves({}, configured_slave_eds());
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));

  EXPECT_EQ(rig.uploads_of(3, 0x1020, 1).size(), 1U) << "1020h sub 1 read once (§3.5 b)";
  EXPECT_TRUE(rig.all_downloads(3).empty());
  EXPECT_FALSE(rig.booted(3).front().configured);
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 10U);
}

// §3.5 c-d: values differ, "The configuration shall be updated on the CANopen device"; then
// (header, DSP 302 §6.3) 1020h = 1F26h/1F27h and 1010h sub 1 'save', "so the next start-up skips
// it". The device holds and has stored the configured values.
TEST(NmtMasterSpec, DifferingVerifyConfigurationDownloadsThenWrites1020hAndSaves) {
  MasterRig rig;
  expect_configuration_of_3(rig);
  rig.add_slave(2);
  rig.add_slave(3);  // 1020h = 0/0
  rig.power_on_network();
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));

  auto booted = rig.booted(3).front();
  EXPECT_TRUE(booted.configured);
  EXPECT_GE(booted.written, 3U);
  EXPECT_EQ(booted.written, booted.total);
  auto value = rig.downloads_of(3, 0x2000, 0);
  auto date = rig.downloads_of(3, 0x1020, 1);
  auto time = rig.downloads_of(3, 0x1020, 2);
  auto save = rig.downloads_of(3, 0x1010, 1);
  ASSERT_EQ(value.size(), 1U);
  ASSERT_EQ(date.size(), 1U);
  ASSERT_EQ(time.size(), 1U);
  ASSERT_EQ(save.size(), 1U);
  EXPECT_EQ(data_u32(date[0].frame), kConfDate);
  EXPECT_EQ(data_u32(time[0].frame), kConfTime);
  EXPECT_EQ(data_u32(save[0].frame), cfg::kSaveSignature);
  EXPECT_EQ(save[0].text().substr(0, 12), "603#23101001");
  // 1020h after every configuration write, 'save' last.
  for (const auto& s : rig.all_downloads(3)) {
    if (addresses(s.frame, 0x1020, 1) || addresses(s.frame, 0x1020, 2) ||
        addresses(s.frame, 0x1010, 1))
      continue;
    EXPECT_LT(s.at, date[0].at) << s;
  }
  EXPECT_LT(date[0].at, save[0].at);
  EXPECT_LT(time[0].at, save[0].at);

  auto& device = rig.slave(3).node();
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 25U);
  EXPECT_EQ(rig.device_value(3, 0x1017, 0), 100U);
  EXPECT_EQ(rig.device_value(3, 0x1020, 1), kConfDate);
  EXPECT_EQ(rig.device_value(3, 0x1020, 2), kConfTime);
  auto stored = device.stored().find(LocalDictionary::key(0x2000, 0));
  ASSERT_NE(stored, device.stored().end());
  EXPECT_EQ(stored->second, le(25, 2));
  auto stored_date = device.stored().find(LocalDictionary::key(0x1020, 1));
  ASSERT_NE(stored_date, device.stored().end());
  EXPECT_EQ(stored_date->second, le(kConfDate, 4));
}

// The stored configuration survives a power cycle, and the boot-up handler's boot (§4.3) finds
// 1020h matching: nothing is downloaded again.
TEST(NmtMasterSpec, SlaveRebootingWithItsSavedConfigurationIsNotDownloadedAgain) {
  MasterRig rig;
  expect_configuration_of_3(rig);
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::StartupComplete, 10s));
  rig.run_for(500ms);

  const auto rebooted = rig.reboot_until_booted(3, 5s);
  ASSERT_TRUE(rebooted.has_value());
  const TimePoint reboot = *rebooted;
  rig.run_for(100ms);
  EXPECT_TRUE(rig.all_downloads(3, reboot).empty());
  EXPECT_FALSE(rig.booted(3).back().configured);
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 25U);
  EXPECT_EQ(rig.count_nmt("000#0103", reboot), 1U);
  EXPECT_EQ(rig.slave(3).node().state(), NmtState::Operational);
}

// §4.3 with the header's words: "check configuration then reconfigures a replaced device, whose
// 1020h no longer matches". A new device (factory values) takes node 3's place.
TEST(NmtMasterSpec, ReplacedDeviceIsConfiguredAgainAfterItsBootUp) {
  MasterRig rig;
  expect_configuration_of_3(rig);
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::StartupComplete, 10s));
  rig.run_for(500ms);

  rig.add_slave(3);  // the old device leaves the bus, a new one is plugged in
  ASSERT_EQ(rig.device_value(3, 0x2000, 0), 10U);
  const TimePoint replaced = rig.bus.now();
  rig.start(3);
  ASSERT_TRUE(rig.run_until_event(
      [&](const MasterEvent& e) {
        return e.kind == Kind::SlaveBooted && e.node_id == 3 && e.at > replaced;
      },
      5s));
  rig.run_for(100ms);
  auto boot_up = rig.events_of(Kind::BootUp, 3);
  ASSERT_FALSE(boot_up.empty());
  EXPECT_TRUE(boot_up.back().assigned);
  EXPECT_TRUE(rig.booted(3).back().configured);
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 25U);
  EXPECT_EQ(rig.device_value(3, 0x1020, 1), kConfDate);
  EXPECT_EQ(rig.slave(3).node().state(), NmtState::Operational);
}

// §3.5 a: "If the values are equals 0 the process shall go to step d)" - no 1020h request, the
// download happens; (header) no 1020h written then.
TEST(NmtMasterSpec, ZeroExpectedConfigurationDateAndTimeAlwaysDownload) {
  MasterRig rig;
  rig.configurations->writes[3] = node3_configuration();
  rig.two_slaves({}, configured_slave_eds());
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));

  EXPECT_TRUE(rig.uploads_of(3, 0x1020, 1).empty());
  EXPECT_EQ(rig.downloads_of(3, 0x2000, 0).size(), 1U);
  EXPECT_TRUE(rig.downloads_of(3, 0x1020, 1).empty());
  EXPECT_TRUE(rig.downloads_of(3, 0x1020, 2).empty());
  EXPECT_TRUE(rig.booted(3).front().configured);
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 25U);
}

// Header: MasterOptions::boot.force_download downloads even when 1020h matches.
TEST(NmtMasterSpec, ForcedDownloadIgnoresAMatchingVerifyConfiguration) {
  MasterRig rig;
  rig.options.boot.force_download = true;
  expect_configuration_of_3(rig);
  rig.two_slaves({}, configured_slave_eds());
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));
  EXPECT_EQ(rig.downloads_of(3, 0x2000, 0).size(), 1U);
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 25U);
}

// Header: MasterOptions::boot.save_configuration = false: no 1010h 'save'.
TEST(NmtMasterSpec, NoSaveWhenSaveConfigurationIsOff) {
  MasterRig rig;
  rig.options.boot.save_configuration = false;
  rig.configurations->writes[3] = node3_configuration();
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 25U);
  EXPECT_TRUE(rig.downloads_of(3, 0x1010, 1).empty());
  EXPECT_TRUE(rig.slave(3).node().stored().empty());
}

// Header: "none at all means there is nothing to download (status OK)".
TEST(NmtMasterSpec, SlaveWithoutConfigurationBootsWithoutAnyWrite) {
  MasterRig rig;
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));
  EXPECT_TRUE(rig.all_downloads(3).empty());
  EXPECT_FALSE(rig.booted(3).front().configured);
}

// §3.5 d: "Depending on the settings of 1F81h and 1F8Ah the configured restore operation shall be
// executed. Only after the restore operation the NMT service reset communication or NMT service
// reset node for the corresponding NMT slave shall be issued." Header: 1011h sub 1F8Ah[node]
// (default 1) 'load', reset node, the boot-up, then the download.
TEST(NmtMasterSpec, RestoreBit7LoadsDefaultsResetsNodeThenDownloads) {
  MasterRig rig;
  rig.assign(3, kSlave | kBoot | kRestore);
  rig.configurations->writes[3] = node3_configuration();
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));

  auto load = rig.downloads_of(3, 0x1011, 1);
  ASSERT_EQ(load.size(), 1U);
  EXPECT_EQ(data_u32(load[0].frame), cfg::kLoadSignature);
  EXPECT_EQ(load[0].text(), "603#231110016C6F6164");
  auto reset = rig.nmt_seen(load[0].at);
  ASSERT_FALSE(reset.empty());
  EXPECT_EQ(reset.front().text(), "000#8103");
  auto boot_up = rig.on_id(0x703, reset.front().at);
  ASSERT_FALSE(boot_up.empty());
  EXPECT_EQ(boot_up.front().text(), "703#00");
  auto value = rig.downloads_of(3, 0x2000, 0);
  ASSERT_EQ(value.size(), 1U);
  EXPECT_GT(value[0].at, boot_up.front().at);
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 25U);
  // No restore for node 2 (bit 7 clear).
  EXPECT_TRUE(rig.downloads_of(2, 0x1011, 1).empty());
}

// §6.12: "The entry value shall determine the sub-index of the object 1011h ... used to initiate
// the restore operation. If the entry value is 0, then no restore shall be sent".
TEST(NmtMasterSpec, Restore1F8AChoosesThe1011hSubIndexAndZeroMeansNoRestore) {
  {
    MasterRig rig;
    rig.assign(3, kSlave | kBoot | kRestore);
    set_value(rig.master, 0x1F8A, 3, 2);
    rig.configurations->writes[3] = node3_configuration();
    rig.two_slaves();
    ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));
    EXPECT_TRUE(rig.downloads_of(3, 0x1011, 1).empty());
    auto load = rig.downloads_of(3, 0x1011, 2);
    ASSERT_EQ(load.size(), 1U);
    EXPECT_EQ(data_u32(load[0].frame), cfg::kLoadSignature);
  }
  {
    MasterRig rig;
    rig.assign(3, kSlave | kBoot | kRestore);
    set_value(rig.master, 0x1F8A, 3, 0);
    rig.configurations->writes[3] = node3_configuration();
    rig.two_slaves();
    ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));
    for (std::uint8_t sub = 1; sub <= 4; ++sub)
      EXPECT_TRUE(rig.downloads_of(3, 0x1011, sub).empty());
    EXPECT_EQ(rig.count_nmt("000#8103"), 0U);
  }
}

// §3.5 a: with 1F26h/1F27h = 0 "the process shall go to step d)", and d): "Depending on the
// settings of 1F81h and 1F8Ah the configured restore operation shall be executed"; Table 25,
// bit 7 = 1: "CANopen device shall be reset to factory defaults by issuing a restore to defaults
// (object 1011h)" - also when no configuration is stored for the device.
// Disabled on main (run it with --gtest_also_run_disabled_tests): with no configuration the
// engine reports "configuration up to date" and sends neither 1011h nor reset node.
TEST(NmtMasterSpec, RestoreBit7RestoresEvenWithoutAConfiguration) {
  MasterRig rig;
  rig.assign(3, kSlave | kBoot | kRestore);
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));
  auto load = rig.downloads_of(3, 0x1011, 1);
  ASSERT_EQ(load.size(), 1U);
  EXPECT_EQ(data_u32(load[0].frame), cfg::kLoadSignature);
  EXPECT_EQ(rig.count_nmt("000#8103"), 1U);
}

// Restore brings back the factory values before the download: a value the slave had saved is
// gone afterwards unless the configuration sets it again.
TEST(NmtMasterSpec, RestoreReplacesSavedValuesByFactoryDefaults) {
  MasterRig rig;
  rig.assign(3, kSlave | kBoot | kRestore);
  rig.configurations->writes[3] = {write_of(0x2000, 0, 25, 2)};
  rig.add_slave(2);
  rig.add_slave(3);
  rig.power_on_slaves();
  rig.run_for(10ms);
  // Someone configured and saved 1017h = 500 ms on the device earlier (CiA 301 SDO expedited
  // downloads: 1017h = 01F4h, then 1010h sub 1 = 'save').
  rig.send_foreign("603#2B171000F4010000");
  rig.run_for(5ms);
  rig.send_foreign("603#2310100173617665");
  rig.run_for(35ms);
  ASSERT_EQ(rig.device_value(3, 0x1017, 0), 500U);
  ASSERT_FALSE(rig.slave(3).node().stored().empty());
  rig.start_master();
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));
  EXPECT_EQ(rig.device_value(3, 0x1017, 0), 0U);
  EXPECT_EQ(rig.device_value(3, 0x2000, 0), 25U);
}

// PDO-safe order (DSP 302 §6.2 hint, CiA 301 §7.5.2.35-38; header: cfg::order_for_download, the
// COB-ID read from the slave when the configuration lacks it). The mapping is given in an order
// the slave would refuse (entries while TPDO1 is valid and sub 0 is 1); the boot still succeeds
// and TPDO1 is valid again with the new mapping.
TEST(NmtMasterSpec, PdoMappingIsDownloadedInPdoSafeOrder) {
  MasterRig rig;
  rig.configurations->writes[3] = {write_of(0x1A00, 1, 0x60000108, 4),
                                   write_of(0x1A00, 2, 0x60000108, 4), write_of(0x1A00, 0, 2, 1),
                                   write_of(0x1800, 2, 254, 1)};
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));
  EXPECT_TRUE(rig.boot_errors(3).empty());
  EXPECT_EQ(rig.device_value(3, 0x1A00, 0), 2U);
  EXPECT_EQ(rig.device_value(3, 0x1A00, 2), 0x60000108U);
  EXPECT_EQ(rig.device_value(3, 0x1800, 2), 254U);
  EXPECT_EQ(rig.device_value(3, 0x1800, 1), 0x183U) << "TPDO1 not valid again";
  EXPECT_FALSE(rig.uploads_of(3, 0x1800, 1).empty()) << "COB-ID not read from the slave";
  // The COB-ID was made invalid (bit 31) before the mapping changed.
  auto cob = rig.downloads_of(3, 0x1800, 1);
  ASSERT_EQ(cob.size(), 2U);
  EXPECT_EQ(data_u32(cob[0].frame), 0x80000183U);
  EXPECT_EQ(data_u32(cob[1].frame), 0x183U);
  auto first_entry = rig.downloads_of(3, 0x1A00, 1);
  ASSERT_EQ(first_entry.size(), 1U);
  EXPECT_GT(first_entry[0].at, cob[0].at);
  EXPECT_LT(first_entry[0].at, cob[1].at);
}

// Header: values longer than MasterOptions::sdo.block_threshold go by SDO block transfer (CiA 301
// §7.2.4.3.9: block download initiate, ccs 6), shorter ones expedited or segmented.
TEST(NmtMasterSpec, LongConfigurationValueGoesByBlockTransfer) {
  MasterRig rig;
  std::vector<std::uint8_t> table(200);
  for (std::size_t i = 0; i < table.size(); ++i) table[i] = static_cast<std::uint8_t>(i * 7);
  rig.configurations->writes[3] = {{0x2002, 0, table}, write_of(0x2000, 0, 25, 2)};
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::SlaveBooted, 10s, 3));

  auto block = rig.downloads_of(3, 0x2002, 0);
  ASSERT_EQ(block.size(), 1U);
  EXPECT_EQ(block[0].frame.data[0] >> 5U, 6U) << block[0];
  auto small = rig.downloads_of(3, 0x2000, 0);
  ASSERT_EQ(small.size(), 1U);
  EXPECT_EQ(small[0].frame.data[0] >> 5U, 1U) << small[0];
  auto stored = rig.slave(3).node().dictionary().get_bytes(0x2002, 0);
  ASSERT_TRUE(stored.has_value());
  EXPECT_EQ(std::vector<std::uint8_t>(stored->begin(), stored->end()), table);
}

// Header, "pipelined across slaves" (§3.3: boot NMT slave runs as a parallel process per slave,
// "The sub process ... shall run asynchronously to other processes"): the downloads of several
// slaves overlap in time. The devices answer after 1 ms, as real ones do (bench_master_boot):
// with answers in zero time one slave's SDO exchange never leaves the bus idle, and the boot-up
// messages of the others (7xxh) lose every arbitration against it.
TEST(NmtMasterSpec, SlavesAreConfiguredInParallel) {
  MasterRig rig;
  for (std::uint8_t node = 2; node <= 5; ++node) {
    rig.assign(node, kSlave | kBoot);
    const std::string name = "node " + std::to_string(node);
    rig.configurations->writes[node] = {
        write_of(0x2000, 0, 100U + node, 2),
        write_of(0x1017, 0, 1000, 2),
        {0x2001, 0, std::vector<std::uint8_t>(name.begin(), name.end())},
        {0x2002, 0, std::vector<std::uint8_t>(20, node)}};
    rig.add_slave(node, fault([](DeviceFaults& f) { f.sdo_latency = 1ms; }));
  }
  rig.power_on_network();
  ASSERT_TRUE(rig.run_until_kind(Kind::StartupComplete, 10s));

  // Every slave's first write comes before any slave's last write.
  TimePoint latest_first{};
  TimePoint earliest_last = TimePoint::max();
  for (std::uint8_t node = 2; node <= 5; ++node) {
    auto writes = rig.all_downloads(node);
    ASSERT_GE(writes.size(), 4U) << int{node};
    latest_first = std::max(latest_first, writes.front().at);
    earliest_last = std::min(earliest_last, writes.back().at);
    EXPECT_EQ(rig.device_value(node, 0x2000, 0), 100U + node);
  }
  EXPECT_LT(latest_first, earliest_last);
}

}  // namespace
}  // namespace nmt::master_spec
