// A loaded network on the simulated bus (nmt/sim/sim_network.hpp).
#include "nmt/sim/sim_network.hpp"

#include <cctype>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <utility>

#include "cfg/device_file.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/node_id.hpp"
#include "nmt/sim/device_state.hpp"

namespace nmt {

namespace {

constexpr std::string_view kSimScheme = "sim:";

cfg::Error sim_error(std::string message) {
  return cfg::Error{"sim: " + std::move(message)};
}

std::optional<double> parse_number(std::string_view text) {
  if (text.empty()) return std::nullopt;
  const std::string copy(text);
  std::size_t used = 0;
  double value = 0;
  try {
    value = std::stod(copy, &used);
  } catch (const std::exception&) {
    return std::nullopt;
  }
  if (used != copy.size() || !std::isfinite(value)) return std::nullopt;
  return value;
}

// Hex digits, with or without 0x, as EMCY codes are written ("8130", "0x8130"), at most
// `max`.
std::optional<std::uint32_t> parse_hex(std::string_view text, std::uint32_t max) {
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    text.remove_prefix(2);
  }
  if (text.empty() || text.size() > 8) return std::nullopt;
  std::uint32_t value = 0;
  for (const char c : text) {
    const int digit = std::isdigit(static_cast<unsigned char>(c)) ? c - '0'
                      : (c >= 'a' && c <= 'f')                    ? c - 'a' + 10
                      : (c >= 'A' && c <= 'F')                    ? c - 'A' + 10
                                                                  : -1;
    if (digit < 0) return std::nullopt;
    value = value * 16 + static_cast<std::uint32_t>(digit);
  }
  if (value > max) return std::nullopt;
  return value;
}

// emcy=NODE@MS:CODE[:REGISTER]: one emergency of the device at NODE, MS ms of simulated time
// after the run began, with error code CODE and 1001h bits REGISTER (hex).
cfg::Result<std::pair<std::uint8_t, ScheduledEmergency>> parse_emcy_fault(std::string_view value) {
  const auto fail = [&] {
    return sim_error("emcy=" + std::string(value) +
                     ": expected NODE@MS:CODE[:REGISTER] (node-ID, ms after the start, EMCY "
                     "error code and error register bits in hex, e.g. 3@1500:8130)");
  };
  const auto at = value.find('@');
  const auto colon = value.find(':', at == std::string_view::npos ? 0 : at);
  if (at == std::string_view::npos || colon == std::string_view::npos) return fail();
  const auto node = cfg::parse_integer_literal(value.substr(0, at)).literal;
  if (!node || !cfg::NodeId::from(static_cast<std::uint8_t>(node->value)) || node->value > 127) {
    return fail();
  }
  const auto ms = parse_number(value.substr(at + 1, colon - at - 1));
  if (!ms || *ms < 0 || *ms > 1e9) return fail();
  std::string_view rest = value.substr(colon + 1);
  const auto second = rest.find(':');
  const auto code = parse_hex(rest.substr(0, second), 0xFFFF);
  if (!code) return fail();
  std::optional<std::uint32_t> reg = 0;
  if (second != std::string_view::npos) reg = parse_hex(rest.substr(second + 1), 0xFF);
  if (!reg) return fail();
  ScheduledEmergency e;
  e.at = TimePoint{} +
         std::chrono::duration_cast<Duration>(std::chrono::duration<double, std::milli>(*ms));
  e.error_code = static_cast<std::uint16_t>(*code);
  e.error_register_bits = static_cast<std::uint8_t>(*reg);
  return std::pair{static_cast<std::uint8_t>(node->value), e};
}

}  // namespace

cfg::Result<std::set<std::uint8_t>> parse_node_list(std::string_view text) {
  std::set<std::uint8_t> out;
  std::optional<cfg::Error> error;
  const auto node = [&](std::string_view part) -> std::uint8_t {
    const auto literal = cfg::parse_integer_literal(part).literal;
    const auto parsed = literal ? cfg::NodeId::from(literal->value) : std::nullopt;
    if (!parsed) {
      if (!error) error = cfg::Error{"'" + std::string(part) + "' is no node-ID 1..127"};
      return 1;
    }
    return *parsed;
  };
  std::size_t begin = 0;
  while (begin <= text.size() && !error) {
    const std::size_t comma = std::min(text.find(',', begin), text.size());
    const std::string_view item = text.substr(begin, comma - begin);
    const std::size_t dash = item.find('-');
    const std::uint8_t first = node(item.substr(0, dash));
    const std::uint8_t last = dash == std::string_view::npos ? first : node(item.substr(dash + 1));
    if (error) break;
    if (last < first) return cfg::Error{"range " + std::string(item) + " is empty"};
    for (unsigned n = first; n <= last; ++n) out.insert(static_cast<std::uint8_t>(n));
    begin = comma + 1;
  }
  if (error) return *error;
  return out;
}

bool is_sim_url(std::string_view url) {
  return url.substr(0, kSimScheme.size()) == kSimScheme;
}

cfg::Result<SimBusOptions> parse_sim_url(std::string_view url) {
  if (!is_sim_url(url)) return sim_error("not a sim: URL: " + std::string(url));
  std::string_view rest = url.substr(kSimScheme.size());
  SimBusOptions options;
  if (rest.empty()) return options;
  if (rest.front() != '?') {
    return sim_error("expected '?' and parameters after 'sim:', got '" + std::string(rest) + "'");
  }
  rest.remove_prefix(1);
  std::set<std::string, std::less<>> seen;
  while (!rest.empty()) {
    const auto amp = rest.find('&');
    const std::string_view pair = rest.substr(0, amp);
    rest = amp == std::string_view::npos ? std::string_view() : rest.substr(amp + 1);
    const auto eq = pair.find('=');
    const std::string name(pair.substr(0, eq));
    const std::string_view value = eq == std::string_view::npos ? "" : pair.substr(eq + 1);
    if (name != "device" && name != "emcy" && !seen.insert(name).second) {
      return sim_error("parameter '" + name + "' given twice");
    }
    if (name == "bitrate") {
      const auto parsed = cfg::parse_integer_literal(value);
      if (!parsed.literal || parsed.literal->value < 1 || parsed.literal->value > 1'000'000'000) {
        return sim_error("bitrate=" + std::string(value) + ": expected 1 ... 1000000000 bit/s");
      }
      options.bitrate_bps = static_cast<std::uint32_t>(parsed.literal->value);
    } else if (name == "latency_ms") {
      const auto parsed = parse_number(value);
      if (!parsed || *parsed < 0 || *parsed > 60'000) {
        return sim_error("latency_ms=" + std::string(value) + ": expected 0 ... 60000 ms");
      }
      options.latency_ms = *parsed;
    } else if (name == "loss") {
      const auto parsed = parse_number(value);
      if (!parsed || *parsed < 0 || *parsed > 1) {
        return sim_error("loss=" + std::string(value) + ": expected a probability 0 ... 1");
      }
      options.loss = *parsed;
    } else if (name == "seed") {
      const auto parsed = cfg::parse_integer_literal(value);
      if (!parsed.literal) {
        return sim_error("seed=" + std::string(value) + ": expected an unsigned number");
      }
      options.seed = parsed.literal->value;
    } else if (name == "state") {
      if (value.empty()) return sim_error("state=: expected a directory");
      options.state_dir = value;
    } else if (name == "unconfigured") {
      auto nodes = parse_node_list(value);
      if (!nodes)
        return sim_error("unconfigured=" + std::string(value) + ": " + nodes.error().message);
      options.unconfigured = std::move(nodes).value();
    } else if (name == "device") {
      const auto at = value.rfind('@');
      if (at == std::string_view::npos || at == 0) {
        return sim_error("device=" + std::string(value) +
                         ": expected FILE@NODES (an EDS or DCF and node-IDs, e.g. drive.eds@2-7)");
      }
      auto nodes = parse_node_list(value.substr(at + 1));
      if (!nodes) return sim_error("device=" + std::string(value) + ": " + nodes.error().message);
      for (const std::uint8_t node : *nodes) {
        if (!options.device_files.emplace(node, std::string(value.substr(0, at))).second) {
          return sim_error("device=" + std::string(value) + ": node " + std::to_string(node) +
                           " has a device= already");
        }
      }
    } else if (name == "emcy") {
      auto fault = parse_emcy_fault(value);
      if (!fault) return fault.error();
      options.emergencies[fault->first].push_back(fault->second);
    } else {
      return sim_error(
          "unknown parameter '" + name +
          "' (known: bitrate, latency_ms, loss, seed, state, unconfigured, device, emcy)");
    }
  }
  return options;
}

DeviceFaults with_identity_of(const cfg::DeviceDescription& file, cfg::NodeId node,
                              DeviceFaults faults) {
  const cfg::DeviceIdentity identity = cfg::identity_of(file, node);
  faults.device_type = identity.device_type;
  faults.vendor_id = identity.vendor_id;
  faults.product_code = identity.product_code;
  faults.revision_number = identity.revision_number;
  faults.serial_number = identity.serial_number;
  return faults;
}

cfg::Result<std::vector<SimulatedDevice>> simulated_devices(const cfg::Network& network,
                                                            const SimBusOptions& options,
                                                            std::vector<cfg::NodeId>* skipped,
                                                            std::vector<cfg::NodeId>* owners) {
  DeviceFaults faults;
  faults.sdo_latency = std::chrono::duration_cast<Duration>(
      std::chrono::duration<double, std::milli>(options.latency_ms));
  // device=: each file read once, whatever the number of its node-IDs.
  std::map<std::string, cfg::DeviceDescription> files;
  for (const auto& [node, file] : options.device_files) {
    if (files.contains(file)) continue;
    cfg::ReadResult read = cfg::read_device_file(file);
    if (!read.device || read.diagnostics.has_errors()) {
      std::string first;
      for (const auto& d : read.diagnostics.items()) {
        if (d.severity == cfg::Severity::Error) {
          first = d.message;
          break;
        }
      }
      return cfg::Error{"sim: device=" + file + ": cannot simulate it: " + first};
    }
    files.emplace(file, std::move(*read.device));
  }
  // The devices: the network's nodes in order, then the device= node-IDs it does not have.
  struct Wanted {
    cfg::NodeId node;
    const cfg::DeviceDescription* dcf;
    std::string file;
  };
  std::vector<Wanted> wanted;
  for (const auto& node : network.nodes) {
    if (const auto it = options.device_files.find(node.node_id.value());
        it != options.device_files.end()) {
      wanted.push_back({node.node_id, &files.at(it->second), it->second});
    } else if (node.dcf) {
      wanted.push_back({node.node_id, &*node.dcf, node.file});
    } else if (skipped != nullptr) {
      skipped->push_back(node.node_id);
    }
  }
  for (const auto& [id, file] : options.device_files) {
    const cfg::NodeId node = *cfg::NodeId::from(id);
    if (network.find(node) == nullptr) wanted.push_back({node, &files.at(file), file});
  }
  std::vector<SimulatedDevice> devices;
  devices.reserve(wanted.size());
  for (const auto& [node, dcf, file] : wanted) {
    // unconfigured=: the device of the node powers on without node-ID and waits for LSS to
    // give it one (CiA 305); the node-ID is only where its DCF says it belongs.
    const bool unconfigured = options.unconfigured.contains(node.value());
    auto identity = with_identity_of(*dcf, node, faults);
    if (const auto it = options.emergencies.find(node.value()); it != options.emergencies.end()) {
      identity.emergencies = it->second;
    }
    auto device = unconfigured ? SimulatedDevice::create_unconfigured(*dcf, identity)
                               : SimulatedDevice::create(*dcf, node.value(), identity);
    if (!device) {
      return cfg::Error{file + ": error: cannot simulate node " + std::to_string(node.value()) +
                        (unconfigured ? " unconfigured: " : ": ") + device.error().message};
    }
    if (!options.state_dir.empty()) {
      // Like a real device, it powers on with what it saved last time (CiA 301 §7.5.2.13),
      // the node-ID LSS stored included (CiA 305).
      auto saved = load_device_state(options.state_dir, node);
      if (!saved) {
        return cfg::Error{saved.error().message + " (remove the file to start from the DCF)",
                          saved.error().category};
      }
      if (*saved) restore_device_state(device->node(), std::move(**saved));
    }
    devices.push_back(std::move(device).value());
    if (owners != nullptr) owners->push_back(node);
  }
  return devices;
}

}  // namespace nmt
