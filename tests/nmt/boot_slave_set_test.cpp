// The master's boot engines as one set (BootSlaveSet, libnmt/core/src/master/boot_slave_set.hpp):
// the deadline it reports after every call, the order of due engines, and the start-up's
// boot-up gate (CiA 302-2 §3.1 d-e), through a fake port that answers for every node.
#include <gtest/gtest.h>

#include <chrono>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "master/boot_slave_set.hpp"
#include "nmt/master/master_options.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;

/// Records which node asked for which object; every node is an optional boot slave.
class AnyNodePort final : public BootSlavePort {
 public:
  std::vector<std::pair<std::uint8_t, std::uint16_t>> accesses;  ///< (node, index)

  void transfer(std::uint64_t, SdoTransferScheduler::Request r, TimePoint) override {
    accesses.emplace_back(r.node.value(), r.object.index);
  }
  void cancel_transfers(cfg::NodeId, TimePoint) override {}
  void queue_nmt(NmtCommand, cfg::NodeId) override {}
  bool start_error_control(cfg::NodeId, TimePoint) override { return false; }
  BootSlaveExpectations expectations(cfg::NodeId) const override {
    BootSlaveExpectations e;
    e.assignment =
        cfg::SlaveAssignment::make(cfg::SlaveAssignment::kSlave | cfg::SlaveAssignment::kBootSlave);
    return e;
  }
  std::optional<Duration> heartbeat_time(cfg::NodeId) const override { return std::nullopt; }
  KnownState known_state(cfg::NodeId) const override { return {}; }
  std::optional<TimePoint> last_heartbeat(cfg::NodeId) const override { return std::nullopt; }
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId) const override {
    return std::nullopt;
  }
  std::optional<std::vector<std::uint8_t>> program(cfg::NodeId) const override {
    return std::nullopt;
  }
  TimePoint startup_began() const override { return TimePoint{}; }
  void boot_con(cfg::NodeId, std::optional<BootError>, bool, TimePoint,
                Outbox<MasterEvent>&) override {}
};

cfg::NodeId id(std::uint8_t node) {
  return *cfg::NodeId::from(node);
}

struct Rig {
  AnyNodePort port;
  BootSlaveSet boots{port, BootSlaveProcess::Options::from(MasterOptions{})};
  BootSlaveSet::Output out;
  TimePoint now{Duration{1'000'000}};

  /// §3.1 d: the boot of `node` after the reset of all nodes waits for its boot-up until `until`.
  void start_after_reset(std::uint8_t node, TimePoint until) {
    boots.with(id(node), [&](BootSlaveProcess& b) { b.start_after_reset(until, now, out); });
  }
  bool boot_up(std::uint8_t node, TimePoint at) {
    return boots.with(id(node), [&](BootSlaveProcess& b) { return b.on_boot_up(at, out); });
  }
};

TEST(BootSlaveSet, ReportsTheEarliestEngineDeadlineAfterEveryCall) {
  Rig rig;
  EXPECT_EQ(rig.boots.next_deadline(), std::nullopt);
  rig.start_after_reset(3, rig.now + 500ms);
  rig.start_after_reset(7, rig.now + 200ms);
  EXPECT_EQ(rig.boots.next_deadline(), rig.now + 200ms);
  EXPECT_TRUE(rig.boot_up(7, rig.now + 10ms));  // node 7 identifies: its wait is over
  EXPECT_EQ(rig.boots.next_deadline(), rig.now + 500ms);
  EXPECT_TRUE(rig.boot_up(3, rig.now + 20ms));
  EXPECT_EQ(rig.boots.next_deadline(), std::nullopt);
  EXPECT_EQ(rig.port.accesses,
            (std::vector<std::pair<std::uint8_t, std::uint16_t>>{{7, 0x1000}, {3, 0x1000}}));
}

// §3.1 d-e: after the reset of all nodes the boots start together once every reset slave
// booted up; the gate opens for all of them, in node-ID order.
TEST(BootSlaveSet, GateOpensWhenEverySlaveWaitingAtItBootedUp) {
  Rig rig;
  rig.boots.gate().close(rig.now + 500ms, false);
  rig.start_after_reset(3, rig.now + 500ms);
  rig.start_after_reset(2, rig.now + 500ms);
  EXPECT_TRUE(rig.boot_up(3, rig.now + 10ms));
  rig.boots.open_gate(rig.now + 10ms, rig.out);
  EXPECT_TRUE(rig.boots.gate().closed()) << "node 2 has not booted up";
  EXPECT_TRUE(rig.port.accesses.empty());
  EXPECT_TRUE(rig.boot_up(2, rig.now + 30ms));
  rig.boots.open_gate(rig.now + 30ms, rig.out);
  EXPECT_FALSE(rig.boots.gate().closed());
  EXPECT_EQ(rig.port.accesses,
            (std::vector<std::pair<std::uint8_t, std::uint16_t>>{{2, 0x1000}, {3, 0x1000}}));
  EXPECT_EQ(rig.boots.next_deadline(), std::nullopt) << "both waits ended with the gate";
}

// Engines due at the same time run in node-ID order, whatever order they were started in;
// a boot-up lost at the closed gate ends with the wait, and the boot identifies anyway.
TEST(BootSlaveSet, RunsEnginesDueTogetherInNodeIdOrder) {
  Rig rig;
  rig.boots.gate().close(rig.now + 500ms, false);
  rig.start_after_reset(9, rig.now + 500ms);
  rig.start_after_reset(4, rig.now + 500ms);
  rig.boots.on_timer(rig.now + 499ms, rig.out);
  EXPECT_TRUE(rig.port.accesses.empty());
  rig.boots.on_timer(rig.now + 500ms, rig.out);
  EXPECT_EQ(rig.port.accesses,
            (std::vector<std::pair<std::uint8_t, std::uint16_t>>{{4, 0x1000}, {9, 0x1000}}));
  EXPECT_EQ(rig.boots.next_deadline(), std::nullopt);
}

}  // namespace
}  // namespace nmt
