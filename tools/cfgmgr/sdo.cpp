// cfgmgr sdo read|write --bus URL NODE INDEX[:SUB] [VALUE]: one SDO transfer (CiA 301 §7.2.4)
// with any node of a running network, from the command line. The value's data type comes from
// --type, else from the node's EDS/DCF (--eds); the value text is the project's value parser's
// (cfg::parse_value, the syntax of EDS/DCF values). The client is libnmt's SdoClient
// (nmt/io/sdo_session.hpp); this file parses arguments and prints. With --via-manager the tool is
// an SDO requesting device (DSP 302 §7) and transfers on the channel the network's SDO manager
// grants instead of the node's default SDO.
#include <algorithm>
#include <cctype>
#include <cstdint>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include <unistd.h>

#include "../common/tool_support.hpp"
#include "cfg/bytes.hpp"
#include "cfg/data_type.hpp"
#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/value.hpp"
#include "commands.hpp"
#include "master_run.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/sdo_session.hpp"
#include "nmt/sdo/sdo_abort.hpp"
#include "nmt/sdo/sdo_client.hpp"

namespace cfgmgr {
namespace {

constexpr std::string_view kTool = "sdo";

struct SdoCliOptions {
  std::string bus;
  std::string node;
  std::string address;
  std::string value;
  std::string type;
  std::string eds;
  std::string file;    ///< write: the value's bytes from this file
  std::string output;  ///< read: the value's bytes to this file
  bool raw = false;
  bool json = false;
  bool block = false;
  double sdo_timeout_s = 1.0;
  bool via_manager = false;
  std::string own_node_id;  ///< --node-id: the tool's node-ID as an SRD
  double manager_timeout_s = 10.0;
  bool verbose = false;
};

/// The short type names of --type (the CiA 301 names are accepted as well).
struct TypeName {
  std::string_view name;
  cfg::DataType type;
};
constexpr TypeName kTypeNames[] = {
    {"bool", cfg::DataType::Boolean},       {"i8", cfg::DataType::Integer8},
    {"i16", cfg::DataType::Integer16},      {"i24", cfg::DataType::Integer24},
    {"i32", cfg::DataType::Integer32},      {"i40", cfg::DataType::Integer40},
    {"i48", cfg::DataType::Integer48},      {"i56", cfg::DataType::Integer56},
    {"i64", cfg::DataType::Integer64},      {"u8", cfg::DataType::Unsigned8},
    {"u16", cfg::DataType::Unsigned16},     {"u24", cfg::DataType::Unsigned24},
    {"u32", cfg::DataType::Unsigned32},     {"u40", cfg::DataType::Unsigned40},
    {"u48", cfg::DataType::Unsigned48},     {"u56", cfg::DataType::Unsigned56},
    {"u64", cfg::DataType::Unsigned64},     {"f32", cfg::DataType::Real32},
    {"f64", cfg::DataType::Real64},         {"str", cfg::DataType::VisibleString},
    {"octets", cfg::DataType::OctetString}, {"unicode", cfg::DataType::UnicodeString},
    {"domain", cfg::DataType::Domain},      {"tod", cfg::DataType::TimeOfDay},
    {"td", cfg::DataType::TimeDifference},
};

cfg::DataType parse_type(const std::string& text) {
  std::string lower = text;
  std::transform(lower.begin(), lower.end(), lower.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  for (const auto& t : kTypeNames) {
    if (t.name == lower) return t.type;
  }
  if (auto type = cfg::data_type_from_name(text)) return *type;
  fail_command(kTool, tools::kExitUsage,
               "--type " + text +
                   ": expected u8..u64, i8..i64, bool, f32, f64, str, octets, "
                   "unicode, domain, tod, td, or a CiA 301 name such as UNSIGNED32");
}

cfg::NodeId parse_node(const std::string& text, std::string_view what = "NODE") {
  const auto node = tools::parse_node_id_argument(text);
  if (!node) fail_command(kTool, tools::kExitUsage, tools::node_id_argument_error(what, text));
  return *node;
}

// INDEX[:SUB], both hex as CiA 301 writes them: "1018:1", "0x1018:0x01", "1018h:01h".
cfg::ObjectAddress parse_address(const std::string& text) {
  const auto colon = text.find(':');
  const std::string_view all(text);
  const auto index = parse_hex_argument(all.substr(0, colon), 4);
  std::optional<std::uint64_t> sub = 0;
  if (colon != std::string::npos) sub = parse_hex_argument(all.substr(colon + 1), 2);
  if (!index || !sub) {
    fail_command(kTool, tools::kExitUsage,
                 "INDEX[:SUB] " + text +
                     ": expected a hex index and sub-index, e.g. 1018:1 or "
                     "0x1017:0x00");
  }
  return {static_cast<std::uint16_t>(*index), static_cast<std::uint8_t>(*sub)};
}

// The data type: --type, else the object's DataType in --eds; nullopt when neither gives one.
std::optional<cfg::DataType> data_type_of(const SdoCliOptions& o, cfg::ObjectAddress address) {
  if (!o.type.empty()) return parse_type(o.type);
  if (o.eds.empty()) return std::nullopt;
  auto read = cfg::read_device_file(o.eds);
  if (!read.device) {
    tools::print_diagnostics(read.diagnostics);
    // A file that cannot be read at all is one error at line 0 (cfg/device_file.hpp).
    exit_with(read.diagnostics.items().size() == 1 && read.diagnostics.items()[0].line == 0
                  ? tools::kExitIo
                  : tools::kExitInputErrors);
  }
  const cfg::SubObject* sub = read.device->sub(address.index, address.sub_index);
  if (sub == nullptr) {
    fail_command(kTool, tools::kExitUsage,
                 o.eds + ": has no " + cfg::to_string(address) + " (give --type)");
  }
  const auto type = sub->basic_type();
  if (!type) {
    fail_command(kTool, tools::kExitUsage,
                 o.eds + ":" + std::to_string(sub->line) + ": " + cfg::to_string(address) +
                     " has no basic data type (give --type)");
  }
  return type;
}

nmt::SdoTransferOptions transfer_options(const SdoCliOptions& o, std::size_t write_size = 0) {
  nmt::SdoTransferOptions options;
  options.timeout = sdo_timeout_or_exit(kTool, o.sdo_timeout_s);
  // CiA 301 §7.2.4.3.9: block transfer; the client falls back to segmented when the server
  // answers 0504 0001 (nmt/sdo/sdo_client.hpp).
  if (o.block || write_size > nmt::kBlockDownloadThreshold) options.mode = nmt::SdoMode::Block;
  return options;
}

std::string_view protocol_name(nmt::SdoProtocol p) {
  switch (p) {
    case nmt::SdoProtocol::Expedited:
      return "expedited";
    case nmt::SdoProtocol::Segmented:
      return "segmented";
    case nmt::SdoProtocol::Block:
      break;
  }
  return "block";
}

// What a transfer gave, for the text line and the JSON object.
struct Outcome {
  std::string operation;  // "read" or "write"
  std::uint8_t node = 0;
  cfg::ObjectAddress address;
  std::optional<cfg::DataType> type;
  nmt::SdoResult result;
  std::optional<cfg::Value> value;  // read, typed, decoded
  std::vector<std::uint8_t> bytes;  // read: as received; write: as sent
  nmt::SdoSessionChannel channel;   // the channel the transfer used
};

std::string json_of(const Outcome& o) {
  const auto null_or = [](bool has, const std::string& text) {
    return has ? tools::json_string(text) : std::string("null");
  };
  const bool ok = o.result.ok();
  std::string out = "{\"operation\": " + tools::json_string(o.operation) +
                    ", \"node_id\": " + std::to_string(o.node) +
                    ", \"index\": " + std::to_string(o.address.index) +
                    ", \"sub_index\": " + std::to_string(o.address.sub_index) +
                    ", \"address\": " + tools::json_string(cfg::to_string(o.address)) +
                    ", \"ok\": " + (ok ? "true" : "false") + ", \"type\": " +
                    null_or(o.type.has_value(), o.type ? std::string(cfg::to_string(*o.type)) : "");
  out += ", \"value\": " + null_or(o.value.has_value(), o.value ? cfg::format_value(*o.value) : "");
  out +=
      ", \"text\": " + null_or(o.value.has_value(), o.value ? cfg::describe_value(*o.value) : "");
  out += ", \"hex\": " + null_or(ok, tools::hex_string(o.bytes));
  out += ", \"size\": " + (ok ? std::to_string(o.bytes.size()) : std::string("null"));
  out += ", \"protocol\": " + null_or(ok, std::string(protocol_name(o.result.protocol)));
  const std::string code = cfg::hex(nmt::to_u32(o.result.abort), 8);
  out += ", \"abort\": " + null_or(!ok, code);
  out += ", \"abort_text\": " + null_or(!ok, std::string(nmt::describe(o.result.abort)));
  out += ", \"aborted_by\": " +
         null_or(!ok, o.result.aborted_by_server ? std::string("device") : std::string("client"));
  out += ", \"cob_id_client_to_server\": " +
         std::to_string(o.channel.config.request_cob_id.can_id().id) +
         ", \"cob_id_server_to_client\": " +
         std::to_string(o.channel.config.response_cob_id.can_id().id);
  out += ", \"via_manager\": ";
  if (o.channel.srd_node_id) {
    out += "{\"node_id\": " + std::to_string(o.channel.srd_node_id->value()) +
           ", \"client_index\": " + std::to_string(o.channel.client_index) + "}";
  } else {
    out += "null";
  }
  return out + "}\n";
}

// Ends the command after a failed transfer: the abort code in words, exit 3 when the node did
// not answer (the client's timeout), else 1.
[[noreturn]] void fail_transfer(const Outcome& o) {
  std::string text = "node " + std::to_string(o.node) + ": " + cfg::to_string(o.address) + ": " +
                     o.operation + " failed: SDO abort " + nmt::to_string(o.result.abort);
  text += o.result.aborted_by_server ? ", sent by the device" : ", sent by this client";
  fail_command(kTool,
               o.result.abort == nmt::SdoAbort::Timeout ? tools::kExitIo : tools::kExitInputErrors,
               text);
}

// --via-manager: the node-ID the tool takes as an SRD must be free; a node that answers an
// upload of 1000h on its default SDO (CiA 301 §7.2.4.1) holds it. 300 ms is ample on a live bus.
void require_free_node_id(nmt::SdoSession& session, cfg::NodeId own) {
  nmt::SdoTransferOptions probe;
  probe.timeout = std::chrono::milliseconds(300);
  auto answer = session.upload(0x1000, 0, probe);
  if (!answer) fail_command(kTool, tools::kExitIo, answer.error().message);
  const auto& r = answer.value();
  if (r.ok() || r.aborted_by_server) {
    fail_command(kTool, tools::kExitUsage,
                 "--node-id " + std::to_string(own.value()) + ": node " +
                     std::to_string(own.value()) + " answers on the bus (its default SDO " +
                     cfg::hex_digits(nmt::sdo::default_cob_ids(own).request.can_id().id, 3) + "h/" +
                     cfg::hex_digits(nmt::sdo::default_cob_ids(own).response.can_id().id, 3) +
                     "h); give this tool a free node-ID with --node-id");
  }
}

std::unique_ptr<nmt::SdoSession> open_session(const SdoCliOptions& o, cfg::NodeId node) {
  if (is_sim_url(o.bus)) {
    fail_command(kTool, tools::kExitUsage,
                 "--bus " + o.bus +
                     ": the simulated bus has no node to talk to; use the bus the "
                     "node is on (socketcan:IF, udp://GROUP:PORT)");
  }
  if (auto checked = nmt::check_bus_url(o.bus); !checked) {
    fail_command(kTool, tools::kExitUsage, "--bus: " + checked.error().message);
  }
  if (!o.via_manager) {
    if (!o.own_node_id.empty())
      fail_command(kTool, tools::kExitUsage, "--node-id is for --via-manager");
    // CiA 301 §7.2.4.1: the default SDO of a node is 600h + node-ID (client to server) and
    // 580h + node-ID (server to client).
    auto session = nmt::SdoSession::open(o.bus, nmt::SdoClientConfig::for_node(node));
    if (!session) fail_command(kTool, tools::kExitIo, session.error().message);
    return std::move(session).value();
  }
  if (o.own_node_id.empty()) {
    fail_command(kTool, tools::kExitUsage,
                 "--via-manager needs --node-id: a free node-ID for this tool");
  }
  const auto own = parse_node(o.own_node_id, "--node-id");
  if (own == node) {
    fail_command(kTool, tools::kExitUsage,
                 "--node-id " + o.own_node_id + ": that is NODE; give this tool a " +
                     "free node-ID of its own");
  }
  auto opened = nmt::SdoSession::open(o.bus, nmt::SdoClientConfig::for_node(own));
  if (!opened) fail_command(kTool, tools::kExitIo, opened.error().message);
  auto session = std::move(opened).value();
  require_free_node_id(*session, own);
  nmt::SdoManagerRoute route{.own_node_id = own,
                             .slave = node,
                             .manager_timeout = seconds_to_duration(o.manager_timeout_s)};
  // Steps on stderr with -v, or when a person watches (registration may take seconds while
  // the manager scans node-IDs, DSP 302 §7.2.4).
  if (o.verbose || ::isatty(STDERR_FILENO) == 1) {
    route.progress = [](const std::string& line) {
      std::cerr << "cfgmgr sdo: " << line << '\n' << std::flush;
    };
  }
  if (auto connected = session->connect_via_manager(std::move(route)); !connected) {
    fail_command(kTool, tools::exit_code_for(connected.error()), connected.error().message);
  }
  return session;
}

// Via the manager: release the connection and de-register before the outcome is printed (the
// manager frees both when the tool's heartbeat stops anyway, so a failure is only a warning).
void close_session(nmt::SdoSession& session) {
  if (auto closed = session.close(); !closed) {
    std::cerr << "cfgmgr sdo: warning: " << closed.error().message << '\n' << std::flush;
  }
}

nmt::SdoResult transfer_or_exit(cfg::Result<nmt::SdoResult> result) {
  if (!result) fail_command(kTool, tools::kExitIo, result.error().message);
  return std::move(result).value();
}

void finish(const SdoCliOptions& o, const Outcome& outcome) {
  if (o.json) std::cout << json_of(outcome) << std::flush;
  if (!outcome.result.ok()) fail_transfer(outcome);
}

void run_read(const SdoCliOptions& o) {
  Outcome out;
  out.operation = "read";
  const cfg::NodeId node = parse_node(o.node);
  out.node = node;
  out.address = parse_address(o.address);
  out.type = data_type_of(o, out.address);
  if (o.json && (o.raw || !o.output.empty())) {
    fail_command(kTool, tools::kExitUsage,
                 "--json prints the value as JSON; --raw and -o write its bytes");
  }
  const auto options = transfer_options(o);  // a usage error before the bus
  auto session = open_session(o, node);
  out.result = transfer_or_exit(session->upload(out.address.index, out.address.sub_index, options));
  out.channel = session->channel();
  close_session(*session);
  out.bytes = out.result.data;
  if (out.result.ok()) {
    // Untyped: the bytes as a DOMAIN (hex pairs).
    auto decoded = cfg::decode(out.type.value_or(cfg::DataType::Domain), out.bytes);
    if (!decoded) {
      fail_command(kTool, tools::kExitInputErrors,
                   "node " + std::to_string(out.node) + ": " + cfg::to_string(out.address) + ": " +
                       decoded.error().message + " (" + std::to_string(out.bytes.size()) +
                       " bytes read)");
    }
    out.value = std::move(decoded).value();
  }
  finish(o, out);
  if (o.json) return;
  const std::string_view bytes(reinterpret_cast<const char*>(out.bytes.data()), out.bytes.size());
  if (!o.output.empty() || o.raw) {
    if (auto written = tools::write_output(o.output.empty() ? "-" : o.output, bytes); !written) {
      fail_command(kTool, tools::kExitIo, written.error().message);
    }
    return;
  }
  std::cout << cfg::describe_value(*out.value) << '\n' << std::flush;
}

void run_write(const SdoCliOptions& o) {
  Outcome out;
  out.operation = "write";
  const cfg::NodeId node = parse_node(o.node);
  out.node = node;
  out.address = parse_address(o.address);
  if (o.value.empty() == o.file.empty()) {
    fail_command(kTool, tools::kExitUsage, "give either VALUE or --file FILE");
  }
  if (!o.file.empty()) {
    // The file's bytes are the value, whatever the type (a DOMAIN such as a program).
    auto text = tools::read_input(o.file);
    if (!text) fail_command(kTool, tools::kExitIo, text.error().message);
    const std::string_view view = text.value().view();
    out.bytes.assign(view.begin(), view.end());
    if (!o.type.empty() || !o.eds.empty()) out.type = data_type_of(o, out.address);
  } else {
    out.type = data_type_of(o, out.address);
    if (!out.type) {
      fail_command(kTool, tools::kExitUsage,
                   "VALUE " + o.value +
                       ": give its data type with --type, or the node's EDS/DCF "
                       "with --eds");
    }
    // $NODEID in a value stands for NODE, as in the node's DCF (CiA 306 §4.6.3).
    auto value = cfg::parse_value(*out.type, o.value, out.node);
    if (!value) {
      fail_command(kTool, tools::kExitUsage, "VALUE " + o.value + ": " + value.error().message);
    }
    out.bytes = cfg::encode(*value);
  }
  const auto options = transfer_options(o, out.bytes.size());  // a usage error before the bus
  auto session = open_session(o, node);
  out.result = transfer_or_exit(
      session->download(out.address.index, out.address.sub_index, out.bytes, options));
  out.channel = session->channel();
  close_session(*session);
  finish(o, out);
}

}  // namespace

void add_sdo_command(CLI::App& app) {
  auto o = std::make_shared<SdoCliOptions>();
  auto* cmd = app.add_subcommand(
      "sdo",
      "Read or write one object of a node on a running bus over SDO (CiA 301 section 7.2.4: "
      "expedited, segmented or block transfer), on the node's default SDO (600h/580h + "
      "node-ID) or on a channel the network's SDO manager grants (--via-manager, DSP 302 "
      "section 7); values typed by --type or by the node's EDS/DCF");
  cmd->require_subcommand(1);
  // On `sdo` itself, so that they may come before or after the action (fallthrough) and
  // `cfgmgr sdo --help` (the man page) lists them.
  cmd->add_option("--bus", o->bus, "The bus the node is on (socketcan:IF, udp://GROUP:PORT)")
      ->type_name("URL")
      ->required();
  cmd->add_option("-t,--type", o->type,
                  "The value's data type: u8, u16, u24, u32, u40, u48, u56, u64, i8 ... i64, "
                  "bool, f32, f64, str (VISIBLE_STRING), octets, unicode, domain, tod, td, or a "
                  "CiA 301 name (UNSIGNED32)")
      ->type_name("TYPE");
  cmd->add_option("--eds", o->eds,
                  "Take the data type from the node's EDS or DCF when --type is not given")
      ->type_name("FILE");
  cmd->add_option("--sdo-timeout", o->sdo_timeout_s,
                  "Seconds to wait for each answer of the node (default 1)")
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("--block", o->block,
                "Use block transfer (segmented when the node has none); writes of more than " +
                    std::to_string(nmt::kBlockDownloadThreshold) + " bytes use it anyway");
  cmd->add_flag("--via-manager", o->via_manager,
                "Ask the network's SDO manager for a connection to NODE (DSP 302 section 7) "
                "instead of taking its default SDO, which the master or another tool may be "
                "using: the tool registers as an SDO requesting device with --node-id, asks "
                "for the connection, transfers, then releases it and de-registers");
  cmd->add_option("--node-id", o->own_node_id,
                  "With --via-manager: this tool's own node-ID on the bus, a free one (the "
                  "manager scans node-IDs from 127 down, so a high one registers fastest)")
      ->type_name("ID");
  cmd->add_option("--manager-timeout", o->manager_timeout_s,
                  "With --via-manager: seconds to wait for each answer of the SDO manager "
                  "(registration, connection, release; default 10)")
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_flag("-v,--verbose", o->verbose,
                "With --via-manager: print each step on stderr (also done when stderr is a "
                "terminal)");
  cmd->add_flag("--json", o->json,
                "Print the outcome as one JSON object on stdout (also when the transfer fails): "
                "operation, node_id, index, sub_index, address, ok, type, value, text, hex, "
                "size, protocol, abort, abort_text, aborted_by, cob_id_client_to_server, "
                "cob_id_server_to_client, via_manager (null, or node_id and client_index of "
                "this tool as an SRD)");

  auto* read_cmd = cmd->add_subcommand("read", "Read INDEX:SUB of NODE and print its value");
  read_cmd->add_option("node", o->node, "The node-ID, 1..127")->required()->type_name("NODE");
  read_cmd->add_option("address", o->address, "The object, hex: 1018:1, 0x1017:0, 1008h")
      ->required()
      ->type_name("INDEX[:SUB]");
  read_cmd->add_flag("--raw", o->raw, "Write the value's bytes to stdout, as they came");
  read_cmd->add_option("-o,--output", o->output, "Write the value's bytes to FILE")
      ->type_name("FILE");
  read_cmd->fallthrough();
  read_cmd->callback([o] { run_read(*o); });

  auto* write_cmd =
      cmd->add_subcommand("write", "Write VALUE (or a file's bytes) to INDEX:SUB of NODE");
  write_cmd->add_option("node", o->node, "The node-ID, 1..127")->required()->type_name("NODE");
  write_cmd->add_option("address", o->address, "The object, hex: 1017:0")
      ->required()
      ->type_name("INDEX[:SUB]");
  write_cmd->add_option("value", o->value, "The value, as in an EDS/DCF (1000, 0x3E8, text)")
      ->type_name("VALUE");
  write_cmd->add_option("--file", o->file, "Write this file's bytes instead (- for stdin)")
      ->type_name("FILE");
  write_cmd->fallthrough();
  write_cmd->callback([o] { run_write(*o); });

  cmd->footer(std::string(
      "Actions:\n"
      "  read NODE INDEX[:SUB] [--raw|-o FILE]   print the value (typed: by --type or --eds; "
      "else its bytes in hex)\n"
      "  write NODE INDEX[:SUB] VALUE|--file FILE   write a typed value, or a file's bytes\n\n"
      "INDEX and SUB are hex, as CiA 301 writes them (1018:1 is 1018h sub 01h; a missing SUB "
      "is 0). VALUE is written as in an EDS/DCF (CiA 306): decimal, 0x hex, $NODEID+0x180, "
      "text for strings, hex pairs for octets and domain. A read prints unsigned values as "
      "'1000 (0x000003E8)', strings quoted, bytes in hex.\n\n"
      "Examples:\n"
      "  cfgmgr sdo read --bus socketcan:can0 5 1018:1 --type u32\n"
      "  cfgmgr sdo read --bus udp://239.74.163.2:43113 5 1008 --eds drive.eds\n"
      "  cfgmgr sdo write --bus socketcan:can0 5 1017:0 500 --type u16\n"
      "  cfgmgr sdo write --bus socketcan:can0 5 1F50:1 --file firmware.bin --block\n"
      "  cfgmgr sdo read --bus socketcan:can0 5 1F50:1 -o program.bin --block\n"
      "  cfgmgr sdo read --bus socketcan:can0 5 1000 --json\n"
      "  cfgmgr sdo read --bus socketcan:can0 5 1018:1 --type u32 --via-manager --node-id 120\n\n"
      "With --via-manager the tool is an SDO requesting device (DSP 302 section 7) with node-ID "
      "--node-id: it boots (a boot-up message and a heartbeat every 200 ms), sends the Dynamic "
      "SDO Request (6E0h), waits until the SDO manager registered it, asks for a connection to "
      "NODE (1F00h), transfers on the channel the manager granted (NODE's default SDO when no "
      "one holds it, else another server channel of NODE), and releases everything (1F01h) "
      "before it exits.\n\n"
      "Exit codes:\n"
      "  0  done\n"
      "  1  the transfer was aborted (the SDO abort code and its words are printed; by the "
      "device, or by this client on a protocol error), or the value read does not fit --type, "
      "or the SDO manager refused the registration or the connection (its reason is printed)\n"
      "  2  usage error (bad command line, a NODE outside 1..127, a VALUE that is not of the "
      "type, no type for VALUE, a --node-id that another node answers on)\n"
      "  3  I/O error: a file cannot be read or written, the bus cannot be opened, the node "
      "does not answer (abort 0x05040000 after --sdo-timeout), no SDO manager answers within "
      "--manager-timeout\n"));
}

}  // namespace cfgmgr
