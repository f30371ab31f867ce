// describe(MasterEvent) (nmt/master/master_event_text.hpp): the one place where the NMT master's
// events become words. The engine reports typed values; these are the sentences the tools print.
#include "nmt/master/master_event_text.hpp"

#include <chrono>
#include <string>

#include "cfg/config_manager.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/sdo_abort.hpp"
#include "master/master_text.hpp"
#include "nmt/lss/lss_event_text.hpp"
#include "nmt/protocol/emcy_text.hpp"

namespace nmt {

namespace {

namespace sm = cfg::sdo_manager;
using Kind = MasterEvent::Kind;
using Reason = BootFailure::Reason;

std::string node_words(const std::optional<cfg::NodeId>& node) {
  return node ? node_text(*node) : std::string("node 0");
}

std::string ms_words(Duration d) {
  return std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(d).count()) + " ms";
}

std::string priority_words(std::uint16_t priority) {
  return "priority " + std::to_string(priority);
}

std::string cob_words(cfg::CobId id) {
  return cfg::hex(id.can_id().id, 3);
}

std::string connection_words(const ManagedSdoConnection& c) {
  // Raw node-IDs: a connection row holds the bytes written to 1F10h/1F12h (0: none yet).
  return "node " + std::to_string(c.srd) + " " + cfg::object_name(c.client_index) + " -> node " +
         std::to_string(c.server) + " " + cfg::object_name(c.server_index) + " (COB-IDs " +
         cob_words(c.request) + "/" + cob_words(c.response) + ")";
}

std::string manager_reason_words(const SdoManagerReason& why) {
  using K = SdoManagerReason::Kind;
  const auto node = [&] { return node_words(why.node); };
  switch (why.kind) {
    case K::None:
      return "";
    case K::SlaveDoesNotAnswer:
      return node() + " does not answer";
    case K::NoFreeServerEntry:
      return node() + " has no free server SDO entry";
    case K::TransferFailed:
      return node() + ": " + (why.transfer ? describe_transfer_failure(*why.transfer) : "");
    case K::DefaultSdoInUse:
      return "a default SDO is in use";
    case K::NotAClientEntry:
      return "1F10h names " + cfg::object_name(why.index) + ", no client SDO entry";
    case K::NoFreeServerChannel:
      return "no free server channel on the manager";
    case K::NoFreeCobIds:
      return "no free COB-IDs in 1F02h";
    case K::NoTwoFreeCobIds:
      return "no two free COB-IDs in 1F02h";
    case K::Releases:
      return "1F01h: " + node() + " releases";
    case K::Deregisters:
      return "1F01h: " + node() + " de-registers";
    case K::SrdBootedUp:
      return node() + ": SRD booted up";
    case K::SrdLost:
      return node() + ": SRD lost";
    case K::SlaveFailed:
      return node() + " failed (error control)";
    case K::SlaveBootedUp:
      return node() + " booted up: its server entry is gone";
  }
  return "";
}

std::string flying_words(const MasterEvent& e) {
  using R = FlyingMasterReason;
  const MasterEvent::FlyingMaster f = e.flying.value_or(MasterEvent::FlyingMaster{});
  const std::string node = node_words(e.node_id);
  const std::string priority = priority_words(e.priority.value_or(0));
  const std::string own = priority_words(f.own_priority);
  switch (f.reason) {
    case R::PowerOn:
    case R::ResetCommunication:
      return std::string("flying master start-up after ") +
             (f.reason == R::ResetCommunication ? "a reset communication" : "power-on") +
             ": active master detection in " + ms_words(f.wait);
    case R::TriggerHeard:
      return "negotiation trigger (72h) heard: negotiation, waiting " + ms_words(f.wait);
    case R::NoActiveMaster:
      return "no active master answered within " + ms_words(f.timeout) + ": negotiation, waiting " +
             ms_words(f.wait);
    case R::NoActiveMasterAfterPowerOn:
      return "no active master answered within " + ms_words(f.timeout) +
             " after power-on: reset communication of all nodes";
    case R::NoBetterMaster:
      return "active NMT master: no better master answered within the waiting time (" + own + ")";
    case R::SamePriority:
    case R::HigherPriority:
    case R::WonAgainAfterForce: {
      std::string why =
          f.reason == R::WonAgainAfterForce
              ? std::string(
                    "worse than ours, but it won again after this device forced a "
                    "negotiation")
              : std::string(f.reason == R::SamePriority ? "the same priority level as ours"
                                                        : "a higher priority level than ours") +
                    " (" + own + ")";
      return node + " is the active NMT master (" + priority + "): " + why +
             (f.watch ? "; watching its heartbeat (" + ms_words(*f.watch) + ")"
                      : "; its heartbeat is not watched (no 1016h entry, 1017h is 0)");
    }
    case R::LowerPriority:
      return node + " is master with " + priority + ", lower than ours (" + own +
             "): force NMT flying master negotiation";
    case R::AnsweredToo:
      return node + " answered as active NMT master too (" + priority + "): forcing a negotiation";
    case R::ForceReceived:
      return "force NMT flying master negotiation (76h) received: another master is active or "
             "has a higher priority; reset communication of all nodes";
    case R::HeartbeatLost:
      return "heartbeat of the active NMT master " + node +
             " lost: reset communication of all nodes, negotiation";
    case R::CapableDeviceAnswered:
      return "an NMT master-capable device answered (74h): the network is left to the NMT "
             "master";
    case R::OtherStartedAllNodes:
      return "another device started all nodes first";
    case R::NoCapableDevice:
      return "no NMT master-capable device answered within " + ms_words(f.timeout) +
             ": start all nodes in " + ms_words(f.wait);
  }
  return "";
}

std::string lss_words(const MasterEvent& e) {
  const MasterEvent::Lss l = e.lss.value_or(MasterEvent::Lss{});
  const std::string address = e.lss_address ? to_string(*e.lss_address) : std::string();
  return address + " " + describe(l.outcome, e.node_id, l.error_code, l.spec_error, l.timeout);
}

std::string lss_scan_words(const MasterEvent& e) {
  using Stop = MasterEvent::LssScan::Stop;
  const MasterEvent::LssScan s = e.lss_scan.value_or(MasterEvent::LssScan{});
  std::string text = "LSS: " + std::to_string(s.found) + " unconfigured device" +
                     (s.found == 1 ? "" : "s") + " found, " + std::to_string(s.assigned) +
                     " given a node-ID";
  switch (s.stopped) {
    case Stop::None:
      break;
    case Stop::DeviceStoppedAnswering:
      text += " (scan ended early: scan: the device stopped answering (part " +
              std::to_string(s.part) + "))";
      break;
    case Stop::CouldNotStart:
      text += " (scan ended early: the scan could not start)";
      break;
  }
  return text;
}

std::string slave_booted_words(const MasterEvent& e, const std::string& node) {
  // A slave 1F81h bit 2 leaves to the application ends its boot at step Idle (CiA 302-2 §3.4 b).
  std::string text =
      node + ": booted" +
      (e.step == BootStep::Idle
           ? std::string(" and left to the application (1F81h bit 2 clear: no configuration, no "
                         "start)")
       : e.configured ? " (configured: " + std::to_string(e.total) + " entries, " +
                            std::to_string(e.bytes) + " bytes)"
       : e.no_configuration && e.node_id ? ", " + describe_no_configuration(*e.node_id)
                                         : " (configuration up to date)");
  if (e.program && e.program->after) {
    text += "; program updated from " + cfg::to_string(e.program->before) + " to " +
            cfg::to_string(*e.program->after) + ", " + std::to_string(e.program->bytes) + " bytes";
  }
  if (e.program && e.program->identification_after) {
    text += "; program updated from software identification " +
            cfg::hex(e.program->identification_before.value_or(0), 8) + " to " +
            cfg::hex(*e.program->identification_after, 8) + ", " +
            std::to_string(e.program->bytes) + " bytes";
  }
  return text;
}

/// CiA 302-3's flash status identification (1F57h sub 1), bits 1-7, in words (the list
/// lely-core's co_nmt_boot_wait_flash_on_up_con reports).
std::string flash_status_words(std::uint32_t value) {
  const auto status = (value >> 1) & 0x7FU;
  switch (status) {
    case 0:
      return "no error";
    case 1:
      return "no valid program available";
    case 2:
      return "data format unknown";
    case 3:
      return "data format error or data CRC error";
    case 4:
      return "flash not cleared before write";
    case 5:
      return "flash write error";
    case 6:
      return "general address error";
    case 7:
      return "flash secured (write access currently forbidden)";
    case 63:
      return "unspecified error";
    default:
      if (status > 63) {
        return "manufacturer-specific error " + cfg::hex((value >> 16) & 0xFFFFU, 4) + "h";
      }
      return "reserved status " + std::to_string(status);
  }
}

std::string software_words(const BootFailure& f) {
  if (f.expected_by == cfg::object::kExpectedSoftwareIdentification) {
    return "1F56h sub 1 reports software identification " + cfg::hex(f.actual, 8) +
           ", 1F55h expects " + cfg::hex(f.expected, 8);
  }
  return "1F52h reports " + cfg::to_string(f.software) + ", 1F53h/1F54h expect " +
         cfg::to_string(f.expected_software);
}

}  // namespace

std::string_view to_string(BootFailure::Reason reason) {
  switch (reason) {
    case BootFailure::Reason::NotListed:
      return "not_listed";
    case BootFailure::Reason::TransferFailed:
      return "transfer_failed";
    case BootFailure::Reason::ValueDiffers:
      return "value_differs";
    case BootFailure::Reason::NoExpectedSoftware:
      return "no_expected_software";
    case BootFailure::Reason::SoftwareDiffers:
      return "software_differs";
    case BootFailure::Reason::UpdateNotAllowed:
      return "update_not_allowed";
    case BootFailure::Reason::NoProgramImage:
      return "no_program_image";
    case BootFailure::Reason::SoftwareDiffersAfterUpdate:
      return "software_differs_after_update";
    case BootFailure::Reason::ProgramDownloadFailed:
      return "program_download_failed";
    case BootFailure::Reason::FlashStatusError:
      return "flash_status_error";
    case BootFailure::Reason::FlashNeverReady:
      return "flash_never_ready";
    case BootFailure::Reason::NoHeartbeat:
      return "no_heartbeat";
    case BootFailure::Reason::NoGuardingReply:
      return "no_guarding_reply";
    case BootFailure::Reason::NoConfigurationStored:
      return "no_configuration_stored";
    case BootFailure::Reason::RestoreFailed:
      return "restore_failed";
    case BootFailure::Reason::NoBootUpAfterRestore:
      return "no_boot_up_after_restore";
    case BootFailure::Reason::WriteFailed:
      return "write_failed";
    case BootFailure::Reason::SaveFailed:
      return "save_failed";
    case BootFailure::Reason::ApplicationStepFailed:
      return "application_step_failed";
    case BootFailure::Reason::NoFirstHeartbeat:
      return "no_first_heartbeat";
    case BootFailure::Reason::KeptAlive:
      return "kept_alive";
  }
  return "?";
}

std::string_view to_string(FlyingMasterReason reason) {
  switch (reason) {
    case FlyingMasterReason::PowerOn:
      return "power_on";
    case FlyingMasterReason::ResetCommunication:
      return "reset_communication";
    case FlyingMasterReason::TriggerHeard:
      return "trigger_heard";
    case FlyingMasterReason::NoActiveMaster:
      return "no_active_master";
    case FlyingMasterReason::NoActiveMasterAfterPowerOn:
      return "no_active_master_after_power_on";
    case FlyingMasterReason::NoBetterMaster:
      return "no_better_master";
    case FlyingMasterReason::SamePriority:
      return "same_priority";
    case FlyingMasterReason::HigherPriority:
      return "higher_priority";
    case FlyingMasterReason::WonAgainAfterForce:
      return "won_again_after_force";
    case FlyingMasterReason::LowerPriority:
      return "lower_priority";
    case FlyingMasterReason::AnsweredToo:
      return "answered_too";
    case FlyingMasterReason::ForceReceived:
      return "force_received";
    case FlyingMasterReason::HeartbeatLost:
      return "heartbeat_lost";
    case FlyingMasterReason::CapableDeviceAnswered:
      return "capable_device_answered";
    case FlyingMasterReason::OtherStartedAllNodes:
      return "other_started_all_nodes";
    case FlyingMasterReason::NoCapableDevice:
      return "no_capable_device";
  }
  return "?";
}

std::string_view to_string(LssScanOutcome outcome) {
  switch (outcome) {
    case LssScanOutcome::Stored:
      return "stored";
    case LssScanOutcome::NotStoredAsAsked:
      return "not_stored_as_asked";
    case LssScanOutcome::StoreRefused:
      return "store_refused";
    case LssScanOutcome::StoreUnanswered:
      return "store_unanswered";
    case LssScanOutcome::ConfigureRefused:
      return "configure_refused";
    case LssScanOutcome::ConfigureUnanswered:
      return "configure_unanswered";
    case LssScanOutcome::Duplicate:
      return "duplicate";
    case LssScanOutcome::DuplicateUndoUnanswered:
      return "duplicate_undo_unanswered";
    case LssScanOutcome::NoNodeId:
      return "no_node_id";
  }
  return "?";
}

std::string_view to_string(SdoManagerReason::Kind kind) {
  switch (kind) {
    case SdoManagerReason::Kind::None:
      return "none";
    case SdoManagerReason::Kind::SlaveDoesNotAnswer:
      return "slave_does_not_answer";
    case SdoManagerReason::Kind::NoFreeServerEntry:
      return "no_free_server_entry";
    case SdoManagerReason::Kind::TransferFailed:
      return "transfer_failed";
    case SdoManagerReason::Kind::DefaultSdoInUse:
      return "default_sdo_in_use";
    case SdoManagerReason::Kind::NotAClientEntry:
      return "not_a_client_entry";
    case SdoManagerReason::Kind::NoFreeServerChannel:
      return "no_free_server_channel";
    case SdoManagerReason::Kind::NoFreeCobIds:
      return "no_free_cob_ids";
    case SdoManagerReason::Kind::NoTwoFreeCobIds:
      return "no_two_free_cob_ids";
    case SdoManagerReason::Kind::Releases:
      return "releases";
    case SdoManagerReason::Kind::Deregisters:
      return "deregisters";
    case SdoManagerReason::Kind::SrdBootedUp:
      return "srd_booted_up";
    case SdoManagerReason::Kind::SrdLost:
      return "srd_lost";
    case SdoManagerReason::Kind::SlaveFailed:
      return "slave_failed";
    case SdoManagerReason::Kind::SlaveBootedUp:
      return "slave_booted_up";
  }
  return "?";
}

std::string describe_no_configuration(cfg::NodeId node) {
  const std::string id = std::to_string(node.value());
  return "no configuration for node " + id + " (" +
         cfg::to_string(cfg::ObjectAddress{cfg::object::kConciseDcf, node.value()}) + " empty)";
}

std::string describe_transfer_failure(const SdoResult& result) {
  return cfg::to_string(result.address) + (result.upload ? " upload" : " download") +
         (result.refusal.empty() ? " failed: " + to_string(result.abort)
                                 : " could not start: " + result.refusal);
}

std::string describe(const BootFailure& f, cfg::NodeId node) {
  const auto transfer = [&] {
    return f.transfer ? describe_transfer_failure(*f.transfer) : std::string();
  };
  std::string text;
  switch (f.reason) {
    case Reason::NotListed:
      text = "1F81h sub " + cfg::hex(node.value(), 2) + "h has bit 0 clear";
      break;
    case Reason::TransferFailed:
      text = transfer();
      break;
    case Reason::ValueDiffers:
      // 1000h against 1F84h by its number; 1018h sub 1..4 against 1F85h..1F88h by name.
      text =
          f.object.index == cfg::object::kDeviceType
              ? "1000h is " + cfg::hex(f.actual, 8) + ", 1F84h expects " + cfg::hex(f.expected, 8)
              : cfg::to_string(f.object) + " is " + cfg::hex(f.actual, 8) + ", " +
                    cfg::object_name(f.expected_by) + " expects " + cfg::hex(f.expected, 8);
      break;
    case Reason::NoExpectedSoftware:
      text = "1F81h bit 5 asks for a software version check, but 1F53h, 1F54h and 1F55h sub " +
             cfg::hex(node.value(), 2) + "h are 0";
      break;
    case Reason::SoftwareDiffers:
      text = software_words(f);
      break;
    case Reason::UpdateNotAllowed:
      text = software_words(f) + "; 1F81h bit 6 does not allow an update";
      break;
    case Reason::NoProgramImage:
      text = software_words(f) + "; no program image is available";
      break;
    case Reason::SoftwareDiffersAfterUpdate:
      text = "after the program download " + software_words(f);
      break;
    case Reason::ProgramDownloadFailed:
      text = "program download: " + transfer();
      break;
    case Reason::FlashStatusError:
      text = "after the program download 1F57h sub 1 (flash status) is " + cfg::hex(f.actual, 8) +
             ": " + flash_status_words(f.actual);
      break;
    case Reason::FlashNeverReady:
      text = "after the program download 1F57h sub 1 (flash status) still said 'in progress' " +
             std::string("when the program data timeout had passed");
      break;
    case Reason::NoHeartbeat:
      text = "no heartbeat within the consumer time (1016h)";
      break;
    case Reason::NoGuardingReply:
      text = "no reply to the node guarding request";
      break;
    case Reason::NoConfigurationStored:
      text = "1F26h/1F27h expect a configuration, but none is stored for the node";
      break;
    case Reason::RestoreFailed:
      text = "restore: " + transfer();
      break;
    case Reason::NoBootUpAfterRestore:
      text = "no boot-up after the restore and reset";
      break;
    case Reason::WriteFailed:
      text = transfer() + " (entry " + std::to_string(f.entry) + " of " +
             std::to_string(f.entries) + ")";
      break;
    case Reason::SaveFailed:
      text = "save: " + transfer();
      break;
    case Reason::ApplicationStepFailed:
      text = "the application's configuration step failed";
      break;
    case Reason::NoFirstHeartbeat:
      text = "no heartbeat within the consumer time of " + std::to_string(f.consumer_time_ms) +
             " ms (1016h)";
      break;
    case Reason::KeptAlive:
      text = "kept alive (1F81h bit 4): configuration not checked";
      break;
  }
  return text;
}

std::string describe_boot_error(const MasterEvent& e) {
  std::string text(describe(e.error.value_or(BootError::A)));
  if (e.failure && e.node_id) {
    text += " (" + describe(*e.failure, *e.node_id) + ")";
    if (e.failure->boot_time_ms) {
      text += "; boot time 1F89h (" + std::to_string(*e.failure->boot_time_ms) + " ms) elapsed";
    }
  }
  if (e.boot_emergency) text += "; " + describe_boot_emergency(e);
  return text;
}

std::string describe_emergency(const Emergency& emcy, std::optional<std::uint32_t> device_type) {
  std::string bytes;
  for (const std::uint8_t b : emcy.manufacturer) {
    bytes += (bytes.empty() ? "" : " ") + cfg::hex_digits(b, 2);
  }
  return describe_emcy_code(emcy.error_code, device_type) + "; error register " +
         cfg::hex_digits(emcy.error_register, 2) + "h (" +
         describe_error_register(emcy.error_register) + "); manufacturer bytes " + bytes;
}

std::string describe_boot_emergency(const MasterEvent& e) {
  if (!e.boot_emergency) return {};
  return "the node sent emergency " +
         describe_emcy_code(e.boot_emergency->emcy.error_code, e.boot_emergency->device_type) +
         " during its boot";
}

std::string describe(const MasterEvent& e) {
  const std::string node = node_words(e.node_id);
  switch (e.kind) {
    case Kind::NotMaster:
      return "1F80h is " + cfg::hex(e.nmt_startup, 8) + ": not the NMT master";
    case Kind::StartupBegan:
      return "NMT start-up began";
    case Kind::BootStepChanged:
      if (e.entry_written) {
        return node + ": " + std::to_string(e.written) + " of " + std::to_string(e.total) +
               " entries written";
      }
      return node + ": " + std::string(to_string(e.step));
    case Kind::SlaveBooted:
      return slave_booted_words(e, node) +
             (e.boot_emergency ? "; " + describe_boot_emergency(e) : std::string());
    case Kind::BootError:
      return node + ": boot error " + std::string(1, letter(e.error.value_or(BootError::A))) +
             ": " + describe_boot_error(e);
    case Kind::StartupHalted: {
      std::string text = "NMT start-up halted: mandatory ";
      for (std::size_t i = 0; i < e.halted_by.size(); ++i) {
        const auto& f = e.halted_by[i];
        text += (i == 0 ? "" : ", ") + node_text(f.node) + (i == 0 ? " failed with" : " with") +
                " status " + std::string(1, letter(f.error)) + " (" +
                std::string(describe(f.error)) + ")";
      }
      return text;
    }
    case Kind::StartupAwaitsApplication:
      return "all mandatory slaves booted; waiting for the application to enter operational "
             "(1F80h bit 2)";
    case Kind::StartupComplete:
      return "NMT start-up complete";
    case Kind::MasterStateChanged:
      return "master " + std::string(e.state ? to_string(*e.state) : "?");
    case Kind::SlaveStateChanged:
      return node + ": " +
             (e.state ? std::string(to_string(*e.state))
                      : std::string(e.missing ? "missing" : "state unknown"));
    case Kind::HeartbeatLost:
      return node + ": heartbeat lost";
    case Kind::GuardingLost:
      return node + ": node guarding lost";
    case Kind::ErrorControlResolved:
      return node + (e.heartbeat ? ": heartbeat received again" : ": node guarding replies again");
    case Kind::BootUp:
      return node + ": boot-up" + (e.assigned ? "" : " (not a slave in 1F81h)");
    case Kind::NmtCommandSent:
      return std::string(e.command ? to_string(*e.command) : "?") + " " +
             (e.node_id ? node : std::string("all nodes"));
    case Kind::ApplicationStep:
      return node + ": the application's configuration step";
    case Kind::ProgramProgress:
      return node + ": program download " + std::to_string(e.bytes) + " of " +
             std::to_string(e.total) + " bytes";
    case Kind::SdoFinished: {
      if (!e.sdo) return node + ": SDO transfer done";
      const auto& r = *e.sdo;
      return node + ": " + cfg::to_string(r.address) + (r.upload ? " upload " : " download ") +
             (r.ok() ? std::string("done") : "aborted: " + to_string(r.abort));
    }
    case Kind::NegotiationBegan:
    case Kind::ActiveMaster:
    case Kind::Standby:
    case Kind::ForceNegotiation:
    case Kind::MultipleMasters:
    case Kind::ActiveMasterLost:
    case Kind::MasterDetection:
      return flying_words(e);
    case Kind::SrdRegistered: {
      std::string text = node + ": SRD registered";
      if (e.connection) {
        text += ", " + connection_words(*e.connection);
      } else {
        text += " with all default SDOs";
      }
      if (e.srd && e.srd->slave_error_control) text += ", error control of its slaves";
      return text;
    }
    case Kind::SrdRegistrationFailed:
    case Kind::SdoConnectionRefused: {
      const bool registering = e.kind == Kind::SrdRegistrationFailed;
      if (!e.connection_error) {
        // The SRD did not take the manager's writes (no 1F10h error code).
        return node + ": registration failed: " + manager_reason_words(e.manager_reason);
      }
      const auto error = *e.connection_error;
      return node +
             (registering
                  ? ": registration refused"
                  : ": SDO connection to " +
                        (e.connection ? node_text(e.connection->server) : std::string("node 0")) +
                        " refused") +
             ", error " + cfg::hex(static_cast<std::uint8_t>(error), 2) + " (" +
             std::string(sm::describe(error)) + "): " + manager_reason_words(e.manager_reason);
    }
    case Kind::SdoConnectionEstablished:
      return "SDO connection established: " +
             (e.connection ? connection_words(*e.connection) : std::string());
    case Kind::SdoConnectionReleased:
      return "SDO connection released (" + manager_reason_words(e.manager_reason) +
             "): " + (e.connection ? connection_words(*e.connection) : std::string());
    case Kind::SrdLost:
      return manager_reason_words(e.manager_reason) + ", releasing " + std::to_string(e.released) +
             " SDO connection(s)";
    case Kind::SrdDeregistered:
      return node + ": SRD de-registered";
    case Kind::SlaveFailedReported:
      return node + ": 1F11h reports " +
             (e.connection ? node_text(e.connection->server) : std::string("node 0")) + " failed";
    case Kind::PersistEntry: {
      const std::uint16_t index = e.persist && e.persist->update ? e.persist->update->index : 0;
      return cfg::to_string(
                 cfg::ObjectAddress{index, e.node_id ? e.node_id->value() : std::uint8_t{0}}) +
             ": store the entry of " + node;
    }
    case Kind::LssAssigned:
    case Kind::LssFailed:
      return node + ": LSS: " + lss_words(e);
    case Kind::LssUnmatched:
      return "LSS: unconfigured device " +
             (e.lss_address ? address_digits(*e.lss_address) : std::string()) +
             " matches no slave: left unconfigured";
    case Kind::LssScanEnded:
      return lss_scan_words(e);
    case Kind::ProgramClearRefused: {
      const auto address = e.sdo ? cfg::to_string(e.sdo->address) : std::string("1F51h sub 01h");
      return node + ": program clear (" + address +
             " = 3) refused: " + to_string(e.sdo ? e.sdo->abort : SdoAbort::None) +
             "; the download goes on";
    }
    case Kind::Emergency: {
      if (!e.emergency) return node + ": emergency";
      const auto& r = *e.emergency;
      if (r.emcy.error_code == emcy_code::kErrorReset) {
        return node + (r.ends_error ? ": emergency ended: " : ": emergency: ") +
               describe_emergency(r.emcy, r.device_type);
      }
      return node + ": emergency " + describe_emergency(r.emcy, r.device_type);
    }
    case Kind::EmergencyFlood: {
      if (!e.emergency) return node + ": emergencies not reported";
      const auto& r = *e.emergency;
      const auto window_ms =
          std::chrono::duration_cast<std::chrono::milliseconds>(r.window).count();
      return node + ": " + std::to_string(r.suppressed) + " more emergencies " +
             describe_emcy_code(r.emcy.error_code, r.device_type) + " not reported (at most " +
             std::to_string(r.max_per_window) + " per " + std::to_string(window_ms) +
             " ms per node and code)";
    }
  }
  return std::string(to_string(e.kind));
}

}  // namespace nmt
