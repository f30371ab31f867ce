#include "cfg/network_build.hpp"

#include <algorithm>
#include <utility>

#include "cfg/concise_dcf.hpp"
#include "cfg/data_type.hpp"
#include "cfg/object_index.hpp"

namespace cfg {
namespace {

std::string default_file_name(const NetworkNode& node) {
  return "node" + std::to_string(node.node_id.value()) + ".bin";
}

SubObject domain_entry(std::uint8_t sub_index, std::string name) {
  SubObject sub;
  sub.sub_index = sub_index;
  sub.name = std::move(name);
  sub.data_type = static_cast<std::uint16_t>(DataType::Domain);
  sub.access = AccessType::Rw;
  return sub;
}

// DSP 302 v3.2.1 §6.2: 1F22h is an ARRAY of DOMAIN, sub-index = the node-ID it configures;
// CiA 302-3's 1F58h (program data of node N) has the same shape.
Object domain_array(std::uint16_t index, std::string name, const std::vector<BuiltNode>& nodes,
                    std::string BuiltNode::*file) {
  Object object;
  object.index = index;
  object.name = std::move(name);
  object.object_type = ObjectType::Array;
  object.sub_number = static_cast<std::uint8_t>(kMaxNodeId + 1);
  SubObject count;
  count.sub_index = 0;
  count.name = "Highest sub-index supported";
  count.data_type = static_cast<std::uint16_t>(DataType::Unsigned8);
  count.access = AccessType::Ro;
  count.default_value = std::to_string(kMaxNodeId);
  object.subs.emplace(0, std::move(count));
  for (unsigned x = kMinNodeId; x <= kMaxNodeId; ++x) {
    const auto sub_index = static_cast<std::uint8_t>(x);
    object.subs.emplace(sub_index, domain_entry(sub_index, "Node-ID " + std::to_string(x)));
  }
  for (const auto& node : nodes) {
    if ((node.*file).empty()) continue;
    SubObject& sub = object.subs.at(node.node_id.value());
    sub.download_file = node.*file;
    sub.upload_file = node.*file;
  }
  return object;
}

}  // namespace

NetworkBuild build_network(const Network& network, const NodeFileName& file_name) {
  NetworkBuild out;
  for (const auto& node : network.nodes) {
    BuiltNode built;
    built.node_id = node.node_id;
    built.name = node.name;
    built.file_name = file_name ? file_name(node) : default_file_name(node);
    built.concise_dcf = node_concise_dcf(node);
    built.entries = node.writes.size();
    if (node.program && !node.program->image.empty()) {
      built.program_image = node.program->image;
      const std::string& bin = built.file_name;
      const bool dot_bin = bin.size() > 4 && bin.compare(bin.size() - 4, 4, ".bin") == 0;
      built.program_file_name = (dot_bin ? bin.substr(0, bin.size() - 4) : bin) + ".img";
    }
    out.nodes.push_back(std::move(built));
  }
  out.master = network.master;
  // 1F20h entries naming node DCFs would configure the nodes a second way: 1F22h does now.
  if (Object* store = out.master.object(object::kStoreDcf)) {
    for (auto& [sub_index, sub] : store->subs) sub.download_file.reset();
  }
  out.master.objects.insert_or_assign(
      object::kConciseDcf,
      domain_array(object::kConciseDcf, "Concise DCF", out.nodes, &BuiltNode::file_name));
  const bool programs = std::any_of(out.nodes.begin(), out.nodes.end(),
                                    [](const BuiltNode& n) { return !n.program_image.empty(); });
  if (programs) {
    out.master.objects.insert_or_assign(object::kSlaveProgramData,
                                        domain_array(object::kSlaveProgramData, "Program data",
                                                     out.nodes, &BuiltNode::program_file_name));
  }
  if (!out.master.commissioning) out.master.commissioning.emplace();
  DeviceCommissioning& commissioning = *out.master.commissioning;
  commissioning.canopen_manager = true;
  if (network.master_node_id) commissioning.node_id = network.master_node_id->value();
  if (!network.name.empty()) commissioning.network_name = network.name;
  return out;
}

}  // namespace cfg
