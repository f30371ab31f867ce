// One boot NMT slave engine (BootSlaveProcess, libnmt/core/src/master/boot_slave_process.hpp)
// driven through a fake port: the SDO accesses it asks for, the NMT commands it queues, its one
// report (boot_con) and its events, against CiA 302-2 §3.4-§3.6 and the error status of §3.8
// (Table 1). The whole master with simulated devices is tested in nmt_master_spec*_test.cpp.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <vector>

#include "master/boot_slave_process.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/master_options.hpp"
#include "nmt/protocol/error_control.hpp"
#include "nmt/slave/nmt_slave.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using Kind = MasterEvent::Kind;
using Phase = BootSlaveProcess::Phase;

constexpr std::uint8_t kNode = 5;

/// One SDO access the process asked the master for.
struct Access {
  std::uint64_t try_id = 0;
  std::uint16_t index = 0;
  std::uint8_t sub = 0;
  bool upload = false;
  std::vector<std::uint8_t> data;  ///< download
  Duration timeout{};              ///< its response timeout
  unsigned retries = 0;            ///< repetitions after a timeout
};

/// boot_con as the master received it.
struct Report {
  std::optional<BootError> status;
  bool left_to_application = false;
};

std::vector<std::uint8_t> le32(std::uint32_t v) {
  return {static_cast<std::uint8_t>(v), static_cast<std::uint8_t>(v >> 8),
          static_cast<std::uint8_t>(v >> 16), static_cast<std::uint8_t>(v >> 24)};
}

class FakePort final : public BootSlavePort {
 public:
  BootSlaveExpectations expect;
  std::optional<Duration> heartbeat;  ///< 1016h for the node
  KnownState state{};                 ///< 1F82h
  std::optional<TimePoint> heard;
  std::optional<std::vector<cfg::ObjectWrite>> writes;
  std::optional<std::vector<std::uint8_t>> image;

  std::vector<Access> accesses;
  std::vector<std::pair<NmtCommand, std::uint8_t>> nmt;
  std::size_t cancels = 0;
  std::size_t error_control_starts = 0;
  std::vector<Report> reports;

  void transfer(std::uint64_t try_id, SdoTransferScheduler::Request r, TimePoint) override {
    EXPECT_EQ(r.node, kNode);
    accesses.push_back({try_id, r.object.index, r.object.sub_index, r.upload, std::move(r.data),
                        r.timeout, r.retries});
  }
  void cancel_transfers(cfg::NodeId, TimePoint) override { ++cancels; }
  void queue_nmt(NmtCommand command, cfg::NodeId node) override { nmt.emplace_back(command, node); }
  bool start_error_control(cfg::NodeId, TimePoint) override {
    ++error_control_starts;
    return heartbeat.has_value();
  }
  BootSlaveExpectations expectations(cfg::NodeId) const override { return expect; }
  std::optional<Duration> heartbeat_time(cfg::NodeId) const override { return heartbeat; }
  KnownState known_state(cfg::NodeId) const override { return state; }
  std::optional<TimePoint> last_heartbeat(cfg::NodeId) const override { return heard; }
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId) const override {
    return writes;
  }
  std::optional<std::vector<std::uint8_t>> program(cfg::NodeId) const override { return image; }
  TimePoint startup_began() const override { return TimePoint{}; }
  void boot_con(cfg::NodeId, std::optional<BootError> status, bool left, TimePoint,
                Outbox<MasterEvent>&) override {
    reports.push_back({status, left});
  }
};

struct Rig {
  FakePort port;
  BootUpGate gate;  // open unless a test closes it (the start-up's reset)
  BootSlaveProcess::Options options = BootSlaveProcess::Options::from(MasterOptions{});
  BootSlaveProcess process{*cfg::NodeId::from(kNode), port, gate, options};
  BootSlaveProcess::Output out;
  TimePoint now{Duration{1'000'000}};

  Rig() {
    // Slave, boot (configure and start), optional.
    port.expect.assignment =
        cfg::SlaveAssignment::make(cfg::SlaveAssignment::kSlave | cfg::SlaveAssignment::kBootSlave);
  }
  void mandatory() { port.expect.assignment.value |= cfg::SlaveAssignment::kMandatory; }
  void keep_alive() { port.expect.assignment.value |= cfg::SlaveAssignment::kKeepAlive; }

  const Access& last() const { return port.accesses.back(); }
  /// Answers the last access: an upload with `value`, a download with success.
  void answer(std::optional<std::uint32_t> value = std::nullopt) {
    const auto& a = last();
    SdoResult r;
    r.node_id = cfg::NodeId::from(kNode);
    r.address = {a.index, a.sub};
    r.upload = a.upload;
    if (a.upload) r.data = le32(value.value_or(0));
    process.on_sdo_result(r, now, out);
  }
  void abort(SdoAbort code) {
    const auto& a = last();
    SdoResult r;
    r.node_id = cfg::NodeId::from(kNode);
    r.address = {a.index, a.sub};
    r.upload = a.upload;
    r.abort = code;
    r.aborted_by_server = code != SdoAbort::Timeout;
    process.on_sdo_result(r, now, out);
  }
  std::vector<MasterEvent> events_of(Kind kind) const {
    std::vector<MasterEvent> found;
    for (const auto& e : out.events) {
      if (e.kind == kind) found.push_back(e);
    }
    return found;
  }
  void advance(Duration d) {
    now += d;
    process.on_timer(now, out);
  }
};

void expect_access(const Access& a, std::uint16_t index, std::uint8_t sub, bool upload,
                   const std::vector<std::uint8_t>& data = {}) {
  EXPECT_EQ(a.index, index);
  EXPECT_EQ(a.sub, sub);
  EXPECT_EQ(a.upload, upload);
  EXPECT_EQ(a.data, data);
}

// §3.4 c: "Request object 1000h"; d: "If the value of 1F84h is not 0 and it differs from the
// value of 1000h of the CANopen device, then the process shall finish with error status C."
TEST(BootSlave, ReportsStatusCWhenDeviceTypeDiffers) {
  Rig rig;
  rig.mandatory();
  rig.port.expect.device_type = 0x00020192;
  rig.process.start(rig.now, rig.out);
  ASSERT_EQ(rig.port.accesses.size(), 1U);
  expect_access(rig.last(), 0x1000, 0, true);
  ASSERT_EQ(rig.process.step(), BootStep::Identify);

  rig.answer(0x00020191);

  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::C);
  const auto errors = rig.events_of(Kind::BootError);
  ASSERT_EQ(errors.size(), 1U);
  EXPECT_EQ(errors[0].error, BootError::C);
  EXPECT_TRUE(errors[0].final);  // §3.3: a mandatory slave is retried only after B
  EXPECT_EQ(errors[0].node_id, kNode);
  EXPECT_NE(describe(errors[0]).find("1000h is 0x00020191, 1F84h expects 0x00020192"),
            std::string::npos)
      << describe(errors[0]);
  // The facts behind the letter: 1000h as the device answered, 1F84h as the master expects.
  ASSERT_TRUE(errors[0].failure.has_value());
  const BootFailure& failure = *errors[0].failure;
  EXPECT_EQ(failure.reason, BootFailure::Reason::ValueDiffers);
  EXPECT_EQ(failure.step, BootStep::Identify);
  EXPECT_EQ(failure.object, (cfg::ObjectAddress{0x1000, 0}));
  EXPECT_EQ(failure.actual, 0x00020191U);
  EXPECT_EQ(failure.expected_by, 0x1F84);
  EXPECT_EQ(failure.expected, 0x00020192U);
  EXPECT_EQ(errors[0].boot_try, 1U);
  EXPECT_EQ(rig.port.accesses.size(), 1U);  // no identity, no configuration
  EXPECT_TRUE(rig.port.nmt.empty());
  EXPECT_FALSE(rig.process.running());
  EXPECT_EQ(rig.process.step(), BootStep::Failed);
  EXPECT_EQ(rig.process.next_deadline(), std::nullopt);
}

// §6.6: 1F84h = 0: "the device type ... may not be verified".
TEST(BootSlave, DeviceTypeIsNotCheckedWhen1F84IsZero) {
  Rig rig;
  rig.process.start(rig.now, rig.out);
  rig.answer(0x12345678);
  // Nothing else to check or download: error control, then status OK.
  EXPECT_EQ(rig.port.accesses.size(), 1U);
  EXPECT_EQ(rig.port.error_control_starts, 1U);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  EXPECT_TRUE(rig.events_of(Kind::BootError).empty());
}

// §3.4 c: "If no response is received ... status B". §3.3: an optional slave is tried again
// (MasterOptions::boot.retry_interval); the retry repeats silently while it ends the same way.
TEST(BootSlave, ReportsStatusBAndRetriesAnOptionalSlaveSilently) {
  Rig rig;
  rig.process.start(rig.now, rig.out);
  const auto first_try = rig.last().try_id;
  rig.abort(SdoAbort::Timeout);

  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::B);
  ASSERT_EQ(rig.events_of(Kind::BootError).size(), 1U);
  EXPECT_FALSE(rig.events_of(Kind::BootError)[0].final);
  EXPECT_EQ(rig.events_of(Kind::BootError)[0].boot_try, 1U);
  ASSERT_TRUE(rig.events_of(Kind::BootError)[0].failure.has_value());
  EXPECT_EQ(rig.events_of(Kind::BootError)[0].failure->reason, BootFailure::Reason::TransferFailed);
  EXPECT_EQ(rig.events_of(Kind::BootError)[0].failure->transfer->address,
            (cfg::ObjectAddress{0x1000, 0}));
  EXPECT_EQ(rig.events_of(Kind::BootError)[0].failure->transfer->abort, SdoAbort::Timeout);
  EXPECT_EQ(rig.process.step(), BootStep::RetryWait);
  EXPECT_EQ(rig.process.next_deadline(), rig.now + rig.options.retry_interval);

  rig.advance(rig.options.retry_interval - 1us);
  EXPECT_EQ(rig.port.accesses.size(), 1U);  // not yet
  rig.advance(1us);
  ASSERT_EQ(rig.port.accesses.size(), 2U);
  expect_access(rig.last(), 0x1000, 0, true);
  EXPECT_GT(rig.last().try_id, first_try);  // results of the old try are not this try's
  EXPECT_EQ(rig.process.try_id(), rig.last().try_id);
  // The second try's first step says its number (a tool counts retries from it).
  const auto steps = rig.events_of(Kind::BootStepChanged);
  ASSERT_FALSE(steps.empty());
  EXPECT_EQ(steps.back().step, BootStep::Identify);
  EXPECT_EQ(steps.back().boot_try, 2U);

  rig.abort(SdoAbort::Timeout);
  EXPECT_EQ(rig.port.reports.size(), 2U);
  EXPECT_EQ(rig.events_of(Kind::BootError).size(), 1U);  // the same error: not reported again
}

// §3.4 e: 1F85h-1F88h against 1018h sub 1-4: D vendor-ID, M product code, N revision number,
// O serial number; entries that are 0 are not read.
TEST(BootSlave, ReportsStatusDWhenVendorIdDiffers) {
  Rig rig;
  rig.port.expect.identity = {0x0000032C, 0, 0, 0};
  rig.process.start(rig.now, rig.out);
  rig.answer(0x00020191);
  expect_access(rig.last(), 0x1018, 1, true);
  rig.answer(0x0000032D);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::D);
  EXPECT_NE(describe(rig.events_of(Kind::BootError)[0])
                .find("1018h sub 01h is 0x0000032D, 1F85h expects 0x0000032C"),
            std::string::npos)
      << describe(rig.events_of(Kind::BootError)[0]);
  const auto failure = rig.events_of(Kind::BootError)[0].failure.value();
  EXPECT_EQ(failure.reason, BootFailure::Reason::ValueDiffers);
  EXPECT_EQ(failure.object, (cfg::ObjectAddress{0x1018, 1}));
  EXPECT_EQ(failure.actual, 0x0000032DU);
  EXPECT_EQ(failure.expected_by, 0x1F85);
  EXPECT_EQ(failure.expected, 0x0000032CU);
}

TEST(BootSlave, ReportsStatusMWhenProductCodeDiffers) {
  Rig rig;
  rig.port.expect.identity = {0, 0x00001234, 0, 0};
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  expect_access(rig.last(), 0x1018, 2, true);  // sub 1 is skipped: 1F85h is 0
  rig.answer(0x00001235);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::M);
}

// §6.9: the major revision must be equal, the minor not lower.
TEST(BootSlave, ReportsStatusNWhenMajorRevisionDiffersOrMinorIsLower) {
  for (const std::uint32_t actual : {0x00020005U, 0x00010003U}) {
    Rig rig;
    rig.port.expect.identity = {0, 0, 0x00010004, 0};
    rig.process.start(rig.now, rig.out);
    rig.answer(0);
    expect_access(rig.last(), 0x1018, 3, true);
    rig.answer(actual);
    ASSERT_EQ(rig.port.reports.size(), 1U) << std::hex << actual;
    EXPECT_EQ(rig.port.reports[0].status, BootError::N) << std::hex << actual;
  }
  Rig rig;
  rig.port.expect.identity = {0, 0, 0x00010004, 0x00000007};
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  rig.answer(0x00010009);  // equal major, higher minor: passes on to the serial number
  expect_access(rig.last(), 0x1018, 4, true);
  rig.answer(0x00000008);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::O);
}

// §3.6, keep-alive without a consumed heartbeat: one guarding request (an RTR on 700h + node-ID),
// "In case no confirmation is received and more than 100 milliseconds are elapsed" status F.
TEST(BootSlave, ReportsStatusFWhenTheGuardingRequestIsNotAnsweredWithin100ms) {
  Rig rig;
  rig.keep_alive();
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  ASSERT_EQ(rig.out.frames.size(), 1U);
  EXPECT_EQ(rig.out.frames[0], make_guarding_request(*cfg::NodeId::from(kNode)));
  EXPECT_EQ(rig.out.frames[0].id, 0x705U);
  EXPECT_TRUE(rig.out.frames[0].rtr);
  EXPECT_EQ(rig.process.step(), BootStep::CheckNmtState);
  rig.advance(100ms - 1us);
  EXPECT_TRUE(rig.port.reports.empty());
  rig.advance(1us);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::F);
  EXPECT_TRUE(rig.port.nmt.empty());  // no reset of a slave whose state is unknown
}

// §3.6 with a consumed heartbeat (1016h): none within the consumer time is status E.
TEST(BootSlave, ReportsStatusEWhenAKeepAliveSlaveSendsNoHeartbeat) {
  Rig rig;
  rig.keep_alive();
  rig.port.heartbeat = 200ms;
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  EXPECT_TRUE(rig.out.frames.empty());  // no guarding request: the heartbeat answers
  EXPECT_EQ(rig.process.next_deadline(), rig.now + 200ms);
  rig.advance(200ms);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::E);
}

// §3.5 last paragraph: a keep-alive slave found operational skips check configuration; once
// error control runs the process ends with status L (reported as not final, the slave runs).
TEST(BootSlave, ReportsStatusLForAKeepAliveSlaveFoundOperational) {
  Rig rig;
  rig.keep_alive();
  rig.port.writes = std::vector<cfg::ObjectWrite>{{0x2000, 0, {25, 0}}};
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  ASSERT_TRUE(rig.process.awaits_guard_reply());
  // The guarding reply of its node with state 05h, as the master routes it.
  rig.process.on_guard_reply(NmtState::Operational, rig.now, rig.out);

  EXPECT_EQ(rig.port.error_control_starts, 1U);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::L);
  EXPECT_TRUE(rig.port.nmt.empty());
  EXPECT_EQ(rig.port.accesses.size(), 1U);  // no 1020h, no download
  EXPECT_TRUE(rig.process.booted());
  EXPECT_EQ(rig.process.step(), BootStep::Booted);
}

// §3.4 part 2: a keep-alive slave not operational gets reset communication, then its boot goes
// on after its boot-up (software check, configuration).
TEST(BootSlave, KeepAliveSlaveFoundPreOperationalIsResetAndGoesOnAfterItsBootUp) {
  Rig rig;
  rig.keep_alive();
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  rig.process.on_guard_reply(NmtState::PreOperational, rig.now, rig.out);
  ASSERT_EQ(rig.port.nmt.size(), 1U);
  EXPECT_EQ(rig.port.nmt[0], std::make_pair(NmtCommand::ResetCommunication, kNode));
  EXPECT_EQ(rig.process.step(), BootStep::AwaitBootUp);
  EXPECT_EQ(rig.process.next_deadline(), rig.now + rig.options.reboot_timeout);
  EXPECT_TRUE(rig.process.on_boot_up(rig.now, rig.out));
  EXPECT_EQ(rig.process.next_deadline(), std::nullopt);
  // Nothing to verify or download: error control, then status OK.
  EXPECT_EQ(rig.port.error_control_starts, 1U);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  EXPECT_FALSE(rig.port.reports[0].left_to_application);
}

// §3.5: 1020h differs from 1F26h/1F27h: download in order, then 1020h, then 1010h 'save'; the
// boot ends with status OK and the words of what was written.
TEST(BootSlave, DownloadsTheConfigurationWhen1020hDiffersThenStoresItsDateAndSaves) {
  Rig rig;
  rig.port.expect.configuration = {9000, 1234};
  rig.port.writes =
      std::vector<cfg::ObjectWrite>{{0x2000, 0, {25, 0}}, {0x1010, 1, le32(cfg::kSaveSignature)}};
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  expect_access(rig.last(), 0x1020, 1, true);
  EXPECT_EQ(rig.process.step(), BootStep::VerifyConfiguration);
  rig.answer(8999);  // another date: sub 2 cannot make it match
  ASSERT_EQ(rig.port.accesses.size(), 3U);
  expect_access(rig.last(), 0x2000, 0, false, {25, 0});  // 1010h is the master's to send
  rig.answer();
  expect_access(rig.last(), 0x1020, 1, false, le32(9000));
  rig.answer();
  expect_access(rig.last(), 0x1020, 2, false, le32(1234));
  rig.answer();
  expect_access(rig.last(), 0x1010, 1, false, le32(cfg::kSaveSignature));
  rig.answer();

  EXPECT_EQ(rig.port.error_control_starts, 1U);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  const auto booted = rig.events_of(Kind::SlaveBooted);
  ASSERT_EQ(booted.size(), 1U);
  EXPECT_TRUE(booted[0].configured);
  EXPECT_EQ(booted[0].written, 1U);
  EXPECT_EQ(booted[0].total, 1U);
  EXPECT_EQ(booted[0].bytes, 2U);
  EXPECT_EQ(describe(booted[0]), "node 5: booted (configured: 1 entries, 2 bytes)");
}

// §3.5 c: 1020h equal to 1F26h/1F27h: no download.
TEST(BootSlave, SkipsTheDownloadWhen1020hMatches) {
  Rig rig;
  rig.port.expect.configuration = {9000, 1234};
  rig.port.writes = std::vector<cfg::ObjectWrite>{{0x2000, 0, {25, 0}}};
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  rig.answer(9000);
  expect_access(rig.last(), 0x1020, 2, true);
  rig.answer(1234);
  EXPECT_EQ(rig.port.accesses.size(), 3U);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  EXPECT_EQ(describe(rig.events_of(Kind::SlaveBooted)[0]),
            "node 5: booted (configuration up to date)");
}

// §3.5 a: 1F26h/1F27h = 0 and nothing to download (a master DCF whose 1F22h sub 5 is empty):
// booted without a comparison or a download, which is not "up to date".
TEST(BootSlave, ReportsNoConfigurationWhenItHasNothingToConfigureTheSlaveWith) {
  Rig rig;
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  EXPECT_EQ(rig.port.accesses.size(), 1U);  // 1000h only
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  const auto booted = rig.events_of(Kind::SlaveBooted);
  ASSERT_EQ(booted.size(), 1U);
  EXPECT_FALSE(booted[0].configured);
  EXPECT_TRUE(booted[0].no_configuration);
  EXPECT_EQ(describe(booted[0]),
            "node 5: booted, no configuration for node 5 (1F22h sub 05h empty)");
}

// An empty configuration is one: downloaded (nothing but 1010h), not "no configuration".
// An empty configuration (a node a scanned project knows by its identity only) writes nothing,
// and so saves nothing either: 1010h 'save' would store whatever the device holds in RAM.
TEST(BootSlave, AnEmptyConfigurationIsDownloadedNotReportedAsMissing) {
  Rig rig;
  rig.port.writes = std::vector<cfg::ObjectWrite>{};
  rig.process.start(rig.now, rig.out);
  const std::size_t before = rig.port.accesses.size();
  rig.answer(0);
  EXPECT_EQ(rig.port.accesses.size(), before) << "no 1010h save after an empty download";
  const auto booted = rig.events_of(Kind::SlaveBooted);
  ASSERT_EQ(booted.size(), 1U);
  EXPECT_TRUE(booted[0].configured);
  EXPECT_FALSE(booted[0].no_configuration);
}

// J: "Configuration download failed".
TEST(BootSlave, ReportsStatusJWhenTheSlaveAbortsAConfigurationWrite) {
  Rig rig;
  rig.port.writes = std::vector<cfg::ObjectWrite>{{0x2000, 0, {25, 0}}, {0x2001, 0, {1}}};
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  rig.answer();
  expect_access(rig.last(), 0x2001, 0, false, {1});
  rig.abort(SdoAbort::WriteOfReadOnly);  // 0601 0002
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::J);
  const auto error = rig.events_of(Kind::BootError)[0];
  EXPECT_NE(describe(error).find("(entry 2 of 2)"), std::string::npos);
  // The typed reason: the second of two writes, 2001h sub 00h, aborted with 0601 0002.
  ASSERT_TRUE(error.failure.has_value());
  EXPECT_EQ(error.failure->reason, BootFailure::Reason::WriteFailed);
  EXPECT_EQ(error.failure->step, BootStep::Download);
  EXPECT_EQ(error.failure->entry, 2U);
  EXPECT_EQ(error.failure->entries, 2U);
  ASSERT_TRUE(error.failure->transfer.has_value());
  EXPECT_EQ(error.failure->transfer->address, (cfg::ObjectAddress{0x2001, 0}));
  EXPECT_EQ(error.failure->transfer->abort, SdoAbort::WriteOfReadOnly);
}

// §4.1: with a consumed heartbeat the boot waits for the first one; none within the consumer
// time is status K.
TEST(BootSlave, ReportsStatusKWhenTheFirstHeartbeatNeverComes) {
  Rig rig;
  rig.port.heartbeat = 300ms;
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  EXPECT_TRUE(rig.process.awaits_first_heartbeat());
  EXPECT_TRUE(rig.port.reports.empty());
  rig.process.on_heartbeat_timeout(rig.now + 300ms, rig.out);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::K);
  EXPECT_NE(describe(rig.events_of(Kind::BootError)[0]).find("consumer time of 300 ms"),
            std::string::npos);
  ASSERT_TRUE(rig.events_of(Kind::BootError)[0].failure.has_value());
  EXPECT_EQ(rig.events_of(Kind::BootError)[0].failure->reason,
            BootFailure::Reason::NoFirstHeartbeat);
  EXPECT_EQ(rig.events_of(Kind::BootError)[0].failure->consumer_time_ms, 300U);
}

// §3.4 a: a node without 1F81h bit 0 ends with status A, final.
TEST(BootSlave, ReportsStatusAWhenTheNodeIsNoSlave) {
  Rig rig;
  rig.port.expect.assignment = {};
  rig.process.start(rig.now, rig.out);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::A);
  EXPECT_TRUE(rig.events_of(Kind::BootError)[0].final);
  EXPECT_TRUE(rig.port.accesses.empty());
}

// §3.4 b, Table 20: 1F81h bit 2 clear: neither configured nor started, unless the application
// asks.
TEST(BootSlave, SlaveWithoutBit2IsLeftToTheApplication) {
  Rig rig;
  rig.port.expect.assignment = cfg::SlaveAssignment::make(cfg::SlaveAssignment::kSlave);
  rig.process.start(rig.now, rig.out);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_TRUE(rig.port.reports[0].left_to_application);
  EXPECT_TRUE(rig.port.accesses.empty());
  EXPECT_EQ(rig.process.step(), BootStep::Idle);

  rig.process.start(BootSlaveProcess::AskedBy::Application, rig.now, rig.out);
  ASSERT_EQ(rig.port.accesses.size(), 1U);
  expect_access(rig.last(), 0x1000, 0, true);
}

// After the start-up's reset communication the try waits for the boot-up (or until the wait
// ends) before its first request.
TEST(BootSlave, AfterResetTheTryBeginsWithTheBootUp) {
  Rig rig;
  rig.process.start_after_reset(rig.now + 500ms, rig.now, rig.out);
  EXPECT_EQ(rig.process.step(), BootStep::AwaitBootUp);
  EXPECT_TRUE(rig.port.accesses.empty());
  EXPECT_EQ(rig.process.next_deadline(), rig.now + 500ms);
  EXPECT_TRUE(rig.process.on_boot_up(rig.now + 10ms, rig.out));
  ASSERT_EQ(rig.port.accesses.size(), 1U);
  expect_access(rig.last(), 0x1000, 0, true);
  EXPECT_EQ(rig.process.next_deadline(), std::nullopt);

  Rig lost;
  lost.gate.close(lost.now + 500ms, false);
  lost.process.start_after_reset(lost.now + 500ms, lost.now, lost.out);
  lost.advance(500ms);  // its boot-up was lost: identify anyway
  EXPECT_FALSE(lost.gate.closed()) << "the wait's end opens the gate for all";
  ASSERT_EQ(lost.port.accesses.size(), 1U);
  expect_access(lost.last(), 0x1000, 0, true);
}

// The start-up's boot-up gate (CiA 302-2 §3.1 d-e, boot_up_gate.hpp): a boot-up while the gate
// is closed is seen, and the try waits for the others; it identifies when the master opens the
// gate (pass_boot_up_gate), at once, its wait's deadline gone.
TEST(BootSlave, BootUpAtTheClosedGateWaitsUntilTheGateOpens) {
  Rig rig;
  rig.gate.close(rig.now + 500ms, false);
  rig.process.start_after_reset(rig.now + 500ms, rig.now, rig.out);
  EXPECT_TRUE(rig.process.on_boot_up(rig.now + 10ms, rig.out));
  EXPECT_TRUE(rig.process.at_boot_up_gate());
  EXPECT_TRUE(rig.process.boot_up_seen());
  EXPECT_TRUE(rig.port.accesses.empty()) << "an SDO request before the gate opened";
  EXPECT_EQ(rig.process.next_deadline(), rig.now + 500ms);
  rig.gate.open();
  rig.process.pass_boot_up_gate(rig.now + 20ms, rig.out);
  ASSERT_EQ(rig.port.accesses.size(), 1U);
  expect_access(rig.last(), 0x1000, 0, true);
  EXPECT_EQ(rig.process.next_deadline(), std::nullopt);
}

// 1F25h: a reconfiguration request downloads although 1020h would match, until a try succeeds.
TEST(BootSlave, ReconfigurationRequestDownloadsWithoutReading1020h) {
  Rig rig;
  rig.port.expect.configuration = {9000, 1234};
  rig.port.writes = std::vector<cfg::ObjectWrite>{{0x2000, 0, {25, 0}}};
  rig.process.start(rig.now, rig.out);
  rig.process.request_reconfiguration();
  rig.answer(0);
  expect_access(rig.last(), 0x2000, 0, false, {25, 0});
  rig.answer();
  rig.answer();
  rig.answer();
  rig.answer();
  ASSERT_EQ(rig.port.reports.size(), 1U);
  rig.process.start(rig.now, rig.out);
  rig.answer(0);
  expect_access(rig.last(), 0x1020, 1, true);  // the request held until that success
}

// ------------------------------------ check and update software version (§3.4 part 2 b, DSP 302
// §9, CiA 302-2 Table 1 G/H/I)

constexpr cfg::ProgramVersion kExpectedProgram{15671, 29'700'000};  // 1F53h/1F54h sub 5
constexpr cfg::ProgramVersion kRunningProgram{15000, 1000};         // what 1F52h reports first

/// 1F81h bit 5 (and bit 6 when `update`), 1F53h/1F54h set, a 300-byte image available.
void verify_software(Rig& rig, bool update) {
  rig.port.expect.assignment.value |=
      cfg::SlaveAssignment::kVerifySoftware | (update ? cfg::SlaveAssignment::kUpdateSoftware : 0);
  rig.port.expect.software = kExpectedProgram;
  rig.port.image = std::vector<std::uint8_t>(300, 0x5A);
}

/// Starts the try and answers 1000h, then 1F52h sub 1 and 2 with `version`.
void report_version(Rig& rig, cfg::ProgramVersion version) {
  rig.process.start(rig.now, rig.out);
  rig.answer(0);  // 1000h
  expect_access(rig.last(), 0x1F52, 1, true);
  EXPECT_EQ(rig.process.step(), BootStep::CheckSoftware);
  rig.answer(version.date_days);
  expect_access(rig.last(), 0x1F52, 2, true);
  rig.answer(version.time_ms);
}

/// The update up to the 1F50h download: stop answered, clear answered by `clear`.
void stop_and_clear(Rig& rig, std::optional<SdoAbort> clear_abort = std::nullopt) {
  expect_access(rig.last(), 0x1F51, 1, false, {0});  // stop
  EXPECT_EQ(rig.process.step(), BootStep::UpdateSoftware);
  rig.answer();
  expect_access(rig.last(), 0x1F51, 1, false, {3});  // clear (CiA 302-3)
  if (clear_abort) {
    rig.abort(*clear_abort);
  } else {
    rig.answer();
  }
}

std::string boot_error_text(const Rig& rig) {
  const auto errors = rig.events_of(Kind::BootError);
  return errors.empty() ? std::string() : describe(errors.back());
}

// DSP 302 §9 / CiA 302-3: 1F51h sub 1 = 0 (stop), = 3 (clear), 1F50h sub 1 = image, 1F51h sub 1
// = 1 (start), then 1F52h again; each step with its own wait (MasterOptions), the image once
// repeated after a timeout.
TEST(BootSlave, Dsp302Sec9UpdateStopsClearsDownloadsStartsAndReadsTheVersionAgain) {
  Rig rig;
  verify_software(rig, true);
  report_version(rig, kRunningProgram);
  const Access stop = rig.last();
  EXPECT_EQ(stop.timeout, rig.options.program_control_timeout);
  EXPECT_EQ(stop.retries, rig.options.sdo_retries);
  stop_and_clear(rig);
  EXPECT_EQ(rig.port.accesses[rig.port.accesses.size() - 2].timeout,
            rig.options.program_clear_timeout);
  expect_access(rig.last(), 0x1F50, 1, false, *rig.port.image);
  EXPECT_EQ(rig.last().timeout, rig.options.program_data_timeout);
  EXPECT_EQ(rig.last().retries, 1U) << "one repetition from the start of the image";
  rig.answer();
  expect_access(rig.last(), 0x1F51, 1, false, {1});  // start
  EXPECT_EQ(rig.last().timeout, rig.options.program_control_timeout);
  rig.answer();
  // §3.4 part 2 b: the version is checked again after the download.
  expect_access(rig.last(), 0x1F52, 1, true);
  EXPECT_EQ(rig.process.step(), BootStep::CheckSoftware);
  rig.answer(kExpectedProgram.date_days);
  rig.answer(kExpectedProgram.time_ms);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  EXPECT_TRUE(rig.process.booted());
  // What the report shows: the versions before and after, the image's bytes.
  const auto booted = rig.events_of(Kind::SlaveBooted);
  ASSERT_EQ(booted.size(), 1U);
  ASSERT_TRUE(booted[0].program.has_value());
  EXPECT_EQ(booted[0].program->before, kRunningProgram);
  EXPECT_EQ(booted[0].program->after, kExpectedProgram);
  EXPECT_EQ(booted[0].program->bytes, 300U);
  EXPECT_TRUE(booted[0].program->ended.has_value());
  EXPECT_EQ(booted[0].program->clear_refused, std::nullopt);  // clear was accepted
  EXPECT_TRUE(rig.events_of(Kind::ProgramClearRefused).empty());
  EXPECT_NE(
      describe(booted[0]).find("; program updated from 2025-01-25 00:00:01.000 (1F52h 15000, "
                               "1000) to 2026-11-27 08:15:00.000 (1F52h 15671, 29700000), 300 "
                               "bytes"),
      std::string::npos)
      << describe(booted[0]);
  // The defaults differ, so the steps above took their own.
  EXPECT_NE(rig.options.program_control_timeout, rig.options.program_clear_timeout);
  EXPECT_NE(rig.options.program_data_timeout, rig.options.program_control_timeout);
}

// DSP 302 v3.2.1 §9: "The range for the sub-objects of the Program Control Object is 0 to 2";
// "If the action is not possible, the Device responds with ... 0800 0024h". A device built to
// that text refuses CiA 302-3's clear (3): the download goes on and the boot ends with OK.
class BootSlaveClearRefused : public ::testing::TestWithParam<SdoAbort> {};

TEST_P(BootSlaveClearRefused, Dsp302Sec9DeviceRefusingClearStillGetsTheImage) {
  Rig rig;
  verify_software(rig, true);
  report_version(rig, kRunningProgram);
  stop_and_clear(rig, GetParam());
  expect_access(rig.last(), 0x1F50, 1, false, *rig.port.image);
  rig.answer();
  expect_access(rig.last(), 0x1F51, 1, false, {1});
  rig.answer();
  rig.answer(kExpectedProgram.date_days);
  rig.answer(kExpectedProgram.time_ms);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  EXPECT_TRUE(rig.events_of(Kind::BootError).empty());
  // Reported, with the abort, and in the boot's account of the update.
  const auto refused = rig.events_of(Kind::ProgramClearRefused);
  ASSERT_EQ(refused.size(), 1U);
  ASSERT_TRUE(refused[0].sdo.has_value());
  EXPECT_EQ(refused[0].sdo->abort, GetParam());
  EXPECT_NE(describe(refused[0]).find("refused: " + to_string(GetParam())), std::string::npos)
      << describe(refused[0]);
  const auto booted = rig.events_of(Kind::SlaveBooted);
  ASSERT_EQ(booted.size(), 1U);
  ASSERT_TRUE(booted[0].program.has_value());
  EXPECT_EQ(booted[0].program->clear_refused, GetParam());
}

INSTANTIATE_TEST_SUITE_P(RefusalsOfClear, BootSlaveClearRefused,
                         ::testing::Values(SdoAbort::ValueRangeExceeded,     // 0609 0030
                                           SdoAbort::ValueTooHigh,           // 0609 0031
                                           SdoAbort::ValueTooLow,            // 0609 0032
                                           SdoAbort::NoDataAvailable,        // 0800 0024
                                           SdoAbort::General,                // 0800 0000
                                           SdoAbort::CannotStoreOrTransfer)  // 0800 0020
);

// Not a refusal of the value: no answer (0504 0000 after the retries), or another abort, ends
// the update with I naming the step.
TEST(BootSlave, ReportsStatusIWhenClearTimesOutOrIsAbortedForAnotherReason) {
  for (const SdoAbort code : {SdoAbort::Timeout, SdoAbort::DeviceState}) {
    Rig rig;
    verify_software(rig, true);
    report_version(rig, kRunningProgram);
    stop_and_clear(rig, code);
    ASSERT_EQ(rig.port.reports.size(), 1U) << to_string(code);
    EXPECT_EQ(rig.port.reports[0].status, BootError::I);
    EXPECT_NE(boot_error_text(rig).find("1F51h sub 01h download failed: " + to_string(code)),
              std::string::npos)
        << boot_error_text(rig);
    EXPECT_TRUE(rig.events_of(Kind::ProgramClearRefused).empty()) << "a failure, not a refusal";
  }
}

// DSP 302 §9: "If the download fails, the Device responds with an Abort SDO Transfer (error code
// 0606 0000h)"; CiA 302-2 Table 1 I: the update failed. The abort in words.
TEST(BootSlave, ReportsStatusIWhenTheDeviceAborts1F50hWith06060000) {
  Rig rig;
  verify_software(rig, true);
  report_version(rig, kRunningProgram);
  stop_and_clear(rig);
  expect_access(rig.last(), 0x1F50, 1, false, *rig.port.image);
  rig.abort(SdoAbort::HardwareError);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::I);
  EXPECT_NE(boot_error_text(rig).find("1F50h sub 01h download failed: 0x06060000 (access failed "
                                      "due to a hardware error)"),
            std::string::npos)
      << boot_error_text(rig);
  EXPECT_EQ(rig.port.accesses.size(), 6U) << "no start after the failed download";
}

// A transfer the master's SDO client refused to start (SdoClient::check_start: an image longer
// than the 32-bit size of CiA 301 §7.2.4.3.3) ends the update with I (Table 1) in the client's
// words, not with an abort code no device sent.
TEST(BootSlave, ReportsStatusIInTheClientsWordsWhenTheImageDownloadCouldNotStart) {
  Rig rig;
  verify_software(rig, true);
  report_version(rig, kRunningProgram);
  stop_and_clear(rig);
  expect_access(rig.last(), 0x1F50, 1, false, *rig.port.image);
  SdoResult r;
  r.node_id = cfg::NodeId::from(kNode);
  r.address = {0x1F50, 1};
  r.refusal = "a value of 4294967296 bytes is longer than an SDO download can state";
  ASSERT_FALSE(r.ok());
  rig.process.on_sdo_result(r, rig.now, rig.out);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::I);
  EXPECT_NE(boot_error_text(rig).find("1F50h sub 01h download could not start: a value of "
                                      "4294967296 bytes is longer than an SDO download can state"),
            std::string::npos)
      << boot_error_text(rig);
  EXPECT_EQ(boot_error_text(rig).find("0x"), std::string::npos) << "no abort code";
}

// §3.4 part 2 b: "In case the software version will stay incorrect the process Boot NMT slave
// shall end with error status" (I, Table 1).
TEST(BootSlave, ReportsStatusIWhenTheVersionIsStillWrongAfterTheUpdate) {
  Rig rig;
  verify_software(rig, true);
  report_version(rig, kRunningProgram);
  stop_and_clear(rig);
  rig.answer();  // 1F50h
  rig.answer();  // start
  rig.answer(kRunningProgram.date_days);
  rig.answer(kRunningProgram.time_ms);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::I);
  EXPECT_NE(boot_error_text(rig).find("after the program download 1F52h reports"),
            std::string::npos)
      << boot_error_text(rig);
  const auto error = rig.events_of(Kind::BootError).back();
  ASSERT_TRUE(error.program.has_value());
  EXPECT_EQ(error.program->before, kRunningProgram);
  EXPECT_EQ(error.program->after, kRunningProgram);
  std::size_t images = 0;
  for (const auto& a : rig.port.accesses) images += a.index == 0x1F50 ? 1 : 0;
  EXPECT_EQ(images, 1U) << "one update per try";
}

// Table 1 H: the version differs and 1F81h bit 6 does not allow the update: no program access.
TEST(BootSlave, ReportsStatusHWhenTheVersionDiffersAndBit6IsClear) {
  Rig rig;
  verify_software(rig, false);
  report_version(rig, kRunningProgram);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::H);
  EXPECT_EQ(rig.port.accesses.size(), 3U);  // 1000h, 1F52h sub 1 and 2
  EXPECT_NE(boot_error_text(rig).find("1F81h bit 6 does not allow an update"), std::string::npos)
      << boot_error_text(rig);
}

// Table 1 G: bit 5 set, 1F53h/1F54h not configured (0): 1F52h is not even read.
TEST(BootSlave, ReportsStatusGWhenBit5IsSetWithoutAnExpectedVersion) {
  Rig rig;
  verify_software(rig, true);
  rig.port.expect.software = {};
  rig.process.start(rig.now, rig.out);
  rig.answer(0);  // 1000h
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::G);
  EXPECT_EQ(rig.port.accesses.size(), 1U);
}

// --- CiA 302-3 software identification (1F55h/1F56h/1F57h), as lely-core's master checks and
// updates it (src/co/nmt_boot.c): chosen per node by a non-zero 1F55h sub node-ID.

constexpr std::uint32_t kExpectedId = 0x5EC0'0002;  // 1F55h sub 5
constexpr std::uint32_t kRunningId = 0x5EC0'0001;   // what 1F56h sub 1 reports first

/// 1F81h bit 5 (and 6), 1F55h sub 5 set and no 1F53h/1F54h, a 300-byte image.
void verify_identification(Rig& rig, bool update) {
  verify_software(rig, update);
  rig.port.expect.software = {};
  rig.port.expect.software_identification = kExpectedId;
}

/// Starts the try, answers 1000h, then 1F56h sub 1 with `id`.
void report_identification(Rig& rig, std::uint32_t id) {
  rig.process.start(rig.now, rig.out);
  rig.answer(0);  // 1000h
  expect_access(rig.last(), 0x1F56, 1, true);
  EXPECT_EQ(rig.process.step(), BootStep::CheckSoftware);
  rig.answer(id);
}

/// The update up to the flash status read: stop, clear and the image answered.
void download_image(Rig& rig) {
  stop_and_clear(rig);
  expect_access(rig.last(), 0x1F50, 1, false, *rig.port.image);
  rig.answer();
  expect_access(rig.last(), 0x1F57, 1, true);  // flash status, CiA 302-3
}

TEST(BootSlave, Cia302_3MatchingSoftwareIdentificationGoesOnToCheckConfiguration) {
  Rig rig;
  verify_identification(rig, true);
  report_identification(rig, kExpectedId);
  // 1000h and 1F56h sub 1, no 1F52h; no configuration to check here: booted.
  EXPECT_EQ(rig.port.accesses.size(), 2U);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  EXPECT_TRUE(rig.process.booted());
}

TEST(BootSlave, Cia302_3UpdateWaitsForTheFlashStatusThenStartsAndReadsTheIdentificationAgain) {
  Rig rig;
  verify_identification(rig, true);
  report_identification(rig, kRunningId);
  download_image(rig);
  rig.answer(0x1);  // bit 0: in progress
  const auto reads = rig.port.accesses.size();
  rig.advance(99ms);
  EXPECT_EQ(rig.port.accesses.size(), reads) << "read again only after 100 ms";
  rig.advance(1ms);
  ASSERT_EQ(rig.port.accesses.size(), reads + 1);
  expect_access(rig.last(), 0x1F57, 1, true);
  rig.answer(0x0);                                   // done, no error
  expect_access(rig.last(), 0x1F51, 1, false, {1});  // start
  rig.answer();
  expect_access(rig.last(), 0x1F56, 1, true);  // identification again
  rig.answer(kExpectedId);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, std::nullopt);
  const auto booted = rig.events_of(Kind::SlaveBooted);
  ASSERT_EQ(booted.size(), 1U);
  ASSERT_TRUE(booted[0].program.has_value());
  EXPECT_EQ(booted[0].program->identification_before, kRunningId);
  EXPECT_EQ(booted[0].program->identification_after, kExpectedId);
  EXPECT_EQ(booted[0].program->bytes, 300U);
  EXPECT_NE(describe(booted[0]).find("; program updated from software identification 0x5EC00001 "
                                     "to 0x5EC00002, 300 bytes"),
            std::string::npos)
      << describe(booted[0]);
}

// lely-core's list of flash status values: bits 1-7 = 5 is "flash write error".
TEST(BootSlave, ReportsStatusIWhenTheFlashStatusReportsAnError) {
  Rig rig;
  verify_identification(rig, true);
  report_identification(rig, kRunningId);
  download_image(rig);
  rig.answer(5U << 1);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::I);
  const auto errors = rig.events_of(Kind::BootError);
  ASSERT_EQ(errors.size(), 1U);
  ASSERT_TRUE(errors[0].failure.has_value());
  EXPECT_EQ(errors[0].failure->reason, BootFailure::Reason::FlashStatusError);
  EXPECT_EQ(errors[0].failure->actual, 5U << 1);
  EXPECT_NE(
      boot_error_text(rig).find("1F57h sub 1 (flash status) is 0x0000000A: flash write error"),
      std::string::npos)
      << boot_error_text(rig);
}

TEST(BootSlave, ReportsStatusIWhenTheFlashStatusStaysInProgressBeyondTheProgramDataTimeout) {
  Rig rig;
  verify_identification(rig, true);
  report_identification(rig, kRunningId);
  download_image(rig);
  const auto image_done = rig.now;
  while (rig.port.reports.empty() && rig.now - image_done < 2 * rig.options.program_data_timeout) {
    rig.answer(0x1);
    rig.advance(100ms);
  }
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::I);
  EXPECT_GE(rig.now - image_done, rig.options.program_data_timeout);
  EXPECT_LT(rig.now - image_done, rig.options.program_data_timeout + 200ms);
  const auto errors = rig.events_of(Kind::BootError);
  ASSERT_EQ(errors.size(), 1U);
  EXPECT_EQ(errors[0].failure->reason, BootFailure::Reason::FlashNeverReady);
}

// CiA 302-3 makes 1F57h optional: a device without it is started, and 1F56h decides.
TEST(BootSlave, Cia302_3DeviceWithoutFlashStatusIsStartedAndCheckedBy1F56h) {
  Rig rig;
  verify_identification(rig, true);
  report_identification(rig, kRunningId);
  download_image(rig);
  rig.abort(SdoAbort::ObjectDoesNotExist);
  expect_access(rig.last(), 0x1F51, 1, false, {1});
  rig.answer();
  expect_access(rig.last(), 0x1F56, 1, true);
  rig.answer(kRunningId);  // the image did not take
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::I);
  EXPECT_NE(boot_error_text(rig).find("1F56h sub 1 reports software identification 0x5EC00001, "
                                      "1F55h expects 0x5EC00002"),
            std::string::npos)
      << boot_error_text(rig);
}

TEST(BootSlave, Cia302_3ReportsStatusHWhenTheIdentificationDiffersAndBit6IsClear) {
  Rig rig;
  verify_identification(rig, false);
  report_identification(rig, kRunningId);
  ASSERT_EQ(rig.port.reports.size(), 1U);
  EXPECT_EQ(rig.port.reports[0].status, BootError::H);
  const auto errors = rig.events_of(Kind::BootError);
  ASSERT_EQ(errors.size(), 1U);
  EXPECT_EQ(errors[0].failure->object, (cfg::ObjectAddress{0x1F56, 1}));
  EXPECT_EQ(errors[0].failure->actual, kRunningId);
  EXPECT_EQ(errors[0].failure->expected_by, 0x1F55);
  EXPECT_EQ(errors[0].failure->expected, kExpectedId);
}

// The start-up's reset of all nodes while the try waits to read 1F57h again: the wait ends with
// the try, and the next try begins at 1000h.
TEST(BootSlave, Cia302_3ResetDuringTheFlashStatusWaitEndsTheWait) {
  Rig rig;
  verify_identification(rig, true);
  report_identification(rig, kRunningId);
  download_image(rig);
  rig.answer(0x1);  // in progress: read again in 100 ms
  EXPECT_EQ(rig.process.next_deadline(), rig.now + 100ms);
  rig.process.reset(rig.now);
  EXPECT_EQ(rig.process.next_deadline(), std::nullopt);
  const auto reads = rig.port.accesses.size();
  rig.advance(200ms);
  EXPECT_EQ(rig.port.accesses.size(), reads) << "no 1F57h read after the reset";
  rig.process.start(rig.now, rig.out);
  expect_access(rig.last(), 0x1000, 0, true);
}

}  // namespace
}  // namespace nmt
