// Loading the network a cfgmgr command runs and building its NMT master (libnmt's
// MasterConfig::from_network), with the tools' diagnostics and exit codes.
#pragma once

#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/network.hpp"
#include "nmt/master/master_config.hpp"
#include "nmt/master/nmt_master.hpp"
#include "run_args.hpp"

namespace cfgmgr {

/// The network loaded (the files a master DCF names looked for in `dcf_path` too, --dcf-path),
/// `programs` applied and cfg::check_programs run (diagnostics printed; exit 1 on errors, 3 when
/// unreadable, 2 for a malformed --program/--program-version). `defines` are --define's
/// NAME=VALUE (exit 2 for one without '=').
std::shared_ptr<const cfg::Network> load_network_or_exit(
    const std::string& path, unsigned net, const ProgramOverrides& programs = {},
    const std::vector<std::string>& dcf_path = {}, const std::vector<std::string>& defines = {});

/// --define's NAME=VALUE as NetworkOptions::placeholders; nullopt (and a message naming the
/// argument on stderr) for one without '=' or with an empty NAME.
std::optional<std::map<std::string, std::string>> parse_defines(
    const std::vector<std::string>& defines);

/// The master of `network` with node-ID `node_id_text` (empty: the network's, else 7Fh) and
/// `options` (its configurations come from the network). It is the configuration manager
/// (1F20h-1F27h): of options.manager when given (a store directory), else of one in memory,
/// and a node with nothing stored reads the network's configuration. Ends the command with
/// exit 2 for a bad --node-id, 1 when the master cannot be built.
nmt::NmtMaster build_master(std::string_view tool, const std::string& description,
                            const std::shared_ptr<const cfg::Network>& network,
                            const std::string& node_id_text, nmt::MasterOptions options);
/// build_master in two halves, for a command that changes the typed configuration in between
/// (push: --boot-time, --no-start, --only): the master DCF read into a checked MasterConfig,
/// then the master built from it. Both end the command as build_master does.
nmt::MasterConfig master_config_or_exit(std::string_view tool, const std::string& description,
                                        const std::shared_ptr<const cfg::Network>& network,
                                        const std::string& node_id_text,
                                        nmt::MasterOptions options);
nmt::NmtMaster build_master_or_exit(const nmt::MasterConfig& config, const std::string& description,
                                    const cfg::Network& network);

}  // namespace cfgmgr
