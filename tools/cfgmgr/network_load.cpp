// The network loaded and its master built (network_load.hpp).
#include "network_load.hpp"

#include <iostream>
#include <map>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "cfg/node_id.hpp"

namespace cfgmgr {

namespace {

// NODE=TEXT of --program/--program-version: the node and the text; exit 2 when malformed.
std::pair<cfg::NodeId, std::string> node_assignment_or_exit(std::string_view option,
                                                            const std::string& spec) {
  const std::size_t eq = spec.find('=');
  const auto id = tools::parse_node_id_argument(std::string_view(spec).substr(0, eq));
  if (eq == std::string::npos || !id || eq + 1 == spec.size()) {
    exit_with(tools::kExitUsage,
              "cfgmgr: " + std::string(option) + " " + spec + ": expected NODE=" +
                  (option == "--program" ? "FILE" : "VERSION") + " with NODE a node-ID (1..127)");
  }
  return {*id, spec.substr(eq + 1)};
}

// --program/--program-version applied to the network; errors go to `diagnostics`.
void apply_program_overrides(cfg::Network& network, const ProgramOverrides& programs,
                             cfg::Diagnostics& diagnostics) {
  std::map<std::uint8_t, std::pair<std::string, std::optional<cfg::ProgramVersion>>> wanted;
  for (const auto& spec : programs.files) {
    auto [node, file] = node_assignment_or_exit("--program", spec);
    wanted[node.value()].first = file;
  }
  for (const auto& spec : programs.versions) {
    auto [node, text] = node_assignment_or_exit("--program-version", spec);
    auto version = cfg::parse_program_version(text);
    if (!version) {
      exit_with(tools::kExitUsage,
                "cfgmgr: --program-version " + spec + ": " + version.error().message);
    }
    wanted[node.value()].second = *version;
  }
  for (const auto& [id, program] : wanted) {
    const auto node = *cfg::NodeId::from(id);
    if (auto set = cfg::set_node_program(network, node, program.first, program.second); !set) {
      diagnostics.add("--program", 0, cfg::Severity::Error,
                      "node " + std::to_string(id) + ": " + set.error().message);
    }
  }
}

}  // namespace

std::optional<std::map<std::string, std::string>> parse_defines(
    const std::vector<std::string>& defines) {
  std::map<std::string, std::string> out;
  for (const auto& d : defines) {
    const auto eq = d.find('=');
    if (eq == std::string::npos || eq == 0) {
      std::cerr << "--define " << d << ": expected NAME=VALUE\n";
      return std::nullopt;
    }
    out[d.substr(0, eq)] = d.substr(eq + 1);
  }
  return out;
}

std::shared_ptr<const cfg::Network> load_network_or_exit(const std::string& path, unsigned net,
                                                         const ProgramOverrides& programs,
                                                         const std::vector<std::string>& dcf_path,
                                                         const std::vector<std::string>& defines) {
  cfg::NetworkOptions load_options;
  load_options.net = net;
  load_options.dcf_path = dcf_path;
  load_options.dcf_path_hint = kDcfPathHint;
  auto placeholders = parse_defines(defines);
  if (!placeholders) exit_with(tools::kExitUsage);
  load_options.placeholders = std::move(*placeholders);
  auto load = cfg::load_network(path, load_options);
  if (load.network) {
    apply_program_overrides(*load.network, programs, load.diagnostics);
    cfg::check_programs(*load.network, load.diagnostics);
  }
  tools::print_diagnostics(load.diagnostics);
  if (load.unreadable) exit_with(tools::kExitIo);
  if (!load.ok()) exit_with(tools::kExitInputErrors);
  return std::make_shared<const cfg::Network>(std::move(*load.network));
}

nmt::MasterConfig master_config_or_exit(std::string_view tool, const std::string& description,
                                        const std::shared_ptr<const cfg::Network>& network,
                                        const std::string& node_id_text,
                                        nmt::MasterOptions options) {
  cfg::NodeId node_id = nmt::MasterConfig::default_node_id(*network);
  if (!node_id_text.empty()) {
    const auto parsed = tools::parse_node_id_argument(node_id_text);
    if (!parsed) {
      fail_command(tool, tools::kExitUsage,
                   tools::node_id_argument_error("--node-id", node_id_text));
    }
    node_id = *parsed;
  }
  // Said here with the flag that changes it (from_network refuses it too).
  if (const cfg::NetworkNode* clash = network->find(node_id)) {
    fail_command(tool, node_id_text.empty() ? tools::kExitInputErrors : tools::kExitUsage,
                 "the master's node-ID " + std::to_string(node_id.value()) +
                     " is also the node-ID of " + clash->file + " (give another with --node-id N)");
  }
  // DSP 302 §6: the master is the network's configuration manager, 1F20h-1F27h included; the
  // master DCF goes through the typed configuration, as an embedder's master does.
  auto config = nmt::MasterConfig::from_network(network, node_id, std::move(options));
  // What the DCF says is checked here, so that a later failure of build_master_or_exit is the
  // caller's change.
  cfg::Status valid = config ? config->validate() : cfg::Status(config.error());
  if (!valid) {
    const std::string& from = network->master_from_file ? network->master_file : description;
    exit_with(tools::kExitInputErrors, from + ": error: " + valid.error().message);
  }
  return std::move(config).value();
}

nmt::NmtMaster build_master_or_exit(const nmt::MasterConfig& config, const std::string& description,
                                    const cfg::Network& network) {
  auto master = config.build();
  if (!master) {
    const std::string& from = network.master_from_file ? network.master_file : description;
    exit_with(tools::kExitInputErrors, from + ": error: " + master.error().message);
  }
  return std::move(master).value();
}

nmt::NmtMaster build_master(std::string_view tool, const std::string& description,
                            const std::shared_ptr<const cfg::Network>& network,
                            const std::string& node_id_text, nmt::MasterOptions options) {
  return build_master_or_exit(
      master_config_or_exit(tool, description, network, node_id_text, std::move(options)),
      description, *network);
}

}  // namespace cfgmgr
