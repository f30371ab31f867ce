// cfgmgr build NETWORK -o DIR: the master DCF and every slave's concise DCF of a network
// description (cfg/network_build.hpp), what lely's dcfgen makes from its YAML, so that a master
// DCF alone describes the network.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <system_error>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/bus_yml.hpp"
#include "cfg/device_file.hpp"
#include "cfg/dynamic_channels.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/network.hpp"
#include "cfg/network_build.hpp"
#include "cfg/node_id.hpp"
#include "commands.hpp"
#include "master_run.hpp"

namespace cfgmgr {
namespace {

constexpr std::string_view kTool = "build";

struct BuildCliOptions {
  std::string network;
  std::string output_dir;
  unsigned net = 1;
  std::string node_id;
  bool lf = false;
  std::vector<std::string> variables;  ///< NODE=FILE
  std::vector<std::string> dcf_path;   ///< --dcf-path DIR
  std::vector<std::string> defines;    ///< --define NAME=VALUE
};

void write_or_exit(const std::string& path, std::string_view bytes) {
  if (auto written = tools::write_output(path, bytes); !written) {
    exit_with(tools::kExitIo, written.error().message);
  }
}

// --variables NODE=FILE: node NODE's DCF with the network variables of FILE allocated into its
// [DynamicChannels] (CiA DSP 302 §8.2), as the DCF of the programmed device (§8.5).
void write_programmed_node(const std::string& spec, const cfg::Network& network,
                           const std::filesystem::path& dir, const BuildCliOptions& options) {
  const std::size_t eq = spec.find('=');
  const auto id = tools::parse_node_id_argument(std::string_view(spec).substr(0, eq));
  if (eq == std::string::npos || !id) {
    fail_command(kTool, tools::kExitUsage,
                 "--variables " + spec + ": expected NODE=FILE with NODE a node-ID (1..127)");
  }
  const std::string file = spec.substr(eq + 1);
  const cfg::NetworkNode* node = nullptr;
  for (const auto& n : network.nodes) {
    if (n.node_id == *id) node = &n;
  }
  if (node == nullptr || !node->dcf) {
    fail_command(kTool, tools::kExitInputErrors,
                 "--variables: node " + std::to_string(id->value()) +
                     (node == nullptr ? " is not in the network" : " has no DCF in the network"));
  }
  cfg::DeviceDescription device = *node->dcf;
  const std::optional<cfg::DynamicChannels> channels = cfg::dynamic_channels_of(device);
  if (!channels || channels->segments.empty()) {
    fail_command(kTool, tools::kExitInputErrors,
                 "--variables: node " + std::to_string(id->value()) + " (" + node->file +
                     ") has no [DynamicChannels] segments to allocate variables in");
  }
  auto text = tools::read_input(file);
  if (!text) fail_command(kTool, tools::exit_code_for(text.error()), text.error().message);
  auto vars = cfg::parse_network_variables(*text, file);
  if (!vars) fail_command(kTool, tools::kExitInputErrors, vars.error().message);
  auto allocation = cfg::allocate_variables(*channels, *vars);
  if (!allocation)
    fail_command(kTool, tools::kExitInputErrors, file + ": " + allocation.error().message);
  if (auto added = cfg::add_variable_objects(device, *channels, *allocation); !added) {
    fail_command(kTool, tools::kExitInputErrors, node->file + ": " + added.error().message);
  }
  cfg::WriteOptions write_options;
  write_options.kind = cfg::FileKind::Dcf;
  write_options.line_ending = options.lf ? cfg::LineEnding::Lf : cfg::LineEnding::Crlf;
  const std::string name = "node" + std::to_string(id->value()) + ".dcf";
  device.file_info.set("FileName", name);
  const std::string path = (dir / name).string();
  write_or_exit(path, cfg::write_device_description(device, write_options));
  std::cout << path << ": node " << int{id->value()} << " programmed, "
            << tools::plural(allocation->size(), "network variable") << " from " << file << '\n';
}

void run_build(const BuildCliOptions& options) {
  if (options.net == 0)
    fail_command(kTool, tools::kExitUsage, "--net: networks are numbered from 1");
  const auto network =
      load_network_or_exit(options.network, options.net, {}, options.dcf_path, options.defines);
  // A bus.yml is built as dcfgen builds it, so that ros2_canopen's launch files find the files:
  // each slave's concise DCF is named after its key, `<slave>.bin` (dcfgen's Slave.write_bin).
  // A key that is no plain file name ([A-Za-z0-9._-], not starting with a dot), or one that
  // another slave's name or our nodeN.bin would also give (case-insensitively: a file system may
  // not tell them apart), keeps ours, nodeN.bin, so that no file is written twice.
  cfg::NodeFileName file_name;
  if (cfg::is_bus_yml_path(options.network)) {
    const auto plain = [](const std::string& name) {
      return !name.empty() && name.front() != '.' &&
             std::all_of(name.begin(), name.end(), [](char c) {
               return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '.' || c == '_' ||
                      c == '-';
             });
    };
    const auto folded = [](std::string name) {
      for (char& c : name) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
      return name;
    };
    std::map<std::string, int> uses;  // folded file name -> slaves that would get it
    for (const auto& node : network->nodes) {
      if (plain(node.name)) ++uses[folded(node.name + ".bin")];
      ++uses[folded("node" + std::to_string(node.node_id.value()) + ".bin")];
    }
    file_name = [plain, folded, uses](const cfg::NetworkNode& node) {
      const std::string own = node.name + ".bin";
      if (plain(node.name) && uses.at(folded(own)) == 1) return own;
      return "node" + std::to_string(node.node_id.value()) + ".bin";
    };
  }
  const cfg::NetworkBuild build = cfg::build_network(*network, file_name);
  // The master's node-ID as cfgmgr master and push take it (--node-id, else the network's, else
  // 7Fh), and a check that the master can be built from the dictionary written (CiA 306 §4.7: a
  // DCF names its node).
  const std::uint8_t node_id =
      build_master(kTool, options.network, network, options.node_id, {}).node_id().value();

  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(options.output_dir, ec);
  if (ec || !fs::is_directory(options.output_dir)) {
    exit_with(tools::kExitIo,
              tools::io_error(options.output_dir, "cannot create the directory" +
                                                      (ec ? ": " + ec.message() : std::string()))
                  .message);
  }
  const fs::path dir(options.output_dir);
  for (const std::string& spec : options.variables) {
    write_programmed_node(spec, *network, dir, options);
  }
  for (const auto& node : build.nodes) {
    const std::string path = (dir / node.file_name).string();
    write_or_exit(path, std::string_view(reinterpret_cast<const char*>(node.concise_dcf.data()),
                                         node.concise_dcf.size()));
    std::cout << path << ": node " << int{node.node_id.value()}
              << (node.name.empty() ? "" : " (" + node.name + ")") << ", " << node.entries
              << (node.entries == 1 ? " entry, " : " entries, ")
              << tools::plural(node.concise_dcf.size(), "byte") << '\n';
    if (!node.program_image.empty()) {
      // CiA 302-3 program data (1F58h sub N names it), as dcfgen's software_file.
      const std::string image = (dir / node.program_file_name).string();
      write_or_exit(image,
                    std::string_view(reinterpret_cast<const char*>(node.program_image.data()),
                                     node.program_image.size()));
      std::cout << image << ": node " << int{node.node_id.value()} << "'s program, "
                << tools::plural(node.program_image.size(), "byte") << '\n';
    }
  }
  cfg::WriteOptions write_options;
  write_options.kind = cfg::FileKind::Dcf;
  write_options.line_ending = options.lf ? cfg::LineEnding::Lf : cfg::LineEnding::Crlf;
  cfg::DeviceDescription master = build.master;
  master.file_info.set("FileName", "master.dcf");
  master.commissioning->node_id = node_id;
  const std::string master_path = (dir / "master.dcf").string();
  write_or_exit(master_path, cfg::write_device_description(master, write_options));
  std::cout << master_path << ": the master ("
            << (network->master_from_file ? "from " + network->master_file : std::string("derived"))
            << "), 1F22h names " << tools::plural(build.nodes.size(), "concise DCF") << '\n';
}

}  // namespace

void add_build_command(CLI::App& app) {
  auto options = std::make_shared<BuildCliOptions>();
  auto* cmd = app.add_subcommand(
      "build",
      "Write a network's master DCF and one concise DCF per slave into a directory, as lely's "
      "dcfgen does: DIR/master.dcf (1F80h, 1F81h, 1F84h-1F88h, 1F26h/1F27h, 1016h as cfgmgr "
      "master derives them, or the network's own master DCF; 1F22h sub N names node N's file "
      "with DownloadFile= and UploadFile=) and DIR/nodeN.bin (the CiA 302 concise DCF the master "
      "downloads to node N; from a bus.yml DIR/<slave>.bin, dcfgen's names)");
  cmd->add_option("network", options->network,
                  "CiA 306-3 project file (nodelist.cpj; DCF paths relative to it) or a master "
                  "DCF (CANopenManager=1) whose 1F20h/1F22h name node files with DownloadFile= or "
                  "UploadFile= (lely dcfgen's master.dcf), or a lely / ros2_canopen bus.yml")
      ->required()
      ->type_name("NETWORK");
  cmd->add_option("-o,--output", options->output_dir,
                  "The directory to write into (created when missing; files in it are replaced "
                  "whole, never left half-written)")
      ->required()
      ->type_name("DIR");
  add_dcf_path_option(*cmd, options->dcf_path);
  cmd->add_option("--net", options->net,
                  "Which network of the project file: 1 is [Topology], N is [TopologyN]")
      ->capture_default_str()
      ->type_name("N");
  add_define_option(*cmd, options->defines);
  cmd->add_option("--node-id", options->node_id,
                  "The master's node-ID written into master.dcf (1..127); default: the "
                  "network's, else 0x7F (127), as cfgmgr master takes it")
      ->type_name("N");
  cmd->add_flag("--lf", options->lf, "End the master DCF's lines with LF instead of CRLF");
  cmd->add_option("--variables", options->variables,
                  "Program node NODE (a programmable device whose DCF has [DynamicChannels]): "
                  "allocate the network variables of FILE into its segments (CiA DSP 302 §8.2) "
                  "and write its DCF with them as DIR/nodeNODE.dcf (§8.5). FILE has one variable "
                  "per line, name,type,direction: a CiA 301 type name or number, in or out; "
                  "'#' starts a comment line. May be given for several nodes")
      ->type_name("NODE=FILE");
  cmd->footer(std::string("cfgmgr push DIR/master.dcf configures the network as cfgmgr push "
                          "NETWORK does (the same writes, the same 1F26h/1F27h).\n\n"
                          "Examples:\n"
                          "  cfgmgr build samples/network/nodelist.cpj -o out\n"
                          "  cfgmgr build plant.cpj --net 2 -o net2\n"
                          "  cfgmgr build plant.cpj -o out --variables 5=plc5.csv\n"
                          "    with plc5.csv:\n"
                          "      # name,type,direction\n"
                          "      start_button,BOOLEAN,in\n"
                          "      level,UNSIGNED8,in\n"
                          "      setpoint,UNSIGNED16,out\n"
                          "  cfgmgr push out/master.dcf --bus socketcan:can0\n\n") +
              std::string(tools::kExitCodesHelp));
  cmd->callback([options] { run_build(*options); });
}

}  // namespace cfgmgr
