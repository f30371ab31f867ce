// The texts of the NMT master: the error status of CiA 302-2 §3.8 (Table 1) in words, the names
// of the boot steps, start-up states and event kinds (nmt/master/nmt_master.hpp), and the event
// helpers of master_text.hpp.
#include "master/master_text.hpp"

#include <utility>

namespace nmt {

std::string_view describe(BootError error) {
  // CiA 302-2 §3.8, Table 1.
  switch (error) {
    case BootError::A:
      return "the device is not listed in object 1F81h";
    case BootError::B:
      return "no response received for upload request of object 1000h";
    case BootError::C:
      return "value of object 1000h differs from object 1F84h (device type)";
    case BootError::D:
      return "value of object 1018h sub 01h differs from object 1F85h (vendor-ID)";
    case BootError::E:
      return "heartbeat event: no heartbeat message received from the device";
    case BootError::F:
      return "node guarding event: no confirmation for the guarding request";
    case BootError::G:
      return "objects for program download are not configured or inconsistent";
    case BootError::H:
      return "software update is required, but not allowed because of configuration or status";
    case BootError::I:
      return "software update is required, but program download failed";
    case BootError::J:
      return "configuration download failed";
    case BootError::K:
      return "heartbeat event during start error control: no heartbeat message received";
    case BootError::L:
      return "NMT slave was initially operational";
    case BootError::M:
      return "value of object 1018h sub 02h differs from object 1F86h (product code)";
    case BootError::N:
      return "value of object 1018h sub 03h differs from object 1F87h (revision number)";
    case BootError::O:
      return "value of object 1018h sub 04h differs from object 1F88h (serial number)";
  }
  return "unknown error status";
}

std::string_view to_string(BootStep step) {
  switch (step) {
    case BootStep::Idle:
      return "idle";
    case BootStep::AwaitBootUp:
      return "waiting for boot-up";
    case BootStep::Identify:
      return "identify";
    case BootStep::CheckNmtState:
      return "check NMT state";
    case BootStep::CheckSoftware:
      return "check software version";
    case BootStep::UpdateSoftware:
      return "software update";
    case BootStep::VerifyConfiguration:
      return "verify configuration";
    case BootStep::Restore:
      return "restore";
    case BootStep::Download:
      return "download";
    case BootStep::Save:
      return "save";
    case BootStep::ApplicationStep:
      return "application step";
    case BootStep::StartErrorControl:
      return "start error control";
    case BootStep::Booted:
      return "booted";
    case BootStep::Failed:
      return "failed";
    case BootStep::RetryWait:
      return "waiting to retry";
  }
  return "?";
}

std::string_view to_string(StartupState state) {
  switch (state) {
    case StartupState::Off:
      return "off";
    case StartupState::NotMaster:
      return "not master";
    case StartupState::Negotiating:
      return "negotiating";
    case StartupState::Standby:
      return "standby";
    case StartupState::BootingSlaves:
      return "booting slaves";
    case StartupState::Halted:
      return "halted";
    case StartupState::AwaitApplication:
      return "waiting for the application";
    case StartupState::Operational:
      return "operational";
    case StartupState::ExecutingLss:
      return "executing LSS";
  }
  return "?";
}

std::string_view to_string(MasterEvent::Kind kind) {
  using K = MasterEvent::Kind;
  switch (kind) {
    case K::NotMaster:
      return "not_master";
    case K::StartupBegan:
      return "startup_began";
    case K::BootStepChanged:
      return "boot_step";
    case K::SlaveBooted:
      return "slave_booted";
    case K::BootError:
      return "boot_error";
    case K::StartupHalted:
      return "startup_halted";
    case K::StartupAwaitsApplication:
      return "startup_awaits_application";
    case K::StartupComplete:
      return "startup_complete";
    case K::MasterStateChanged:
      return "master_state";
    case K::SlaveStateChanged:
      return "slave_state";
    case K::HeartbeatLost:
      return "heartbeat_lost";
    case K::GuardingLost:
      return "guarding_lost";
    case K::ErrorControlResolved:
      return "error_control_resolved";
    case K::BootUp:
      return "boot_up";
    case K::NmtCommandSent:
      return "nmt_command";
    case K::ApplicationStep:
      return "application_step";
    case K::ProgramProgress:
      return "program_progress";
    case K::SdoFinished:
      return "sdo_finished";
    case K::NegotiationBegan:
      return "negotiation_began";
    case K::ActiveMaster:
      return "active_master";
    case K::Standby:
      return "standby";
    case K::ForceNegotiation:
      return "force_negotiation";
    case K::MultipleMasters:
      return "multiple_masters";
    case K::ActiveMasterLost:
      return "active_master_lost";
    case K::MasterDetection:
      return "master_detection";
    case K::SrdRegistered:
      return "srd_registered";
    case K::SrdRegistrationFailed:
      return "srd_registration_failed";
    case K::SdoConnectionEstablished:
      return "sdo_connection_established";
    case K::SdoConnectionRefused:
      return "sdo_connection_refused";
    case K::SdoConnectionReleased:
      return "sdo_connection_released";
    case K::SrdLost:
      return "srd_lost";
    case K::SrdDeregistered:
      return "srd_deregistered";
    case K::SlaveFailedReported:
      return "slave_failed_reported";
    case K::PersistEntry:
      return "persist_entry";
    case K::LssAssigned:
      return "lss_assigned";
    case K::LssUnmatched:
      return "lss_unmatched";
    case K::LssFailed:
      return "lss_failed";
    case K::LssScanEnded:
      return "lss_scan_ended";
    case K::ProgramClearRefused:
      return "program_clear_refused";
    case K::Emergency:
      return "emergency";
    case K::EmergencyFlood:
      return "emergency_flood";
  }
  return "?";
}

std::string node_text(cfg::NodeId node) {
  return "node " + std::to_string(node.value());
}

MasterEvent master_event(MasterEvent::Kind kind, TimePoint at, std::optional<cfg::NodeId> node) {
  MasterEvent e{kind};
  e.at = at;
  e.node_id = node;
  return e;
}

}  // namespace nmt
