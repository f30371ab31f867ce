// BootSlaveSet (boot_slave_set.hpp): the boot engines of the master, their gate and deadlines.
#include "master/boot_slave_set.hpp"

#include <bitset>

#include "master/master_support.hpp"

namespace nmt {

BootSlaveSet::BootSlaveSet(BootSlavePort& port, const BootSlaveProcess::Options& options) {
  engines_.reserve(cfg::kMaxNodeId);
  for (const auto node : all_node_ids()) engines_.emplace_back(node, port, gate_, options);
}

void BootSlaveSet::track(cfg::NodeId node) {
  const auto deadline = engines_[node.value() - 1U].next_deadline();
  deadlines_.move(node, deadline_of_[node.value()], deadline);
  deadline_of_[node.value()] = deadline;
}

void BootSlaveSet::open_gate(TimePoint now, Output& out, bool quiet) {
  for (const auto& b : engines_) {
    if (!quiet && b.at_boot_up_gate() && !b.boot_up_seen()) return;  // not yet
  }
  gate_.open();
  for (const auto node : all_node_ids()) {
    with(node, [&](BootSlaveProcess& b) { b.pass_boot_up_gate(now, out); });
  }
}

void BootSlaveSet::on_timer(TimePoint now, Output& out) {
  if (gate_.quiet_over(now)) open_gate(now, out, true);
  struct DueNodes {
    std::bitset<128> nodes;
    void push_back(cfg::NodeId node) { nodes.set(node.value()); }
  } due;
  deadlines_.due(now, due);
  if (due.nodes.none()) return;
  for (const auto node : all_node_ids()) {
    if (due.nodes[node.value()]) with(node, [&](BootSlaveProcess& b) { b.on_timer(now, out); });
  }
}

std::optional<TimePoint> BootSlaveSet::next_deadline() const {
  return earliest(gate_.next_deadline(), deadlines_.earliest());
}

}  // namespace nmt
