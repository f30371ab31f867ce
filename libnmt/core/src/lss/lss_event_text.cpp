// The words of the LSS engines' events (nmt/lss/lss_event_text.hpp), made from their typed fields.
#include "nmt/lss/lss_event_text.hpp"

#include <chrono>
#include <cstdio>

namespace nmt {

namespace {

using lss::Cs;
using ServiceKind = LssMasterEvent::Kind;

std::string ms_words(Duration d) {
  return std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(d).count()) + " ms";
}

std::string no_answer(Duration timeout) {
  return "no answer within " + ms_words(timeout);
}

// The command specifier whose answer carries the error code (CiA 305, lss::error_text).
Cs answer_of(LssService service) {
  switch (service) {
    case LssService::ConfigureBitTiming:
      return Cs::ConfigureBitTiming;
    case LssService::StoreConfiguration:
      return Cs::StoreConfiguration;
    default:
      return Cs::ConfigureNodeId;
  }
}

std::string hex32(std::uint32_t value) {
  char hex[16];
  std::snprintf(hex, sizeof hex, "%08Xh", value);
  return hex;
}

// How a service ended, without its name in front: "no answer within 100 ms".
std::string words(const LssMasterEvent& e) {
  switch (e.kind) {
    case ServiceKind::Timeout:
      // A Fastscan step ends by the scan step, not by a timeout: a device went silent midway.
      if (e.service == LssService::Fastscan) {
        return "the device stopped answering (part " + std::to_string(e.part) + ")";
      }
      return no_answer(e.timeout);
    case ServiceKind::Refused:
      return "refused: " + lss::error_text(answer_of(e.service), e.error_code, e.spec_error);
    case ServiceKind::NotFound:
      if (e.service != LssService::Fastscan) return "no device answered";
      if (e.after) return "no unconfigured device above " + to_string(*e.after);
      return "no unconfigured device answered";
    case ServiceKind::Absent:
      return "no device " + to_string(e.address) + " unconfigured";
    case ServiceKind::Done:
      break;
  }
  switch (e.service) {
    case LssService::SwitchStateGlobal:
      return "all devices to LSS " + std::string(to_string(e.state));
    case LssService::SwitchStateSelective:
      return to_string(e.address) + " in LSS configuration";
    case LssService::ConfigureNodeId:
    case LssService::ConfigureBitTiming:
    case LssService::StoreConfiguration:
      return "done";
    case LssService::ActivateBitTiming:
      return "devices switched after twice the switch delay";
    case LssService::InquireNodeId:
      return "node-ID " + std::to_string(e.value);
    case LssService::InquireVendorId:
    case LssService::InquireProductCode:
    case LssService::InquireRevision:
    case LssService::InquireSerial:
      return hex32(e.value);
    case LssService::IdentifyRemoteSlaves:
    case LssService::IdentifyNonConfigured:
      return "a device answered";
    case LssService::Fastscan:
      return "found " + to_string(e.address);
  }
  return "done";
}

std::string node_id_number(std::optional<cfg::NodeId> node_id) {
  return std::to_string(node_id ? node_id->value() : lss::kUnconfigured);
}

// A procedure's Done. AnyUnconfigured and SetBitRate end with their last service and say its
// line; InquireNodeId and InquireIdentity the address, then the inquire node-ID's line.
std::string done_words(const LssProcedureEvent& e) {
  const std::string name(to_string(e.procedure));
  switch (e.procedure) {
    case LssProcedureKind::Scan:
    case LssProcedureKind::FindUnconfigured:
      return name + ": " + std::to_string(e.found) + " unconfigured devices found";
    case LssProcedureKind::AnyUnconfigured: {
      LssMasterEvent probe;
      probe.service = LssService::IdentifyNonConfigured;
      probe.kind = e.found > 0 ? ServiceKind::Done : ServiceKind::NotFound;
      return describe(probe);
    }
    case LssProcedureKind::FindProduct:
      return name + ": " + std::to_string(e.addresses.size()) + " found";
    case LssProcedureKind::AssignNodeId:
      return name + ": " + to_string(e.address) + " node-ID " + node_id_number(e.node_id) +
             (e.outcome == LssScanOutcome::NotStoredAsAsked ? ", not stored (as asked)"
                                                            : ", stored");
    case LssProcedureKind::InquireNodeId:
    case LssProcedureKind::InquireIdentity:
      return name + ": " + to_string(e.address) + " " +
             std::string(to_string(LssService::InquireNodeId)) + ": node-ID " +
             node_id_number(e.node_id);
    case LssProcedureKind::SetBitRate: {
      LssMasterEvent activated;
      activated.service = LssService::ActivateBitTiming;
      return describe(activated);
    }
  }
  return name + ": done";
}

std::string failed_words(const LssProcedureEvent& e) {
  const std::string name(to_string(e.procedure));
  if (!e.step) return name + ": could not start";
  const LssMasterEvent& step = *e.step;
  if (step.ok() && step.service == LssService::InquireNodeId) {
    // An answer CiA 305 does not allow (nmt/lss/lss.hpp: 1..127, FFh not configured).
    return "inquire node-ID answered " + std::to_string(step.value) +
           ": no node-ID (CiA 305: 1..127, or 255 for not configured)";
  }
  if (step.service == LssService::Fastscan) return name + ": " + words(step);
  return describe(step);
}

}  // namespace

std::string describe(const LssMasterEvent& event) {
  return std::string(to_string(event.service)) + ": " + words(event);
}

std::string describe(LssScanOutcome outcome, std::optional<cfg::NodeId> node_id,
                     std::uint8_t error_code, std::uint8_t spec_error, Duration timeout) {
  using O = LssScanOutcome;
  const std::string duplicate =
      "more than one device answered configure node-ID with this LSS address (CiA 305 takes LSS "
      "addresses to be unique)";
  const auto error = [&](Cs service) { return lss::error_text(service, error_code, spec_error); };
  const std::string got =
      "got node-ID " + (node_id ? std::to_string(node_id->value()) : std::string("?")) + ", ";
  const std::string left = "left unconfigured: ";
  switch (outcome) {
    case O::Stored:
      return got + "stored";
    case O::NotStoredAsAsked:
      return got + "not stored (as asked)";
    case O::StoreRefused:
      return got + "not stored: store configuration refused: " + error(Cs::StoreConfiguration);
    case O::StoreUnanswered:
      return got + "not stored: store configuration: " + no_answer(timeout);
    case O::ConfigureRefused:
      return left + "configure node-ID refused: " + error(Cs::ConfigureNodeId);
    case O::ConfigureUnanswered:
      return left + "configure node-ID: " + no_answer(timeout);
    case O::Duplicate:
      return left + duplicate;
    case O::DuplicateUndoUnanswered:
      return left + duplicate + "; undoing its node-ID: " + no_answer(timeout);
    case O::NoNodeId:
      return left + "no node-ID for it";
  }
  return left;
}

std::string describe(const LssProcedureEvent& event) {
  switch (event.kind) {
    case LssProcedureEvent::Kind::Assigned:
    case LssProcedureEvent::Kind::Skipped:
      return std::string(to_string(event.procedure)) + ": " + to_string(event.address) + " " +
             describe(event.outcome.value_or(LssScanOutcome::NoNodeId), event.node_id,
                      event.error_code, event.spec_error,
                      event.step ? event.step->timeout : Duration{});
    case LssProcedureEvent::Kind::Done:
      return done_words(event);
    case LssProcedureEvent::Kind::Failed:
      return failed_words(event);
  }
  return std::string(to_string(event.procedure));
}

}  // namespace nmt
