#include "nmt/slave/nmt_slave.hpp"

#include <array>
#include <cassert>

namespace nmt {

std::string_view to_string(NmtState state) {
  switch (state) {
    case NmtState::Initialising:
      return "initialising";
    case NmtState::Stopped:
      return "stopped";
    case NmtState::Operational:
      return "operational";
    case NmtState::PreOperational:
      return "pre-operational";
  }
  return "unknown";
}

std::optional<NmtState> nmt_state_from_byte(std::uint8_t byte) {
  // CiA 301 §7.2.8.3.2: bit 7 is the guarding toggle bit (reserved in heartbeats).
  switch (byte & 0x7F) {
    case 0x00:
      return NmtState::Initialising;
    case 0x04:
      return NmtState::Stopped;
    case 0x05:
      return NmtState::Operational;
    case 0x7F:
      return NmtState::PreOperational;
    default:
      return std::nullopt;
  }
}

std::string_view to_string(NmtCommand command) {
  switch (command) {
    case NmtCommand::Start:
      return "start";
    case NmtCommand::Stop:
      return "stop";
    case NmtCommand::EnterPreOperational:
      return "enter pre-operational";
    case NmtCommand::ResetNode:
      return "reset node";
    case NmtCommand::ResetCommunication:
      return "reset communication";
  }
  return "unknown";
}

std::optional<NmtCommand> nmt_command_from_byte(std::uint8_t byte) {
  switch (byte) {
    case 0x01:
      return NmtCommand::Start;
    case 0x02:
      return NmtCommand::Stop;
    case 0x80:
      return NmtCommand::EnterPreOperational;
    case 0x81:
      return NmtCommand::ResetNode;
    case 0x82:
      return NmtCommand::ResetCommunication;
    default:
      return std::nullopt;
  }
}

std::string_view to_string(ResetScope scope) {
  return scope == ResetScope::Application ? "reset application" : "reset communication";
}

CanFrame make_nmt_command(NmtCommand command, NmtTarget target) {
  const std::array<std::uint8_t, 2> bytes{static_cast<std::uint8_t>(command), target.byte()};
  return CanFrame::make(kNmtCobId, bytes);
}

std::optional<NmtCommandFrame> parse_nmt_command(const CanFrame& frame) {
  // CiA 301 §7.2.8.3.1: NMT module control is COB-ID 0 with exactly two bytes.
  if (frame.id != kNmtCobId || frame.extended || frame.rtr || frame.error || frame.dlc != 2) {
    return std::nullopt;
  }
  auto command = nmt_command_from_byte(frame.data[0]);
  auto target = NmtTarget::from_byte(frame.data[1]);
  if (!command || !target) return std::nullopt;
  return NmtCommandFrame{*command, *target};
}

CanFrame make_boot_up(cfg::NodeId node_id) {
  const std::array<std::uint8_t, 1> bytes{0x00};
  return CanFrame::make(kErrorControlCobIdBase + node_id, bytes);
}

NmtServices services_in(NmtState state) {
  // CiA 301 §7.3.2.2 Table 51: SDO, SYNC/TIME and EMCY run in pre-operational and operational;
  // PDO only in operational; error control and NMT in every state but initialising.
  NmtServices s;
  switch (state) {
    case NmtState::Initialising:
      break;
    case NmtState::PreOperational:
      s.sdo = s.emcy = s.sync_time = s.error_control = s.nmt = true;
      break;
    case NmtState::Operational:
      s.sdo = s.pdo = s.emcy = s.sync_time = s.error_control = s.nmt = true;
      break;
    case NmtState::Stopped:
      s.error_control = s.nmt = true;
      break;
  }
  return s;
}

NmtSlave::NmtSlave(cfg::NodeId node_id) : node_id_(node_id), pending_node_id_(node_id) {}

bool NmtSlave::on_frame(const CanFrame& frame, TimePoint /*now*/, Output& out) {
  if (state_ == NmtState::Initialising) return false;
  auto command = parse_nmt_command(frame);
  if (!command || !command->target.addresses(node_id_)) return false;

  Transition t{state_, state_, command->command, std::nullopt};
  switch (command->command) {
    case NmtCommand::Start:
      t.to = NmtState::Operational;
      break;
    case NmtCommand::Stop:
      t.to = NmtState::Stopped;
      break;
    case NmtCommand::EnterPreOperational:
      t.to = NmtState::PreOperational;
      break;
    case NmtCommand::ResetNode:
      t.to = NmtState::Initialising;
      t.reset = ResetScope::Application;
      break;
    case NmtCommand::ResetCommunication:
      t.to = NmtState::Initialising;
      t.reset = ResetScope::Communication;
      break;
  }
  state_ = t.to;
  pending_reset_ = t.reset;
  out.report(t);
  return true;
}

void NmtSlave::finish_initialisation(TimePoint /*now*/, Output& out) {
  assert(state_ == NmtState::Initialising);
  // CiA 301 §7.3.2.2.1: the node-ID takes effect in reset communication, which every reset passes.
  node_id_ = pending_node_id_;
  state_ = NmtState::PreOperational;
  pending_reset_.reset();
  out.send(make_boot_up(node_id_));
}

void NmtSlave::set_state(NmtState state) {
  assert(state_ != NmtState::Initialising && state != NmtState::Initialising);
  state_ = state;
}

void NmtSlave::start(TimePoint /*now*/, Output& /*out*/) {
  state_ = NmtState::Initialising;
  pending_reset_ = ResetScope::Application;
}

void NmtSlave::set_node_id(cfg::NodeId node_id) {
  pending_node_id_ = node_id;
}

}  // namespace nmt
