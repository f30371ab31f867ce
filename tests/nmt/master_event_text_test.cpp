// describe(MasterEvent) (nmt/master/master_event_text.hpp): the words a person reads are made from
// the event's typed fields alone. The status texts are CiA 302-2 §3.8 Table 1's; the SDO abort
// texts CiA 301 §7.2.4.3.17's; the LSS error code CiA 305 §8.3.1's.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "nmt/master/master_event_text.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using Kind = MasterEvent::Kind;

constexpr cfg::NodeId node(std::uint8_t id) {
  return *cfg::NodeId::from(id);
}

MasterEvent event(Kind kind, std::optional<cfg::NodeId> about = std::nullopt) {
  MasterEvent e{kind};
  e.node_id = about;
  return e;
}

TEST(MasterEventText, BootErrorCSaysTable1AndTheValuesCompared) {
  auto e = event(Kind::BootError, node(3));
  e.error = BootError::C;
  e.failure = BootFailure{.reason = BootFailure::Reason::ValueDiffers,
                          .object = {0x1000, 0},
                          .actual = 0x00020191,
                          .expected_by = 0x1F84,
                          .expected = 0x00020192};
  EXPECT_EQ(describe(e),
            "node 3: boot error C: value of object 1000h differs from object 1F84h (device type) "
            "(1000h is 0x00020191, 1F84h expects 0x00020192)");
  EXPECT_EQ(describe_boot_error(e),
            "value of object 1000h differs from object 1F84h (device type) (1000h is "
            "0x00020191, 1F84h expects 0x00020192)");
}

TEST(MasterEventText, BootErrorNNamesTheIdentityObjects) {
  auto e = event(Kind::BootError, node(5));
  e.error = BootError::N;
  e.failure = BootFailure{.reason = BootFailure::Reason::ValueDiffers,
                          .object = {0x1018, 3},
                          .actual = 0x00010000,
                          .expected_by = 0x1F87,
                          .expected = 0x00020000};
  EXPECT_EQ(describe(e),
            "node 5: boot error N: value of object 1018h sub 03h differs from object 1F87h "
            "(revision number) (1018h sub 03h is 0x00010000, 1F87h expects 0x00020000)");
}

TEST(MasterEventText, FinalBootErrorBSaysTheAbortAndTheBootTime) {
  auto e = event(Kind::BootError, node(2));
  e.error = BootError::B;
  e.final = true;
  SdoResult r;
  r.address = {0x1000, 0};
  r.upload = true;
  r.abort = SdoAbort::Timeout;
  e.failure = BootFailure{
      .reason = BootFailure::Reason::TransferFailed, .transfer = r, .boot_time_ms = 3000};
  EXPECT_EQ(describe(e),
            "node 2: boot error B: no response received for upload request of object 1000h "
            "(1000h sub 00h upload failed: 0x05040000 (SDO protocol timed out)); boot time 1F89h "
            "(3000 ms) elapsed");
}

TEST(MasterEventText, BootErrorJOfAWriteSaysTheEntry) {
  auto e = event(Kind::BootError, node(5));
  e.error = BootError::J;
  SdoResult r;
  r.address = {0x2001, 0};
  r.abort = SdoAbort::WriteOfReadOnly;
  e.failure = BootFailure{
      .reason = BootFailure::Reason::WriteFailed, .transfer = r, .entry = 2, .entries = 2};
  EXPECT_EQ(describe(e),
            "node 5: boot error J: configuration download failed (2001h sub 00h download failed: "
            "0x06010002 (attempt to write a read only object) (entry 2 of 2))");
}

TEST(MasterEventText, StartupHaltedNamesEveryMandatorySlaveAndItsLetter) {
  auto e = event(Kind::StartupHalted, node(2));
  e.halted_by = {{node(2), BootError::B}, {node(3), BootError::C}};
  EXPECT_EQ(describe(e),
            "NMT start-up halted: mandatory node 2 failed with status B (no response received for "
            "upload request of object 1000h), node 3 with status C (value of object 1000h "
            "differs from object 1F84h (device type))");
}

TEST(MasterEventText, NmtCommandsAndStates) {
  auto all = event(Kind::NmtCommandSent);
  all.command = NmtCommand::Start;
  EXPECT_EQ(describe(all), "start all nodes");
  auto one = event(Kind::NmtCommandSent, node(7));
  one.command = NmtCommand::ResetNode;
  EXPECT_EQ(describe(one), std::string(to_string(NmtCommand::ResetNode)) + " node 7");
  auto missing = event(Kind::SlaveStateChanged, node(3));
  missing.missing = true;
  EXPECT_EQ(describe(missing), "node 3: missing");
  EXPECT_EQ(describe(event(Kind::SlaveStateChanged, node(3))), "node 3: state unknown");
  auto resolved = event(Kind::ErrorControlResolved, node(4));
  resolved.heartbeat = true;
  EXPECT_EQ(describe(resolved), "node 4: heartbeat received again");
  auto not_master = event(Kind::NotMaster);
  not_master.nmt_startup = 0x00000008;
  EXPECT_EQ(describe(not_master), "1F80h is 0x00000008: not the NMT master");
}

TEST(MasterEventText, FlyingMasterStandbySaysWhyAndTheWatch) {
  auto e = event(Kind::Standby, node(5));
  e.priority = 0;
  e.flying = MasterEvent::FlyingMaster{
      .reason = FlyingMasterReason::HigherPriority, .own_priority = 1, .watch = 300ms};
  EXPECT_EQ(describe(e),
            "node 5 is the active NMT master (priority 0): a higher priority level than ours "
            "(priority 1); watching its heartbeat (300 ms)");
  e.flying->watch.reset();
  e.flying->reason = FlyingMasterReason::SamePriority;
  e.priority = 1;
  EXPECT_EQ(describe(e),
            "node 5 is the active NMT master (priority 1): the same priority level as ours "
            "(priority 1); its heartbeat is not watched (no 1016h entry, 1017h is 0)");
}

TEST(MasterEventText, FlyingMasterNegotiationAfterPowerOn) {
  auto e = event(Kind::NegotiationBegan, node(1));
  e.flying = MasterEvent::FlyingMaster{.reason = FlyingMasterReason::NoActiveMasterAfterPowerOn,
                                       .timeout = 100ms};
  EXPECT_EQ(describe(e),
            "no active master answered within 100 ms after power-on: reset communication of all "
            "nodes");
}

TEST(MasterEventText, LssSaysWhatWasStoredOrWhyNot) {
  const LssAddress address{0x7E57C0DE, 0x508, 0x20001, 0x999};
  auto stored = event(Kind::LssAssigned, node(5));
  stored.lss_address = address;
  stored.lss = MasterEvent::Lss{.outcome = LssScanOutcome::Stored};
  EXPECT_EQ(describe(stored), "node 5: LSS: " + to_string(address) + " got node-ID 5, stored");
  auto refused = event(Kind::LssFailed, node(5));
  refused.lss_address = address;
  refused.lss = MasterEvent::Lss{.outcome = LssScanOutcome::ConfigureRefused, .error_code = 1};
  EXPECT_EQ(describe(refused), "node 5: LSS: " + to_string(address) +
                                   " left unconfigured: configure node-ID refused: node-ID out "
                                   "of range (error code 1)");
  auto unmatched = event(Kind::LssUnmatched);
  unmatched.lss_address = address;
  EXPECT_EQ(describe(unmatched),
            "LSS: unconfigured device 7E57C0DE:00000508:00020001:00000999 matches no slave: left "
            "unconfigured");
  auto ended = event(Kind::LssScanEnded);
  ended.lss_scan = MasterEvent::LssScan{.found = 1, .assigned = 1};
  EXPECT_EQ(describe(ended), "LSS: 1 unconfigured device found, 1 given a node-ID");
}

TEST(MasterEventText, SdoManagerSaysWhy) {
  auto lost = event(Kind::SrdLost, node(4));
  lost.manager_reason = {.kind = SdoManagerReason::Kind::SrdLost, .node = node(4)};
  lost.released = 2;
  EXPECT_EQ(describe(lost), "node 4: SRD lost, releasing 2 SDO connection(s)");
  auto refused = event(Kind::SdoConnectionRefused, node(4));
  refused.connection = ManagedSdoConnection{.srd = node(4), .server = node(3)};
  refused.connection_error = cfg::sdo_manager::DynamicSdoError::kSlaveNotAvailable;
  refused.manager_reason = {.kind = SdoManagerReason::Kind::SlaveDoesNotAnswer, .node = node(3)};
  EXPECT_EQ(describe(refused), "node 4: SDO connection to node 3 refused, error 0x04 (" +
                                   std::string(cfg::sdo_manager::describe(
                                       cfg::sdo_manager::DynamicSdoError::kSlaveNotAvailable)) +
                                   "): node 3 does not answer");
}

// Every kind has words: a log line is never empty.
TEST(MasterEventText, EveryKindHasALine) {
  for (int k = 0; k <= static_cast<int>(Kind::ProgramClearRefused); ++k) {
    EXPECT_FALSE(describe(event(static_cast<Kind>(k), node(1))).empty()) << k;
  }
}

}  // namespace
}  // namespace nmt
