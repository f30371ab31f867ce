// cfgmgr store put|get|list|rm|configure: the configuration manager's store (DSP 302 §6: 1F20h
// DCF, 1F22h concise DCF, 1F23h EDS, 1F26h/1F27h expected configuration, 1F25h configure
// slave), either a store directory (--store DIR, cfg::ConfigManager) or a running master's
// objects over SDO (--bus URL --master N, e.g. `cfgmgr master ... --store DIR`). Both go through
// the same object view, index and sub-index as a CANopen tool sees them: locally the manager's
// read/write, remotely SDO uploads and downloads.
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
#include "cfg/bytes.hpp"
#include "cfg/config_manager.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/network.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "commands.hpp"
#include "nmt/bus.hpp"
#include "nmt/sdo_client.hpp"
#include "nmt/sdo_session.hpp"

namespace cfgmgr {
namespace {

namespace obj = cfg::object;
constexpr std::string_view kTool = "store";

/// What a node's entry is: the three files of DSP 302 §6.
enum class What : std::uint8_t { Dcf, Concise, Eds };

std::uint16_t index_of(What what) {
  switch (what) {
    case What::Dcf:
      return obj::kStoreDcf;
    case What::Eds:
      return obj::kStoreEds;
    case What::Concise:
      break;
  }
  return obj::kConciseDcf;
}

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

[[noreturn]] void fail(int code, const std::string& message) {
  std::cerr << "cfgmgr store: " << message << '\n';
  exit_with(code);
}

/// The answer of a read or write: an SDO abort code (0: done), the value, and why.
struct Access {
  std::uint32_t abort = 0;
  std::vector<std::uint8_t> data;
  std::string message;
  /// The store directory could not be written, or the master did not answer (exit 3).
  bool io = false;
  bool ok() const { return abort == 0; }
};

/// The store as objects (index, sub-index).
class Store {
 public:
  virtual ~Store() = default;
  virtual Access read(std::uint16_t index, std::uint8_t sub) = 0;
  virtual Access write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) = 0;
  virtual bool remote() const = 0;
};

/// A store directory through cfg::ConfigManager.
class LocalStore final : public Store {
 public:
  explicit LocalStore(cfg::ConfigManager manager) : manager_(std::move(manager)) {}
  Access read(std::uint16_t index, std::uint8_t sub) override {
    auto r = manager_.read(index, sub);
    return {static_cast<std::uint32_t>(r.abort), std::move(r.data), std::move(r.message)};
  }
  Access write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) override {
    auto r = manager_.write(index, sub, data);
    // cfg/config_manager.hpp: 0800 0020h is a directory that could not be written (1F25h,
    // whose wrong signature gives it too, is never written to a store directory).
    const bool io = r.abort == cfg::SdoAbort::CannotStoreOrTransfer;
    return {static_cast<std::uint32_t>(r.abort), {}, std::move(r.message), io};
  }
  bool remote() const override { return false; }

 private:
  cfg::ConfigManager manager_;
};

/// A master's configuration manager over SDO (its server at 600h/580h + node-ID).
class RemoteStore final : public Store {
 public:
  RemoteStore(std::unique_ptr<nmt::SdoSession> session, nmt::Duration timeout)
      : session_(std::move(session)) {
    options_.timeout = timeout;
    // Files are long: block transfer (CiA 301 §7.2.4.3.9), segmented when the server has none.
    options_.mode = nmt::SdoMode::Block;
  }
  Access read(std::uint16_t index, std::uint8_t sub) override {
    return access(session_->upload(index, sub, options_));
  }
  Access write(std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) override {
    return access(session_->download(index, sub, std::move(data), options_));
  }
  bool remote() const override { return true; }

 private:
  static Access access(cfg::Result<nmt::SdoResult> result) {
    if (!result) fail(tools::kExitIo, result.error().message);
    Access a;
    a.abort = static_cast<std::uint32_t>(result->abort);
    a.data = std::move(result->data);
    if (!result->ok()) a.message = nmt::to_string(result->abort);
    a.io = result->abort == nmt::SdoAbort::Timeout;
    return a;
  }

  std::unique_ptr<nmt::SdoSession> session_;
  nmt::SdoTransferOptions options_;
};

std::uint8_t parse_node(const std::string& text, bool allow_all = false) {
  if (allow_all && text == "all") return cfg::kConfigureAllNodes;
  const auto node = tools::parse_node_id_argument(text);
  if (!node) {
    fail(tools::kExitUsage,
         tools::node_id_argument_error("NODE", text) + (allow_all ? " or all" : ""));
  }
  return *node;
}

std::optional<What> parse_what(const std::string& text) {
  if (text == "dcf") return What::Dcf;
  if (text == "concise") return What::Concise;
  if (text == "eds") return What::Eds;
  if (!text.empty()) fail(tools::kExitUsage, "--what " + text + ": expected dcf, concise or eds");
  return std::nullopt;
}

/// put: --what, else the file's extension.
What what_of_file(const std::string& path, const std::string& what) {
  if (auto w = parse_what(what)) return *w;
  std::string ext = path.substr(std::min(path.size(), path.rfind('.') + 1));
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  if (path.rfind('.') == std::string::npos) ext.clear();
  if (ext == "dcf") return What::Dcf;
  if (ext == "eds") return What::Eds;
  if (ext == "bin" || ext == "cdcf" || ext == "concise") return What::Concise;
  fail(tools::kExitUsage, path +
                              ": cannot tell a DCF (.dcf), an EDS (.eds) or a concise DCF (.bin, "
                              ".cdcf) from the name; give --what dcf|concise|eds");
}

[[noreturn]] void fail_access(const Access& a, std::uint16_t index, std::uint8_t sub) {
  std::string text = cfg::to_string(cfg::ObjectAddress{index, sub}) + ": ";
  // The manager's words when it has them, and always the CiA 301 code with its text.
  const std::string code = nmt::to_string(static_cast<nmt::SdoAbort>(a.abort));
  text += a.message.empty() ? code : a.message;
  if (a.message.find(code) == std::string::npos) text += " (SDO abort " + code + ")";
  fail(a.io ? tools::kExitIo : tools::kExitInputErrors, text);
}

Access must(Access a, std::uint16_t index, std::uint8_t sub) {
  if (!a.ok()) fail_access(a, index, sub);
  return a;
}

std::unique_ptr<Store> open_store(const StoreCliOptions& o) {
  const bool local = !o.store.empty();
  const bool remote = !o.bus.empty() || !o.master.empty();
  if (local == remote) {
    fail(tools::kExitUsage, "give either --store DIR or --bus URL --master N");
  }
  if (local) {
    auto opened = cfg::ConfigManager::open(o.store);
    if (!opened) fail(tools::kExitIo, opened.error().message);
    // A damaged entry is reported and not used (cfg/config_manager.hpp).
    tools::print_diagnostics(opened.value().problems());
    return std::make_unique<LocalStore>(std::move(opened).value());
  }
  if (o.bus.empty() || o.master.empty()) {
    fail(tools::kExitUsage, "--bus URL and --master N go together");
  }
  if (o.bus.rfind("sim:", 0) == 0) {
    fail(tools::kExitUsage, "--bus " + o.bus +
                                ": the simulated bus has no master to talk to; use the bus a "
                                "`cfgmgr master` runs on (socketcan:IF, udp://GROUP:PORT)");
  }
  const auto master = tools::parse_node_id_argument(o.master);
  if (!master) fail(tools::kExitUsage, tools::node_id_argument_error("--master", o.master));
  if (auto checked = nmt::check_bus_url(o.bus); !checked) {
    fail(tools::kExitUsage, checked.error().message);
  }
  auto session = nmt::SdoSession::open(o.bus, nmt::SdoClientConfig::for_node(*master));
  if (!session) fail(tools::kExitIo, session.error().message);
  const auto timeout = nmt::Duration(static_cast<std::int64_t>(o.sdo_timeout_s * 1e6));
  return std::make_unique<RemoteStore>(std::move(session).value(), timeout);
}

/// The stamp a configuration stands for: configuration_stamp() of its writes as a concise DCF,
/// the rule derived masters use (cfg/network.hpp). The file is checked as the manager checks
/// it (in memory), so a file the master would refuse is refused here, before the bus.
cfg::ConfigurationStamp stamp_of(What what, cfg::NodeId node, const std::vector<std::uint8_t>& data,
                                 const std::string& path) {
  cfg::ConfigManager check;
  const auto put = check.write(index_of(what), node.value(), data);
  if (!put.ok()) fail(tools::kExitInputErrors, path + ": " + put.message);
  const auto writes = check.configuration_or_error(node);
  if (!writes) fail(tools::kExitInputErrors, path + ": " + writes.error().message);
  return cfg::configuration_stamp(cfg::encode_concise_dcf(writes.value()));
}

void put(Store& store, const StoreCliOptions& o) {
  const std::uint8_t node = parse_node(o.node);
  const What what = what_of_file(o.file, o.what);
  auto text = tools::read_input(o.file);
  if (!text) fail(tools::kExitIo, text.error().message);
  const std::string_view view = text.value().view();
  std::vector<std::uint8_t> data(view.begin(), view.end());
  if (data.empty()) fail(tools::kExitInputErrors, o.file + ": the file is empty (rm removes)");
  std::optional<cfg::ConfigurationStamp> stamp;
  if (what != What::Eds) stamp = stamp_of(what, *cfg::NodeId::from(node), data, o.file);
  const std::size_t size = data.size();
  must(store.write(index_of(what), node, std::move(data)), index_of(what), node);
  if (stamp) {
    must(store.write(obj::kExpectedConfigurationDate, node, cfg::le32_bytes(stamp->days)),
         obj::kExpectedConfigurationDate, node);
    must(store.write(obj::kExpectedConfigurationTime, node, cfg::le32_bytes(stamp->ms)),
         obj::kExpectedConfigurationTime, node);
  }
  std::cerr << "cfgmgr store: node " << int{node} << ": " << size << " bytes to "
            << cfg::object_name(index_of(what));
  if (stamp) {
    std::cerr << ", 1F26h/1F27h = " << stamp->days << " days, " << stamp->ms << " ms";
  }
  std::cerr << '\n';
}

void get(Store& store, const StoreCliOptions& o) {
  const std::uint8_t node = parse_node(o.node);
  const What what = parse_what(o.what).value_or(What::Concise);
  const auto a = must(store.read(index_of(what), node), index_of(what), node);
  const std::string_view bytes(reinterpret_cast<const char*>(a.data.data()), a.data.size());
  if (auto written = tools::write_output(o.output, bytes); !written) {
    fail(tools::kExitIo, written.error().message);
  }
}

/// What list shows of one node.
struct Listed {
  std::uint8_t node = 0;
  std::optional<std::size_t> dcf, eds;
  std::size_t concise_entries = 0;
  std::size_t concise_bytes = 0;  ///< 0: none (an empty 1F22h reads as the 4-byte count 0)
  cfg::ConfigurationStamp stamp;
  bool empty() const { return !dcf && !eds && concise_bytes == 0 && stamp.is_zero(); }
};

std::optional<std::size_t> size_or_empty(Store& store, std::uint16_t index, std::uint8_t node) {
  auto a = store.read(index, node);
  // DSP 302 §6.1/§6.5: nothing stored reads as 0800 0024h.
  if (a.abort == static_cast<std::uint32_t>(cfg::SdoAbort::NoDataAvailable)) return std::nullopt;
  return must(std::move(a), index, node).data.size();
}

std::uint32_t read_u32(Store& store, std::uint16_t index, std::uint8_t node) {
  const auto a = must(store.read(index, node), index, node);
  return cfg::low_le32(a.data);
}

Listed list_node(Store& store, std::uint8_t node) {
  Listed l;
  l.node = node;
  l.dcf = size_or_empty(store, obj::kStoreDcf, node);
  l.eds = size_or_empty(store, obj::kStoreEds, node);
  const auto concise = must(store.read(obj::kConciseDcf, node), obj::kConciseDcf, node);
  // §6.2: the stream starts with the number of entries (UNSIGNED32).
  if (concise.data.size() >= 4) l.concise_entries = cfg::load_le32(concise.data);
  if (l.concise_entries != 0) l.concise_bytes = concise.data.size();
  l.stamp = {read_u32(store, obj::kExpectedConfigurationDate, node),
             read_u32(store, obj::kExpectedConfigurationTime, node)};
  return l;
}

std::string size_text(std::optional<std::size_t> size) {
  return size ? std::to_string(*size) : std::string("-");
}

void list(Store& store, const StoreCliOptions& o) {
  std::vector<Listed> nodes;
  for (unsigned node = cfg::kMinNodeId; node <= cfg::kMaxNodeId; ++node) {
    auto l = list_node(store, static_cast<std::uint8_t>(node));
    if (!l.empty()) nodes.push_back(l);
  }
  std::ostringstream out;
  if (o.json) {
    out << "{\"nodes\": [";
    const char* sep = "";
    for (const auto& l : nodes) {
      auto number = [](std::optional<std::size_t> v) {
        return v ? std::to_string(*v) : std::string("null");
      };
      out << sep << "\n  {\"node_id\": " << int{l.node} << ", \"dcf_bytes\": " << number(l.dcf)
          << ", \"concise_bytes\": "
          << number(l.concise_bytes != 0 ? std::optional(l.concise_bytes) : std::nullopt)
          << ", \"concise_entries\": " << l.concise_entries << ", \"eds_bytes\": " << number(l.eds)
          << ", \"expected_date\": " << l.stamp.days << ", \"expected_time\": " << l.stamp.ms
          << "}";
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
      std::snprintf(line, sizeof line, "%-5d %10s %10s %8zu %10s %8u %10u\n", int{l.node},
                    size_text(l.dcf).c_str(), concise.c_str(), l.concise_entries,
                    size_text(l.eds).c_str(), l.stamp.days, l.stamp.ms);
      out << line;
    }
  }
  std::cout << out.str();
  std::cout.flush();
  if (!std::cout) fail(tools::kExitIo, "<stdout>: write error");
}

void remove(Store& store, const StoreCliOptions& o) {
  const std::uint8_t node = parse_node(o.node);
  // §6.2 application hint 1: the empty data set is the stream with count 0; an empty DCF/EDS
  // removes those (cfg/config_manager.hpp); 1F26h/1F27h = 0 mean "do not verify".
  must(store.write(obj::kConciseDcf, node, cfg::le32_bytes(0)), obj::kConciseDcf, node);
  must(store.write(obj::kStoreDcf, node, {}), obj::kStoreDcf, node);
  must(store.write(obj::kStoreEds, node, {}), obj::kStoreEds, node);
  must(store.write(obj::kExpectedConfigurationDate, node, cfg::le32_bytes(0)),
       obj::kExpectedConfigurationDate, node);
  must(store.write(obj::kExpectedConfigurationTime, node, cfg::le32_bytes(0)),
       obj::kExpectedConfigurationTime, node);
}

void configure(Store& store, const StoreCliOptions& o) {
  const std::uint8_t sub = parse_node(o.node, /*allow_all=*/true);
  if (!store.remote()) {
    fail(tools::kExitUsage, "configure asks a running master: give --bus URL --master N");
  }
  // DSP 302 §6.4: the signature 'conf' = 666E6F63h.
  must(store.write(obj::kConfigureSlave, sub, cfg::le32_bytes(cfg::kConfigureSignature)),
       obj::kConfigureSlave, sub);
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
  auto run = [o](void (*action)(Store&, const StoreCliOptions&)) {
    return [o, action] {
      auto store = open_store(*o);
      action(*store, *o);
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
