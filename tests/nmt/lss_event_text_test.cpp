// describe() of the LSS engines' events (nmt/lss/lss_event_text.hpp): the words made from the
// typed fields, exact. The error codes' meanings are CiA 305's as nmt/lss/lss.hpp cites them
// (CANopenNode 305/CO_LSS.h): configure node-ID 1 node-ID out of range; configure bit timing 1
// bit rate not supported; store configuration 1 not supported, 2 storage media access error;
// FFh manufacturer-specific with the manufacturer's code in byte 2; others reserved.
#include "nmt/lss/lss_event_text.hpp"

#include <gtest/gtest.h>

#include <chrono>

namespace nmt {
namespace {

using namespace std::chrono_literals;
using ServiceKind = LssMasterEvent::Kind;
using Kind = LssProcedureEvent::Kind;

// tests/data/lss/lss_io.eds: 1018h vendor 7E57C0DEh, product 305h, revision 10002h, serial 1001h.
const LssAddress kDevice{0x7E57C0DE, 0x00000305, 0x00010002, 0x00001001};
const std::string kDeviceWords =
    "vendor 7E57C0DEh product 00000305h revision 00010002h serial 00001001h";

LssMasterEvent service(LssService s, ServiceKind kind) {
  LssMasterEvent e;
  e.service = s;
  e.kind = kind;
  return e;
}

LssMasterEvent refused(LssService s, std::uint8_t error_code, std::uint8_t spec_error = 0) {
  auto e = service(s, ServiceKind::Refused);
  e.error_code = error_code;
  e.spec_error = spec_error;
  return e;
}

LssMasterEvent unanswered(LssService s, Duration timeout) {
  auto e = service(s, ServiceKind::Timeout);
  e.timeout = timeout;
  return e;
}

TEST(LssMasterEventWords, NameEachRefusalByItsServicesCiA305ErrorCode) {
  EXPECT_EQ(describe(refused(LssService::ConfigureNodeId, 1)),
            "configure node-ID: refused: node-ID out of range (error code 1)");
  EXPECT_EQ(describe(refused(LssService::ConfigureBitTiming, 1)),
            "configure bit timing: refused: bit rate not supported (error code 1)");
  EXPECT_EQ(describe(refused(LssService::StoreConfiguration, 1)),
            "store configuration: refused: store configuration not supported (error code 1)");
  EXPECT_EQ(describe(refused(LssService::StoreConfiguration, 2)),
            "store configuration: refused: storage media access error (error code 2)");
  EXPECT_EQ(describe(refused(LssService::ConfigureNodeId, 0xFF, 0x33)),
            "configure node-ID: refused: manufacturer-specific error 33h (error code 255)");
  // Error code 2 is store configuration's alone; for configure node-ID it is reserved.
  EXPECT_EQ(describe(refused(LssService::ConfigureNodeId, 2)),
            "configure node-ID: refused: reserved error code (error code 2)");
}

TEST(LssMasterEventWords, SayHowLongAnUnansweredServiceWasWaitedFor) {
  EXPECT_EQ(describe(unanswered(LssService::SwitchStateSelective, 250ms)),
            "switch state selective: no answer within 250 ms");
  EXPECT_EQ(describe(unanswered(LssService::StoreConfiguration, 100ms)),
            "store configuration: no answer within 100 ms");
}

TEST(LssMasterEventWords, TellTheFastscanEndsApart) {
  auto stopped = service(LssService::Fastscan, ServiceKind::Timeout);
  stopped.part = 2;
  EXPECT_EQ(describe(stopped), "Fastscan: the device stopped answering (part 2)");
  EXPECT_EQ(describe(service(LssService::Fastscan, ServiceKind::NotFound)),
            "Fastscan: no unconfigured device answered");
  auto none_above = service(LssService::Fastscan, ServiceKind::NotFound);
  none_above.after = kDevice;
  EXPECT_EQ(describe(none_above), "Fastscan: no unconfigured device above " + kDeviceWords);
  auto absent = service(LssService::Fastscan, ServiceKind::Absent);
  absent.address = kDevice;
  EXPECT_EQ(describe(absent), "Fastscan: no device " + kDeviceWords + " unconfigured");
  auto found = service(LssService::Fastscan, ServiceKind::Done);
  found.address = kDevice;
  EXPECT_EQ(describe(found), "Fastscan: found " + kDeviceWords);
}

TEST(LssMasterEventWords, GiveTheValueOfWhatWasDone) {
  auto global = service(LssService::SwitchStateGlobal, ServiceKind::Done);
  global.state = LssState::Configuration;
  EXPECT_EQ(describe(global), "switch state global: all devices to LSS configuration");
  auto vendor = service(LssService::InquireVendorId, ServiceKind::Done);
  vendor.value = 0x7E57C0DE;
  EXPECT_EQ(describe(vendor), "inquire vendor-ID: 7E57C0DEh");
  auto node_id = service(LssService::InquireNodeId, ServiceKind::Done);
  node_id.value = 5;
  EXPECT_EQ(describe(node_id), "inquire node-ID: node-ID 5");
  EXPECT_EQ(describe(service(LssService::IdentifyNonConfigured, ServiceKind::NotFound)),
            "identify non-configured remote slave: no device answered");
}

LssProcedureEvent scan_device(Kind kind, LssScanOutcome outcome) {
  LssProcedureEvent e;
  e.procedure = LssProcedureKind::Scan;
  e.kind = kind;
  e.address = kDevice;
  e.outcome = outcome;
  if (kind == Kind::Assigned) e.node_id = cfg::NodeId::from(5);
  return e;
}

TEST(LssProcedureEventWords, SayWhatBecameOfAScannedDevice) {
  EXPECT_EQ(describe(scan_device(Kind::Assigned, LssScanOutcome::Stored)),
            "scan: " + kDeviceWords + " got node-ID 5, stored");
  auto store_refused = scan_device(Kind::Assigned, LssScanOutcome::StoreRefused);
  store_refused.error_code = 2;
  store_refused.step = refused(LssService::StoreConfiguration, 2);
  EXPECT_EQ(describe(store_refused),
            "scan: " + kDeviceWords +
                " got node-ID 5, not stored: store configuration refused: storage media access "
                "error (error code 2)");
  auto configure_unanswered = scan_device(Kind::Skipped, LssScanOutcome::ConfigureUnanswered);
  configure_unanswered.step = unanswered(LssService::ConfigureNodeId, 100ms);
  EXPECT_EQ(describe(configure_unanswered),
            "scan: " + kDeviceWords +
                " left unconfigured: configure node-ID: no answer within "
                "100 ms");
  EXPECT_EQ(describe(scan_device(Kind::Skipped, LssScanOutcome::Duplicate)),
            "scan: " + kDeviceWords +
                " left unconfigured: more than one device answered configure node-ID with this "
                "LSS address (CiA 305 takes LSS addresses to be unique)");
}

TEST(LssProcedureEventWords, FailedGivesTheServicesWordsAndAFastscansUnderTheProcedure) {
  LssProcedureEvent failed;
  failed.procedure = LssProcedureKind::AssignNodeId;
  failed.kind = Kind::Failed;
  failed.step = refused(LssService::ConfigureNodeId, 1);
  EXPECT_EQ(describe(failed), "configure node-ID: refused: node-ID out of range (error code 1)");
  failed.procedure = LssProcedureKind::FindUnconfigured;
  failed.step = service(LssService::Fastscan, ServiceKind::Timeout);
  failed.step->part = 1;
  EXPECT_EQ(describe(failed), "find unconfigured devices: the device stopped answering (part 1)");
  // Inquire node-ID answered with 0, no node-ID (CiA 305: 1..127, FFh not configured).
  failed.procedure = LssProcedureKind::InquireNodeId;
  failed.step = service(LssService::InquireNodeId, ServiceKind::Done);
  EXPECT_EQ(describe(failed),
            "inquire node-ID answered 0: no node-ID (CiA 305: 1..127, or 255 for not configured)");
  failed.procedure = LssProcedureKind::Scan;
  failed.step.reset();
  EXPECT_EQ(describe(failed), "scan: could not start");
}

TEST(LssProcedureEventWords, DoneSaysWhatTheProcedureFoundOrGave) {
  LssProcedureEvent done;
  done.kind = Kind::Done;
  done.procedure = LssProcedureKind::AssignNodeId;
  done.address = kDevice;
  done.outcome = LssScanOutcome::NotStoredAsAsked;  // node-ID nullopt: FFh, not configured
  EXPECT_EQ(describe(done),
            "assign node-ID: " + kDeviceWords + " node-ID 255, not stored (as asked)");
  done.procedure = LssProcedureKind::FindUnconfigured;
  done.found = 3;
  EXPECT_EQ(describe(done), "find unconfigured devices: 3 unconfigured devices found");
  done.procedure = LssProcedureKind::SetBitRate;
  EXPECT_EQ(describe(done), "activate bit timing: devices switched after twice the switch delay");
}

}  // namespace
}  // namespace nmt
