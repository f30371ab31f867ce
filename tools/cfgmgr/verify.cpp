// cfgmgr verify NETWORK --bus URL: read back every value the network configures on each node
// (nmt::ConfigurationVerifier: one SDO upload per entry, nothing written) and list where the
// device differs from the description. Exit 0 only when every value was read and none differs.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include "../common/tool_support.hpp"
#include "cfg/bytes.hpp"
#include "cfg/dcf_diff.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "commands.hpp"
#include "master_run.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/manager/configuration_verifier.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"

namespace cfgmgr {
namespace {

constexpr std::string_view kTool = "verify";

struct VerifyCliOptions {
  std::string network;
  std::string bus;
  unsigned net = 1;
  std::string json;
  double sdo_timeout_s = 0.5;
  unsigned retries = 2;
  std::string only;
  std::vector<std::string> dcf_path;  ///< --dcf-path DIR
  std::vector<std::string> defines;   ///< --define NAME=VALUE
};

// One entry as reported: the engine's result with what the description says about it.
struct Entry {
  nmt::VerifyResult result;
  std::string name;
  std::string expected;
  std::string actual;
  // CiA 301 §7.2.4.3.17: 0601 0001 is the device saying the entry is write-only: it cannot be
  // compared, and that is no difference.
  bool write_only() const { return result.abort == nmt::SdoAbort::ReadOfWriteOnly; }
  bool differs() const { return !result.same() && !write_only(); }
};

struct NodeSummary {
  const cfg::NetworkNode* node = nullptr;
  std::size_t entries = 0;
  std::size_t same = 0;
  std::size_t differ = 0;
  std::size_t failed = 0;
  std::size_t write_only = 0;
  /// The node never answered (nmt::VerifyResult::unreachable): none of its entries was read.
  bool unreachable = false;
};

// The value in words by the entry's data type in the node's DCF (hex bytes without one).
std::string in_words(const cfg::SubObject* sub, const std::vector<std::uint8_t>& bytes) {
  if (sub != nullptr) {
    if (const auto type = sub->basic_type()) {
      if (auto value = cfg::decode(*type, bytes)) return cfg::describe_value(*value);
    }
  }
  return bytes.empty() ? std::string("(empty)") : tools::hex_string(bytes) + " (hex bytes)";
}

Entry describe(const cfg::Network& network, nmt::VerifyResult result) {
  const cfg::NetworkNode* node = network.find(result.node_id);
  const cfg::Object* object =
      node != nullptr && node->dcf ? node->dcf->object(result.address.index) : nullptr;
  const cfg::SubObject* sub = object != nullptr ? object->sub(result.address.sub_index) : nullptr;
  std::string name =
      object != nullptr && sub != nullptr ? cfg::parameter_name(*object, *sub) : std::string();
  std::string expected = in_words(sub, result.expected);
  std::string actual = result.read() ? in_words(sub, result.actual)
                                     : "upload failed: " + nmt::to_string(result.abort);
  return Entry{std::move(result), std::move(name), std::move(expected), std::move(actual)};
}

std::string node_label(const cfg::NetworkNode& node) {
  return "node " + std::to_string(node.node_id.value()) +
         (node.name.empty() ? "" : " (" + node.name + ")");
}

void print_report(const std::vector<NodeSummary>& nodes, const std::vector<Entry>& entries) {
  std::size_t name_width = 4;
  for (const auto& n : nodes) name_width = std::max(name_width, n.node->name.size());
  const auto pad = [](std::string text, std::size_t width) {
    text.resize(std::max(width, text.size()), ' ');
    return text;
  };
  std::cout << "node  " << pad("name", name_width) << "  entries  same  differ  failed  result\n";
  for (const auto& n : nodes) {
    char numbers[64];
    std::snprintf(numbers, sizeof numbers, "%7zu  %4zu  %6zu  %6zu", n.entries, n.same, n.differ,
                  n.failed);
    char id[8];
    std::snprintf(id, sizeof id, "%4d", n.node->node_id.value());
    const char* result = n.unreachable                    ? "no response"
                         : n.differ == 0 && n.failed == 0 ? "same as the description"
                         : n.differ != 0                  ? "differs"
                                                          : "not all read";
    std::cout << id << "  " << pad(n.node->name, name_width) << "  " << numbers << "  " << result
              << '\n';
  }
  for (const auto& n : nodes) {
    if (!n.unreachable) continue;
    std::cout << node_label(*n.node) << ": no response to its first upload (is it on the bus?); "
              << tools::plural(n.entries, "entry") << " not read\n";
  }
  for (const auto& e : entries) {
    if (e.result.same() || e.result.unreachable) continue;
    const cfg::NetworkNode& node = *std::find_if(nodes.begin(), nodes.end(), [&](const auto& n) {
                                      return n.node->node_id == e.result.node_id;
                                    })->node;
    std::cout << node_label(node) << ": " << cfg::to_string(e.result.address)
              << (e.name.empty() ? "" : " " + e.name) << ": ";
    if (e.write_only()) {
      std::cout << "write-only, not compared\n";
    } else if (!e.result.read()) {
      std::cout << e.actual << '\n';
    } else {
      std::cout << "expected " << e.expected << ", device has " << e.actual << '\n';
    }
  }
}

std::string json_report(const std::vector<NodeSummary>& nodes, const std::vector<Entry>& entries,
                        bool ok, nmt::Duration elapsed) {
  char number[32];
  std::snprintf(number, sizeof number, "%.6f", static_cast<double>(elapsed.count()) / 1e6);
  std::string out = std::string("{\"ok\": ") + (ok ? "true" : "false") +
                    ", \"elapsed_s\": " + number + ", \"nodes\": [";
  bool first = true;
  for (const auto& n : nodes) {
    out += std::string(first ? "" : ", ") +
           "{\"node_id\": " + std::to_string(n.node->node_id.value()) +
           ", \"name\": " + tools::json_string(n.node->name) +
           ", \"entries\": " + std::to_string(n.entries) + ", \"same\": " + std::to_string(n.same) +
           ", \"differ\": " + std::to_string(n.differ) +
           ", \"failed\": " + std::to_string(n.failed) +
           ", \"write_only\": " + std::to_string(n.write_only) +
           ", \"unreachable\": " + (n.unreachable ? "true" : "false") + "}";
    first = false;
  }
  out += "], \"differences\": [";
  first = true;
  for (const auto& e : entries) {
    if (!e.differs() || e.result.unreachable) continue;  // an absent node: in "nodes" only
    const auto& r = e.result;
    out += std::string(first ? "" : ", ") + "{\"node_id\": " + std::to_string(r.node_id.value()) +
           ", \"index\": " + std::to_string(r.address.index) +
           ", \"sub_index\": " + std::to_string(r.address.sub_index) +
           ", \"address\": " + tools::json_string(cfg::to_string(r.address)) +
           ", \"name\": " + tools::json_string(e.name) +
           ", \"expected\": " + tools::json_string(e.expected) +
           ", \"expected_hex\": " + tools::json_string(tools::hex_string(r.expected)) +
           ", \"actual\": " + (r.read() ? tools::json_string(e.actual) : std::string("null")) +
           ", \"actual_hex\": " +
           (r.read() ? tools::json_string(tools::hex_string(r.actual)) : std::string("null")) +
           ", \"abort\": " +
           (r.read() ? std::string("null") : tools::json_string(nmt::to_string(r.abort))) + "}";
    first = false;
  }
  return out + "]}\n";
}

// Starts the reading of every node with writes.
void start(nmt::ConfigurationVerifier& verifier, const cfg::Network& network, nmt::TimePoint now,
           nmt::ConfigurationVerifier::Output& out) {
  for (const auto& node : network.nodes) {
    if (const auto id = cfg::expected_software_identification(network, node.node_id)) {
      // CiA 302-3: 1F56h sub 1 against 1F55h, which the master checks instead of 1F52h.
      std::vector<cfg::ObjectWrite> writes = node.writes;
      writes.push_back({cfg::object::kProgramSoftwareIdentification, 1, cfg::le32_bytes(*id)});
      verifier.verify(node.node_id, writes, now, out);
      continue;
    }
    const auto program = cfg::expected_program_version(network, node.node_id);
    if (!program) {
      verifier.verify(node.node_id, node.writes, now, out);
      continue;
    }
    // DSP 302 §9: 1F52h sub 1/2 read back against the master's 1F53h/1F54h like any value.
    std::vector<cfg::ObjectWrite> writes = node.writes;
    writes.push_back(
        {cfg::object::kVerifyApplicationSoftware, 1, cfg::le32_bytes(program->date_days)});
    writes.push_back(
        {cfg::object::kVerifyApplicationSoftware, 2, cfg::le32_bytes(program->time_ms)});
    verifier.verify(node.node_id, writes, now, out);
  }
}

// Runs on sim: in simulated time, with a simulated device per node (network_source.hpp).
nmt::Duration run_on_sim(const cfg::Network& network, const SimBusOptions& sim,
                         const nmt::VerifyOptions& options, std::vector<nmt::VerifyResult>& out) {
  std::vector<nmt::SimulatedDevice> built = simulated_devices_or_exit(kTool, network, sim);
  nmt::SimBus bus(sim.bitrate_bps);
  bus.set_loss_rate(sim.loss, sim.seed);
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> devices;
  for (auto& device : built) {
    devices.push_back(
        std::make_unique<nmt::SimEngineNode<nmt::SimulatedDevice>>(std::move(device)));
    bus.attach(*devices.back());
    devices.back()->apply([](nmt::SimulatedDevice& d, nmt::TimePoint now, auto& device_out) {
      d.start(now, device_out);
    });
  }
  nmt::SimEngineNode<nmt::ConfigurationVerifier> reader(options);
  bus.attach(reader);
  reader.set_event_handler(
      [&out](const nmt::VerifyResult& r, nmt::TimePoint) { out.push_back(r); });
  reader.apply([&network](nmt::ConfigurationVerifier& v, nmt::TimePoint now, auto& o) {
    start(v, network, now, o);
  });
  bus.run_until([&reader] { return reader.engine().pending() == 0; });
  return bus.now() - nmt::TimePoint{};
}

// Runs on a real bus in real time.
nmt::Duration run_on_bus(const cfg::Network& network, const std::string& url,
                         const nmt::VerifyOptions& options, std::vector<nmt::VerifyResult>& out) {
  auto opened = nmt::open_bus(url);
  if (!opened) fail_command(kTool, tools::kExitIo, opened.error().message);
  std::unique_ptr<nmt::Bus> bus = std::move(opened).value();
  nmt::BusEventLoop loop(*bus);
  nmt::ConfigurationVerifier verifier(options);
  nmt::EngineRef<nmt::ConfigurationVerifier> ref(verifier);
  ref.set_event_handler([&](const nmt::VerifyResult& r, nmt::TimePoint) {
    out.push_back(r);
    if (verifier.pending() == 0) loop.request_stop();
  });
  loop.add(ref);
  const nmt::TimePoint began = loop.now();
  ref.apply([&network](nmt::ConfigurationVerifier& v, nmt::TimePoint now, auto& o) {
    start(v, network, now, o);
  });
  // Every upload ends (answer, abort or timeout), so the loop stops by itself; the bound only
  // guards against a clock that does not advance.
  cfg::Status status =
      verifier.pending() == 0 ? cfg::Status{} : loop.run_for(std::chrono::hours(24));
  // The last frames (e.g. the end of a block upload) out of the loop's transmit queue.
  loop.clear_stop();
  if (status) status = loop.run_until_sent(std::chrono::seconds(1));
  if (!status) fail_command(kTool, tools::kExitIo, status.error().message);
  return loop.now() - began;
}

void run_verify(const VerifyCliOptions& options) {
  const std::optional<SimBusOptions> sim = parse_bus_url(kTool, options.bus);
  if (options.net == 0)
    fail_command(kTool, tools::kExitUsage, "--net: networks are numbered from 1");
  const nmt::Duration sdo_timeout = sdo_timeout_or_exit(kTool, options.sdo_timeout_s);
  std::set<std::uint8_t> only;
  if (!options.only.empty()) only = parse_only(kTool, options.only);  // before any file
  auto network =
      load_network_or_exit(options.network, options.net, {}, options.dcf_path, options.defines);
  if (!only.empty()) {
    // Only these nodes are read (and, on sim:, simulated); each must be in the network.
    for (const std::uint8_t id : only) {
      if (network->find(*cfg::NodeId::from(id)) == nullptr) {
        fail_command(kTool, tools::kExitUsage,
                     "--only: node " + std::to_string(id) + " is not in " + options.network);
      }
    }
    auto part = std::make_shared<cfg::Network>(*network);
    std::erase_if(part->nodes,
                  [&](const cfg::NetworkNode& n) { return !only.contains(n.node_id.value()); });
    network = std::move(part);
  }

  tools::ReportFile json = open_report_or_exit(options.json);

  nmt::VerifyOptions verify_options;
  verify_options.sdo.timeout = sdo_timeout;
  verify_options.retries = options.retries;
  std::vector<nmt::VerifyResult> results;
  const nmt::Duration elapsed = sim ? run_on_sim(*network, *sim, verify_options, results)
                                    : run_on_bus(*network, options.bus, verify_options, results);

  std::vector<Entry> entries;
  entries.reserve(results.size());
  for (auto& r : results) entries.push_back(describe(*network, std::move(r)));
  // By node, then in the order each node's entries were read.
  std::stable_sort(entries.begin(), entries.end(), [](const Entry& a, const Entry& b) {
    return a.result.node_id < b.result.node_id;
  });
  std::vector<NodeSummary> nodes;
  for (const auto& node : network->nodes) nodes.push_back({&node});
  bool ok = true;
  for (const auto& e : entries) {
    auto& n = *std::find_if(nodes.begin(), nodes.end(), [&](const NodeSummary& s) {
      return s.node->node_id == e.result.node_id;
    });
    ++n.entries;
    n.unreachable = n.unreachable || e.result.unreachable;
    if (e.result.same()) {
      ++n.same;
    } else if (e.write_only()) {
      ++n.write_only;
    } else if (e.result.read()) {
      ++n.differ;
    } else {
      ++n.failed;
    }
    ok = ok && !e.differs();
  }
  print_report(nodes, entries);
  if (json.stream() != nullptr)
    finish_report_or_exit(json, json_report(nodes, entries, ok, elapsed));
  std::cout.flush();
  if (!ok) exit_with(kExitMandatoryFailed);
}

}  // namespace

void add_verify_command(CLI::App& app) {
  auto options = std::make_shared<VerifyCliOptions>();
  auto* cmd = app.add_subcommand(
      "verify",
      "Read back every value the network description configures on each node (the writes "
      "cfgmgr push downloads, one SDO upload each) and list where the device differs from the "
      "description; writes nothing");
  cmd->add_option("network", options->network,
                  "CiA 306-3 project file (nodelist.cpj; DCF paths relative to it) or a master "
                  "DCF (CANopenManager=1) whose 1F20h/1F22h name node files with DownloadFile= or "
                  "UploadFile= (lely dcfgen's master.dcf)")
      ->required()
      ->type_name("NETWORK");
  cmd->add_option("--bus", options->bus,
                  "Bus URL: socketcan:IFNAME, udp://GROUP:PORT (python-can udp_multicast "
                  "compatible), or sim: for the simulated bus with a simulated device per node "
                  "built from the network's DCFs (sim:?bitrate=500000&latency_ms=1&loss=0.01&"
                  "seed=N)")
      ->required()
      ->type_name("URL");
  add_dcf_path_option(*cmd, options->dcf_path);
  cmd->add_option("--net", options->net,
                  "Which network of the project file: 1 is [Topology], N is [TopologyN]")
      ->capture_default_str()
      ->type_name("N");
  add_define_option(*cmd, options->defines);
  cmd->add_option(
         "--json", options->json,
         "Also write the report as JSON: ok, elapsed_s (bus time; simulated on sim:), "
         "nodes [{node_id, name, entries, same, differ, failed, write_only, unreachable}], "
         "differences [{node_id, index, sub_index, address, name, expected, "
         "expected_hex, actual, actual_hex, abort}]")
      ->type_name("FILE");
  cmd->add_option("--sdo-timeout", options->sdo_timeout_s,
                  "Timeout of each SDO response, in seconds")
      ->capture_default_str()
      ->type_name("SECONDS")
      ->check(CLI::PositiveNumber);
  cmd->add_option("--retries", options->retries, "How often a timed-out upload is repeated")
      ->capture_default_str()
      ->type_name("N");
  cmd->add_option("--only", options->only,
                  "Read back only these nodes, e.g. 3,5-7 (each must be in the network)")
      ->type_name("NODES");
  cmd->footer(std::string(
      "The table goes to stdout: per node the entries read, how many are the same as the "
      "description, differ, or could not be read; then one line per entry that is not the "
      "same: node, index, sub-index, name, the expected value and the device's, in words. An "
      "entry written more than once by the download (a PDO's COB-ID, its mapping count) is "
      "compared with its last write. A write-only entry (abort 0601 0001) is listed but not "
      "compared. A node whose first upload goes unanswered (and whose heartbeat was not seen) "
      "is 'no response' and its other entries are not asked: an absent node costs one SDO "
      "timeout.\n\n"
      "Examples:\n"
      "  cfgmgr verify samples/network/nodelist.cpj --bus sim:\n"
      "  cfgmgr verify nodelist.cpj --bus socketcan:can0 --json verify.json\n"
      "  cfgmgr verify nodelist.cpj --bus socketcan:can0 --only 3,5-7\n"
      "  cfgmgr verify master.dcf --bus udp://239.74.163.2:43113 --sdo-timeout 1\n\n"
      "Exit codes:\n"
      "  0  every value was read and is the same as the description\n"
      "  1  the network description has errors (printed as FILE:LINE: error: ...)\n"
      "  2  usage error (bad command line, a --bus URL that does not parse, --only naming a "
      "node that is not in the network)\n"
      "  3  I/O error: the description cannot be read, the bus cannot be opened or fails, "
      "--json cannot be written\n"
      "  4  a value differs, or could not be read (no answer, or an abort)\n"));
  cmd->callback([options] { run_verify(*options); });
}

}  // namespace cfgmgr
