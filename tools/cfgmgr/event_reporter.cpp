// The master's events printed (event_reporter.hpp).
#include "event_reporter.hpp"

#include <iostream>
#include <string>

#include "../common/tool_support.hpp"
#include "cfg/hex.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/protocol/emcy_text.hpp"
#include "nmt/protocol/frame.hpp"
#include "run_args.hpp"

namespace cfgmgr {

void EventReporter::report(const nmt::MasterEvent& e) {
  using K = nmt::MasterEvent::Kind;
  // An event of the master itself (no node_id) is never ignored.
  const int node_id = e.node_id ? int{e.node_id->value()} : 0;
  if (e.node_id && ignored_.contains(*e.node_id)) {
    if (observer_) observer_(e);
    return;
  }
  if (const auto updated = programs_.observe(e)) {
    note(seconds_text(start_, e.at) + "  " + *updated);
  }
  std::string line;
  const std::string node = "node " + std::to_string(node_id) + ": ";
  bool again = false;
  switch (e.kind) {
    case K::NotMaster:
      finished_ = true;
      line = nmt::describe(e);
      break;
    case K::StartupBegan:
      line = "NMT start-up began";
      break;
    case K::SlaveBooted:
      again = !booted_.insert(*e.node_id).second;
      if (e.configured) {
        line = node + (again ? "reconfigured" : "booted, configured") + " (" +
               std::to_string(e.written) + (e.written == 1 ? " entry" : " entries") + ", " +
               tools::plural(e.bytes, "byte") + ")";
      } else if (e.no_configuration) {
        line = node + (again ? "booted again" : "booted") + ", " +
               nmt::describe_no_configuration(*e.node_id);
      } else {
        line = node + (again ? "booted again" : "booted") + " (configuration up to date)";
      }
      break;
    case K::BootError:
      if (e.error) {
        line = node + "boot error " + std::string(1, nmt::letter(*e.error)) + ": " +
               std::string(nmt::describe(*e.error));
      } else {
        line = node + "boot error: " + nmt::describe(e);
      }
      if (e.boot_emergency) line += "; " + nmt::describe_boot_emergency(e);
      if (!e.final) line += " (trying again)";
      break;
    case K::Emergency:
    case K::EmergencyFlood:
      line = nmt::describe(e);  // "node 3: emergency 8130h life guard error or heartbeat ..."
      break;
    case K::StartupHalted:
      halted_ = true;
      finished_ = true;
      line =
          nmt::describe(e);  // "NMT start-up halted: mandatory node N failed with status X (...)"
      break;
    case K::StartupComplete:
      complete_ = true;
      finished_ = true;
      line = "NMT start-up complete";
      break;
    case K::HeartbeatLost:
      line = node + "heartbeat lost";
      break;
    case K::GuardingLost:
      line = node + "node guarding lost";
      break;
    case K::ErrorControlResolved:
      line = node + "error control resolved";
      break;
    case K::BootUp:
      line = node + "boot-up seen" + (e.assigned ? "" : " (not a slave of this master)");
      break;
    case K::ProgramClearRefused:
      break;  // noted above (programs_), also under a live view
    case K::ActiveMaster:
    case K::Standby:
    case K::ForceNegotiation:
    case K::MultipleMasters:
    case K::ActiveMasterLost:
    case K::SrdRegistered:
    case K::SrdRegistrationFailed:
    case K::SdoConnectionEstablished:
    case K::SdoConnectionRefused:
    case K::SdoConnectionReleased:
    case K::SrdLost:
    case K::SrdDeregistered:
    case K::SlaveFailedReported:
    case K::LssAssigned:
    case K::LssUnmatched:
    case K::LssFailed:
    case K::LssScanEnded:
      // flying master: who is active and why; SDO manager: what it did; LSS: which device got
      // which node-ID, and which matched no node
      line = nmt::describe(e);
      break;
    default:
      if (verbose_) line = nmt::describe(e);
      break;
  }
  const bool emergency = e.kind == K::Emergency || e.kind == K::EmergencyFlood;
  if (!line.empty() && !quiet_) {
    std::cerr << seconds_text(start_, e.at) << "  " << line << '\n' << std::flush;
  } else if (!line.empty() && emergency) {
    // A live view has no words for an EMCY: the line goes above it (bounded by the flood rule).
    note(seconds_text(start_, e.at) + "  " + line);
  }
  if (json_ != nullptr) write_json(e);
  if (observer_) observer_(e);
}

void EventReporter::note(const std::string& line) {
  if (note_handler_) {
    note_handler_(line);
  } else {
    std::cerr << line << '\n' << std::flush;
  }
}

namespace {
// A boot error's facts (nmt::BootFailure) as a JSON object: the reason, the step it failed in,
// and what the reason has (the object and values compared, the failed transfer and its abort).
std::string json_failure(const nmt::BootFailure& f) {
  using R = nmt::BootFailure::Reason;
  std::string out = "{\"reason\": " + tools::json_string(nmt::to_string(f.reason)) +
                    ", \"step\": " + tools::json_string(nmt::to_string(f.step));
  if (f.reason == R::ValueDiffers) {
    out += ", \"object\": " + tools::json_string(cfg::to_string(f.object)) +
           ", \"actual\": " + std::to_string(f.actual) +
           ", \"expected_by\": " + tools::json_string(cfg::hex_digits(f.expected_by, 4) + "h") +
           ", \"expected\": " + std::to_string(f.expected);
  }
  if (f.transfer) {
    out += ", \"object\": " + tools::json_string(cfg::to_string(f.transfer->address)) +
           ", \"abort\": " + std::to_string(static_cast<std::uint32_t>(f.transfer->abort)) +
           ", \"abort_text\": " + tools::json_string(nmt::to_string(f.transfer->abort));
  }
  if (f.reason == R::WriteFailed) {
    out +=
        ", \"entry\": " + std::to_string(f.entry) + ", \"entries\": " + std::to_string(f.entries);
  }
  if (f.reason == R::NoFirstHeartbeat) {
    out += ", \"consumer_time_ms\": " + std::to_string(f.consumer_time_ms);
  }
  if (f.boot_time_ms) out += ", \"boot_time_ms\": " + std::to_string(*f.boot_time_ms);
  return out + "}";
}
// An EMCY (CiA 301 §7.2.7) as a JSON object: the numbers a script compares, the code's words.
std::string json_emergency(const nmt::MasterEvent::EmergencyReport& r) {
  std::string bytes;
  for (const std::uint8_t b : r.emcy.manufacturer) bytes += cfg::hex_digits(b, 2);
  std::string out =
      "{\"error_code\": " + std::to_string(r.emcy.error_code) +
      ", \"error_code_hex\": " + tools::json_string(cfg::hex_digits(r.emcy.error_code, 4)) +
      ", \"error_register\": " + std::to_string(r.emcy.error_register) +
      ", \"manufacturer\": " + tools::json_string(bytes) + ", \"code_text\": " +
      tools::json_string(nmt::describe_emcy_code(r.emcy.error_code, r.device_type)) +
      ", \"register_text\": " +
      tools::json_string(nmt::describe_error_register(r.emcy.error_register)) +
      ", \"ends_error\": " + (r.ends_error ? "true" : "false");
  if (r.device_type) out += ", \"device_type\": " + std::to_string(*r.device_type);
  if (r.suppressed != 0) out += ", \"suppressed\": " + std::to_string(r.suppressed);
  return out + "}";
}
}  // namespace

void EventReporter::write_json(const nmt::MasterEvent& e) {
  using K = nmt::MasterEvent::Kind;
  std::string out = "{\"time_s\": " + seconds_text(start_, e.at) +
                    ", \"event\": " + tools::json_string(nmt::to_string(e.kind)) +
                    ", \"node_id\": " + std::to_string(e.node_id ? int{e.node_id->value()} : 0);
  switch (e.kind) {
    case K::BootError:
      if (e.error) {
        out += ", \"error\": " + tools::json_string(std::string(1, nmt::letter(*e.error))) +
               ", \"description\": " + tools::json_string(nmt::describe(*e.error));
      } else {
        out += ", \"error\": null";
      }
      out += std::string(", \"final\": ") + (e.final ? "true" : "false");
      if (e.failure) out += ", \"failure\": " + json_failure(*e.failure);
      break;
    case K::StartupHalted: {
      std::string list;
      for (const auto& f : e.halted_by) {
        list += std::string(list.empty() ? "" : ", ") +
                "{\"node_id\": " + std::to_string(f.node.value()) +
                ", \"error\": " + tools::json_string(std::string(1, nmt::letter(f.error))) + "}";
      }
      out += ", \"halted_by\": [" + list + "]";
      break;
    }
    case K::NotMaster:
      out += ", \"nmt_startup\": " + std::to_string(e.nmt_startup);
      break;
    case K::SlaveBooted:
      out += std::string(", \"configured\": ") + (e.configured ? "true" : "false") +
             ", \"no_configuration\": " + (e.no_configuration ? "true" : "false") +
             ", \"entries\": " + std::to_string(e.written) +
             ", \"bytes\": " + std::to_string(e.bytes);
      break;
    case K::BootUp:
      out += std::string(", \"assigned\": ") + (e.assigned ? "true" : "false");
      break;
    case K::BootStepChanged:
      out += ", \"step\": " + tools::json_string(nmt::to_string(e.step));
      break;
    case K::MasterStateChanged:
    case K::SlaveStateChanged:
      if (e.state) out += ", \"state\": " + tools::json_string(nmt::to_string(*e.state));
      break;
    case K::NmtCommandSent:
      if (e.command) out += ", \"command\": " + tools::json_string(nmt::to_string(*e.command));
      break;
    case K::NegotiationBegan:
    case K::ActiveMaster:
    case K::Standby:
    case K::ForceNegotiation:
    case K::MultipleMasters:
    case K::ActiveMasterLost:
    case K::MasterDetection:
      if (e.priority) out += ", \"priority\": " + std::to_string(*e.priority);
      if (e.flying) out += ", \"reason\": " + tools::json_string(nmt::to_string(e.flying->reason));
      break;
    case K::LssAssigned:
    case K::LssFailed:
    case K::LssUnmatched:
      if (e.lss) {
        out += ", \"outcome\": " + tools::json_string(nmt::to_string(e.lss->outcome)) +
               ", \"error_code\": " + std::to_string(e.lss->error_code);
      }
      break;
    case K::LssScanEnded:
      if (e.lss_scan) {
        out += ", \"found\": " + std::to_string(e.lss_scan->found) +
               ", \"assigned\": " + std::to_string(e.lss_scan->assigned);
      }
      break;
    case K::SdoConnectionReleased:
    case K::SrdLost:
      out += ", \"reason\": " + tools::json_string(nmt::to_string(e.manager_reason.kind));
      break;
    case K::SrdRegistrationFailed:
    case K::SdoConnectionRefused:
      // The JSON keeps 1F10h's byte (DSP 302 §7.2.3), the value a script compares with.
      if (e.connection_error) {
        out +=
            ", \"connection_error\": " + std::to_string(static_cast<unsigned>(*e.connection_error));
      }
      out += ", \"reason\": " + tools::json_string(nmt::to_string(e.manager_reason.kind));
      break;
    case K::ProgramClearRefused:
      if (e.sdo) out += ", \"abort\": " + tools::json_string(nmt::to_string(e.sdo->abort));
      break;
    default:
      break;
  }
  if (e.connection) {
    // SDO manager kinds (DSP 302 §7.2.3): the connection, as 1F03h describes it, and its COB-IDs.
    const auto& c = *e.connection;
    out += ", \"connection\": {\"row\": " + std::to_string(c.row) +
           ", \"client_node_id\": " + std::to_string(c.srd) +
           ", \"client_index\": " + std::to_string(c.client_index) +
           ", \"server_node_id\": " + std::to_string(c.server) +
           ", \"server_index\": " + std::to_string(c.server_index) +
           ", \"request_cob_id\": " + std::to_string(c.request.word()) +
           ", \"response_cob_id\": " + std::to_string(c.response.word()) + "}";
  }
  if (e.lss_address)
    out += ", \"lss_address\": " + tools::json_string(nmt::address_digits(*e.lss_address));
  if (e.emergency) out += ", \"emergency\": " + json_emergency(*e.emergency);
  if (e.boot_emergency) out += ", \"boot_emergency\": " + json_emergency(*e.boot_emergency);
  if (e.boot_try != 0) out += ", \"try\": " + std::to_string(e.boot_try);
  out += ", \"text\": " + tools::json_string(nmt::describe(e)) + "}\n";
  *json_ << out << std::flush;
}

void EventReporter::report_bus(const nmt::BusEvent& e, nmt::TimePoint at) {
  using K = nmt::BusEvent::Kind;
  const bool routine =
      e.kind == K::LostArbitration || e.kind == K::BusError || e.kind == K::ErrorWarning;
  if (!quiet_ && (verbose_ || !routine)) {
    note(seconds_text(start_, at) + "  bus: " + e.text);
  }
  if (json_ == nullptr) return;
  *json_ << "{\"time_s\": " << seconds_text(start_, at)
         << ", \"event\": " << tools::json_string(nmt::to_string(e.kind))
         << ", \"node_id\": 0, \"frame\": " << tools::json_string(nmt::to_candump(e.frame))
         << ", \"text\": " << tools::json_string(e.text) << "}\n"
         << std::flush;
}

}  // namespace cfgmgr
