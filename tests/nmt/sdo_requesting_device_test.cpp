// The SDO requesting device (DSP 302 §7, ../shared/spec/001_846495643a25878e.txt) against a
// scripted manager: the test writes the manager's frames by hand. SRD: node 7Fh (§7.2.4
// guideline 2: the highest node-ID) from tests/data/sdo_channels.eds (client entries
// 1280h-1282h with COB-IDs 80000000h, 1F10h, 1F11h). Words from the §7.2.3 bit tables; SDO
// bytes from CiA 301 §7.2.4.3 (expedited download 23h/2Bh, its confirmation 60h, upload 40h/43h,
// abort 80h).
#include "nmt/sdo/sdo_requesting_device.hpp"

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
using Frames = std::vector<std::string>;
using Kind = SrdEvent::Kind;

constexpr cfg::NodeId kSrd = 0x7F_node;

cfg::DeviceDescription channels_eds() {
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sdo_channels.eds");
  EXPECT_TRUE(result.device.has_value()) << result.diagnostics.format();
  return result.device.value_or(cfg::DeviceDescription{});
}

struct Rig {
  std::unique_ptr<SdoRequestingDevice> srd;
  TimePoint now{};
  Frames sent;
  std::vector<SrdEvent> events;

  explicit Rig(SrdOptions options = {}) {
    auto created = SdoRequestingDevice::create(channels_eds(), kSrd, std::move(options));
    EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
    srd = std::move(created).value();
    power_on_at(*srd, now);
    timer(now);  // boot-up
  }
  void take(SdoRequestingDevice::Output& out) {
    sent.clear();
    for (const auto& f : out.frames) sent.push_back(to_candump(f));
    events.clear();
    for (auto& e : out.events) {
      if (e.kind != Kind::Device) events.push_back(std::move(e));
    }
  }
  // `candump` may carry spaces for reading (they are removed).
  Frames frame(std::string candump) {
    std::erase(candump, ' ');
    now += 1ms;
    auto f = from_candump(candump);
    EXPECT_TRUE(f.has_value()) << candump;
    SdoRequestingDevice::Output out;
    srd->on_frame(f.value_or(CanFrame{}), now, out);
    take(out);
    return sent;
  }
  void timer(TimePoint at) {
    now = at;
    SdoRequestingDevice::Output out;
    srd->on_timer(now, out);
    take(out);
  }
  template <class Fn>
  auto call(Fn&& fn) {
    SdoRequestingDevice::Output out;
    auto r = fn(*srd, now, out);
    take(out);
    return r;
  }
  std::uint64_t value(std::uint16_t index, std::uint8_t sub = 0) const {
    return srd->node().dictionary().get_unsigned(index, sub).value_or(0xDEADBEEF);
  }

  // The scripted manager (node 1) registers the SRD on 1280h with pool COB-IDs 680h/681h.
  void registered() {
    EXPECT_TRUE(call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); }));
    frame("67F#2F801203 01000000");
    frame("67F#23801201 80060000");
    frame("67F#23801202 81060000");
    frame("67F#23101F00 02008012");
  }
  // ... and connects it to node 5 on 1281h with 682h/683h.
  void connected() {
    registered();
    EXPECT_TRUE(
        call([](auto& s, auto t, auto& o) { return s.request_connection(5_node, 0x1281, t, o); }));
    frame("681#60001F0000000000");
    frame("67F#2F811203 05000000");
    frame("67F#23811201 82060000");
    frame("67F#23811202 83060000");
    frame("67F#23101F00 06008112");
  }
};

TEST(SdoRequestingDevice, RegistrationSets1F10hTo0001hAndSendsTheDynamicSdoRequest_7_2_1) {
  Rig r;
  ASSERT_TRUE(r.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); }));
  // §7.2.1: COB-ID 1760 = 6E0h, a data frame without data bytes.
  EXPECT_EQ(r.sent, Frames{"6E0#"});
  // §7.2.3: xxxx0001h, xxxx the client entry for the channel to the manager.
  EXPECT_EQ(r.value(0x1F10), 0x12800001u);
  EXPECT_EQ(r.srd->registration(), SrdRegistration::Requested);
  // The manager's scan reads it over the SRD's default SDO (67Fh/5FFh).
  EXPECT_EQ(r.frame("67F#40101F0000000000"), Frames{"5FF#43101F0001008012"});
  // A second request while one is open sends nothing.
  EXPECT_FALSE(r.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); }));
  EXPECT_TRUE(r.sent.empty());
}

TEST(SdoRequestingDevice, ErrorControlRequestIs0009hAndAllDefaultSdosIs00000003h_7_2_3) {
  Rig ec({.request_error_control = true});
  (void)ec.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); });
  EXPECT_EQ(ec.value(0x1F10), 0x12800009u);

  Rig all({.all_default_sdos = true});
  (void)all.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); });
  EXPECT_EQ(all.value(0x1F10), 0x00000003u);
}

TEST(SdoRequestingDevice, ManagerConfirmationWithCnxnState1OpensTheChannelToTheManager_7_2_3) {
  Rig r;
  (void)r.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); });
  // The manager writes 1280h sub 3 (its node-ID), sub 1, sub 2: no event yet.
  EXPECT_EQ(r.frame("67F#2F801203 01000000"), Frames{"5FF#6080120300000000"});
  r.frame("67F#23801201 80060000");
  r.frame("67F#23801202 81060000");
  EXPECT_TRUE(r.events.empty());
  EXPECT_EQ(r.srd->registration(), SrdRegistration::Requested);
  // 1F10h = 12800002h: index 1280h, Cnxn state 1, Rq indication reset.
  EXPECT_EQ(r.frame("67F#23101F00 02008012"), Frames{"5FF#60101F0000000000"});
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::Registered);
  EXPECT_EQ(r.events[0].client_index, 0x1280);
  EXPECT_EQ(r.events[0].slave_node_id, 1);  // the manager, from sub 3
  EXPECT_EQ(r.srd->registration(), SrdRegistration::Registered);
  EXPECT_EQ(r.srd->manager_channel(), 0x1280);
}

TEST(SdoRequestingDevice, ManagerResetOf1F10hAfterItsScanIsNoConfirmation_7_2_1) {
  Rig r;
  (void)r.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); });
  r.frame("67F#23101F00 00000000");
  EXPECT_TRUE(r.events.empty());
  EXPECT_EQ(r.srd->registration(), SrdRegistration::Requested);
}

TEST(SdoRequestingDevice, RefusedRegistrationReportsTheErrorCodeInWords_7_2_3) {
  Rig r;
  (void)r.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); });
  // Cnxn state 0, error 01h: no SDO channel free for connection from SRD to SDO manager.
  r.frame("67F#23101F00 00018012");
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::RegistrationFailed);
  EXPECT_EQ(r.events[0].state.error(), cfg::sdo_manager::DynamicSdoError::kNoChannelToManager);
  EXPECT_NE(r.events[0].text.find("no SDO channel free for connection from SRD to SDO manager"),
            std::string::npos);
  EXPECT_EQ(r.srd->registration(), SrdRegistration::Unregistered);
}

TEST(SdoRequestingDevice, NoManagerAnswerEndsTheRegistrationAfterTheTimeout_7_2_4) {
  Rig r({.registration_timeout = 2s});
  (void)r.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); });
  const TimePoint start = r.now;
  EXPECT_EQ(r.srd->next_deadline(), start + 2s);
  r.timer(start + 2s - 1ms);
  EXPECT_TRUE(r.events.empty());
  r.timer(start + 2s);
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::RegistrationFailed);
  EXPECT_NE(r.events[0].text.find("no SDO manager answered"), std::string::npos);
  // §7.2.4 guideline 1: the user decides; a new request is possible.
  EXPECT_TRUE(r.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); }));
}

TEST(SdoRequestingDevice, ConnectionRequestWrites1F00hOverTheManagerChannel_7_2_2) {
  Rig r;
  r.registered();
  ASSERT_TRUE(
      r.call([](auto& s, auto t, auto& o) { return s.request_connection(5_node, 0x1281, t, o); }));
  // 1F00h = 1281h << 16 | 7Fh << 8 | 05h, expedited on the channel's request COB-ID 680h.
  EXPECT_EQ(r.sent, Frames{"680#23001F00057F8112"});
  EXPECT_EQ(r.frame("681#60001F0000000000"), Frames{});
  EXPECT_TRUE(r.events.empty());
  // The manager writes 1281h (sub 3 = S, sub 1, sub 2), then 1F10h = 12810006h (Cnxn state 3).
  r.frame("67F#2F811203 05000000");
  r.frame("67F#23811201 82060000");
  r.frame("67F#23811202 83060000");
  r.frame("67F#23101F00 06008112");
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::Connected);
  EXPECT_EQ(r.events[0].client_index, 0x1281);
  EXPECT_EQ(r.events[0].slave_node_id, 5);
  EXPECT_EQ(r.srd->connections(), std::vector<std::uint16_t>{0x1281});
  ASSERT_TRUE(r.srd->connection(0x1281).has_value());
  EXPECT_EQ(r.srd->connection(0x1281)->request_cob_id, cfg::CobId::standard(0x682));
}

TEST(SdoRequestingDevice, TransfersRunOnTheChannelTheManagerWrote) {
  Rig r;
  r.connected();
  const auto id =
      r.call([](auto& s, auto t, auto& o) { return s.upload(0x1281, 0x1000, 0, t, o); });
  ASSERT_TRUE(id.ok());
  EXPECT_EQ(r.sent, Frames{"682#4000100000000000"});
  r.frame("683#4300100091010F00");
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::Transfer);
  ASSERT_TRUE(r.events[0].transfer.has_value());
  EXPECT_EQ(r.events[0].transfer->id, *id);
  EXPECT_TRUE(r.events[0].transfer->ok());
  EXPECT_EQ(r.events[0].transfer->data, (std::vector<std::uint8_t>{0x91, 0x01, 0x0F, 0x00}));
  // No connection on 1282h: nothing starts.
  EXPECT_FALSE(r.call([](auto& s, auto t, auto& o) { return s.upload(0x1282, 0x1000, 0, t, o); }));
}

// engine.hpp rule 5: a transfer its client cannot start returns why and puts nothing into `out`.
TEST(SdoRequestingDevice, ATransferTheClientCannotStartReturnsWhyAndSendsNothing) {
  Rig r;
  r.connected();
  SdoTransferOptions zero;
  zero.timeout = Duration::zero();
  const auto refused =
      r.call([&](auto& s, auto t, auto& o) { return s.upload(0x1281, 0x1000, 0, t, o, zero); });
  ASSERT_FALSE(refused.ok());
  EXPECT_EQ(refused.error().message, "the SDO response timeout must be positive (it is 0 us)");
  EXPECT_EQ(r.sent, Frames{});
  EXPECT_TRUE(r.events.empty());
  // The channel is untouched and no id was used up.
  const auto id =
      r.call([](auto& s, auto t, auto& o) { return s.upload(0x1281, 0x1000, 0, t, o); });
  ASSERT_TRUE(id.ok());
  EXPECT_EQ(*id, 1u);
  EXPECT_EQ(r.sent, Frames{"682#4000100000000000"});
}

TEST(SdoRequestingDevice, RefusalByAbort060A0023EndsTheRequest_7_2_3) {
  Rig r;
  r.registered();
  (void)r.call([](auto& s, auto t, auto& o) { return s.request_connection(5_node, 0x1281, t, o); });
  r.frame("681#80001F00 2300 0A06");
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::ConnectionFailed);
  EXPECT_EQ(r.events[0].abort, SdoAbort::ResourceNotAvailable);
  // The next request may go.
  EXPECT_TRUE(
      r.call([](auto& s, auto t, auto& o) { return s.request_connection(6_node, 0x1281, t, o); }));
}

TEST(SdoRequestingDevice, FailureIn1F10hNamesTheReason_7_2_3) {
  Rig r;
  r.registered();
  (void)r.call([](auto& s, auto t, auto& o) { return s.request_connection(5_node, 0x1281, t, o); });
  r.frame("681#60001F0000000000");
  // Cnxn state 0, error 03h: no more free server SDO entries on slave S.
  r.frame("67F#23101F00 00038112");
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::ConnectionFailed);
  EXPECT_EQ(r.events[0].state.error(), cfg::sdo_manager::DynamicSdoError::kNoFreeServerOnSlave);
  EXPECT_NE(r.events[0].text.find("no more free server SDO entries on slave S"), std::string::npos);
  EXPECT_TRUE(r.srd->connections().empty());
}

TEST(SdoRequestingDevice, MissingConfirmationTimesOutTheRequest) {
  Rig r({.connection_timeout = 1s});
  r.registered();
  (void)r.call([](auto& s, auto t, auto& o) { return s.request_connection(5_node, 0x1281, t, o); });
  r.frame("681#60001F0000000000");
  r.timer(r.now + 1s);
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::ConnectionFailed);
}

TEST(SdoRequestingDevice, ReleaseWrites1F01hAndTheManagerInvalidatingTheEntryEndsIt_7_2_2) {
  Rig r;
  r.connected();
  ASSERT_TRUE(r.call([](auto& s, auto t, auto& o) { return s.release(5_node, 0x1281, t, o); }));
  EXPECT_EQ(r.sent, Frames{"680#23011F00057F8112"});
  r.frame("681#60011F0000000000");
  EXPECT_TRUE(r.events.empty());
  // A transfer still running when the entry goes ends without a frame on the lost COB-IDs.
  (void)r.call([](auto& s, auto t, auto& o) { return s.upload(0x1281, 0x1000, 0, t, o); });
  r.frame("67F#23811201 82060080");  // bit 31 on sub 1
  EXPECT_TRUE(r.sent.size() == 1u && r.sent[0] == "5FF#6081120100000000");
  ASSERT_EQ(r.events.size(), 2u);
  EXPECT_EQ(r.events[0].kind, Kind::Transfer);
  EXPECT_EQ(r.events[0].transfer->abort, SdoAbort::General);
  EXPECT_EQ(r.events[1].kind, Kind::ConnectionReleased);
  EXPECT_EQ(r.events[1].client_index, 0x1281);
  EXPECT_EQ(r.events[1].slave_node_id, 5);
  r.frame("67F#23811202 83060080");  // sub 2: already released
  EXPECT_TRUE(r.events.empty());
  EXPECT_TRUE(r.srd->connections().empty());
}

TEST(SdoRequestingDevice, SlaveFailedIn1F11hIsReported_7_2_3) {
  Rig r;
  r.connected();
  // 1F11h = 0005h: reason 00h (error control), slave 5; UNSIGNED16, expedited 2 bytes (2Bh).
  EXPECT_EQ(r.frame("67F#2B111F00 05000000"), Frames{"5FF#60111F0000000000"});
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::SlaveFailed);
  EXPECT_EQ(r.events[0].slave_node_id, 5);
}

TEST(SdoRequestingDevice, DeregistrationWrites1F01hWithSlaveZero_7_2_1) {
  Rig r;
  r.connected();
  ASSERT_TRUE(r.call([](auto& s, auto t, auto& o) { return s.deregister(t, o); }));
  EXPECT_EQ(r.sent, Frames{"680#23011F00007F0000"});
  r.frame("681#60011F0000000000");
  ASSERT_EQ(r.events.size(), 2u);
  EXPECT_EQ(r.events[0].kind, Kind::ConnectionReleased);
  EXPECT_EQ(r.events[1].kind, Kind::Deregistered);
  EXPECT_EQ(r.srd->registration(), SrdRegistration::Unregistered);
  EXPECT_TRUE(r.srd->connections().empty());
}

TEST(SdoRequestingDevice, AllDefaultSdosGrantLetsTheSrdUseDefaultSdos_7_2_2) {
  Rig r({.all_default_sdos = true});
  (void)r.call([](auto& s, auto t, auto& o) { return s.register_at_manager(t, o); });
  // 00000004h: Cnxn state 2.
  r.frame("67F#23101F00 04000000");
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_EQ(r.events[0].kind, Kind::Registered);
  EXPECT_EQ(r.srd->registration(), SrdRegistration::AllDefaultSdos);
  EXPECT_TRUE(r.call(
      [](auto& s, auto t, auto& o) { return s.upload_default(5_node, 0x1000, 0, t, o).ok(); }));
  EXPECT_EQ(r.sent, Frames{"605#4000100000000000"});
  r.frame("585#4300100091010F00");
  ASSERT_EQ(r.events.size(), 1u);
  EXPECT_TRUE(r.events[0].transfer->ok());
}

}  // namespace
}  // namespace nmt
