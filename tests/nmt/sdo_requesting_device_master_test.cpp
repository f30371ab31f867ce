// The SRD engine against the SDO manager of NmtMaster (DSP 302 §7) on the simulated bus: the
// master of tests/data/master/master.dcf with slaves 2 and 3 (slave.eds; slave 2 gets an
// additional server entry 1201h, not valid), the SRD at node 70h from tests/data/sdo_channels.eds.
// Register (§7.2.1), connect to slave 2 twice (the second time its default SDO is taken, so the
// manager sets up 1201h on it, §7.1), read over both, release everything (§7.2.2).
#include <gtest/gtest.h>

#include "cfg/device_file.hpp"
#include "nmt/sdo/sdo_requesting_device.hpp"
#include "nmt_master_spec_test_rig.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using master_spec::MasterRig;

// SimEngineNode holds its engine by value; the SRD is handed out as a unique_ptr.
struct SrdSlot {
  using Event = SrdEvent;
  using Output = SdoRequestingDevice::Output;
  std::unique_ptr<SdoRequestingDevice> srd;
  bool on_frame(const CanFrame& f, TimePoint now, Output& out) {
    return srd->on_frame(f, now, out);
  }
  void on_timer(TimePoint now, Output& out) { srd->on_timer(now, out); }
  std::optional<TimePoint> next_deadline() const { return srd->next_deadline(); }
};

std::unique_ptr<SdoRequestingDevice> make_srd(std::uint8_t node) {
  auto eds = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sdo_channels.eds");
  EXPECT_TRUE(eds.device.has_value());
  auto created = SdoRequestingDevice::create(eds.device.value_or(cfg::DeviceDescription{}),
                                             cfg::NodeId::from(node).value());
  EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
  return std::move(created).value();
}

void add_server_entry(LocalDictionary& dict, std::uint16_t index) {
  for (std::uint8_t sub = 0; sub <= 3; ++sub) {
    DictionaryEntry e;
    e.index = index;
    e.sub_index = sub;
    e.name = "server SDO parameter";
    const bool cob_id = sub == 1 || sub == 2;
    e.basic_type = cob_id ? cfg::DataType::Unsigned32 : cfg::DataType::Unsigned8;
    e.data_type = static_cast<std::uint16_t>(*e.basic_type);
    e.access = sub == 0 ? cfg::AccessType::Const : cfg::AccessType::Rw;
    e.bytes = cob_id ? std::vector<std::uint8_t>{0, 0, 0, 0x80}
                     : std::vector<std::uint8_t>{static_cast<std::uint8_t>(sub == 0 ? 3 : 0)};
    dict.insert(e);
  }
}

TEST(SdoRequestingDeviceWithManager, RegistersConnectsTwiceToOneSlaveReadsAndReleases) {
  MasterRig rig;
  rig.options.sdo_manager.enabled = true;
  rig.options.sdo_manager.scan_timeout = 20ms;
  rig.add_slave(2);
  add_server_entry(rig.slave(2).node().dictionary(), 0x1201);
  rig.add_slave(3);
  rig.power_on_network();
  ASSERT_TRUE(rig.run_until_kind(MasterEvent::Kind::StartupComplete, 10s));

  SimEngineNode<SrdSlot> slot(SrdSlot{make_srd(0x70)});
  std::vector<SrdEvent> events;
  slot.set_event_handler([&](const SrdEvent& e, TimePoint) {
    if (e.kind != SrdEvent::Kind::Device) events.push_back(e);
  });
  rig.bus.attach(slot);
  auto& srd = *slot.engine().srd;
  slot.apply([](SrdSlot& s, TimePoint now, SrdSlot::Output& out) { s.srd->start(now, out); });
  rig.bus.run_for(10ms);

  auto wait = [&](SrdEvent::Kind kind, std::size_t count = 1) {
    return rig.bus.run_until(
        [&] {
          return std::count_if(events.begin(), events.end(), [&](const SrdEvent& e) {
                   return e.kind == kind;
                 }) >= static_cast<std::ptrdiff_t>(count);
        },
        rig.bus.now() + 10s);
  };

  ASSERT_TRUE(slot.apply([](SrdSlot& s, TimePoint now, SrdSlot::Output& out) {
    return s.srd->register_at_manager(now, out);
  }));
  ASSERT_TRUE(wait(SrdEvent::Kind::Registered));
  EXPECT_EQ(srd.registration(), SrdRegistration::Registered);
  EXPECT_EQ(srd.manager_channel(), 0x1280);
  // The request goes at once after the confirmation (§7.2.2).

  // First connection: slave 2's default SDO is free (§7.1).
  ASSERT_TRUE(slot.apply([](SrdSlot& s, TimePoint now, SrdSlot::Output& out) {
    return s.srd->request_connection(*cfg::NodeId::from(2), 0x1281, now, out);
  }));
  ASSERT_TRUE(wait(SrdEvent::Kind::Connected)) << (events.empty() ? "" : events.back().text);
  EXPECT_EQ(srd.connection(0x1281)->request_cob_id, cfg::CobId::standard(0x602));

  // Second: the default SDO is taken, the manager configures slave 2's 1201h.
  ASSERT_TRUE(slot.apply([](SrdSlot& s, TimePoint now, SrdSlot::Output& out) {
    return s.srd->request_connection(*cfg::NodeId::from(2), 0x1282, now, out);
  }));
  ASSERT_TRUE(wait(SrdEvent::Kind::Connected, 2)) << (events.empty() ? "" : events.back().text);
  const auto second = srd.connection(0x1282);
  ASSERT_TRUE(second.has_value());
  EXPECT_NE(second->request_cob_id, cfg::CobId::standard(0x602));
  EXPECT_EQ(rig.slave(2).node().sdo_config(0x1201)->request_cob_id, second->request_cob_id);

  // Both channels read slave 2's 1000h at the same time.
  for (const std::uint16_t client : {std::uint16_t{0x1281}, std::uint16_t{0x1282}}) {
    ASSERT_TRUE(slot.apply([client](SrdSlot& s, TimePoint now, SrdSlot::Output& out) {
      return s.srd->upload(client, 0x1000, 0, now, out);
    }));
  }
  ASSERT_TRUE(wait(SrdEvent::Kind::Transfer, 2));
  const auto device_type = rig.slave(2).node().dictionary().get_bytes(0x1000, 0);
  ASSERT_TRUE(device_type.has_value());
  for (const auto& e : events) {
    if (e.kind != SrdEvent::Kind::Transfer) continue;
    ASSERT_TRUE(e.transfer->ok()) << e.text;
    EXPECT_TRUE(std::equal(e.transfer->data.begin(), e.transfer->data.end(), device_type->begin(),
                           device_type->end()));
  }

  // 1F01h index 0: every connection to slave 2 (§7.2.3).
  ASSERT_TRUE(slot.apply([](SrdSlot& s, TimePoint now, SrdSlot::Output& out) {
    return s.srd->release(*cfg::NodeId::from(2), 0, now, out);
  }));
  ASSERT_TRUE(wait(SrdEvent::Kind::ConnectionReleased, 2));
  EXPECT_TRUE(srd.connections().empty());
  // The manager invalidates the SRD's entry first, then slave 2's 1201h.
  EXPECT_TRUE(rig.bus.run_until(
      [&] { return !rig.slave(2).node().sdo_config(0x1201)->request_cob_id.valid(); },
      rig.bus.now() + 1s));

  ASSERT_TRUE(slot.apply(
      [](SrdSlot& s, TimePoint now, SrdSlot::Output& out) { return s.srd->deregister(now, out); }));
  ASSERT_TRUE(wait(SrdEvent::Kind::Deregistered));
  EXPECT_EQ(srd.registration(), SrdRegistration::Unregistered);
}

}  // namespace
}  // namespace nmt
