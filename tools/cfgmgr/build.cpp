// cfgmgr build NETWORK -o DIR: the master DCF and every slave's concise DCF of a network
// description (cfg/network_build.hpp), what lely's dcfgen makes from its YAML, so that a master
// DCF alone describes the network.
#include <filesystem>
#include <iostream>
#include <memory>
#include <string>
#include <system_error>

#include "../common/tool_support.hpp"
#include "cfg/device_file.hpp"
#include "cfg/network.hpp"
#include "cfg/network_build.hpp"
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
};

void write_or_exit(const std::string& path, std::string_view bytes) {
  if (auto written = tools::write_output(path, bytes); !written) {
    std::cerr << written.error().message << '\n';
    exit_with(tools::kExitIo);
  }
}

void run_build(const BuildCliOptions& options) {
  if (options.net == 0)
    fail_command(kTool, tools::kExitUsage, "--net: networks are numbered from 1");
  const auto network = load_network_or_exit(options.network, options.net);
  const cfg::NetworkBuild build = cfg::build_network(*network);
  // The master's node-ID as cfgmgr master and push take it (--node-id, else the network's, else
  // 7Fh), and a check that the master can be built from the dictionary written (CiA 306 §4.7: a
  // DCF names its node).
  const std::uint8_t node_id =
      build_master(kTool, options.network, network, options.node_id, {}).node_id().value();

  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(options.output_dir, ec);
  if (ec || !fs::is_directory(options.output_dir)) {
    std::cerr << tools::io_error(options.output_dir, "cannot create the directory" +
                                                         (ec ? ": " + ec.message() : std::string()))
                     .message
              << '\n';
    exit_with(tools::kExitIo);
  }
  const fs::path dir(options.output_dir);
  for (const auto& node : build.nodes) {
    const std::string path = (dir / node.file_name).string();
    write_or_exit(path, std::string_view(reinterpret_cast<const char*>(node.concise_dcf.data()),
                                         node.concise_dcf.size()));
    std::cout << path << ": node " << int{node.node_id.value()}
              << (node.name.empty() ? "" : " (" + node.name + ")") << ", " << node.entries
              << (node.entries == 1 ? " entry, " : " entries, ")
              << tools::plural(node.concise_dcf.size(), "byte") << '\n';
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
      "downloads to node N)");
  cmd->add_option("network", options->network,
                  "CiA 306-3 project file (nodelist.cpj; DCF paths relative to it) or a master "
                  "DCF (CANopenManager=1) whose 1F20h/1F22h name node files with DownloadFile=")
      ->required()
      ->type_name("NETWORK");
  cmd->add_option("-o,--output", options->output_dir,
                  "The directory to write into (created when missing; files in it are replaced "
                  "whole, never left half-written)")
      ->required()
      ->type_name("DIR");
  cmd->add_option("--net", options->net,
                  "Which network of the project file: 1 is [Topology], N is [TopologyN]")
      ->capture_default_str()
      ->type_name("N");
  cmd->add_option("--node-id", options->node_id,
                  "The master's node-ID written into master.dcf (1..127); default: the "
                  "network's, else 0x7F (127), as cfgmgr master takes it")
      ->type_name("N");
  cmd->add_flag("--lf", options->lf, "End the master DCF's lines with LF instead of CRLF");
  cmd->footer(std::string("cfgmgr push DIR/master.dcf configures the network as cfgmgr push "
                          "NETWORK does (the same writes, the same 1F26h/1F27h).\n\n"
                          "Examples:\n"
                          "  cfgmgr build samples/network/nodelist.cpj -o out\n"
                          "  cfgmgr build plant.cpj --net 2 -o net2\n"
                          "  cfgmgr push out/master.dcf --bus socketcan:can0\n\n") +
              std::string(tools::kExitCodesHelp));
  cmd->callback([options] { run_build(*options); });
}

}  // namespace cfgmgr
