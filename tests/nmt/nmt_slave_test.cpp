// NMT slave state machine (CiA 301 §7.3.2). Frame bytes are those of the NMT overview in
// /work/shared/spec/002_*.txt (e.g. "000 2 01 01: NMT host commands node 1 into operational",
// "701 1 00: node 1 boot-up message").
#include "nmt/slave/nmt_slave.hpp"

#include <gtest/gtest.h>

namespace nmt {
namespace {

using namespace cfg::literals;

CanFrame frame(std::string_view candump) {
  auto f = from_candump(candump);
  EXPECT_TRUE(f.has_value()) << candump;
  return f.value_or(CanFrame{});
}

// Feeds one frame; the transition it reported (the slave reports at most one and sends nothing).
std::optional<NmtTransition> feed(NmtSlave& slave, std::string_view candump) {
  NmtSlave::Output out;
  const bool taken = slave.on_frame(frame(candump), TimePoint{}, out);
  EXPECT_TRUE(out.frames.empty());
  EXPECT_EQ(out.events.size(), taken ? 1u : 0u);
  if (!taken || out.events.empty()) return std::nullopt;
  return out.events.front();
}

// Ends initialisation; the one frame it sent.
std::string finish(NmtSlave& slave) {
  NmtSlave::Output out;
  slave.finish_initialisation(TimePoint{}, out);
  EXPECT_TRUE(out.events.empty());
  if (out.frames.size() != 1) return "frames: " + std::to_string(out.frames.size());
  return to_candump(out.frames.front());
}

NmtSlave booted(std::uint8_t node_id) {
  NmtSlave slave(*cfg::NodeId::from(node_id));
  (void)finish(slave);
  return slave;
}

static_assert(Engine<NmtSlave>);

TEST(NmtSlave, StartsInitialisingAndBootsIntoPreOperationalWithBootUpMessage) {
  NmtSlave slave(2_node);
  EXPECT_EQ(slave.state(), NmtState::Initialising);
  EXPECT_EQ(slave.pending_reset(), ResetScope::Application);  // power-on: reset application
  EXPECT_EQ(finish(slave), "702#00");
  EXPECT_EQ(slave.state(), NmtState::PreOperational);
  EXPECT_FALSE(slave.pending_reset().has_value());
}

TEST(NmtSlave, IgnoresCommandsWhileInitialising) {
  NmtSlave slave(1_node);
  EXPECT_FALSE(feed(slave, "000#0101").has_value());
  EXPECT_EQ(slave.state(), NmtState::Initialising);
  EXPECT_FALSE(slave.next_deadline().has_value());  // nothing in the NMT slave is timed
}

TEST(NmtSlave, StartStopAndEnterPreOperationalFollowTheStateDiagram) {
  NmtSlave slave = booted(1);
  // Transition (3): start remote node from pre-operational.
  auto t = feed(slave, "000#0101");
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->from, NmtState::PreOperational);
  EXPECT_EQ(t->to, NmtState::Operational);
  EXPECT_EQ(t->command, NmtCommand::Start);
  EXPECT_FALSE(t->reset.has_value());
  // (8): stop from operational.
  EXPECT_EQ(feed(slave, "000#0201")->to, NmtState::Stopped);
  // (7): enter pre-operational from stopped.
  EXPECT_EQ(feed(slave, "000#8001")->to, NmtState::PreOperational);
  // (5): stop from pre-operational, (6): start from stopped, (4): pre-op from operational.
  EXPECT_EQ(feed(slave, "000#0201")->to, NmtState::Stopped);
  EXPECT_EQ(feed(slave, "000#0101")->to, NmtState::Operational);
  EXPECT_EQ(feed(slave, "000#8001")->to, NmtState::PreOperational);
}

TEST(NmtSlave, ResetNodeAsksForResetApplicationAndBootsAgain) {
  NmtSlave slave = booted(5);
  (void)feed(slave, "000#0105");
  auto t = feed(slave, "000#8105");
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->to, NmtState::Initialising);
  EXPECT_EQ(t->reset, ResetScope::Application);
  EXPECT_EQ(slave.pending_reset(), ResetScope::Application);
  EXPECT_EQ(finish(slave), "705#00");
  EXPECT_EQ(slave.state(), NmtState::PreOperational);
}

TEST(NmtSlave, ResetCommunicationFromStoppedAsksForResetCommunication) {
  NmtSlave slave = booted(5);
  (void)feed(slave, "000#0205");
  auto t = feed(slave, "000#8205");
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->from, NmtState::Stopped);
  EXPECT_EQ(t->reset, ResetScope::Communication);
}

TEST(NmtSlave, NodeIdZeroAddressesAllNodes) {
  NmtSlave a = booted(1);
  NmtSlave b = booted(127);
  EXPECT_EQ(feed(a, "000#0100")->to, NmtState::Operational);
  EXPECT_EQ(feed(b, "000#0100")->to, NmtState::Operational);
}

TEST(NmtSlave, IgnoresCommandsForOtherNodesAndMalformedFrames) {
  NmtSlave slave = booted(3);
  EXPECT_FALSE(feed(slave, "000#0104").has_value());       // other node
  EXPECT_FALSE(feed(slave, "000#01").has_value());         // one byte
  EXPECT_FALSE(feed(slave, "000#010300").has_value());     // three bytes
  EXPECT_FALSE(feed(slave, "000#0303").has_value());       // unknown specifier
  EXPECT_FALSE(feed(slave, "000#R2").has_value());         // remote frame
  EXPECT_FALSE(feed(slave, "001#0103").has_value());       // not COB-ID 0
  EXPECT_FALSE(feed(slave, "00000000#0103").has_value());  // 29-bit identifier
  EXPECT_FALSE(feed(slave, "000#0180").has_value());       // node-ID 128
  EXPECT_EQ(slave.state(), NmtState::PreOperational);
}

TEST(NmtSlave, RepeatedCommandIsReportedWithoutStateChange) {
  NmtSlave slave = booted(3);
  auto t = feed(slave, "000#8003");
  ASSERT_TRUE(t.has_value());
  EXPECT_EQ(t->from, NmtState::PreOperational);
  EXPECT_EQ(t->to, NmtState::PreOperational);
}

TEST(NmtSlave, NewNodeIdTakesEffectAtNextInitialisation) {
  NmtSlave slave = booted(3);
  slave.set_node_id(9_node);
  EXPECT_EQ(slave.node_id(), 3);
  (void)feed(slave, "000#8203");
  EXPECT_EQ(finish(slave), "709#00");
  EXPECT_EQ(slave.node_id(), 9);
}

TEST(NmtSlave, ServicesPerStateFollowCia301Table) {
  // CiA 301 §7.3.2.2 / spec/002 "NMT states and communication object relation".
  auto pre = services_in(NmtState::PreOperational);
  EXPECT_TRUE(pre.sdo);
  EXPECT_FALSE(pre.pdo);
  EXPECT_TRUE(pre.emcy);
  EXPECT_TRUE(pre.sync_time);
  EXPECT_TRUE(pre.error_control);
  EXPECT_TRUE(pre.nmt);

  auto op = services_in(NmtState::Operational);
  EXPECT_TRUE(op.sdo);
  EXPECT_TRUE(op.pdo);
  EXPECT_TRUE(op.emcy);
  EXPECT_TRUE(op.error_control);

  auto stopped = services_in(NmtState::Stopped);
  EXPECT_FALSE(stopped.sdo);
  EXPECT_FALSE(stopped.pdo);
  EXPECT_FALSE(stopped.emcy);
  EXPECT_FALSE(stopped.sync_time);
  EXPECT_TRUE(stopped.error_control);
  EXPECT_TRUE(stopped.nmt);

  auto init = services_in(NmtState::Initialising);
  EXPECT_FALSE(init.sdo || init.pdo || init.emcy || init.error_control || init.nmt);
}

TEST(NmtSlave, CommandFramesAreEncodedAsTheSpecExamples) {
  // spec/002: "000 2 80 01: NMT host commands node 1 into pre-operational state" etc.
  EXPECT_EQ(to_candump(make_nmt_command(NmtCommand::EnterPreOperational, 1_node)), "000#8001");
  EXPECT_EQ(to_candump(make_nmt_command(NmtCommand::Start, 5_node)), "000#0105");
  EXPECT_EQ(to_candump(make_nmt_command(NmtCommand::Stop, 1_node)), "000#0201");
  EXPECT_EQ(to_candump(make_nmt_command(NmtCommand::ResetCommunication, 1_node)), "000#8201");
  EXPECT_EQ(to_candump(make_nmt_command(NmtCommand::ResetNode, NmtTarget::all_nodes())),
            "000#8100");
}

// CiA 301 §7.2.8.3.1: node-ID 0 addresses all nodes, 1..127 one node; nothing else is a command.
TEST(NmtSlave, CommandFramesNameOneNodeOrAllNodes) {
  auto all = parse_nmt_command(*from_candump("000#8100"));
  ASSERT_TRUE(all.has_value());
  EXPECT_EQ(all->command, NmtCommand::ResetNode);
  EXPECT_TRUE(all->target.all());
  EXPECT_EQ(all->target.node(), std::nullopt);
  EXPECT_TRUE(all->target.addresses(1_node));
  EXPECT_TRUE(all->target.addresses(127_node));

  auto one = parse_nmt_command(*from_candump("000#017F"));
  ASSERT_TRUE(one.has_value());
  EXPECT_EQ(one->target, NmtTarget(127_node));
  EXPECT_TRUE(one->target.addresses(127_node));
  EXPECT_FALSE(one->target.addresses(1_node));
  EXPECT_EQ(to_candump(make_nmt_command(one->command, one->target)), "000#017F");

  EXPECT_EQ(NmtTarget::from_byte(0x80), std::nullopt);
  EXPECT_EQ(NmtTarget::from_byte(0xFF), std::nullopt);
  EXPECT_EQ(parse_nmt_command(*from_candump("000#01FF")).has_value(), false);
}

TEST(NmtSlave, StateBytesDecodeIgnoringToggleBit) {
  EXPECT_EQ(nmt_state_from_byte(0x7F), NmtState::PreOperational);
  EXPECT_EQ(nmt_state_from_byte(0xFF), NmtState::PreOperational);
  EXPECT_EQ(nmt_state_from_byte(0x85), NmtState::Operational);
  EXPECT_EQ(nmt_state_from_byte(0x04), NmtState::Stopped);
  EXPECT_EQ(nmt_state_from_byte(0x00), NmtState::Initialising);
  EXPECT_FALSE(nmt_state_from_byte(0x01).has_value());
}

}  // namespace
}  // namespace nmt
