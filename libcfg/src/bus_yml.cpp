// The bus.yml reader (cfg/bus_yml.hpp). Each key's meaning is lely-core dcfgen's
// (python/dcf-tools/dcfgen/cli.py, Slave.from_config, Slave.__parse_pdo_config,
// Master.from_config, main; the master's objects from dcfgen/data/master.dcf.em); the comments
// name the dcfgen behaviour each step keeps.
#include "cfg/bus_yml.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <map>
#include <set>
#include <utility>

#include "cfg/cob_id.hpp"
#include "cfg/data_type.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "relative_path.hpp"

namespace cfg {
namespace {

namespace fs = std::filesystem;

// yaml-cpp counts lines from 0; a node made by the reader (absent) has -1.
int line_of(const YAML::Node& node) {
  return node.IsDefined() ? node.Mark().line + 1 : 0;
}

// A key of a mapping with its value, merge keys (`<<`) expanded.
struct Field {
  std::string key;
  int line = 0;
  YAML::Node value;
  std::string path;  // for messages: the keys above it and this one ("axis.tpdo.1.cob_id")
};

// The fields of a mapping in file order; `<<: *anchor` (YAML 1.1 merge key, which PyYAML and
// so dcfgen read) adds the anchor's keys the mapping does not give itself.
std::vector<Field> fields_of(const YAML::Node& map, const std::string& prefix, int depth = 0) {
  std::vector<Field> own;
  if (!map.IsMap()) return own;
  std::vector<YAML::Node> merged;
  for (auto it = map.begin(); it != map.end(); ++it) {
    const std::string key = it->first.IsScalar() ? it->first.Scalar() : std::string();
    if (key == "<<") {
      if (it->second.IsMap()) merged.push_back(it->second);
      if (it->second.IsSequence()) {
        for (const auto& m : it->second) {
          if (m.IsMap()) merged.push_back(m);
        }
      }
      continue;
    }
    own.push_back({key, line_of(it->first), it->second, prefix + key});
  }
  // A merge of a merge of ...: deeper than any real file, and the end of an anchor that merges
  // itself.
  constexpr int kMaxMergeDepth = 16;
  if (depth >= kMaxMergeDepth) return own;
  for (const auto& m : merged) {
    for (auto& f : fields_of(m, prefix, depth + 1)) {
      const bool given =
          std::any_of(own.begin(), own.end(), [&](const Field& o) { return o.key == f.key; });
      if (!given) own.push_back(std::move(f));
    }
  }
  return own;
}

// Whether two values read the same: one node (an alias of the other), two equal scalars, or
// two collections of equal size whose items read the same (to a few levels; deeper ones count
// as different, which at worst gives one warning too many).
bool same_value(const YAML::Node& a, const YAML::Node& b, int depth = 0) {
  if (a.is(b)) return true;
  if (a.Type() != b.Type() || depth > 4) return false;
  if (a.IsScalar()) return a.Scalar() == b.Scalar();
  if (a.IsNull()) return true;
  if (a.size() != b.size()) return false;
  if (a.IsSequence()) {
    for (std::size_t i = 0; i < a.size(); ++i) {
      if (!same_value(a[i], b[i], depth + 1)) return false;
    }
    return true;
  }
  if (a.IsMap()) {
    auto ib = b.begin();
    for (auto ia = a.begin(); ia != a.end(); ++ia, ++ib) {
      if (!same_value(ia->first, ib->first, depth + 1) ||
          !same_value(ia->second, ib->second, depth + 1)) {
        return false;
      }
    }
    return true;
  }
  return false;
}

// The deepest nesting of flow collections ('[', '{') outside quotes and comments: yaml-cpp
// parses them by recursion, and a file nested thousands deep would exhaust the stack.
int flow_depth(std::string_view text) {
  int depth = 0, deepest = 0;
  char quote = 0;
  bool comment = false;
  for (const char c : text) {
    if (c == '\n') {
      comment = false;
      quote = 0;  // a quote left open (it's, in a plain scalar) ends with its line here
    }
    if (comment) continue;
    if (quote != 0) {
      if (c == quote) quote = 0;
      continue;
    }
    if (c == '"' || c == '\'') {
      quote = c;
    } else if (c == '#') {
      comment = true;
    } else if (c == '[' || c == '{') {
      deepest = std::max(deepest, ++depth);
    } else if ((c == ']' || c == '}') && depth > 0) {
      --depth;
    }
  }
  return deepest;
}

const Field* find(const std::vector<Field>& fields, std::string_view key) {
  for (const auto& f : fields) {
    if (f.key == key) return &f;
  }
  return nullptr;
}

// The keys ros2_canopen's (and ros_canopen's) drivers read from the same file; dcfgen ignores
// them and so do we.
bool is_ros_key(std::string_view key) {
  static constexpr std::array<std::string_view, 20> kKeys = {"driver",
                                                             "package",
                                                             "period",
                                                             "namespace",
                                                             "polling",
                                                             "boot_timeout_ms",
                                                             "sdo_timeout_ms",
                                                             "diagnostics",
                                                             "remappings",
                                                             "position_mode",
                                                             "switching_state",
                                                             "homing_timeout_seconds",
                                                             "dcf_bin",
                                                             "enable_lazy_load",
                                                             "non_transmit_timeout",
                                                             "name",
                                                             "use_sim_time",
                                                             "heartbeat_timeout_ms",
                                                             "sync_timeout_ms",
                                                             "can_interface_name"};
  if (key.rfind("scale_", 0) == 0 || key.rfind("offset_", 0) == 0) return true;
  return std::find(kKeys.begin(), kKeys.end(), key) != kKeys.end();
}

// dcfgen's slave keys; dcf_path and configuration_file name where dcfgen's output goes.
constexpr std::array<std::string_view, 23> kSlaveKeys = {"dcf",
                                                         "dcf_path",
                                                         "node_id",
                                                         "revision_number",
                                                         "serial_number",
                                                         "heartbeat_multiplier",
                                                         "heartbeat_consumer",
                                                         "heartbeat_producer",
                                                         "retry_factor",
                                                         "guard_time",
                                                         "life_time_factor",
                                                         "time_cob_id",
                                                         "error_behavior",
                                                         "rpdo",
                                                         "tpdo",
                                                         "boot",
                                                         "mandatory",
                                                         "reset_communication",
                                                         "software_file",
                                                         "software_version",
                                                         "restore_configuration",
                                                         "sdo",
                                                         "configuration_file"};
constexpr std::array<std::string_view, 9> kPdoKeys = {
    "enabled",        "cob_id",     "transmission", "inhibit_time", "event_timer",
    "event_deadline", "sync_start", "mapping",      "rtr"};

template <std::size_t N>
bool one_of(const std::array<std::string_view, N>& keys, std::string_view key) {
  return std::find(keys.begin(), keys.end(), key) != keys.end();
}

// What a slave's settings say, once read; the master's objects are made from these after every
// slave is read (dcfgen's Master.from_config runs after the slaves, too).
struct SlaveSettings {
  std::string name;
  int line = 0;
  NodeId node_id = *NodeId::from(1);
  int node_id_line = 0;
  double heartbeat_multiplier = 3.0;
  bool heartbeat_consumer = false;
  std::uint32_t heartbeat_producer_ms = 0;  // the EDS's 1017h, else the YAML's
  std::uint32_t guard_time_ms = 0;
  std::uint32_t life_time_factor = 0;
  std::uint32_t retry_factor = 3;
  bool boot = true;
  bool mandatory = false;
  bool reset_communication = true;
  std::uint8_t restore_configuration = 0;
  std::optional<std::uint32_t> revision_number;
  std::optional<std::uint32_t> serial_number;
};

struct MasterSettings {
  std::optional<NodeId> node_id;
  std::optional<std::uint16_t> baudrate_kbps;
  std::uint32_t vendor_id = 0, product_code = 0, revision_number = 0, serial_number = 0;
  double heartbeat_multiplier = 3.0;
  bool heartbeat_consumer = true;
  std::uint32_t heartbeat_producer_ms = 0;
  std::optional<std::uint32_t> emcy_inhibit_time, sync_period_us, sync_window_us, sync_overflow,
      time_cob_id, nmt_inhibit_time, boot_time_ms;
  std::map<std::uint8_t, std::uint32_t> error_behavior;
  bool start = true, start_nodes = true, start_all_nodes = false, reset_all_nodes = false,
       stop_all_nodes = false;
};

// A TPDO's CAN identifier and where it was configured, for the clash check.
struct TpdoUse {
  std::string who;
  int line = 0;
};

class Reader {
 public:
  Reader(const std::string& path, const NetworkOptions& options, Diagnostics& diagnostics)
      : path_(path), options_(options), diagnostics_(diagnostics) {}

  bool unreadable = false;
  std::optional<Network> load();

 private:
  void error(int line, std::string message) {
    diagnostics_.add(path_, line, Severity::Error, std::move(message));
  }
  void warning(int line, std::string message) {
    diagnostics_.add(path_, line, Severity::Warning, std::move(message));
  }
  void note_ros_key(const Field& f) {
    if (ros_keys_.emplace(f.key, f.line).second && first_ros_line_ == 0) first_ros_line_ = f.line;
  }

  // Typed values of keys: nullopt (and an error at the key's line) for the wrong type.
  std::optional<std::int64_t> integer(const Field& f, std::int64_t min, std::int64_t max);
  std::optional<std::uint32_t> unsigned_of(const Field& f, std::uint32_t max = 0xFFFFFFFFU) {
    auto v = integer(f, 0, max);
    return v ? std::optional<std::uint32_t>(static_cast<std::uint32_t>(*v)) : std::nullopt;
  }
  std::optional<bool> boolean(const Field& f);
  std::optional<double> real(const Field& f);
  std::optional<std::string> text(const Field& f);
  // A path of the file with its `@NAME@` placeholders replaced; nullopt (an error) when one is
  // not given.
  std::optional<std::string> path_value(const Field& f, const std::string& who);
  bool is_map(const Field& f, const std::string& who) {
    if (f.value.IsMap()) return true;
    error(f.line, who + f.key + ": expected a mapping of keys");
    return false;
  }

  void read_options(const std::vector<Field>& fields);
  void read_master(const std::vector<Field>& fields);
  void read_slave(const std::string& name, int line, const std::vector<Field>& fields);
  // One rpdo/tpdo entry of a slave into its DCF.
  void read_pdo(DeviceDescription& dcf, const SlaveSettings& slave, bool receive, const Field& f);
  void read_mapping(DeviceDescription& dcf, const SlaveSettings& slave, bool receive,
                    std::uint16_t mapping_index, const Field& f, const std::string& who);
  // Sets the ParameterValue of `index` sub `sub` to `value` (text of a value of the entry's
  // type, checked here at `line`); false (an error, or a warning for a read-only entry) when it
  // is not set.
  bool set(DeviceDescription& dcf, const SlaveSettings& slave, std::uint16_t index,
           std::uint8_t sub, std::string_view value, int line, const std::string& who);
  void set_heartbeat_consumer(DeviceDescription& dcf, const SlaveSettings& slave);
  std::optional<const DeviceDescription*> device_file(const std::string& file, int line,
                                                      const std::string& who);
  DeviceDescription make_master(const std::vector<NetworkNode>& nodes);
  void report_ros_keys();

  const std::string& path_;
  const NetworkOptions& options_;
  Diagnostics& diagnostics_;
  fs::path base_;
  double heartbeat_multiplier_ = 3.0;       // options: heartbeat_multiplier (dcfgen's default 3.0)
  std::uint32_t retry_factor_ = 3;          // options: retry_factor (dcfgen's default 3)
  std::uint32_t next_auto_cob_id_ = 0x680;  // dcfgen: options["cob_id"], PDO 5 and up
  MasterSettings master_;
  std::vector<SlaveSettings> slaves_;
  std::vector<NetworkNode> nodes_;                  // the slaves read, in file order
  std::map<std::uint32_t, TpdoUse> tpdos_;          // valid TPDOs by CAN identifier
  std::map<std::string, DeviceDescription> files_;  // each EDS/DCF read once
  std::map<std::string, int> ros_keys_;
  int first_ros_line_ = 0;
};

std::optional<std::int64_t> Reader::integer(const Field& f, std::int64_t min, std::int64_t max) {
  const auto bad = [&](const std::string& why) {
    error(f.line, f.path + ": expected an integer from " + std::to_string(min) + " to " +
                      std::to_string(max) + why);
    return std::nullopt;
  };
  if (!f.value.IsScalar())
    return bad(", not a " + std::string(f.value.IsMap() ? "mapping" : "list"));
  std::string t = f.value.Scalar();
  // PyYAML (YAML 1.1) gives booleans to int() as 1 and 0 (dcfgen: `int(cfg["start"])`).
  if (t == "true" || t == "True" || t == "TRUE")
    return min <= 1 && 1 <= max ? std::optional<std::int64_t>(1) : bad("");
  if (t == "false" || t == "False" || t == "FALSE")
    return min <= 0 ? std::optional<std::int64_t>(0) : bad("");
  t.erase(std::remove(t.begin(), t.end(), '_'), t.end());  // YAML 1.1: 1_000
  bool negative = false;
  std::string_view digits = t;
  if (!digits.empty() && (digits[0] == '-' || digits[0] == '+')) {
    negative = digits[0] == '-';
    digits.remove_prefix(1);
  }
  std::optional<std::uint64_t> magnitude;
  if (digits.size() > 2 && digits[0] == '0' && (digits[1] == 'b' || digits[1] == 'o')) {
    const int base = digits[1] == 'b' ? 2 : 8;
    std::uint64_t v = 0;
    bool ok = true;
    for (char c : digits.substr(2)) {
      const int d = c - '0';
      if (d < 0 || d >= base || v > (UINT64_MAX >> 3)) ok = false;
      v = v * static_cast<unsigned>(base) + static_cast<unsigned>(d);
    }
    if (ok) magnitude = v;
  } else if (const auto parsed = parse_integer_literal(digits); parsed.literal) {
    magnitude = parsed.literal->value;
  }
  if (!magnitude) return bad(", not '" + f.value.Scalar() + "'");
  if (*magnitude > static_cast<std::uint64_t>(INT64_MAX)) return bad(", not " + f.value.Scalar());
  const std::int64_t v =
      negative ? -static_cast<std::int64_t>(*magnitude) : static_cast<std::int64_t>(*magnitude);
  if (v < min || v > max) return bad(", not " + f.value.Scalar());
  return v;
}

std::optional<bool> Reader::boolean(const Field& f) {
  if (f.value.IsScalar()) {
    const std::string& t = f.value.Scalar();
    for (std::string_view yes : {"true", "True", "TRUE", "yes", "Yes", "on", "On"}) {
      if (t == yes) return true;
    }
    for (std::string_view no : {"false", "False", "FALSE", "no", "No", "off", "Off"}) {
      if (t == no) return false;
    }
    // dcfgen takes bool() of the value: a number is true unless 0.
    if (const auto parsed = parse_integer_literal(t); parsed.literal) {
      return parsed.literal->value != 0;
    }
  }
  error(f.line, f.path + ": expected true or false");
  return std::nullopt;
}

std::optional<double> Reader::real(const Field& f) {
  if (f.value.IsScalar()) {
    const std::string& t = f.value.Scalar();
    char* end = nullptr;
    const double v = std::strtod(t.c_str(), &end);
    if (!t.empty() && end == t.c_str() + t.size() && std::isfinite(v) && v >= 0) return v;
  }
  error(f.line, f.path + ": expected a non-negative number");
  return std::nullopt;
}

std::optional<std::string> Reader::text(const Field& f) {
  if (f.value.IsScalar()) return f.value.Scalar();
  error(f.line, f.path + ": expected a text");
  return std::nullopt;
}

std::optional<std::string> Reader::path_value(const Field& f, const std::string& who) {
  auto value = text(f);
  if (!value) return std::nullopt;
  std::string out;
  for (std::size_t at = 0; at < value->size();) {
    const auto open = value->find('@', at);
    const auto close = open == std::string::npos ? open : value->find('@', open + 1);
    if (close == std::string::npos) {
      out += value->substr(at);
      break;
    }
    const std::string name = value->substr(open + 1, close - open - 1);
    const auto it = options_.placeholders.find(name);
    if (name.empty() || it == options_.placeholders.end()) {
      error(f.line, who + f.key + " '" + *value + "' holds the CMake placeholder @" + name +
                        "@ (ros2_canopen's CMake fills it with configure_file): give its value "
                        "(--define " +
                        name + "=DIR), or write the path");
      return std::nullopt;
    }
    out += value->substr(at, open - at) + it->second;
    at = close + 1;
  }
  return out;
}

std::optional<Network> Reader::load() {
  auto file = read_file(path_);
  if (!file) {
    error(0, file.error().message);
    unreadable = true;
    return std::nullopt;
  }
  base_ = fs::path(path_).parent_path();
  constexpr int kMaxFlowDepth = 64;
  if (flow_depth(file->view()) > kMaxFlowDepth) {
    error(0,
          "not a bus.yml: [ ] and { } nested more than " + std::to_string(kMaxFlowDepth) + " deep");
    return std::nullopt;
  }
  YAML::Node root;
  try {
    root = YAML::Load(std::string(file->view()));
  } catch (const YAML::Exception& e) {
    error(e.mark.line + 1, "not valid YAML: " + e.msg);
    return std::nullopt;
  }
  if (!root.IsMap()) {
    error(line_of(root),
          "not a bus.yml: expected a mapping with master, options and one key "
          "per slave (lely dcfgen), or nodes and defaults (ros2_canopen)");
    return std::nullopt;
  }
  const std::vector<Field> top = fields_of(root, "");
  if (const Field* o = find(top, "options"); o != nullptr && is_map(*o, "")) {
    read_options(fields_of(o->value, "options."));
  }
  const Field* master = find(top, "master");
  if (master == nullptr) {
    // dcfgen's main reads cfg["master"]: without it there is no master to configure.
    error(1, "no 'master' key: dcfgen needs the master's settings (at least its node_id)");
  } else if (is_map(*master, "")) {
    read_master(fields_of(master->value, "master."));
  }

  const Field* nodes = find(top, "nodes");
  const Field* defaults = find(top, "defaults");
  std::vector<Field> default_fields;
  if (defaults != nullptr && is_map(*defaults, ""))
    default_fields = fields_of(defaults->value, "defaults.");
  if (defaults != nullptr && nodes == nullptr) {
    warning(defaults->line,
            "defaults without nodes: ros2_canopen applies defaults to the entries of nodes "
            "only; not used");
  }
  for (const auto& f : top) {
    if (f.key == "options" || f.key == "master" || f.key == "nodes" || f.key == "defaults" ||
        f.key.rfind('.', 0) == 0) {
      continue;  // dcfgen skips names starting with '.'
    }
    if (!f.value.IsMap()) {
      error(f.line, f.key + ": expected a slave's settings (a mapping with dcf and node_id)");
      continue;
    }
    read_slave(f.key, f.line, fields_of(f.value, f.key + "."));
  }
  if (nodes != nullptr && is_map(*nodes, "")) {
    for (const auto& n : fields_of(nodes->value, "nodes.")) {
      if (!n.value.IsMap()) {
        error(n.line, "nodes." + n.key + ": expected a slave's settings (a mapping)");
        continue;
      }
      std::vector<Field> own = fields_of(n.value, n.key + ".");
      for (const auto& d : default_fields) {
        const Field* mine = find(own, d.key);
        if (mine == nullptr) {
          own.push_back(d);
        } else if (!same_value(mine->value, d.value)) {
          warning(mine->line, "nodes." + n.key + "." + d.key +
                                  ": the node's own value is used; ros2_canopen's cogen.py "
                                  "lets defaults." +
                                  d.key + " (line " + std::to_string(d.line) + ") overwrite it");
        }
      }
      read_slave(n.key, n.line, own);
    }
  }

  Network network;
  network.file = path_;
  network.master_node_id = master_.node_id;
  std::vector<NetworkNode> nodes_out;
  nodes_out.swap(nodes_);
  std::sort(nodes_out.begin(), nodes_out.end(),
            [](const NetworkNode& a, const NetworkNode& b) { return a.node_id < b.node_id; });
  network.master = make_master(nodes_out);
  network.nodes = std::move(nodes_out);
  report_ros_keys();
  return network;
}

void Reader::report_ros_keys() {
  if (ros_keys_.empty()) return;
  std::string list;
  for (const auto& [key, line] : ros_keys_) {
    list += (list.empty() ? "" : ", ") + key;
  }
  diagnostics_.add(path_, first_ros_line_, Severity::Note,
                   "not used by cfgmgr (ros2_canopen driver settings): " + list);
}

void Reader::read_options(const std::vector<Field>& fields) {
  for (const auto& f : fields) {
    if (f.key == "dcf_path") {
      // dcfgen writes it into master.dcf as the directory of the generated files; the inputs
      // are found relative to the bus.yml, so a placeholder in it changes nothing here.
      if (auto v = text(f); v && v->find('@') != std::string::npos) {
        diagnostics_.add(path_, f.line, Severity::Note,
                         "options.dcf_path '" + *v +
                             "': where dcfgen's master looks for the generated files (a CMake "
                             "placeholder here); not used by cfgmgr, which reads the slaves' "
                             "files relative to " +
                             fs::path(path_).filename().string());
      }
    } else if (f.key == "heartbeat_multiplier") {
      if (auto v = real(f)) heartbeat_multiplier_ = *v;
    } else if (f.key == "retry_factor") {
      if (auto v = unsigned_of(f, 0xFF)) retry_factor_ = *v;
    } else if (is_ros_key(f.key)) {
      note_ros_key(f);
    } else {
      warning(f.line, "options." + f.key + ": unknown key (dcfgen reads " +
                          "dcf_path, heartbeat_multiplier, retry_factor); ignored");
    }
  }
  master_.heartbeat_multiplier = heartbeat_multiplier_;
}

void Reader::read_master(const std::vector<Field>& fields) {
  MasterSettings& m = master_;
  for (const auto& f : fields) {
    const auto u32 = [&](std::optional<std::uint32_t>& out, std::uint32_t max) {
      if (auto v = unsigned_of(f, max)) out = *v;
    };
    const auto flag = [&](bool& out) {
      if (auto v = boolean(f)) out = *v;
    };
    if (f.key == "node_id") {
      if (auto v = unsigned_of(f, 0xFF)) {
        if (auto id = NodeId::from(*v)) {
          m.node_id = id;
        } else {
          error(f.line, "master.node_id: " + std::to_string(*v) + " is not a node-ID (1..127)");
        }
      }
    } else if (f.key == "baudrate") {
      if (auto v = unsigned_of(f, 1000)) m.baudrate_kbps = static_cast<std::uint16_t>(*v);
    } else if (f.key == "vendor_id") {
      if (auto v = unsigned_of(f)) m.vendor_id = *v;
    } else if (f.key == "product_code") {
      if (auto v = unsigned_of(f)) m.product_code = *v;
    } else if (f.key == "revision_number") {
      if (auto v = unsigned_of(f)) m.revision_number = *v;
    } else if (f.key == "serial_number") {
      if (auto v = unsigned_of(f)) m.serial_number = *v;
    } else if (f.key == "heartbeat_multiplier") {
      if (auto v = real(f)) m.heartbeat_multiplier = *v;
    } else if (f.key == "heartbeat_consumer") {
      flag(m.heartbeat_consumer);
    } else if (f.key == "heartbeat_producer") {
      if (auto v = unsigned_of(f, 0xFFFF)) m.heartbeat_producer_ms = *v;
    } else if (f.key == "emcy_inhibit_time") {
      u32(m.emcy_inhibit_time, 0xFFFF);
    } else if (f.key == "sync_period") {
      u32(m.sync_period_us, 0xFFFFFFFFU);
    } else if (f.key == "sync_window") {
      u32(m.sync_window_us, 0xFFFFFFFFU);
    } else if (f.key == "sync_overflow") {
      u32(m.sync_overflow, 240);
    } else if (f.key == "time_cob_id") {
      u32(m.time_cob_id, 0xFFFFFFFFU);
    } else if (f.key == "nmt_inhibit_time") {
      u32(m.nmt_inhibit_time, 0xFFFF);
    } else if (f.key == "boot_time") {
      u32(m.boot_time_ms, 0xFFFFFFFFU);
    } else if (f.key == "error_behavior") {
      if (!is_map(f, "master.")) continue;
      for (const auto& e : fields_of(f.value, f.path + ".")) {
        const auto sub = integer({e.key, e.line, YAML::Node(e.key), e.path}, 1, 0xFE);
        const auto value = unsigned_of(e, 0xFF);
        if (sub && value) m.error_behavior[static_cast<std::uint8_t>(*sub)] = *value;
      }
    } else if (f.key == "start") {
      flag(m.start);
    } else if (f.key == "start_nodes") {
      flag(m.start_nodes);
    } else if (f.key == "start_all_nodes") {
      flag(m.start_all_nodes);
    } else if (f.key == "reset_all_nodes") {
      flag(m.reset_all_nodes);
    } else if (f.key == "stop_all_nodes") {
      flag(m.stop_all_nodes);
    } else if (f.key == "dcf" || f.key == "dcf_path") {
      warning(f.line, "master." + f.key + ": dcfgen makes the master's DCF itself; ignored");
    } else if (is_ros_key(f.key)) {
      note_ros_key(f);
    } else {
      warning(f.line, "master." + f.key + ": unknown key; ignored");
    }
  }
}

std::optional<const DeviceDescription*> Reader::device_file(const std::string& file, int line,
                                                            const std::string& who) {
  if (auto it = files_.find(file); it != files_.end()) return &it->second;
  auto bytes = read_file(file);
  if (!bytes) {
    error(line, who + "dcf '" + file + "': " + bytes.error().message);
    return std::nullopt;
  }
  ReadOptions read_options;
  read_options.mode = options_.mode;
  read_options.file_name = file;
  ReadResult read = parse_device_description(bytes->view(), read_options);
  diagnostics_.append(read.diagnostics);
  if (!read.device || read.diagnostics.has_errors()) return std::nullopt;
  return &files_.emplace(file, std::move(*read.device)).first->second;
}

// An unsigned value an entry of `dcf` has before any download: ParameterValue, else
// DefaultValue ($NODEID resolved), as dcfgen's parse_value() of the EDS reads it.
std::optional<std::uint32_t> eds_value(const DeviceDescription& dcf, std::uint16_t index,
                                       std::uint8_t sub, NodeId node) {
  const SubObject* s = dcf.sub(index, sub);
  if (s == nullptr || !s->configured_value() || s->configured_value()->empty()) {
    return std::nullopt;
  }
  auto value = parse_value(DataType::Unsigned32, *s->configured_value(), node.value());
  if (!value) return std::nullopt;
  return static_cast<std::uint32_t>(value->as_unsigned());
}

bool Reader::set(DeviceDescription& dcf, const SlaveSettings& slave, std::uint16_t index,
                 std::uint8_t sub, std::string_view value, int line, const std::string& who) {
  const std::string where = to_string(ObjectAddress{index, sub});
  SubObject* s = dcf.sub(index, sub);
  if (s == nullptr) {
    error(line, who + where + " is not in the EDS/DCF");
    return false;
  }
  const auto type = s->basic_type();
  if (!type) {
    error(line, who + where + " has no basic data type");
    return false;
  }
  auto parsed = parse_value(*type, value, slave.node_id.value());
  if (!parsed) {
    error(line, who + where + " = " + std::string(value) + ": " + parsed.error().message);
    return false;
  }
  if (!is_writable(s->access)) {
    // dcfgen warns and writes it; a device refuses the write (CiA 301 abort 0601 0002), and the
    // download would end there: not written.
    warning(line, who + where + " is " + std::string(to_string(s->access)) +
                      " in the EDS/DCF: not written");
    return false;
  }
  s->parameter_value = format_value(*parsed);
  return true;
}

void Reader::read_mapping(DeviceDescription& dcf, const SlaveSettings& slave, bool receive,
                          std::uint16_t mapping_index, const Field& f, const std::string& who) {
  if (!f.value.IsSequence()) {
    error(f.line, who + "mapping: expected a list of {index, sub_index}");
    return;
  }
  if (dcf.object(mapping_index) == nullptr) {
    error(f.line, who + "mapping: the EDS/DCF has no " + hex_digits(mapping_index, 4) + "h");
    return;
  }
  std::vector<std::uint32_t> entries;
  unsigned bits_total = 0;
  bool ok = true;
  for (const auto& item : f.value) {
    const int line = line_of(item);
    if (!item.IsMap()) {
      error(line, who + "mapping: expected {index, sub_index}");
      ok = false;
      continue;
    }
    const auto fields = fields_of(item, f.path + ".");
    const Field* index_field = find(fields, "index");
    const Field* sub_field = find(fields, "sub_index");
    if (index_field == nullptr) {
      error(line, who + "mapping: an entry without index");
      ok = false;
      continue;
    }
    const auto index = integer(*index_field, 0, 0xFFFF);
    const auto sub =
        sub_field != nullptr ? integer(*sub_field, 0, 0xFF) : std::optional<std::int64_t>(0);
    if (!index || !sub) {
      ok = false;
      continue;
    }
    const ObjectAddress address{static_cast<std::uint16_t>(*index),
                                static_cast<std::uint8_t>(*sub)};
    const SubObject* s = dcf.sub(address.index, address.sub_index);
    const auto type = s != nullptr ? s->basic_type() : std::nullopt;
    if (s == nullptr || !type || data_type_info(*type).size_bytes == 0) {
      error(line, who + "mapping: " + to_string(address) +
                      (s == nullptr ? " is not in the EDS/DCF" : " has no fixed-size basic type"));
      ok = false;
      continue;
    }
    if (!s->pdo_mapping) {
      warning(line, who + "mapping: " + to_string(address) +
                        " has PDOMapping=0 in the EDS/DCF: the device refuses to map it");
    }
    // CiA 301 §7.5.2.36/38: index << 16 | sub-index << 8 | length in bits.
    const unsigned bits = data_type_info(*type).size_bytes * 8U;
    bits_total += bits;
    entries.push_back(std::uint32_t{address.index} << 16 | std::uint32_t{address.sub_index} << 8 |
                      bits);
  }
  if (!ok) return;
  if (bits_total > 64) {
    warning(f.line, who + "mapping of " + std::to_string(bits_total) +
                        " bits: more than the 64 of a CAN frame (the device refuses it)");
  }
  (void)receive;
  if (!set(dcf, slave, mapping_index, 0, std::to_string(entries.size()), f.line,
           who + "mapping: ")) {
    return;
  }
  for (std::size_t k = 0; k < entries.size(); ++k) {
    set(dcf, slave, mapping_index, static_cast<std::uint8_t>(k + 1), hex(entries[k], 8), f.line,
        who + "mapping: ");
  }
}

void Reader::read_pdo(DeviceDescription& dcf, const SlaveSettings& slave, bool receive,
                      const Field& f) {
  const std::string kind = receive ? "rpdo" : "tpdo";
  const auto number = integer({f.key, f.line, YAML::Node(f.key), f.path}, 1, 512);
  if (!number) return;
  const std::string who = slave.name + "." + kind + "." + f.key + ": ";
  if (!f.value.IsMap()) {
    error(f.line, who + "expected the PDO's settings (a mapping)");
    return;
  }
  const auto comm = static_cast<std::uint16_t>(
      (receive ? object::kRpdoCommunicationFirst : object::kTpdoCommunicationFirst) + *number - 1);
  if (dcf.sub(comm, 1) == nullptr) {
    // dcfgen: KeyError "Receive-PDO N not available".
    error(f.line, who + "the EDS/DCF has no " + (receive ? "RPDO " : "TPDO ") + f.key + " (" +
                      hex_digits(comm, 4) + "h sub 1)");
    return;
  }
  const auto fields = fields_of(f.value, f.path + ".");
  for (const auto& k : fields) {
    if (!one_of(kPdoKeys, k.key)) warning(k.line, who + k.key + ": unknown PDO key; ignored");
  }
  const std::uint32_t eds_cob = eds_value(dcf, comm, 1, slave.node_id).value_or(kCobIdInvalidBit);
  std::uint32_t cob = eds_cob;
  int cob_line = f.line;
  if (const Field* c = find(fields, "cob_id")) {
    cob_line = c->line;
    if (c->value.IsScalar() && c->value.Scalar() == "auto") {
      const auto i = static_cast<unsigned>(*number - 1);
      if (i < 4) {
        // CiA 301 §7.3.5 pre-defined connection set: RPDO n 200h + 100h (n-1), TPDO n 180h + ...
        cob = (i + 1) * 0x100 + (receive ? 0x100U : 0x80U) + slave.node_id.value();
      } else {
        // dcfgen: the next free identifier from 680h up, for the whole network.
        if (next_auto_cob_id_ >= 0x6E0) {
          error(c->line, who +
                             "cob_id: auto: no valid 11-bit COB-ID left (dcfgen allocates "
                             "680h..6DFh for PDOs 5 and up)");
          return;
        }
        cob = next_auto_cob_id_++;
      }
    } else if (auto v = unsigned_of(*c)) {
      cob = *v;
    } else {
      return;
    }
  }
  const Field* enabled_field = find(fields, "enabled");
  bool enabled = true;  // dcfgen: cfg.get("enabled", "true")
  if (enabled_field != nullptr) {
    if (auto v = boolean(*enabled_field)) enabled = *v;
  }
  if ((cob & kCobIdInvalidBit) != 0) {
    // dcfgen configures nothing of a PDO whose COB-ID stays invalid.
    for (const auto& k : fields) {
      if (k.key != "enabled" && k.key != "cob_id") {
        warning(k.line, who + k.key + ": not written: the PDO's COB-ID " + hex(cob, 8) +
                            " has bit 31 set (not valid) and no cob_id makes it valid, so "
                            "dcfgen ignores its settings; give cob_id (auto or a number)");
      }
    }
    // Written even when it is the EDS's default (`enabled: false` of a PDO the EDS leaves
    // invalid): the device's stored COB-ID may not be its default (dcfgen-differences.md).
    if (eds_cob != cob || enabled_field != nullptr || find(fields, "cob_id") != nullptr) {
      set(dcf, slave, comm, 1, hex(cob, 8), cob_line, who + "cob_id: ");
    }
    return;
  }
  const auto parameter = [&](std::string_view key, std::uint8_t sub, bool applies,
                             std::uint32_t max) {
    const Field* p = find(fields, key);
    if (p == nullptr) return;
    const auto v = unsigned_of(*p, max);
    if (!v) return;
    if (!applies) {
      warning(p->line, who + p->key + ": not written: an " + (receive ? "RPDO" : "TPDO") +
                           " has none (dcfgen ignores it)");
      return;
    }
    set(dcf, slave, comm, sub, std::to_string(*v), p->line, who + p->key + ": ");
  };
  parameter("transmission", 2, true, 0xFF);
  parameter("inhibit_time", 3, !receive, 0xFFFF);
  parameter("event_timer", 5, !receive, 0xFFFF);
  parameter("event_deadline", 5, receive, 0xFFFF);  // CiA 301 v4.2 RPDO sub 5
  parameter("sync_start", 6, !receive, 0xFF);
  if (const Field* m = find(fields, "mapping")) {
    read_mapping(dcf, slave, receive,
                 static_cast<std::uint16_t>(
                     comm + (object::kRpdoMappingFirst - object::kRpdoCommunicationFirst)),
                 *m, who);
  }
  const std::uint32_t final_cob = enabled ? cob : (cob | kCobIdInvalidBit);
  if (final_cob != eds_cob || find(fields, "cob_id") != nullptr || enabled_field != nullptr) {
    set(dcf, slave, comm, 1, hex(final_cob, 8), cob_line, who + "cob_id: ");
  }
  if (!receive && enabled) {
    const CobId id = CobId::from_word(cob);
    const std::uint32_t key = id.can_id().id | (id.extended() ? 0x80000000U : 0U);
    const auto [it, fresh] = tpdos_.emplace(key, TpdoUse{slave.name + " TPDO " + f.key, cob_line});
    if (!fresh) {
      // CiA 301 §7.2.2: a PDO has one producer.
      error(cob_line, who + "COB-ID " + hex(id.can_id().id, 3) + " is also the COB-ID of " +
                          it->second.who + " (line " + std::to_string(it->second.line) +
                          "): two TPDOs on one CAN identifier");
    }
  }
}

void Reader::set_heartbeat_consumer(DeviceDescription& dcf, const SlaveSettings& slave) {
  if (!master_.node_id) return;
  const std::uint32_t master = master_.node_id->value();
  const auto heartbeat = static_cast<std::uint32_t>(
      static_cast<double>(master_.heartbeat_producer_ms) * master_.heartbeat_multiplier);
  const Object* consumer = dcf.object(object::kConsumerHeartbeatTime);
  if (slave.heartbeat_consumer && heartbeat > 0) {
    if (consumer == nullptr) {
      warning(slave.line, slave.name + ": heartbeat_consumer: the EDS/DCF has no 1016h");
      return;
    }
    // dcfgen: the entry that already watches the master, else the first unused one.
    std::optional<std::uint8_t> sub;
    for (const auto& [s, _] : consumer->subs) {
      if (s == 0) continue;
      const auto v = eds_value(dcf, object::kConsumerHeartbeatTime, s, slave.node_id).value_or(0);
      if (((v >> 16) & 0xFF) == master) {
        sub = s;
        break;
      }
    }
    for (const auto& [s, _] : consumer->subs) {
      if (sub || s == 0) continue;
      const auto v = eds_value(dcf, object::kConsumerHeartbeatTime, s, slave.node_id).value_or(0);
      const auto node = (v >> 16) & 0xFF;
      if ((v & 0xFFFF) == 0 || node == 0 || node > 127) sub = s;
    }
    if (!sub) {
      warning(slave.line, slave.name + ": heartbeat_consumer: no unused entry in 1016h");
      return;
    }
    set(dcf, slave, object::kConsumerHeartbeatTime, *sub,
        hex(master << 16 | (heartbeat & 0xFFFF), 8), slave.line,
        slave.name + ": heartbeat_consumer: ");
    return;
  }
  if (consumer == nullptr) return;
  // dcfgen: a slave that is not to consume the master's heartbeat stops doing so.
  for (const auto& [s, _] : consumer->subs) {
    if (s == 0) continue;
    const auto v = eds_value(dcf, object::kConsumerHeartbeatTime, s, slave.node_id).value_or(0);
    if ((v & 0xFFFF) != 0 && ((v >> 16) & 0xFF) == master) {
      set(dcf, slave, object::kConsumerHeartbeatTime, s, hex(master << 16, 8), slave.line,
          slave.name + ": heartbeat_consumer: ");
    }
  }
}

void Reader::read_slave(const std::string& name, int line, const std::vector<Field>& fields) {
  SlaveSettings s;
  s.name = name;
  s.line = line;
  s.heartbeat_multiplier = heartbeat_multiplier_;
  s.retry_factor = retry_factor_;
  const std::string who = name + ".";
  for (const auto& f : fields) {
    if (is_ros_key(f.key)) {
      note_ros_key(f);
    } else if (!one_of(kSlaveKeys, f.key)) {
      warning(f.line, who + f.key + ": unknown key; ignored");
    }
  }
  const Field* dcf_field = find(fields, "dcf");
  if (dcf_field == nullptr) {
    error(line, name + ": no dcf: the slave's EDS or DCF is needed to configure it");
    return;
  }
  const auto dcf_name = path_value(*dcf_field, who);
  if (!dcf_name) return;
  const std::string file = detail::resolve_relative(base_, *dcf_name);
  const auto read = device_file(file, dcf_field->line, who);
  if (!read) return;
  DeviceDescription dcf = **read;

  // The node-ID: node_id, else the DCF's own; dcfgen ignores a slave with neither.
  if (const Field* f = find(fields, "node_id")) {
    const auto v = unsigned_of(*f, 0xFF);
    if (!v) return;
    const auto id = NodeId::from(*v);
    if (!id) {
      error(f->line, who + "node_id: " + std::to_string(*v) + " is not a node-ID (1..127)");
      return;
    }
    s.node_id = *id;
    s.node_id_line = f->line;
  } else if (const auto own = dcf.node_id(); own && NodeId::from(*own)) {
    s.node_id = *NodeId::from(*own);
    s.node_id_line = line;
  } else {
    warning(line, name + ": no node_id and none in its DCF: ignored (as dcfgen does)");
    return;
  }
  if (master_.node_id && *master_.node_id == s.node_id) {
    error(s.node_id_line, who + "node_id: node-ID clash: " + std::to_string(s.node_id.value()) +
                              " is the master's node_id");
    return;
  }
  for (const auto& other : slaves_) {
    if (other.node_id == s.node_id) {
      error(s.node_id_line, who + "node_id: node-ID clash: " + std::to_string(s.node_id.value()) +
                                " is also the node-ID of " + other.name + " (line " +
                                std::to_string(other.node_id_line) + ")");
      return;
    }
  }

  const auto u32 = [&](std::string_view key, std::uint32_t max) -> std::optional<std::uint32_t> {
    const Field* f = find(fields, key);
    return f != nullptr ? unsigned_of(*f, max) : std::nullopt;
  };
  const auto flag = [&](std::string_view key, bool& out) {
    if (const Field* f = find(fields, key)) {
      if (auto v = boolean(*f)) out = *v;
    }
  };
  const auto write_var = [&](std::string_view key, std::uint16_t index, std::uint32_t max) {
    const Field* f = find(fields, key);
    if (f == nullptr) return std::optional<std::uint32_t>();
    const auto v = unsigned_of(*f, max);
    if (!v) return std::optional<std::uint32_t>();
    if (dcf.object(index) == nullptr) {
      warning(f->line,
              who + f->key + ": the EDS/DCF has no " + hex_digits(index, 4) + "h: not written");
      return v;
    }
    set(dcf, s, index, 0, std::to_string(*v), f->line, who + f->key + ": ");
    return v;
  };
  s.revision_number = u32("revision_number", 0xFFFFFFFFU);
  s.serial_number = u32("serial_number", 0xFFFFFFFFU);
  if (const Field* f = find(fields, "heartbeat_multiplier")) {
    if (auto v = real(*f)) s.heartbeat_multiplier = *v;
  }
  flag("heartbeat_consumer", s.heartbeat_consumer);
  if (auto v = u32("retry_factor", 0xFF)) s.retry_factor = *v;

  // dcfgen's order of writes; a later setting of the same entry (an `sdo` entry) wins, as the
  // later write does on the device. The master's heartbeat entry comes first (dcfgen inserts
  // it at the front of the stream).
  set_heartbeat_consumer(dcf, s);
  write_var("time_cob_id", object::kCobIdTime, 0xFFFFFFFFU);
  s.heartbeat_producer_ms =
      eds_value(dcf, object::kProducerHeartbeatTime, 0, s.node_id).value_or(0);
  if (auto v = write_var("heartbeat_producer", object::kProducerHeartbeatTime, 0xFFFF)) {
    s.heartbeat_producer_ms = *v;
  }
  s.guard_time_ms = eds_value(dcf, object::kGuardTime, 0, s.node_id).value_or(0);
  if (auto v = write_var("guard_time", object::kGuardTime, 0xFFFF)) s.guard_time_ms = *v;
  s.life_time_factor = eds_value(dcf, object::kLifeTimeFactor, 0, s.node_id).value_or(0);
  if (auto v = write_var("life_time_factor", object::kLifeTimeFactor, 0xFF))
    s.life_time_factor = *v;
  if (s.guard_time_ms != 0 && s.life_time_factor != 0 && s.heartbeat_producer_ms != 0) {
    // CiA 301 §7.2.8.1: a device uses heartbeat or node guarding, not both.
    warning(line, name +
                      ": heartbeat and node guarding both configured: the master watches the "
                      "heartbeat only (as dcfgen)");
    s.guard_time_ms = 0;
    s.life_time_factor = 0;
  }
  if (const Field* f = find(fields, "error_behavior")) {
    if (is_map(*f, who)) {
      for (const auto& e : fields_of(f->value, f->path + ".")) {
        const auto sub = integer({e.key, e.line, YAML::Node(e.key), e.path}, 1, 0xFE);
        const auto value = unsigned_of(e, 0xFF);
        if (sub && value) {
          set(dcf, s, object::kErrorBehaviour, static_cast<std::uint8_t>(*sub),
              std::to_string(*value), e.line, who + "error_behavior: ");
        }
      }
    }
  }
  for (const bool receive : {true, false}) {
    if (const Field* f = find(fields, receive ? "rpdo" : "tpdo")) {
      if (!is_map(*f, who)) continue;
      for (const auto& pdo : fields_of(f->value, f->path + ".")) read_pdo(dcf, s, receive, pdo);
    }
  }
  flag("boot", s.boot);
  flag("mandatory", s.mandatory);
  flag("reset_communication", s.reset_communication);
  if (auto v = u32("restore_configuration", 0xFF))
    s.restore_configuration = static_cast<std::uint8_t>(*v);
  // dcfgen (master.dcf.em): software_version sets 1F81h bit 5 and is the expected software
  // identification 1F55h sub N; software_file sets bit 6 and is 1F58h sub N, the image lely's
  // master downloads. Both become the node's NodeProgram: the master checks the slave's 1F56h
  // sub 1 against 1F55h and updates it from the file (CiA 302-3, docs/master.md).
  std::optional<NodeProgram> program;
  if (const Field* f = find(fields, "software_version")) {
    const auto v = unsigned_of(*f, 0xFFFFFFFFU);
    if (v && *v == 0) {
      // dcfgen: 0 leaves 1F81h bit 5 clear; nothing is checked.
      warning(f->line, who +
                           "software_version: 0 means 'not given': the node's software is "
                           "not checked (1F81h bit 5 clear, as in dcfgen)");
    }
    if (v && *v != 0) {
      program.emplace();
      program->identification = *v;
      program->source = path_;
      program->line = f->line;
    }
  }
  if (const Field* f = find(fields, "software_file")) {
    if (auto image_name = path_value(*f, who)) {
      if (!program) {
        warning(f->line, who +
                             "software_file without software_version: 1F81h bit 5 stays clear, "
                             "so the master neither checks nor updates the node's software (as "
                             "lely's master); give software_version, the identification the "
                             "device reports in 1F56h sub 1, to have it updated");
      } else {
        program->file = detail::resolve_relative(base_, *image_name);
        program->line = f->line;
        auto image = read_program_image(program->file);
        if (!image) {
          error(f->line, who + "software_file '" + program->file + "': " + image.error().message);
        } else {
          program->image = std::move(image).value();
        }
      }
    }
  }
  if (const Field* f = find(fields, "sdo")) {
    if (!f->value.IsSequence()) {
      error(f->line, who + "sdo: expected a list of {index, sub_index, value}");
    } else {
      for (const auto& item : f->value) {
        const int item_line = line_of(item);
        if (!item.IsMap()) {
          error(item_line, who + "sdo: expected {index, sub_index, value}");
          continue;
        }
        const auto entry = fields_of(item, f->path + ".");
        const Field* index = find(entry, "index");
        if (index == nullptr) {
          error(item_line, who + "sdo: an entry without index");
          continue;
        }
        const auto i = integer(*index, 0, 0xFFFF);
        const Field* sub = find(entry, "sub_index");
        const auto k = sub != nullptr ? integer(*sub, 0, 0xFF) : std::optional<std::int64_t>(0);
        const Field* value = find(entry, "value");
        std::string text = "0";  // dcfgen: sdo.get("value", 0)
        if (value != nullptr) {
          if (!value->value.IsScalar()) {
            error(value->line, who + "sdo: value: expected a number or a text");
            continue;
          }
          text = value->value.Scalar();
          if (text == "true") text = "1";
          if (text == "false") text = "0";
        }
        if (i && k) {
          set(dcf, s, static_cast<std::uint16_t>(*i), static_cast<std::uint8_t>(*k), text,
              item_line, who + "sdo: ");
        }
      }
    }
  }

  ConciseOptions concise;
  concise.node_id = s.node_id.value();
  concise.base_dir = fs::path(file).parent_path().string();
  concise.file_name = file;
  auto writes = concise_writes_from_dcf(dcf, concise, diagnostics_);
  if (!writes) return;
  NetworkNode node;
  node.node_id = s.node_id;
  node.name = name;
  node.file = file;
  node.dcf = std::move(dcf);
  node.writes = std::move(*writes);
  node.program = std::move(program);
  nodes_.push_back(std::move(node));
  slaves_.push_back(std::move(s));
}

// An entry of the master's dictionary, made when derive_master has none.
SubObject& master_entry(DeviceDescription& master, std::uint16_t index, std::uint8_t sub,
                        std::string_view name, DataType type) {
  Object& object = master.objects[index];
  if (object.subs.empty()) {
    object.index = index;
    object.name = std::string(name);
    object.object_type = sub == 0 ? ObjectType::Var : ObjectType::Array;
    if (sub != 0) {
      SubObject count;
      count.sub_index = 0;
      count.name = "Highest sub-index supported";
      count.data_type = static_cast<std::uint16_t>(DataType::Unsigned8);
      count.access = AccessType::Ro;
      count.default_value = hex(0, 2);  // the highest sub-index, set below
      object.subs.emplace(0, std::move(count));
    }
  }
  auto [it, fresh] = object.subs.try_emplace(sub);
  if (fresh) {
    it->second.sub_index = sub;
    it->second.name = std::string(name);
    it->second.data_type = static_cast<std::uint16_t>(type);
    it->second.access = AccessType::Rw;
    it->second.default_value = "0";
    if (object.object_type == ObjectType::Array) {
      object.subs.at(0).default_value = hex(object.subs.rbegin()->first, 2);
      object.sub_number = static_cast<std::uint8_t>(object.subs.size());
    }
  }
  return it->second;
}

DeviceDescription Reader::make_master(const std::vector<NetworkNode>& nodes) {
  DeviceDescription master = derive_master(nodes);
  const MasterSettings& m = master_;
  if (master.commissioning) {
    if (m.node_id) master.commissioning->node_id = m.node_id->value();
    master.commissioning->baudrate_kbps = m.baudrate_kbps;
  }
  const auto put = [&](std::uint16_t index, std::uint8_t sub, std::string_view name, DataType type,
                       std::uint32_t value) {
    master_entry(master, index, sub, name, type).parameter_value =
        hex(value, type == DataType::Unsigned8    ? 2
                   : type == DataType::Unsigned16 ? 4
                                                  : 8);
  };
  // master.dcf.em: 1F80h from start, start_nodes, start_all_nodes, reset_all_nodes,
  // stop_all_nodes (CiA 302-2 §6.2 Tables 8-14).
  std::uint32_t startup = NmtStartup::kMaster;
  if (m.start_all_nodes) startup |= NmtStartup::kStartAllNodes;
  if (!m.start) startup |= NmtStartup::kNoAutoOperational;
  if (!m.start_nodes) startup |= NmtStartup::kNoStartSlaves;
  if (m.reset_all_nodes) startup |= NmtStartup::kResetAllNodes;
  if (m.stop_all_nodes) startup |= NmtStartup::kStopAllNodes;
  put(object::kNmtStartup, 0, "NMT startup", DataType::Unsigned32, startup);
  if (m.heartbeat_producer_ms != 0) {
    put(object::kProducerHeartbeatTime, 0, "Producer heartbeat time", DataType::Unsigned16,
        m.heartbeat_producer_ms);
  }
  if (m.sync_period_us) {
    put(0x1006, 0, "Communication cycle period", DataType::Unsigned32, *m.sync_period_us);
  }
  if (m.sync_window_us) {
    put(0x1007, 0, "Synchronous window length", DataType::Unsigned32, *m.sync_window_us);
  }
  if (m.sync_overflow) {
    put(0x1019, 0, "Synchronous counter overflow value", DataType::Unsigned8, *m.sync_overflow);
  }
  if (m.time_cob_id)
    put(object::kCobIdTime, 0, "COB-ID time stamp", DataType::Unsigned32, *m.time_cob_id);
  if (m.emcy_inhibit_time) {
    put(object::kInhibitTimeEmcy, 0, "Inhibit time EMCY", DataType::Unsigned16,
        *m.emcy_inhibit_time);
  }
  for (const auto& [sub, value] : m.error_behavior) {
    put(object::kErrorBehaviour, sub, "Error behavior", DataType::Unsigned8, value);
  }
  if (m.nmt_inhibit_time) {
    put(object::kNmtInhibitTime, 0, "NMT inhibit time", DataType::Unsigned16, *m.nmt_inhibit_time);
  }
  if (m.boot_time_ms) put(object::kBootTime, 0, "Boot time", DataType::Unsigned32, *m.boot_time_ms);
  if (m.vendor_id != 0) put(object::kIdentity, 1, "Vendor-ID", DataType::Unsigned32, m.vendor_id);
  if (m.product_code != 0) {
    put(object::kIdentity, 2, "Product code", DataType::Unsigned32, m.product_code);
  }
  if (m.revision_number != 0) {
    put(object::kIdentity, 3, "Revision number", DataType::Unsigned32, m.revision_number);
  }
  if (m.serial_number != 0) {
    put(object::kIdentity, 4, "Serial number", DataType::Unsigned32, m.serial_number);
  }
  if (Object* identity = master.object(object::kIdentity)) {
    const auto highest = identity->subs.rbegin()->first;
    identity->subs.at(0).default_value = hex(highest, 2);
    identity->sub_number = static_cast<std::uint8_t>(identity->subs.size());
  }

  // 1016h (master.dcf.em): one entry per slave that produces a heartbeat (its EDS's 1017h, else
  // heartbeat_producer), time = producer x heartbeat_multiplier; none when heartbeat_consumer is
  // false.
  std::vector<std::uint32_t> consumers;
  for (const auto& s : slaves_) {
    if (!m.heartbeat_consumer || s.heartbeat_producer_ms == 0) continue;
    const double time = static_cast<double>(s.heartbeat_producer_ms) * s.heartbeat_multiplier;
    consumers.push_back(std::uint32_t{s.node_id.value()} << 16 |
                        (static_cast<std::uint32_t>(time) & 0xFFFF));
  }
  if (Object* heartbeat = master.object(object::kConsumerHeartbeatTime)) {
    for (auto& [sub, entry] : heartbeat->subs) {
      if (sub == 0) continue;
      entry.parameter_value.reset();
      if (sub <= consumers.size()) entry.parameter_value = hex(consumers[sub - 1U], 8);
    }
  }
  // 1F81h: bit 0 slave, bit 2 boot, bit 3 mandatory, bit 4 keep alive (no reset
  // communication), bit 7 restore (CiA 302-2 §6.3, Tables 19-25); node guarding by the master
  // (byte 1 retry factor, bytes 2-3 guard time) when the slave has a guard time and a life
  // time factor and no heartbeat.
  for (const auto& s : slaves_) {
    std::uint8_t flags = SlaveAssignment::kSlave;
    if (s.boot) flags |= SlaveAssignment::kBootSlave;
    if (s.mandatory) flags |= SlaveAssignment::kMandatory;
    if (!s.reset_communication) flags |= SlaveAssignment::kKeepAlive;
    if (s.restore_configuration != 0) flags |= SlaveAssignment::kRestore;
    const bool guarding = s.guard_time_ms != 0 && s.life_time_factor != 0;
    const auto assignment =
        SlaveAssignment::make(flags, guarding ? static_cast<std::uint8_t>(s.retry_factor) : 0,
                              guarding ? static_cast<std::uint16_t>(s.guard_time_ms) : 0);
    const NodeId node = s.node_id;
    if (!std::any_of(nodes.begin(), nodes.end(),
                     [&](const NetworkNode& n) { return n.node_id == node; })) {
      continue;
    }
    put(object::kSlaveAssignment, node.value(), "NMT slave assignment", DataType::Unsigned32,
        assignment.value);
    if (s.restore_configuration != 0) {
      put(object::kRestoreConfiguration, node.value(), "Restore configuration", DataType::Unsigned8,
          s.restore_configuration);
    }
    // 1F87h/1F88h: the YAML's revision and serial number, else the DCF's (dcfgen: 0 is not
    // checked).
    if (s.revision_number) {
      put(object::kRevisionNumber, node.value(), "Revision number", DataType::Unsigned32,
          *s.revision_number);
    }
    std::optional<std::uint32_t> serial = s.serial_number;
    if (!serial) {
      // dcfgen expects the DCF's serial number (1018h sub 4) where the YAML gives none.
      for (const auto& n : nodes) {
        if (n.node_id == node && n.dcf) serial = identity_of(*n.dcf, node).serial_number;
      }
    }
    if (serial && *serial != 0) {
      put(object::kSerialNumber, node.value(), "Serial number", DataType::Unsigned32, *serial);
    }
  }
  // After 1F81h is written: the program's bits 5/6 and 1F55h sub N.
  for (const auto& n : nodes) {
    if (n.program) set_expected_program(master, n.node_id, *n.program);
  }
  return master;
}

}  // namespace

bool is_bus_yml_path(std::string_view path) {
  const std::string ext = fs::path(path).extension().string();
  return iequals(ext, ".yml") || iequals(ext, ".yaml");
}

NetworkLoad load_bus_yml(const std::string& path, const NetworkOptions& options) {
  NetworkLoad out;
  Reader reader(path, options, out.diagnostics);
  try {
    out.network = reader.load();
  } catch (const YAML::Exception& e) {
    out.diagnostics.add(path, e.mark.line + 1, Severity::Error, "not a bus.yml: " + e.msg);
    out.network.reset();
  }
  out.unreadable = reader.unreadable;
  return out;
}

}  // namespace cfg
