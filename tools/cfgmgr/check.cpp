// cfgmgr check FILE...: read EDS/DCF files (CiA 306), check them against the CiA 301/302 object
// definitions in schemas/, and print every diagnostic. Exit 0 when nothing is an error. A network
// description (CiA 306-3 project file, or a master DCF with --network) is checked as a whole:
// every node's DCF, and across nodes (cfg/network_check.hpp). A DCF's own download (a single file
// as each node of a network) runs through the write rules of a CiA 301 device
// (cfg/write_acceptance.hpp): a write the device will refuse is a warning, an error with --strict.
#include <algorithm>
#include <cctype>
#include <filesystem>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/bus_yml.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/network.hpp"
#include "cfg/network_check.hpp"
#include "cfg/schema.hpp"
#include "cfg/write_acceptance.hpp"
#include "commands.hpp"
#include "network_load.hpp"
#include "run_args.hpp"

namespace cfgmgr {
namespace {

struct CheckOptions {
  std::vector<std::string> files;
  bool strict = false;
  bool json = false;
  bool no_schema = false;
  bool network = false;
  unsigned net = 1;
  std::string schema_dir;
  std::vector<std::string> dcf_path;  ///< --dcf-path DIR
  std::vector<std::string> defines;   ///< --define NAME=VALUE
};

struct FileReport {
  std::string file;
  bool readable = true;
  std::size_t objects = 0;
  std::optional<std::size_t> nodes;  ///< set for a network description
  cfg::Diagnostics diagnostics;
};

std::string json_report(const std::vector<FileReport>& reports, bool ok) {
  std::string out = "{\"ok\": " + std::string(ok ? "true" : "false") + ", \"files\": [";
  bool first = true;
  for (const auto& r : reports) {
    if (!first) out += ", ";
    first = false;
    const auto& d = r.diagnostics;
    out += "{\"file\": " + tools::json_string(r.file) +
           ", \"readable\": " + (r.readable ? "true" : "false") +
           ", \"ok\": " + (r.readable && !d.has_errors() ? "true" : "false") +
           ", \"objects\": " + std::to_string(r.objects) +
           (r.nodes ? ", \"network\": true, \"nodes\": " + std::to_string(*r.nodes)
                    : std::string(", \"network\": false")) +
           ", \"errors\": " + std::to_string(d.count(cfg::Severity::Error)) +
           ", \"warnings\": " + std::to_string(d.count(cfg::Severity::Warning)) +
           ", \"notes\": " + std::to_string(d.count(cfg::Severity::Note)) +
           ", \"diagnostics\": " + tools::json_diagnostics(d) + "}";
  }
  return out + "]}\n";
}

// True for a path whose extension is `ext` (any case): CiA 306 §2 names DCFs .dcf, CiA 306-3
// project files .cpj.
bool has_extension(const std::string& path, std::string_view ext) {
  return cfg::iequals(std::filesystem::path(path).extension().string(), ext);
}

// A CiA 306-3 project file has a [Topology] section (network 1) or [TopologyN]. Looks at every
// '[' of the file: no copy per section (a device file has thousands).
bool has_topology_section(std::string_view text) {
  for (std::size_t at = 0; (at = text.find('[', at)) != std::string_view::npos; ++at) {
    const bool line_start = at == 0 || text[at - 1] == '\n' || text[at - 1] == '\r';
    if (line_start && at + 1 < text.size() && (text[at + 1] | 0x20) == 't' &&
        cfg::iequals(text.substr(at + 1, 8), "topology")) {
      return true;
    }
  }
  return false;
}

// The writes the file configures, as the master downloads them (concise_writes_from_dcf,
// PDO-safe order), against a device built from the file: what a CiA 301 device would refuse
// (cfg/write_acceptance.hpp). Needs the node-ID the DCF is for; a file whose writes cannot be
// made (the reader or the node-ID warning said why) is not run. A master's DCF
// (CANopenManager=1) configures the master itself, which no download configures: not run, as
// the network check runs only the nodes'.
void check_own_download(const cfg::DeviceDescription& device, const std::string& path,
                        FileReport& report) {
  if (device.commissioning && device.commissioning->canopen_manager.value_or(false)) return;
  const auto id = device.node_id();
  const auto node = id ? cfg::NodeId::from(*id) : std::nullopt;
  if (!node) return;
  cfg::ConciseOptions concise;
  concise.node_id = node->value();
  concise.base_dir = std::filesystem::path(path).parent_path().string();
  concise.file_name = report.file;
  cfg::Diagnostics ignored;  // dcf2concise's findings; the reader's are already in the report
  const auto writes = cfg::concise_writes_from_dcf(device, concise, ignored);
  if (!writes) return;
  cfg::check_download(device, *node, *writes, report.file, "", report.diagnostics);
}

// The whole description: what load_network reports (unreadable node files and node-ID clashes
// at the project file's line, each DCF's own diagnostics), each node's DCF against the schemas,
// and the checks across nodes.
FileReport check_network_file(const std::string& file, const CheckOptions& options,
                              const std::vector<cfg::DeviceDescription>& schemas,
                              bool& unreadable) {
  FileReport report;
  report.file = file;
  cfg::NetworkOptions load_options;
  load_options.net = options.net;
  if (auto placeholders = parse_defines(options.defines)) {
    load_options.placeholders = std::move(*placeholders);
  } else {
    exit_with(tools::kExitUsage);
  }
  load_options.mode = options.strict ? cfg::ReadMode::Strict : cfg::ReadMode::Tolerant;
  load_options.dcf_path = options.dcf_path;
  load_options.dcf_path_hint = kDcfPathHint;
  cfg::NetworkLoad load = cfg::load_network(file, load_options);
  report.diagnostics = std::move(load.diagnostics);
  if (load.unreadable) {
    report.readable = false;
    unreadable = true;
    return report;
  }
  if (!load.network) return report;
  const cfg::Network& network = *load.network;
  report.nodes = network.nodes.size();
  for (const auto& node : network.nodes) {
    if (!node.dcf) continue;
    report.objects += node.dcf->objects.size();
    for (const auto& schema : schemas) {
      cfg::check_against_schema(*node.dcf, schema, node.file, report.diagnostics);
    }
  }
  cfg::check_network(network, report.diagnostics);
  cfg::check_programs(network, report.diagnostics);  // DSP 302 §9: images and versions
  return report;
}

void run_check(const CheckOptions& options) {
  if (std::count(options.files.begin(), options.files.end(), "-") > 1) {
    fail_command("check", tools::kExitUsage, "error: '-' (stdin) can be given only once");
  }
  // The standard's object definitions: from --schema-dir, else as cfg::find_schema_dir() finds
  // them ($CANOPEN_SCHEMA_DIR, or installed beside the program). Never skipped silently: when
  // they cannot be had the check fails (exit 3, before any file is read); --no-schema opts out.
  std::vector<cfg::DeviceDescription> schemas;
  if (!options.no_schema) {
    const bool asked = !options.schema_dir.empty();
    std::string dir = options.schema_dir;
    if (!asked) {
      auto found = cfg::find_schema_dir();
      if (!found) {
        fail_command("check", tools::kExitIo,
                     "error: " + found.error().message +
                         "; give --schema-dir DIR, or --no-schema to check without them");
      }
      dir = std::move(found).value();
    }
    for (auto name : cfg::kStandardSchemas) {
      auto schema = cfg::load_schema(name, dir);
      if (!schema) {
        // The message may end with the schema file's diagnostics, one a line.
        std::string why = schema.error().message;
        while (!why.empty() && why.back() == '\n') why.pop_back();
        fail_command("check", tools::kExitIo,
                     "error: " + std::string(asked ? "--schema-dir " : "schema directory ") + dir +
                         ": cannot load schema " + std::string(name) + ": " + why);
      }
      schemas.push_back(std::move(schema).value());
    }
  }

  std::vector<FileReport> reports;
  bool any_unreadable = false;
  bool any_errors = false;
  for (const auto& file : options.files) {
    FileReport report;
    const bool from_stdin = file == "-";
    report.file = from_stdin ? "<stdin>" : file;
    cfg::ReadOptions read_options;
    read_options.mode = options.strict ? cfg::ReadMode::Strict : cfg::ReadMode::Tolerant;
    read_options.file_name = report.file;
    auto text = tools::read_input(file);
    if (!text) {
      std::cerr << text.error().message << '\n';
      report.readable = false;
      any_unreadable = true;
      reports.push_back(std::move(report));
      continue;
    }
    if (!from_stdin && (options.network || has_extension(file, ".cpj") ||
                        cfg::is_bus_yml_path(file) || has_topology_section(*text))) {
      text->release();
      report = check_network_file(file, options, schemas, any_unreadable);
      if (options.strict) report.diagnostics = tools::promote_warnings(report.diagnostics);
      tools::print_diagnostics(report.diagnostics);
      any_errors = any_errors || report.diagnostics.has_errors();
      if (!options.json && report.readable) {
        std::cout << report.file << ": "
                  << tools::plural(report.diagnostics.count(cfg::Severity::Error), "error") << ", "
                  << tools::plural(report.diagnostics.count(cfg::Severity::Warning), "warning")
                  << ", " << tools::plural(report.nodes.value_or(0), "node") << '\n';
      }
      reports.push_back(std::move(report));
      continue;
    }
    auto read = cfg::parse_device_description(*text, read_options);
    text->release();  // the model holds copies: give the file's bytes back now
    report.diagnostics = read.diagnostics;
    if (read.device) {
      report.objects = read.device->objects.size();
      for (const auto& schema : schemas) {
        cfg::check_against_schema(*read.device, schema, report.file, report.diagnostics);
      }
      // CiA 306 §4.7: a DCF describes one configured node, so it says which node-ID it is for.
      if (has_extension(file, ".dcf") && !read.device->node_id()) {
        report.diagnostics.add(report.file, 0, cfg::Severity::Warning,
                               "a DCF should give the node-ID in [DeviceComissioning] NodeID "
                               "(CiA 306)");
      }
      check_own_download(*read.device, from_stdin ? std::string() : file, report);
    } else if (!report.diagnostics.has_errors()) {
      report.diagnostics.add(report.file, 0, cfg::Severity::Error, "not a device description");
    }
    // Strict is lint: every warning is an error, as with -Werror.
    if (options.strict) report.diagnostics = tools::promote_warnings(report.diagnostics);
    tools::print_diagnostics(report.diagnostics);
    any_errors = any_errors || report.diagnostics.has_errors();
    if (!options.json) {
      std::cout << report.file << ": "
                << tools::plural(report.diagnostics.count(cfg::Severity::Error), "error") << ", "
                << tools::plural(report.diagnostics.count(cfg::Severity::Warning), "warning")
                << ", " << tools::plural(report.objects, "object") << '\n';
    }
    reports.push_back(std::move(report));
    // After the last file the process exits: that model goes with it, unfreed.
    if (&file == &options.files.back()) tools::keep_until_exit(std::move(read));
  }
  if (options.json) std::cout << json_report(reports, !any_unreadable && !any_errors);
  std::cout.flush();
  if (any_unreadable) exit_with(tools::kExitIo);
  if (any_errors) exit_with(tools::kExitInputErrors);
}

}  // namespace

void add_check_command(CLI::App& app) {
  auto options = std::make_shared<CheckOptions>();
  auto* cmd = app.add_subcommand(
      "check",
      "Read EDS/DCF files, check them against the CiA 301/302 object definitions and a DCF's "
      "download against the write rules of a CiA 301 device (a write the device will refuse: a "
      "warning naming the SDO abort code), and print every diagnostic (FILE:LINE: severity: "
      "message) on stderr");
  cmd->add_option("files", options->files,
                  "EDS or DCF files ('-': stdin), or network descriptions: a CiA 306-3 project "
                  "file (.cpj, or any file with a [Topology] section) or a lely dcfgen / "
                  "ros2_canopen bus.yml (.yml, .yaml) is checked as a whole")
      ->required()
      ->type_name("FILE");
  cmd->add_flag("--strict", options->strict,
                "Lint: every deviation from CiA 306 and every warning is an error");
  cmd->add_flag("--json", options->json, "Print the result as JSON on stdout");
  cmd->add_option("--schema-dir", options->schema_dir,
                  "Directory of the schema EDS files (default: $CANOPEN_SCHEMA_DIR, else "
                  "share/canopen/schemas of the installation)")
      ->type_name("DIR");
  cmd->add_flag("--no-schema", options->no_schema,
                "Do not check against the CiA 301/302 object definitions");
  cmd->add_flag("--network", options->network,
                "Check every FILE as a network description (needed for a master DCF whose "
                "1F20h/1F22h name the node files): missing files, node-ID clashes, COB-ID "
                "clashes between TPDOs, PDO mappings of objects that are not mappable");
  add_dcf_path_option(*cmd, options->dcf_path);
  cmd->add_option("--net", options->net,
                  "Which network of a project file: 1 is [Topology], N is [TopologyN]")
      ->capture_default_str()
      ->check(CLI::PositiveNumber)
      ->type_name("N");
  add_define_option(*cmd, options->defines);
  cmd->footer(std::string("Examples:\n"
                          "  cfgmgr check drive.eds\n"
                          "  cfgmgr check --strict network/*.dcf\n"
                          "  cfgmgr check --json node3.dcf | jq .files[0].errors\n"
                          "  cfgmgr check samples/network/nodelist.cpj\n"
                          "  cfgmgr check --network master.dcf\n\n") +
              std::string(tools::kExitCodesHelp));
  cmd->callback([options] { run_check(*options); });
}

}  // namespace cfgmgr
