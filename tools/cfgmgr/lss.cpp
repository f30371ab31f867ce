// cfgmgr lss scan|set-id|inquire|set-bitrate --bus URL: the Layer Setting Services of CiA 305
// from the command line, for devices straight out of the box (no node-ID, or the factory's
// one) on a running bus. The procedures are libnmt's LssProcedure (nmt/lss/lss_procedure.hpp, which
// cites its sources) run by LssSession (nmt/io/lss_session.hpp); this file parses arguments and
// prints.
#include <cstdint>
#include <iostream>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/network.hpp"
#include "commands.hpp"
#include "master_run.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/lss_session.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_event_text.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/lss/lss_procedure.hpp"

namespace cfgmgr {
namespace {

constexpr std::string_view kTool = "lss";
/// A device refused a service (its error code in words) or no device answered.
constexpr int kExitDevice = 4;

using Event = nmt::LssProcedureEvent;

struct LssCliOptions {
  std::string bus;
  bool json = false;
  double timeout_ms = 100;
  double scan_step_ms = 20;
  std::string address;  ///< set-id, inquire: VENDOR:PRODUCT:REVISION:SERIAL
  std::string node_id;  ///< set-id
  bool no_store = false;
  std::string kbit;  ///< set-bitrate
  unsigned delay_ms = 100;
  bool all = false;                   ///< scan: configured devices too
  std::vector<std::string> products;  ///< scan --all: VENDOR:PRODUCT to look for
  std::vector<std::string> devices;   ///< scan --all: device files whose product to look for
};

[[noreturn]] void fail(int code, const std::string& message) {
  fail_command(kTool, code, message);
}

nmt::Duration ms(double value) {
  return nmt::Duration(static_cast<std::int64_t>(value * 1000.0));
}

std::string address_text(const nmt::LssAddress& a) {
  return nmt::address_digits(a);
}

// VENDOR:PRODUCT:REVISION:SERIAL, each part hex with up to 8 digits (0x prefix or h suffix
// allowed); nullopt for anything else.
std::optional<nmt::LssAddress> parse_lss_address(std::string_view text) {
  nmt::LssAddress address;
  for (int part = 0; part < 4; ++part) {
    const auto colon = text.find(':');
    if ((colon == std::string_view::npos) != (part == 3)) return std::nullopt;
    const auto value = parse_hex_argument(text.substr(0, colon), 8);
    if (!value) return std::nullopt;
    address.part(part) = static_cast<std::uint32_t>(*value);
    if (colon != std::string_view::npos) text.remove_prefix(colon + 1);
  }
  return address;
}

nmt::LssAddress address_or_exit(const std::string& text) {
  auto address = parse_lss_address(text);
  if (!address) {
    fail(tools::kExitUsage, "ADDRESS " + text +
                                ": expected VENDOR:PRODUCT:REVISION:SERIAL, four hex numbers "
                                "(1018h sub 1-4), e.g. 7E57C0DE:305:10002:1001 (as `cfgmgr lss "
                                "scan` prints them)");
  }
  return *address;
}

// CiA 305: configure node-ID takes 1..127, or FFh (not configured: nullopt); anything else is
// no node-ID and never reaches the bus (the LSS master takes a cfg::NodeId).
std::optional<cfg::NodeId> node_id_or_exit(const std::string& text) {
  const auto value = tools::node_id_argument_value(text, /*unconfigured_ok=*/true);
  if (value && *value == nmt::lss::kUnconfigured) return std::nullopt;
  const auto node_id = value ? cfg::NodeId::from(*value) : std::nullopt;
  if (!node_id) {
    fail(tools::kExitUsage,
         tools::node_id_argument_error("NODE-ID", text) + " (or 255, 'unconfigured')");
  }
  return node_id;
}

// The node-ID as the commands print it: the number, or 255 for "not configured".
int node_id_number(std::optional<cfg::NodeId> node_id) {
  return node_id ? int{node_id->value()} : int{nmt::lss::kUnconfigured};
}

std::unique_ptr<nmt::LssSession> open_or_exit(const LssCliOptions& o) {
  if (is_sim_url(o.bus)) {
    fail(tools::kExitUsage, "--bus " + o.bus +
                                ": the simulated bus has no device to talk to; use the bus the "
                                "devices are on (socketcan:IF, udp://GROUP:PORT)");
  }
  if (auto checked = nmt::check_bus_url(o.bus); !checked) {
    fail(tools::kExitUsage, "--bus: " + checked.error().message);
  }
  nmt::LssMasterOptions options;
  options.timeout = ms(o.timeout_ms);
  options.scan_step = ms(o.scan_step_ms);
  auto session = nmt::LssSession::open(o.bus, options);
  if (!session) fail(tools::kExitIo, session.error().message);
  return std::move(session).value();
}

// The procedure's end: Done, or exit 3 (the bus failed) or 4 (a device refused or did not
// answer: `who` and the procedure's words, with `hint` when the selection went unanswered).
Event done_or_exit(cfg::Result<Event> result, const std::string& who,
                   const std::string& select_hint = {}) {
  if (!result) fail(tools::kExitIo, result.error().message);
  Event e = std::move(result).value();
  if (e.kind == Event::Kind::Done) return e;
  const std::string words = nmt::describe(e);
  std::string text = who.empty() ? words : who + ": " + words;
  const bool timeout = e.step && e.step->kind == nmt::LssMasterEvent::Kind::Timeout;
  if (e.step && e.step->service == nmt::LssService::SwitchStateSelective) {
    text += select_hint;
  } else if (timeout) {
    text += " (is the device on this bus and at this bit rate?)";
  }
  fail(kExitDevice, text);
}

const std::string kSelectHint = " (no device with this address on the bus, or not in LSS waiting)";

std::string json_address(const nmt::LssAddress& a) {
  return "{\"address\": " + tools::json_string(address_text(a)) +
         ", \"vendor_id\": " + std::to_string(a.vendor_id) +
         ", \"product_code\": " + std::to_string(a.product_code) +
         ", \"revision\": " + std::to_string(a.revision) +
         ", \"serial\": " + std::to_string(a.serial) + "}";
}

// --- scan ---------------------------------------------------------------------------------------

// A product to look for with --all: vendor-ID and product code (1018h sub 1 and 2).
using Product = std::pair<std::uint32_t, std::uint32_t>;

// --product VENDOR:PRODUCT and the identity of each --device file; exits 2/1/3 on bad ones.
std::set<Product> products_or_exit(const LssCliOptions& o) {
  std::set<Product> products;
  for (const auto& text : o.products) {
    // The first two parts of an LSS address.
    auto address = parse_lss_address(text + ":0:0");
    if (!address) {
      fail(tools::kExitUsage,
           "--product " + text + ": expected VENDOR:PRODUCT, two hex numbers (1018h sub 1-2)");
    }
    products.emplace(address->vendor_id, address->product_code);
  }
  for (const auto& path : o.devices) {
    auto text = tools::read_input(path);
    if (!text) fail(tools::exit_code_for(text.error()), text.error().message);
    cfg::ReadOptions read_options;
    read_options.file_name = path;
    auto read = cfg::parse_device_description(*text, read_options);
    tools::print_diagnostics(read.diagnostics);
    if (!read.ok()) exit_with(tools::kExitInputErrors);
    // The identity the file says (1018h, else [DeviceInfo]), as the device answers it.
    const cfg::DeviceIdentity identity = cfg::identity_of(*read.device, *cfg::NodeId::from(1));
    if (!identity.vendor_id || !identity.product_code) {
      fail(tools::kExitInputErrors,
           path +
               ": no vendor-ID and product code (1018h sub 1-2 or [DeviceInfo] VendorNumber, "
               "ProductNumber): identify remote slave needs both");
    }
    products.emplace(*identity.vendor_id, *identity.product_code);
  }
  return products;
}

std::string node_id_text(std::optional<cfg::NodeId> node_id) {
  return node_id ? std::to_string(node_id->value()) : std::string("FFh (unconfigured)");
}

std::string node_id_json(std::optional<cfg::NodeId> node_id) {
  return node_id ? std::to_string(node_id->value()) : std::string("null");
}

/// A device `scan --all` lists: its LSS address and active node-ID (nullopt: unconfigured).
struct ScannedDevice {
  nmt::LssAddress address;
  std::optional<cfg::NodeId> node_id;
};

void run_scan(const LssCliOptions& o) {
  if (!o.all && (!o.products.empty() || !o.devices.empty())) {
    fail(tools::kExitUsage, "--product and --device go with --all");
  }
  std::set<Product> products = products_or_exit(o);
  auto session = open_or_exit(o);
  const std::vector<nmt::LssAddress> found =
      done_or_exit(session->find_unconfigured(), "").addresses;
  // --all: the products of the unconfigured devices too, then every device of each product
  // with its node-ID.
  std::set<nmt::LssAddress> all(found.begin(), found.end());
  std::vector<ScannedDevice> devices;
  if (o.all) {
    for (const auto& a : found) products.emplace(a.vendor_id, a.product_code);
    for (const auto& [vendor, product] : products) {
      for (const auto& a : done_or_exit(session->find_product(vendor, product), "").addresses) {
        all.insert(a);
      }
    }
    for (const auto& a : all) {
      const auto e =
          done_or_exit(session->inquire_node_id(a), "LSS address " + address_text(a), kSelectHint);
      devices.push_back({a, e.node_id});
    }
  }
  if (o.json) {
    std::string out = "{\"unconfigured\": [";
    for (std::size_t i = 0; i < found.size(); ++i) {
      out += (i ? ", " : "") + json_address(found[i]);
    }
    out += "]";
    if (o.all) {
      out += ", \"devices\": [";
      for (std::size_t i = 0; i < devices.size(); ++i) {
        std::string device = json_address(devices[i].address);
        device.pop_back();
        out +=
            (i ? ", " : "") + device + ", \"node_id\": " + node_id_json(devices[i].node_id) + "}";
      }
      out += "]";
    }
    std::cout << out << "}\n" << std::flush;
    return;
  }
  if (!o.all) {
    for (const auto& a : found) std::cout << address_text(a) << '\n';
    std::cout << std::flush;
    std::cerr << "cfgmgr lss: " << tools::plural(found.size(), "unconfigured device") << '\n';
    return;
  }
  for (const auto& [a, node_id] : devices) {
    std::cout << address_text(a) << "  node-ID " << node_id_text(node_id) << '\n';
  }
  std::cout << std::flush;
  std::size_t unconfigured = 0;
  for (const auto& d : devices) unconfigured += d.node_id ? 0 : 1;
  std::cerr << "cfgmgr lss: " << tools::plural(devices.size(), "device") << ", " << unconfigured
            << " unconfigured (of " << tools::plural(products.size(), "product")
            << " looked for)\n";
}

// --- set-id -------------------------------------------------------------------------------------

void run_set_id(const LssCliOptions& o) {
  const auto address = address_or_exit(o.address);
  const auto node_id = node_id_or_exit(o.node_id);
  auto session = open_or_exit(o);
  const std::string who = "LSS address " + address_text(address);
  const auto e =
      done_or_exit(session->assign_node_id(address, node_id, !o.no_store), who, kSelectHint);
  const auto& before = e.previous_node_id;
  const bool was_unconfigured = before == nmt::lss::kUnconfigured;
  if (o.json) {
    std::cout << "{\"address\": " << tools::json_string(address_text(address))
              << ", \"node_id\": " << node_id_number(node_id)
              << ", \"stored\": " << (o.no_store ? "false" : "true") << ", \"previous_node_id\": "
              << (before ? std::to_string(*before) : std::string("null")) << "}\n"
              << std::flush;
    return;
  }
  std::cout << who << ": node-ID " << node_id_number(node_id) << " configured"
            << (o.no_store ? " (not stored: lost at power-off)" : " and stored") << "; "
            << (was_unconfigured ? "the device boots with it now"
                                 : "the device takes it at its next NMT reset communication")
            << '\n'
            << std::flush;
}

// --- inquire ------------------------------------------------------------------------------------

void run_inquire(const LssCliOptions& o) {
  std::optional<nmt::LssAddress> address;
  if (!o.address.empty()) address = address_or_exit(o.address);
  auto session = open_or_exit(o);
  const std::string who = address ? "LSS address " + address_text(*address) : std::string();
  const auto e = done_or_exit(session->inquire_identity(address), who, kSelectHint);
  if (o.json) {
    std::string out = json_address(e.address);
    out.pop_back();
    std::cout << out << ", \"node_id\": " << node_id_json(e.node_id) << "}\n" << std::flush;
    return;
  }
  std::cout << address_text(e.address) << "  node-ID " << node_id_text(e.node_id) << '\n'
            << std::flush;
}

// --- set-bitrate --------------------------------------------------------------------------------

void run_set_bitrate(const LssCliOptions& o) {
  const auto kbit = cfg::parse_integer_literal(o.kbit);
  std::optional<std::uint8_t> index;
  if (kbit.literal && kbit.literal->value <= 0xFFFF) {
    index = nmt::lss::bit_timing_index(static_cast<std::uint16_t>(kbit.literal->value));
  }
  if (!index) {
    fail(tools::kExitUsage, "KBIT " + o.kbit +
                                ": expected a rate of the CiA 305 bit timing table: 1000, 800, "
                                "500, 250, 125, 50, 20 or 10");
  }
  if (o.delay_ms > 0xFFFF) fail(tools::kExitUsage, "--delay-ms: at most 65535");
  auto session = open_or_exit(o);
  std::cerr << "cfgmgr lss: warning: this changes the bit rate of every LSS device on the bus "
               "to "
            << o.kbit << " kbit/s: the whole network must follow (this bus too)\n"
            << std::flush;
  // Every device answers configure bit timing and store; the first answer is taken, a refusal
  // of any device that comes first ends the command.
  (void)done_or_exit(
      session->set_bit_rate(*index, !o.no_store, static_cast<std::uint16_t>(o.delay_ms)), "");
  if (o.json) {
    std::cout << "{\"kbit\": " << o.kbit << ", \"table_index\": " << int{*index}
              << ", \"delay_ms\": " << o.delay_ms
              << ", \"stored\": " << (o.no_store ? "false" : "true") << "}\n"
              << std::flush;
    return;
  }
  std::cout << "bit rate " << o.kbit << " kbit/s activated"
            << (o.no_store ? " (not stored: the devices return to their stored rate at power-off)"
                           : " and stored")
            << "; the devices stay in LSS configuration until the next `cfgmgr lss` command or "
               "LSS master switches them to waiting\n"
            << std::flush;
}

}  // namespace

void add_lss_command(CLI::App& app) {
  auto o = std::make_shared<LssCliOptions>();
  auto* cmd = app.add_subcommand(
      "lss",
      "Layer Setting Services (CiA 305) on a running bus: find devices without node-ID "
      "(Fastscan), give a device its node-ID by its LSS address (1018h sub 1-4), inquire a "
      "device's identity and node-ID, set the bit rate of every device");
  cmd->require_subcommand(1);
  cmd->add_option("--bus", o->bus, "The bus the devices are on (socketcan:IF, udp://GROUP:PORT)")
      ->type_name("URL")
      ->required();
  cmd->add_flag("--json", o->json, "Print the outcome as one JSON object on stdout");
  cmd->add_option("--timeout", o->timeout_ms,
                  "Milliseconds to wait for a device's answer (default 100)")
      ->type_name("MS")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--scan-step", o->scan_step_ms,
                  "Milliseconds each Fastscan request waits for answers; above the devices' "
                  "answer time (default 20)")
      ->type_name("MS")
      ->check(CLI::PositiveNumber);

  auto* scan = cmd->add_subcommand(
      "scan",
      "List the LSS addresses of all devices without node-ID (Fastscan); with --all every "
      "device with its node-ID; assigns nothing");
  scan->add_flag("--all", o->all,
                 "Configured devices too: every device of each product looked for (those of "
                 "the unconfigured devices, --product, --device) by identify remote slave over "
                 "the whole revision and serial number range, each with its node-ID (inquire)");
  scan->add_option("--product", o->products,
                   "With --all: look for the devices of this product too (1018h sub 1-2, hex)")
      ->type_name("VENDOR:PRODUCT");
  scan->add_option("--device", o->devices,
                   "With --all: look for the devices of this file's product too (its 1018h sub "
                   "1-2 or [DeviceInfo] VendorNumber/ProductNumber)")
      ->type_name("FILE.eds");
  scan->fallthrough();
  scan->callback([o] { run_scan(*o); });

  auto* set_id = cmd->add_subcommand(
      "set-id",
      "Give the device with LSS address ADDRESS the node-ID NODE-ID: switch state selective, "
      "configure node-ID, store configuration, switch state global to waiting");
  set_id->add_option("address", o->address, "VENDOR:PRODUCT:REVISION:SERIAL, hex")
      ->required()
      ->type_name("ADDRESS");
  set_id
      ->add_option("node_id", o->node_id,
                   "1..127, or 255 / 'unconfigured' (the device forgets its node-ID)")
      ->required()
      ->type_name("NODE-ID");
  set_id->add_flag("--no-store", o->no_store,
                   "Do not store the node-ID in the device (it is lost at power-off)");
  set_id->fallthrough();
  set_id->callback([o] { run_set_id(*o); });

  auto* inquire = cmd->add_subcommand(
      "inquire",
      "Print the LSS address and node-ID of the device with ADDRESS, or without ADDRESS of the "
      "only LSS device on the bus");
  inquire->add_option("address", o->address, "VENDOR:PRODUCT:REVISION:SERIAL, hex")
      ->type_name("ADDRESS");
  inquire->fallthrough();
  inquire->callback([o] { run_inquire(*o); });

  auto* bitrate = cmd->add_subcommand(
      "set-bitrate",
      "Set the bit rate of every LSS device on the bus: switch state global to configuration, "
      "configure bit timing, store, activate bit timing with the switch delay");
  bitrate->add_option("kbit", o->kbit, "1000, 800, 500, 250, 125, 50, 20 or 10")
      ->required()
      ->type_name("KBIT");
  bitrate
      ->add_option("--delay-ms", o->delay_ms,
                   "The switch delay: the devices wait this long before and after they "
                   "switch (default 100)")
      ->type_name("N");
  bitrate->add_flag("--no-store", o->no_store,
                    "Do not store the bit rate in the devices (they return to their stored "
                    "rate at power-off)");
  bitrate->fallthrough();
  bitrate->callback([o] { run_set_bitrate(*o); });

  cmd->footer(std::string(
      "Actions:\n"
      "  scan                      the LSS addresses of all devices without node-ID, one a line\n"
      "  scan --all                every device with its node-ID (configured ones: of the "
      "products looked for)\n"
      "  set-id ADDRESS NODE-ID    give one device its node-ID (and store it)\n"
      "  inquire [ADDRESS]         a device's LSS address and node-ID\n"
      "  set-bitrate KBIT          the bit rate of the whole network\n\n"
      "An LSS address is the device's 1018h sub 1-4: VENDOR:PRODUCT:REVISION:SERIAL, each hex "
      "(a DCF's [DeviceComissioning] LSS_SerialNumber gives the serial number). A device without "
      "node-ID (FFh) sends no boot-up and does not answer SDO until LSS gives it one; then it "
      "boots (boot-up 700h + node-ID). inquire without ADDRESS switches every device to LSS "
      "configuration: use it with one LSS device on the bus only. Fastscan finds devices "
      "without node-ID only; scan --all finds configured ones by identify remote slave, which "
      "names vendor-ID and product code exactly, so only those of the products it is given or "
      "finds unconfigured (a binary search: about 130 requests of --scan-step per device). "
      "set-bitrate changes the rate "
      "of every device at once; switch the bus (ip link set can0 type can bitrate ...) and "
      "every other node along with them.\n\n"
      "Examples:\n"
      "  cfgmgr lss scan --bus socketcan:can0\n"
      "  cfgmgr lss scan --bus udp://239.74.163.2:43113 --json\n"
      "  cfgmgr lss scan --bus socketcan:can0 --all --device drive.eds --product 7E57C0DE:305\n"
      "  cfgmgr lss set-id --bus socketcan:can0 7E57C0DE:00000305:00010002:00001001 5\n"
      "  cfgmgr lss inquire --bus socketcan:can0 7E57C0DE:305:10002:1001\n"
      "  cfgmgr lss set-bitrate --bus socketcan:can0 250 --delay-ms 200\n\n"
      "Exit codes:\n"
      "  0  done (scan: also when it found no device)\n"
      "  1  a --device file has errors or names no vendor-ID and product code\n"
      "  2  usage error (bad command line, an ADDRESS or KBIT that does not parse, a --bus URL "
      "that does not parse or is sim:)\n"
      "  3  I/O error: the bus cannot be opened or fails\n"
      "  4  a device refused (its error code in words: node-ID out of range, bit rate not "
      "supported, storage not supported) or no device answered\n"));
}

}  // namespace cfgmgr
