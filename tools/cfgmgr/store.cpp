// cfgmgr store put|get|list|rm|configure: the configuration manager's store (DSP 302 §6: 1F20h
// DCF, 1F22h concise DCF, 1F23h EDS, 1F26h/1F27h expected configuration, 1F25h configure
// slave), either a store directory (--store DIR, cfg::ConfigManager) or a running master's
// objects over SDO (--bus URL --master N, e.g. `cfgmgr master ... --store DIR`). Both go through
// the same object view, index and sub-index as a CANopen tool sees them: locally the manager's
// read/write, remotely SDO uploads and downloads. The operations are libnmt's
// nmt::ConfigStoreClient (nmt/manager/config_store_client.hpp); this file is the command line.
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/config_manager.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_index.hpp"
#include "commands.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/remote_config_store.hpp"
#include "nmt/manager/config_store_client.hpp"

namespace cfgmgr {
namespace {

constexpr std::string_view kTool = "store";

struct StoreCliOptions {
  std::string store;  ///< --store DIR
  std::string bus;    ///< --bus URL
  std::string master;
  double sdo_timeout_s = 1.0;
  // The sub-commands' arguments.
  std::string node;
  std::string file;
  std::string what;
  std::string output = "-";
  bool json = false;
};

/// The client's failures: exit 3 when the store or the master could not be reached, else 1.
template <class T>
T must(cfg::Result<T> result, const std::string& prefix = {}) {
  if (!result)
    fail_command(kTool, tools::exit_code_for(result.error()), prefix + result.error().message);
  return std::move(result).value();
}

void must(const cfg::Status& status) {
  if (!status) fail_command(kTool, tools::exit_code_for(status.error()), status.error().message);
}

cfg::NodeId parse_node(const std::string& text) {
  const auto node = tools::parse_node_id_argument(text);
  if (!node) fail_command(kTool, tools::kExitUsage, tools::node_id_argument_error("NODE", text));
  return *node;
}

std::optional<nmt::StoreFile> parse_what(const std::string& text) {
  if (text == "dcf") return nmt::StoreFile::Dcf;
  if (text == "concise") return nmt::StoreFile::Concise;
  if (text == "eds") return nmt::StoreFile::Eds;
  if (!text.empty())
    fail_command(kTool, tools::kExitUsage, "--what " + text + ": expected dcf, concise or eds");
  return std::nullopt;
}

/// put: --what, else the file's extension.
nmt::StoreFile what_of_file(const std::string& path, const std::string& what) {
  if (auto w = parse_what(what)) return *w;
  std::string ext = path.substr(std::min(path.size(), path.rfind('.') + 1));
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (path.rfind('.') == std::string::npos) ext.clear();
  if (ext == "dcf") return nmt::StoreFile::Dcf;
  if (ext == "eds") return nmt::StoreFile::Eds;
  if (ext == "bin" || ext == "cdcf" || ext == "concise") return nmt::StoreFile::Concise;
  fail_command(kTool, tools::kExitUsage,
               path +
                   ": cannot tell a DCF (.dcf), an EDS (.eds) or a concise DCF (.bin, "
                   ".cdcf) from the name; give --what dcf|concise|eds");
}

std::unique_ptr<nmt::StoreObjects> open_store(const StoreCliOptions& o) {
  const bool local = !o.store.empty();
  const bool remote = !o.bus.empty() || !o.master.empty();
  if (local == remote) {
    fail_command(kTool, tools::kExitUsage, "give either --store DIR or --bus URL --master N");
  }
  if (local) {
    auto opened = cfg::ConfigManager::open(o.store);
    if (!opened) fail_command(kTool, tools::kExitIo, opened.error().message);
    // A damaged entry is reported and not used (cfg/config_manager.hpp).
    tools::print_diagnostics(opened.value().problems());
    return std::make_unique<nmt::StoreDirectoryObjects>(std::move(opened).value());
  }
  if (o.bus.empty() || o.master.empty()) {
    fail_command(kTool, tools::kExitUsage, "--bus URL and --master N go together");
  }
  if (o.bus.rfind("sim:", 0) == 0) {
    fail_command(kTool, tools::kExitUsage,
                 "--bus " + o.bus +
                     ": the simulated bus has no master to talk to; use the bus a "
                     "`cfgmgr master` runs on (socketcan:IF, udp://GROUP:PORT)");
  }
  const auto master = tools::parse_node_id_argument(o.master);
  if (!master)
    fail_command(kTool, tools::kExitUsage, tools::node_id_argument_error("--master", o.master));
  if (auto checked = nmt::check_bus_url(o.bus); !checked) {
    fail_command(kTool, tools::kExitUsage, checked.error().message);
  }
  const auto timeout = nmt::Duration(static_cast<std::int64_t>(o.sdo_timeout_s * 1e6));
  auto opened = nmt::open_remote_store(o.bus, *master, timeout);
  if (!opened) fail_command(kTool, tools::kExitIo, opened.error().message);
  return std::move(opened).value();
}

void put(nmt::ConfigStoreClient& store, const StoreCliOptions& o) {
  const cfg::NodeId node = parse_node(o.node);
  const nmt::StoreFile what = what_of_file(o.file, o.what);
  auto text = tools::read_input(o.file);
  if (!text) fail_command(kTool, tools::kExitIo, text.error().message);
  const std::string_view view = text.value().view();
  std::vector<std::uint8_t> data(view.begin(), view.end());
  if (data.empty())
    fail_command(kTool, tools::kExitInputErrors, o.file + ": the file is empty (rm removes)");
  const std::size_t size = data.size();
  // A file the manager would refuse is named by its path.
  const auto stamp = must(store.put(node, what, std::move(data)), o.file + ": ");
  std::cerr << "cfgmgr store: node " << int{node.value()} << ": " << size << " bytes to "
            << cfg::object_name(nmt::store_index(what));
  if (stamp) {
    std::cerr << ", 1F26h/1F27h = " << stamp->days << " days, " << stamp->ms << " ms";
  }
  std::cerr << '\n';
}

void get(nmt::ConfigStoreClient& store, const StoreCliOptions& o) {
  const cfg::NodeId node = parse_node(o.node);
  const auto data = must(store.get(node, parse_what(o.what).value_or(nmt::StoreFile::Concise)));
  const std::string_view bytes(reinterpret_cast<const char*>(data.data()), data.size());
  if (auto written = tools::write_output(o.output, bytes); !written) {
    fail_command(kTool, tools::kExitIo, written.error().message);
  }
}

std::string size_text(std::optional<std::size_t> size) {
  return size ? std::to_string(*size) : std::string("-");
}

void list(nmt::ConfigStoreClient& store, const StoreCliOptions& o) {
  const auto nodes = must(store.list());
  std::ostringstream out;
  if (o.json) {
    out << "{\"nodes\": [";
    const char* sep = "";
    for (const auto& l : nodes) {
      auto number = [](std::optional<std::size_t> v) {
        return v ? std::to_string(*v) : std::string("null");
      };
      out << sep << "\n  {\"node_id\": " << int{l.node.value()}
          << ", \"dcf_bytes\": " << number(l.dcf_bytes) << ", \"concise_bytes\": "
          << number(l.concise_bytes != 0 ? std::optional(l.concise_bytes) : std::nullopt)
          << ", \"concise_entries\": " << l.concise_entries
          << ", \"eds_bytes\": " << number(l.eds_bytes) << ", \"expected_date\": " << l.stamp.days
          << ", \"expected_time\": " << l.stamp.ms << "}";
      sep = ",";
    }
    out << (nodes.empty() ? "" : "\n") << "]}\n";
  } else {
    // Sizes in bytes as stored (the DCF and EDS uncompressed); '-': nothing stored.
    char line[160];
    std::snprintf(line, sizeof line, "%-5s %10s %10s %8s %10s %8s %10s\n", "node", "dcf", "concise",
                  "entries", "eds", "1F26h", "1F27h");
    out << line;
    for (const auto& l : nodes) {
      const std::string concise =
          l.concise_bytes != 0 ? std::to_string(l.concise_bytes) : std::string("-");
      std::snprintf(line, sizeof line, "%-5d %10s %10s %8zu %10s %8u %10u\n", int{l.node.value()},
                    size_text(l.dcf_bytes).c_str(), concise.c_str(), l.concise_entries,
                    size_text(l.eds_bytes).c_str(), l.stamp.days, l.stamp.ms);
      out << line;
    }
  }
  std::cout << out.str();
  std::cout.flush();
  if (!std::cout) fail_command(kTool, tools::kExitIo, "<stdout>: write error");
}

void remove(nmt::ConfigStoreClient& store, const StoreCliOptions& o) {
  must(store.remove(parse_node(o.node)));
}

void configure(nmt::ConfigStoreClient& store, const StoreCliOptions& o) {
  std::optional<cfg::NodeId> node;
  if (o.node != "all") {
    const auto id = tools::parse_node_id_argument(o.node);
    if (!id)
      fail_command(kTool, tools::kExitUsage,
                   tools::node_id_argument_error("NODE", o.node) + " or all");
    node = *id;
  }
  if (!store.remote()) {
    fail_command(kTool, tools::kExitUsage,
                 "configure asks a running master: give --bus URL --master N");
  }
  must(store.configure(node));
}

void add_target_options(CLI::App& cmd, StoreCliOptions& o) {
  cmd.add_option("--store", o.store,
                 "The store directory (created when missing): one file per entry, written "
                 "atomically; what `cfgmgr master --store DIR` serves")
      ->type_name("DIR");
  cmd.add_option("--bus", o.bus,
                 "Talk to a running master instead: its bus (socketcan:IF, udp://GROUP:PORT)")
      ->type_name("URL");
  cmd.add_option("--master", o.master, "The master's node-ID on --bus (1..127, e.g. 0x7F)")
      ->type_name("N");
  cmd.add_option("--sdo-timeout", o.sdo_timeout_s,
                 "Seconds to wait for each answer of the master (default 1)")
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
}

}  // namespace

void add_store_command(CLI::App& app) {
  auto o = std::make_shared<StoreCliOptions>();
  auto* cmd = app.add_subcommand(
      "store",
      "Put, get, list and remove the configurations a configuration manager stores per node "
      "(DSP 302 section 6: 1F20h DCF, 1F22h concise DCF, 1F23h EDS, 1F26h/1F27h expected "
      "configuration date/time), in a store directory or in a running master over SDO, and ask "
      "a running master to configure a node (1F25h 'conf')");
  cmd->require_subcommand(1);
  // On `store` itself, so that they may come before or after the action (fallthrough) and
  // `cfgmgr store --help` (the man page) lists them.
  add_target_options(*cmd, *o);
  auto run = [o](void (*action)(nmt::ConfigStoreClient&, const StoreCliOptions&)) {
    return [o, action] {
      auto objects = open_store(*o);
      nmt::ConfigStoreClient client(*objects);
      action(client, *o);
    };
  };

  auto* put_cmd = cmd->add_subcommand(
      "put", "Store FILE for NODE: a DCF in 1F20h, a concise DCF in 1F22h, an EDS in 1F23h");
  put_cmd->add_option("node", o->node, "The node-ID, 1..127")->required()->type_name("NODE");
  put_cmd->add_option("file", o->file, "The file (- for stdin, then with --what)")
      ->required()
      ->type_name("FILE");
  put_cmd
      ->add_option("--what", o->what,
                   "dcf, concise or eds; default: from the extension (.dcf, .eds, "
                   ".bin/.cdcf/.concise)")
      ->type_name("WHAT");
  put_cmd->fallthrough();
  put_cmd->callback(run(put));

  auto* get_cmd = cmd->add_subcommand("get", "Write what is stored for NODE to -o FILE");
  get_cmd->add_option("node", o->node, "The node-ID, 1..127")->required()->type_name("NODE");
  get_cmd->add_option("--what", o->what, "dcf, concise (default) or eds")->type_name("WHAT");
  get_cmd->add_option("-o,--output", o->output, "Where to write it (default -: stdout)")
      ->type_name("FILE");
  get_cmd->fallthrough();
  get_cmd->callback(run(get));

  auto* list_cmd = cmd->add_subcommand("list", "A table of the nodes with something stored");
  list_cmd->add_flag("--json", o->json,
                     "JSON instead: {\"nodes\": [{node_id, dcf_bytes, concise_bytes, "
                     "concise_entries, eds_bytes, expected_date, expected_time}]}, null for "
                     "nothing stored");
  list_cmd->fallthrough();
  list_cmd->callback(run(list));

  auto* rm_cmd =
      cmd->add_subcommand("rm", "Remove everything stored for NODE (DCF, concise DCF, EDS, stamp)");
  rm_cmd->add_option("node", o->node, "The node-ID, 1..127")->required()->type_name("NODE");
  rm_cmd->fallthrough();
  rm_cmd->callback(run(remove));

  auto* configure_cmd = cmd->add_subcommand(
      "configure",
      "Ask a running master (--bus, --master) to configure NODE now, or all: 1F25h = 'conf'");
  configure_cmd->add_option("node", o->node, "The node-ID 1..127, or all (1F25h sub 80h)")
      ->required()
      ->type_name("NODE");
  configure_cmd->fallthrough();
  configure_cmd->callback(run(configure));

  cmd->footer(std::string(
      "Actions (each with --store DIR, a store directory, or --bus URL --master N, the "
      "configuration manager of a running master such as cfgmgr master NETWORK --bus URL "
      "[--store DIR], over SDO: block transfer, segmented when the master has none; a node "
      "with nothing stored there reads the network's configuration, what the master "
      "downloads):\n"
      "  put NODE FILE [--what dcf|concise|eds]   store FILE for NODE\n"
      "  get NODE [--what dcf|concise|eds] [-o FILE|--output FILE]   write what is stored "
      "(default: the concise DCF, to stdout)\n"
      "  list [--json]   the nodes with something stored\n"
      "  rm NODE   remove everything stored for NODE\n"
      "  configure NODE|all   ask the master to configure NODE now (1F25h = 'conf'; --bus "
      "only)\n\n"
      "put: a .dcf goes to 1F20h (the master derives the writes from it; no 1F22h copy is "
      "made, so the two cannot disagree), a concise DCF to 1F22h, an .eds to 1F23h. The file is "
      "checked first as the manager checks it. A DCF or concise DCF also sets 1F26h/1F27h to "
      "the stamp of its writes (the rule of derived masters, cfg/network.hpp), so the master "
      "downloads it once and afterwards skips a device whose 1020h matches. When a node has "
      "both, its concise DCF is what the master downloads.\n\n"
      "list: node, sizes in bytes (dcf and eds uncompressed, '-' for nothing stored), the "
      "concise DCF's entries, and 1F26h (days since 1984-01-01) / 1F27h (ms after midnight).\n\n"
      "Examples:\n"
      "  cfgmgr store put 5 drive.dcf --store /var/lib/canopen/store\n"
      "  cfgmgr store put 5 drive.cdcf --bus udp://239.74.163.2:43113 --master 0x7F\n"
      "  cfgmgr store get 5 --what concise -o node5.cdcf --store /var/lib/canopen/store\n"
      "  cfgmgr store list --json --store /var/lib/canopen/store\n"
      "  cfgmgr store rm 5 --store /var/lib/canopen/store\n"
      "  cfgmgr store configure 5 --bus socketcan:can0 --master 1\n\n"
      "Exit codes:\n"
      "  0  done\n"
      "  1  refused: the file is no valid DCF or concise DCF (the message says why), nothing is "
      "stored for the node, or the master answered with an SDO abort (code and words)\n"
      "  2  usage error (bad command line, a NODE outside 1..127, neither or both of --store "
      "and --bus, configure without --bus)\n"
      "  3  I/O error: a file or the store directory cannot be read or written, the bus cannot "
      "be opened, the master does not answer\n"));
}

}  // namespace cfgmgr
