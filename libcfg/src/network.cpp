#include "cfg/network.hpp"

#include <algorithm>
#include <filesystem>
#include <initializer_list>
#include <map>
#include <string_view>
#include <utility>

#include "cfg/bus_yml.hpp"
#include "cfg/bytes.hpp"
#include "cfg/data_type.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "device_file_detail.hpp"
#include "ini_scanner.hpp"
#include "relative_path.hpp"

namespace cfg {

std::string detail::resolve_relative(const std::filesystem::path& base_dir,
                                     const std::string& name) {
  const auto join = [&base_dir](const std::string& n) {
    const std::filesystem::path p(n);
    return (p.is_absolute() || base_dir.empty() ? p : base_dir / p).string();
  };
  std::string path = join(name);
  std::error_code ec;
  if (name.find('\\') != std::string::npos && !std::filesystem::exists(path, ec)) {
    std::string slashed = name;
    std::replace(slashed.begin(), slashed.end(), '\\', '/');
    if (std::filesystem::exists(join(slashed), ec)) path = join(slashed);
  }
  return path;
}

namespace {

namespace fs = std::filesystem;

// --- the project file (CiA 306-3)
// -----------------------------------------------------------------

struct Entry {
  std::string key;  // as written
  std::string value;
  int line = 0;
};

struct Section {
  std::string name;
  int line = 0;
  std::vector<Entry> entries;

  // The last entry of `key` (a key given twice takes the later value, as the DCF reader does).
  const Entry* find(std::string_view key) const {
    const auto it = std::find_if(entries.rbegin(), entries.rend(),
                                 [key](const Entry& e) { return iequals(e.key, key); });
    return it == entries.rend() ? nullptr : &*it;
  }
};

class SectionCollector final : public detail::IniSink {
 public:
  std::vector<Section> sections;

  void on_section(int line, std::string_view name, std::string_view, bool) override {
    sections.push_back({std::string(name), line, {}});
  }
  void on_key(int line, std::string_view key, std::string_view value) override {
    if (!sections.empty())
      sections.back().entries.push_back({std::string(key), std::string(value), line});
  }
  void on_comment(int, char) override {}
  void on_junk(int, std::string_view) override {}
};

// Messages are built in one string (no temporaries per `+`).
std::string concat(std::initializer_list<std::string_view> parts) {
  std::string out;
  for (const std::string_view part : parts) out += part;
  return out;
}

std::string_view strip_bom(std::string_view text) {
  if (text.substr(0, 3) == "\xEF\xBB\xBF") text.remove_prefix(3);
  return text;
}

// "Topology" is network 1, "Topology<n>" network n; 0 for any other name.
unsigned topology_number(std::string_view name) {
  constexpr std::string_view kTopology = "Topology";
  if (name.size() < kTopology.size() || !iequals(name.substr(0, kTopology.size()), kTopology)) {
    return 0;
  }
  const std::string_view rest = name.substr(kTopology.size());
  if (rest.empty()) return 1;
  unsigned n = 0;
  for (char c : rest) {
    if (c < '0' || c > '9' || n > 100000) return 0;
    n = n * 10 + static_cast<unsigned>(c - '0');
  }
  return n;
}

// A number of the project file: CiA 306 literal, an inline comment cut off.
std::optional<std::uint64_t> number_of(std::string_view text) {
  if (const auto cut = detail::find_inline_comment(text); cut != std::string_view::npos) {
    text = detail::trim_blanks(text.substr(0, cut));
  }
  const auto parsed = parse_integer_literal(text);
  if (!parsed.literal) return std::nullopt;
  return parsed.literal->value;
}

fs::path directory_of(const std::string& path) {
  return fs::path(path).parent_path();
}

// --- reading node files --------------------------------------------------------------------------

class Loader {
 public:
  Loader(const std::string& path, const NetworkOptions& options, Diagnostics& diagnostics)
      : path_(path), options_(options), diagnostics_(diagnostics) {}

  bool unreadable = false;

  std::optional<Network> load();

 private:
  std::optional<Network> load_project(const std::vector<Section>& sections);
  std::optional<Network> load_master_dcf(std::string_view text);
  // Reads and parses a DCF named at `line` of `naming_file`; nullopt when it cannot be read
  // (an error at that line) or not be parsed.
  std::optional<DeviceDescription> read_dcf(const std::string& file, const std::string& naming_file,
                                            int line, const std::string& what);
  std::optional<DeviceDescription> parse_dcf(std::string_view text, const std::string& file);
  // The node-ID of a DCF must be the one the description gives it.
  void check_node_id(const DeviceDescription& dcf, NodeId node, const std::string& naming_file,
                     int line, const std::string& what);
  // A slave from its DCF: its configuration writes; nullopt when they cannot be made.
  std::optional<NetworkNode> node_from_dcf(DeviceDescription dcf, NodeId node, std::string file,
                                           std::string name);
  // NodeXProgramFile= / NodeXProgramVersion= of [Topology] (our keys, see network.hpp).
  std::optional<NodeProgram> read_program(const Section& topology, const std::string& prefix,
                                          const fs::path& base);
  // The file a master DCF's DOMAIN entry `sub` names (network.hpp: DownloadFile=, else
  // UploadFile=; as written, else by its name in dcf_path, else beside the master DCF), with
  // the key's words for messages ("1F22h sub 02h UploadFile"). nullopt when the entry names
  // none; `path` empty when the file is nowhere (an error at the key's line).
  struct NamedFile {
    std::string what;
    std::string path;
    int line = 0;
  };
  std::optional<NamedFile> named_file(std::string_view text, std::uint16_t index,
                                      const SubObject& sub, const fs::path& base);
  void error(const std::string& file, int line, std::string message) {
    diagnostics_.add(file, line, Severity::Error, std::move(message));
  }

  const std::string& path_;
  const NetworkOptions& options_;
  Diagnostics& diagnostics_;
};

std::optional<Network> Loader::load() {
  auto text = read_file(path_);
  if (!text) {
    error(path_, 0, text.error().message);
    unreadable = true;
    return std::nullopt;
  }
  SectionCollector collector;
  detail::scan_ini(strip_bom(text->view()), collector);
  const bool is_project =
      std::any_of(collector.sections.begin(), collector.sections.end(),
                  [](const Section& s) { return topology_number(s.name) != 0; });
  if (is_project) return load_project(collector.sections);
  return load_master_dcf(text->view());
}

std::optional<DeviceDescription> Loader::parse_dcf(std::string_view text, const std::string& file) {
  ReadOptions read_options;
  read_options.mode = options_.mode;
  read_options.file_name = file;
  ReadResult read = parse_device_description(text, read_options);
  diagnostics_.append(read.diagnostics);
  if (!read.device || read.diagnostics.has_errors()) return std::nullopt;
  return std::move(read.device);
}

std::optional<DeviceDescription> Loader::read_dcf(const std::string& file,
                                                  const std::string& naming_file, int line,
                                                  const std::string& what) {
  auto text = read_file(file);
  if (!text) {
    error(naming_file, line, what + " '" + file + "': " + text.error().message);
    return std::nullopt;
  }
  return parse_dcf(text->view(), file);
}

void Loader::check_node_id(const DeviceDescription& dcf, NodeId node,
                           const std::string& naming_file, int line, const std::string& what) {
  const auto own = dcf.node_id();
  if (!own || *own == node.value()) return;
  error(naming_file, line,
        what + ": node-ID clash: the DCF's [DeviceComissioning] NodeID is " + std::to_string(*own) +
            ", the network description gives node-ID " + std::to_string(node.value()));
}

std::optional<NetworkNode> Loader::node_from_dcf(DeviceDescription dcf, NodeId node,
                                                 std::string file, std::string name) {
  ConciseOptions concise;
  concise.node_id = node.value();
  concise.base_dir = directory_of(file).string();
  concise.file_name = file;
  auto writes = concise_writes_from_dcf(dcf, concise, diagnostics_);
  if (!writes) return std::nullopt;
  NetworkNode out;
  out.node_id = node;
  out.name = !name.empty() ? std::move(name)
                           : (dcf.commissioning ? dcf.commissioning->node_name : std::string());
  out.file = std::move(file);
  out.dcf = std::move(dcf);
  out.writes = std::move(*writes);
  return out;
}

std::optional<Network> Loader::load_project(const std::vector<Section>& sections) {
  const Section* topology = nullptr;
  for (const auto& s : sections) {
    if (topology_number(s.name) == options_.net) topology = &s;  // a repeated one: the last
  }
  if (topology == nullptr) {
    std::string message =
        "no [Topology" + (options_.net == 1 ? std::string() : std::to_string(options_.net)) +
        "] section for network " + std::to_string(options_.net) + "; the file describes network";
    std::string numbers;
    for (const auto& s : sections) {
      if (const unsigned n = topology_number(s.name); n != 0) {
        numbers += (numbers.empty() ? " " : ", ") + std::to_string(n);
      }
    }
    error(path_, 0, message + (numbers.find(',') != std::string::npos ? "s" : "") + numbers);
    return std::nullopt;
  }

  Network network;
  network.file = path_;
  network.net = options_.net;
  if (const Entry* e = topology->find("NetName")) network.name = e->value;
  const fs::path base = directory_of(path_);
  if (const Entry* e = topology->find("EDSBaseName"); e != nullptr && !e->value.empty()) {
    network.eds_base_dir = detail::resolve_relative(base, e->value);
  }
  const std::string section_name = "[" + topology->name + "] ";

  std::size_t present = 0;
  std::optional<DeviceDescription> master;
  for (unsigned x = kMinNodeId; x <= kMaxNodeId; ++x) {
    const std::string prefix = "Node" + std::to_string(x);
    const Entry* present_entry = topology->find(prefix + "Present");
    if (present_entry == nullptr) continue;  // CiA 306-3: a missing entry means "not present"
    const auto flag = number_of(present_entry->value);
    if (!flag || *flag > 1) {
      error(path_, present_entry->line,
            section_name + present_entry->key + "=" + present_entry->value +
                ": expected 0x00 (not present) or 0x01 (present)");
      continue;
    }
    if (*flag == 0) continue;
    ++present;
    const NodeId node = *NodeId::from(x);
    const Entry* dcf_entry = topology->find(prefix + "DCFName");
    if (dcf_entry == nullptr || dcf_entry->value.empty()) {
      error(path_, present_entry->line,
            concat({section_name, "node ", std::to_string(x), " is present but has no ", prefix,
                    "DCFName: nothing to configure it from"}));
      continue;
    }
    const std::string file = detail::resolve_relative(base, dcf_entry->value);
    auto dcf = read_dcf(file, path_, dcf_entry->line, section_name + dcf_entry->key);
    if (!dcf) continue;
    check_node_id(*dcf, node, path_, dcf_entry->line,
                  concat({section_name, dcf_entry->key, " '", file, "'"}));
    if (dcf->commissioning && dcf->commissioning->canopen_manager.value_or(false)) {
      if (master) {
        error(path_, dcf_entry->line,
              concat({section_name, dcf_entry->key, " '", file,
                      "': a second DCF with CANopenManager=1; the master's is '",
                      network.master_file, "'"}));
        continue;
      }
      network.master_from_file = true;
      network.master_file = file;
      network.master_node_id = node;
      master = std::move(dcf);
      continue;
    }
    const Entry* name_entry = topology->find(prefix + "Name");
    if (auto slave = node_from_dcf(std::move(*dcf), node, file,
                                   name_entry != nullptr ? name_entry->value : std::string())) {
      slave->program = read_program(*topology, prefix, base);
      network.nodes.push_back(std::move(*slave));
    }
  }
  if (const Entry* nodes = topology->find("Nodes")) {
    const auto count = number_of(nodes->value);
    if (!count) {
      error(path_, nodes->line, section_name + "Nodes=" + nodes->value + ": not a number");
    } else if (*count != present) {
      diagnostics_.add(path_, nodes->line, Severity::Warning,
                       section_name + "Nodes=" + nodes->value + " but " + std::to_string(present) +
                           " node" + (present == 1 ? " is" : "s are") + " present");
    }
  }
  if (master) {
    // The description's programs win over the master DCF's own 1F53h/1F54h (network.hpp).
    for (const auto& node : network.nodes) {
      if (node.program) set_expected_program(*master, node.node_id, *node.program);
    }
  }
  network.master = master ? std::move(*master) : derive_master(network.nodes);
  return network;
}

std::optional<NodeProgram> Loader::read_program(const Section& topology, const std::string& prefix,
                                                const fs::path& base) {
  const std::string section_name = "[" + topology.name + "] ";
  const Entry* file_entry = topology.find(prefix + "ProgramFile");
  const Entry* version_entry = topology.find(prefix + "ProgramVersion");
  if (file_entry != nullptr && file_entry->value.empty()) file_entry = nullptr;
  if (file_entry == nullptr && version_entry == nullptr) return std::nullopt;
  NodeProgram program;
  program.source = path_;
  program.line = file_entry != nullptr ? file_entry->line : version_entry->line;
  if (version_entry != nullptr) {
    auto version = parse_program_version(version_entry->value);
    if (!version) {
      // No program for the node: the error stops every tool that runs the network, and a
      // second "image without a version" about the same key would say nothing new.
      error(path_, version_entry->line,
            concat({section_name, version_entry->key, "=", version_entry->value, ": ",
                    version.error().message}));
      return std::nullopt;
    }
    program.version = *version;
  }
  if (file_entry != nullptr) {
    program.file = detail::resolve_relative(base, file_entry->value);
    auto image = read_program_image(program.file);
    if (!image) {
      error(path_, file_entry->line,
            concat(
                {section_name, file_entry->key, " '", program.file, "': ", image.error().message}));
    } else {
      program.image = std::move(image).value();
    }
  }
  return program;
}

// The line of `key`= in the section that begins at `section_line` of `text` (1-based), else
// `section_line`: the model keeps the section's line only, and this is asked only for messages.
int key_line(std::string_view text, int section_line, std::string_view key) {
  int line = 0;
  std::size_t at = 0;
  while (at <= text.size()) {
    const std::size_t end = std::min(text.find('\n', at), text.size());
    std::string_view row = detail::trim_blanks(text.substr(at, end - at));
    ++line;
    if (line > section_line) {
      if (!row.empty() && row.front() == '[') break;
      const auto eq = row.find('=');
      if (eq != std::string_view::npos && iequals(detail::trim_blanks(row.substr(0, eq)), key)) {
        return line;
      }
    }
    at = end + 1;
  }
  return section_line;
}

std::optional<Loader::NamedFile> Loader::named_file(std::string_view text, std::uint16_t index,
                                                    const SubObject& sub, const fs::path& base) {
  const bool download = sub.download_file && !sub.download_file->empty();
  const bool upload = sub.upload_file && !sub.upload_file->empty();
  if (!download && !upload) return std::nullopt;
  const std::string_view key = download ? "DownloadFile" : "UploadFile";
  const std::string& name = download ? *sub.download_file : *sub.upload_file;
  NamedFile out;
  out.what = to_string(ObjectAddress{index, sub.sub_index}) + " " + std::string(key);
  out.line = key_line(text, sub.line, key);
  if (download && upload && *sub.download_file != *sub.upload_file) {
    diagnostics_.add(path_, out.line, Severity::Warning,
                     concat({out.what, " '", name, "' and UploadFile '", *sub.upload_file,
                             "' name different files: DownloadFile is used"}));
  }
  const std::string written = detail::resolve_relative(base, name);
  std::error_code ec;
  if (fs::exists(written, ec)) {
    out.path = written;
    return out;
  }
  // lely's dcfgen writes its dcf_path joined to the file's name, a path of the machine that ran
  // it: the name alone is looked for where this machine keeps the files.
  std::string file_name = name;
  std::replace(file_name.begin(), file_name.end(), '\\', '/');
  file_name = fs::path(file_name).filename().string();
  for (const std::string& dir : options_.dcf_path) {
    const std::string candidate = (fs::path(dir) / file_name).string();
    if (fs::exists(candidate, ec)) {
      out.path = candidate;
      return out;
    }
  }
  const std::string beside = (base / file_name).string();
  if (!file_name.empty() && beside != written && fs::exists(beside, ec)) {
    diagnostics_.add(path_, out.line, Severity::Warning,
                     concat({out.what, " '", name, "' does not exist; using '", beside,
                             "' beside the master DCF instead"}));
    out.path = beside;
    return out;
  }
  std::string looked;
  for (const std::string& dir : options_.dcf_path) {
    looked += "'" + (fs::path(dir) / file_name).string() + "', ";
  }
  looked += "'" + beside + "'";
  error(path_, out.line,
        concat({out.what, " '", name, "': no such file (nor ", looked,
                "); the master DCF names a file of another machine or one that was moved: "
                "rebuild the master DCF here (dcfgen) or pass the directory that holds '",
                file_name, "'",
                options_.dcf_path_hint.empty() ? std::string_view()
                                               : std::string_view(options_.dcf_path_hint)}));
  return out;
}

// A node file named by 1F22h: a concise DCF, or (written by hand) a DCF.
bool looks_like_text_dcf(std::span<const std::uint8_t> bytes) {
  std::string_view text(reinterpret_cast<const char*>(bytes.data()), bytes.size());
  text = strip_bom(text);
  const auto first = text.find_first_not_of(" \t\r\n");
  return first != std::string_view::npos && (text[first] == '[' || text[first] == ';');
}

std::optional<Network> Loader::load_master_dcf(std::string_view text) {
  auto dcf = parse_dcf(text, path_);
  if (!dcf) return std::nullopt;
  if (!dcf->commissioning || !dcf->commissioning->canopen_manager.value_or(false)) {
    error(path_, 0,
          "neither a CiA 306-3 project file (no [Topology] section) nor a master DCF "
          "([DeviceComissioning] CANopenManager=1)");
    return std::nullopt;
  }
  Network network;
  network.file = path_;
  network.name = dcf->commissioning->network_name;
  network.master_from_file = true;
  network.master_file = path_;
  if (const auto own = dcf->node_id()) network.master_node_id = NodeId::from(*own);
  const fs::path base = directory_of(path_);

  for (unsigned x = kMinNodeId; x <= kMaxNodeId; ++x) {
    const auto sub_index = static_cast<std::uint8_t>(x);
    const NodeId node = *NodeId::from(x);
    // DSP 302 §6.1/§6.2: sub-index X of 1F20h (store DCF) and 1F22h (concise DCF) is node X's.
    const SubObject* sub = nullptr;
    std::uint16_t index = 0;
    for (const std::uint16_t candidate : {object::kStoreDcf, object::kConciseDcf}) {
      const SubObject* s = dcf->sub(candidate, sub_index);
      const auto names = [](const OptionalText& t) { return t && !t->empty(); };
      if (s != nullptr && (names(s->download_file) || names(s->upload_file))) {
        sub = s;
        index = candidate;
        break;
      }
    }
    if (sub == nullptr) continue;
    if (network.master_node_id && *network.master_node_id == node) {
      diagnostics_.add(path_, sub->line, Severity::Warning,
                       to_string(ObjectAddress{index, sub_index}) +
                           ": names a file for the master's own node-ID; ignored");
      continue;
    }
    const auto named = named_file(text, index, *sub, base);
    if (!named || named->path.empty()) continue;
    const std::string& what = named->what;
    const std::string& file = named->path;
    auto bytes = read_file(file);
    if (!bytes) {
      error(path_, named->line, concat({what, " '", file, "': ", bytes.error().message}));
      continue;
    }
    const std::string_view view = bytes->view();
    const std::span<const std::uint8_t> data(reinterpret_cast<const std::uint8_t*>(view.data()),
                                             view.size());
    if (index == object::kStoreDcf || looks_like_text_dcf(data)) {
      auto node_dcf = parse_dcf(view, file);
      if (!node_dcf) continue;
      check_node_id(*node_dcf, node, path_, named->line, concat({what, " '", file, "'"}));
      if (auto slave = node_from_dcf(std::move(*node_dcf), node, file, {})) {
        network.nodes.push_back(std::move(*slave));
      }
      continue;
    }
    auto writes = decode_concise_dcf(data);
    if (!writes) {
      error(path_, named->line,
            concat({what, " '", file, "': not a concise DCF: ", writes.error().message}));
      continue;
    }
    NetworkNode slave;
    slave.node_id = node;
    slave.file = file;
    slave.writes = std::move(writes).value();
    network.nodes.push_back(std::move(slave));
  }
  // CiA 302-3 1F58h sub X: the image of node X's program; its version is the master DCF's own
  // (1F53h/1F54h, check_programs).
  for (unsigned x = kMinNodeId; x <= kMaxNodeId; ++x) {
    const SubObject* sub = dcf->sub(object::kSlaveProgramData, static_cast<std::uint8_t>(x));
    if (sub == nullptr) continue;
    const auto named = named_file(text, object::kSlaveProgramData, *sub, base);
    if (!named || named->path.empty()) continue;
    const auto it = std::find_if(network.nodes.begin(), network.nodes.end(),
                                 [x](const NetworkNode& n) { return n.node_id.value() == x; });
    if (it == network.nodes.end()) {
      diagnostics_.add(path_, named->line, Severity::Warning,
                       concat({named->what, " '", named->path, "': node ", std::to_string(x),
                               " has no configuration (1F20h/1F22h sub ", hex_digits(x, 2),
                               "h name no file); its program is not used"}));
      continue;
    }
    NodeProgram program;
    program.file = named->path;
    program.source = path_;
    program.line = named->line;
    auto image = read_program_image(program.file);
    if (!image) {
      error(path_, named->line,
            concat({named->what, " '", program.file, "': ", image.error().message}));
      continue;
    }
    program.image = std::move(image).value();
    it->program = std::move(program);
  }
  network.master = std::move(*dcf);
  return network;
}

// --- the derived master
// ---------------------------------------------------------------------------

// An unsigned value of a DCF entry: ParameterValue, else DefaultValue.
std::optional<std::uint32_t> configured_unsigned(const DeviceDescription& dcf, std::uint16_t index,
                                                 std::uint8_t sub_index, NodeId node) {
  const SubObject* sub = dcf.sub(index, sub_index);
  if (sub == nullptr) return std::nullopt;
  const OptionalText& text = sub->configured_value();
  if (!text || text->empty()) return std::nullopt;
  auto value = parse_value(DataType::Unsigned32, *text, node.value());
  if (!value) return std::nullopt;
  return static_cast<std::uint32_t>(value->as_unsigned());
}

// True when a device built from `dcf` accepts 1020h sub 1 and 2 (DSP 302 §6.3 verify
// configuration): both there and writable.
bool has_verify_configuration(const DeviceDescription& dcf) {
  for (const int sub : {1, 2}) {
    const SubObject* s = dcf.sub(object::kVerifyConfiguration, static_cast<std::uint8_t>(sub));
    if (s == nullptr || !is_writable(s->access)) return false;
  }
  return true;
}

// The value a node has after its configuration: the write of that entry, else the DCF's.
std::optional<std::uint32_t> value_after_download(const NetworkNode& node, std::uint16_t index,
                                                  std::uint8_t sub_index) {
  // The last write of the entry is what the device keeps: a COB-ID is written invalid first
  // and valid last (PDOs, 1014h; download_order.hpp).
  for (auto w = node.writes.rbegin(); w != node.writes.rend(); ++w) {
    if (w->index == index && w->sub_index == sub_index && !w->data.empty() && w->data.size() <= 4) {
      return static_cast<std::uint32_t>(load_le(w->data, w->data.size()));
    }
  }
  if (!node.dcf) return std::nullopt;
  return configured_unsigned(*node.dcf, index, sub_index, node.node_id);
}

std::optional<std::uint32_t> device_info_number(const DeviceDescription& dcf,
                                                std::string_view key) {
  const std::string* text = dcf.device_info.find(key);
  if (text == nullptr) return std::nullopt;
  const auto value = number_of(detail::trim_blanks(*text));
  if (!value || *value > 0xFFFFFFFFU) return std::nullopt;
  return static_cast<std::uint32_t>(*value);
}

SubObject make_entry(std::uint8_t sub_index, std::string name, DataType type, AccessType access,
                     std::uint32_t value) {
  SubObject sub;
  sub.sub_index = sub_index;
  sub.name = std::move(name);
  sub.data_type = static_cast<std::uint16_t>(type);
  sub.access = access;
  sub.default_value = hex(value, type == DataType::Unsigned8 ? 2 : 8);
  return sub;
}

Object make_var(std::uint16_t index, std::string name, DataType type, AccessType access,
                std::uint32_t value) {
  Object object;
  object.index = index;
  object.name = name;
  object.object_type = ObjectType::Var;
  object.subs.emplace(0, make_entry(0, std::move(name), type, access, value));
  return object;
}

// An ARRAY of UNSIGNED32 with sub-indices 1..127, one per node-ID (CiA 302-2 §6).
Object make_node_array(std::uint16_t index, const std::string& name, const std::string& sub_name,
                       const std::map<std::uint8_t, std::uint32_t>& values) {
  Object object;
  object.index = index;
  object.name = name;
  object.object_type = ObjectType::Array;
  object.sub_number = static_cast<std::uint8_t>(kMaxNodeId + 1);
  object.subs.emplace(0, make_entry(0, "Highest sub-index supported", DataType::Unsigned8,
                                    AccessType::Ro, kMaxNodeId));
  for (unsigned x = kMinNodeId; x <= kMaxNodeId; ++x) {
    const auto sub_index = static_cast<std::uint8_t>(x);
    const auto it = values.find(sub_index);
    SubObject sub = make_entry(sub_index, sub_name + " " + std::to_string(x), DataType::Unsigned32,
                               AccessType::Rw, 0);
    if (it != values.end() && it->second != 0) sub.parameter_value = hex(it->second, 8);
    object.subs.emplace(sub_index, std::move(sub));
  }
  return object;
}

// 1F81h sub `node` with `bits` set: its ParameterValue (else DefaultValue, else 0) | bits.
void add_assignment_bits(DeviceDescription& master, NodeId node, std::uint32_t bits) {
  SubObject* sub = master.sub(object::kSlaveAssignment, node.value());
  if (sub == nullptr) return;  // not a slave of this master: nothing to check or update
  const std::uint32_t value =
      configured_unsigned(master, object::kSlaveAssignment, node.value(), node).value_or(0);
  sub->parameter_value = hex(value | bits, 8);
}

// Sub `node` of the node array `index`, the array made (all entries 0) when `master` has none.
SubObject& node_entry(DeviceDescription& master, std::uint16_t index, const std::string& name,
                      NodeId node) {
  if (master.sub(index, node.value()) == nullptr) {
    Object made = make_node_array(index, name, name + " node", {});
    if (Object* existing = master.object(index)) {
      existing->subs.emplace(node.value(), made.subs.at(node.value()));
    } else {
      master.objects.emplace(index, std::move(made));
    }
  }
  return *master.sub(index, node.value());
}

}  // namespace

std::vector<std::uint8_t> node_concise_dcf(const NetworkNode& node) {
  return encode_concise_dcf(node.writes);
}

const NetworkNode* Network::find(NodeId node) const {
  for (const auto& n : nodes) {
    if (n.node_id == node) return &n;
  }
  return nullptr;
}

NetworkLoad load_network(const std::string& path, const NetworkOptions& options) {
  if (is_bus_yml_path(path)) return load_bus_yml(path, options);  // lely dcfgen's bus.yml
  NetworkLoad out;
  Loader loader(path, options, out.diagnostics);
  out.network = loader.load();
  out.unreadable = loader.unreadable;
  return out;
}

std::optional<std::uint32_t> configured_value(const NetworkNode& node, std::uint16_t index,
                                              std::uint8_t sub_index) {
  return value_after_download(node, index, sub_index);
}

DeviceIdentity identity_of(const DeviceDescription& dcf, NodeId node) {
  const auto identity = [&](std::uint8_t sub, std::string_view key) {
    auto value = configured_unsigned(dcf, object::kIdentity, sub, node);
    return value ? value : device_info_number(dcf, key);
  };
  std::optional<std::uint32_t> serial = configured_unsigned(dcf, object::kIdentity, 4, node);
  if (dcf.commissioning && dcf.commissioning->lss_serial_number) {
    serial = dcf.commissioning->lss_serial_number;
  }
  return {configured_unsigned(dcf, object::kDeviceType, 0, node), identity(1, "VendorNumber"),
          identity(2, "ProductNumber"), identity(3, "RevisionNumber"), serial};
}

ConfigurationStamp configuration_stamp(std::span<const std::uint8_t> concise_dcf) {
  // FNV-1a, 64 bits: every byte changes the hash; not a security measure, a change detector.
  std::uint64_t h = 0xCBF29CE484222325ULL;
  for (const std::uint8_t b : concise_dcf) {
    h ^= b;
    h *= 0x100000001B3ULL;
  }
  constexpr std::uint32_t kFirstDay = 5844;      // 1 January 2000, in days since 1 January 1984
  constexpr std::uint32_t kDays = 18263;         // to 31 December 2049
  constexpr std::uint32_t kMsPerDay = 86400000;  // CiA 301: ms after midnight
  return {kFirstDay + static_cast<std::uint32_t>((h >> 32) % kDays),
          static_cast<std::uint32_t>((h & 0xFFFFFFFFULL) % kMsPerDay)};
}

std::uint16_t heartbeat_consumer_time_ms(std::uint16_t producer_ms) {
  if (producer_ms == 0) return 0;
  const std::uint32_t consumer = std::uint32_t{producer_ms} * 2 + 100;
  return static_cast<std::uint16_t>(std::min<std::uint32_t>(consumer, 0xFFFF));
}

void set_expected_program(DeviceDescription& master, NodeId node, const NodeProgram& program) {
  if (!program.version && !program.identification) return;
  if (program.version) {
    node_entry(master, object::kExpectedApplicationSwDate, "Expected application SW date", node)
        .parameter_value = hex(program.version->date_days, 8);
    node_entry(master, object::kExpectedApplicationSwTime, "Expected application SW time", node)
        .parameter_value = hex(program.version->time_ms, 8);
  }
  if (program.identification) {
    node_entry(master, object::kExpectedSoftwareIdentification, "Expected software identification",
               node)
        .parameter_value = hex(*program.identification, 8);
  }
  // DSP 302 §5.2 Table 23/24: bit 5 verify the version; bit 6 update it automatically, which
  // needs an image to download.
  add_assignment_bits(master, node,
                      SlaveAssignment::kVerifySoftware |
                          (program.file.empty() ? 0U : SlaveAssignment::kUpdateSoftware));
}

std::optional<ProgramVersion> expected_program_version(const Network& network, NodeId node) {
  const DeviceDescription& master = network.master;
  const std::uint8_t x = node.value();
  const auto bits = configured_unsigned(master, object::kSlaveAssignment, x, node).value_or(0);
  if ((bits & SlaveAssignment::kVerifySoftware) == 0) return std::nullopt;
  const ProgramVersion version{
      configured_unsigned(master, object::kExpectedApplicationSwDate, x, node).value_or(0),
      configured_unsigned(master, object::kExpectedApplicationSwTime, x, node).value_or(0)};
  if (version == ProgramVersion{}) return std::nullopt;
  return version;
}

std::optional<std::uint32_t> expected_software_identification(const Network& network, NodeId node) {
  const DeviceDescription& master = network.master;
  const std::uint8_t x = node.value();
  const auto bits = configured_unsigned(master, object::kSlaveAssignment, x, node).value_or(0);
  if ((bits & SlaveAssignment::kVerifySoftware) == 0) return std::nullopt;
  const auto id =
      configured_unsigned(master, object::kExpectedSoftwareIdentification, x, node).value_or(0);
  if (id == 0) return std::nullopt;
  return static_cast<std::uint32_t>(id);
}

Result<std::vector<std::uint8_t>> read_program_image(const std::string& file) {
  auto text = read_file(file);
  if (!text) return text.error();
  const std::string_view view = text->view();
  if (view.empty()) return Error{"the file is empty: no program to download"};
  return std::vector<std::uint8_t>(view.begin(), view.end());
}

Result<void> set_node_program(Network& network, NodeId node, const std::string& file,
                              std::optional<ProgramVersion> version) {
  NetworkNode* target = nullptr;
  for (auto& n : network.nodes) {
    if (n.node_id == node) target = &n;
  }
  if (target == nullptr) {
    return Error{"node " + std::to_string(node.value()) + " is not in " + network.file};
  }
  NodeProgram program = target->program.value_or(NodeProgram{});
  if (version && program.identification) {
    // The master would check 1F56h against 1F55h and never look at this version.
    return Error{"node " + std::to_string(node.value()) +
                 ": a version (1F52h, DSP 302) for a node checked by its software "
                 "identification (1F55h, CiA 302-3: bus.yml software_version); give "
                 "--program NODE=FILE alone"};
  }
  if (!file.empty() && network.master_from_file) {
    // CiA 302-2 Table 24: the master DCF's 1F81h sub X with bit 6 clear forbids the automatic
    // software update of node X. An image from the command line would set the bit and override
    // that interlock silently: refused, naming both.
    const std::uint8_t x = node.value();
    const SubObject* assignment = network.master.sub(object::kSlaveAssignment, x);
    const auto bits = configured_unsigned(network.master, object::kSlaveAssignment, x, node);
    if (assignment != nullptr && bits && (*bits & SlaveAssignment::kUpdateSoftware) == 0) {
      const int line = assignment->parameter_value ? assignment->parameter_value_line
                                                   : assignment->default_value_line;
      return Error{"node " + std::to_string(x) + ": " + network.master_file +
                   (line > 0 ? ":" + std::to_string(line) : std::string()) + ": 1F81h sub " +
                   std::to_string(x) + " = " + hex(*bits, 8) +
                   " clears bit 6 (automatic software update not allowed, CiA 302-2 Table 24): "
                   "the master would not download the image; set bit 6 there or leave out "
                   "--program"};
    }
  }
  if (!file.empty()) {
    auto image = read_program_image(file);
    if (!image) return Error{"'" + file + "': " + image.error().message};
    program.file = file;
    program.image = std::move(image).value();
  }
  if (version) program.version = version;
  program.source.clear();
  program.line = 0;
  target->program = std::move(program);
  set_expected_program(network.master, node, *target->program);
  return {};
}

void check_programs(const Network& network, Diagnostics& diagnostics) {
  const DeviceDescription& master = network.master;
  const std::string master_file = network.master_from_file ? network.master_file : network.file;
  for (const auto& node : network.nodes) {
    const std::uint8_t x = node.node_id.value();
    const std::string who = "node " + std::to_string(x);
    if (node.program) {
      const NodeProgram& p = *node.program;
      // A program from the command line (set_node_program) has no file to point at.
      const std::string file = p.source.empty() ? std::string("--program") : p.source;
      if (!p.file.empty() && !p.version && !p.identification && !network.master_from_file) {
        diagnostics.add(
            file, p.line, Severity::Error,
            who + ": program image '" + p.file + "' without a version: give Node" +
                std::to_string(x) +
                "ProgramVersion= (the master compares it with the node's 1F52h, "
                "DSP 302 §9)" +
                [&] {
                  const auto trailer = program_image_version(p.image);
                  return trailer ? "; the image's trailer says " + to_string(*trailer)
                                 : std::string();
                }());
      }
      const auto trailer = program_image_version(p.image);
      if (trailer && p.version && *trailer != *p.version) {
        diagnostics.add(file, p.line, Severity::Warning,
                        who + ": program image '" + p.file + "' carries version " +
                            to_string(*trailer) + " in its trailer, but the expected version is " +
                            to_string(*p.version) +
                            ": a device reporting the trailer's version fails the boot with "
                            "status I after the update");
      }
    }
    // The master's own objects (from its DCF, or as the description set them).
    const SubObject* assignment = master.sub(object::kSlaveAssignment, x);
    if (assignment == nullptr) continue;
    const std::uint32_t bits =
        configured_unsigned(master, object::kSlaveAssignment, x, node.node_id).value_or(0);
    const int line =
        assignment->parameter_value_line != 0 ? assignment->parameter_value_line : assignment->line;
    const std::string where = "1F81h sub " + std::to_string(x) + " (" + who + ")";
    if ((bits & SlaveAssignment::kVerifySoftware) != 0) {
      const auto date =
          configured_unsigned(master, object::kExpectedApplicationSwDate, x, node.node_id)
              .value_or(0);
      const auto time =
          configured_unsigned(master, object::kExpectedApplicationSwTime, x, node.node_id)
              .value_or(0);
      const auto identification =
          configured_unsigned(master, object::kExpectedSoftwareIdentification, x, node.node_id)
              .value_or(0);
      if (date == 0 && time == 0 && identification == 0) {
        diagnostics.add(master_file, line, Severity::Error,
                        where +
                            " has bit 5 (verify the application software version) but 1F53h "
                            "and 1F54h sub " +
                            std::to_string(x) + " give no expected version, nor 1F55h sub " +
                            std::to_string(x) +
                            " an expected software identification: the boot ends with status G "
                            "(CiA 302-2 Table 1)");
      }
    }
    // A program whose image was named but could not be read has its error already.
    if ((bits & SlaveAssignment::kUpdateSoftware) != 0 &&
        (!node.program || node.program->file.empty())) {
      diagnostics.add(master_file, line, Severity::Warning,
                      where +
                          " has bit 6 (automatic software update allowed) but no program "
                          "image is given for the node (Node" +
                          std::to_string(x) +
                          "ProgramFile= or --program): a wrong version ends its boot with "
                          "status H");
    }
  }
}

DeviceDescription derive_master(std::span<const NetworkNode> nodes) {
  std::map<std::uint8_t, std::uint32_t> assignment, device_type, vendor, product, revision, date,
      time;
  std::vector<std::uint32_t> consumers;
  for (const auto& node : nodes) {
    const std::uint8_t x = node.node_id.value();
    std::uint8_t retry_factor = 0;
    std::uint16_t guard_time_ms = 0;
    const auto producer = value_after_download(node, object::kProducerHeartbeatTime, 0);
    if (producer && *producer != 0) {
      const auto consumer = heartbeat_consumer_time_ms(static_cast<std::uint16_t>(*producer));
      // CiA 301 §7.5.2.26: bits 16-23 node-ID, bits 0-15 time in ms.
      consumers.push_back(std::uint32_t{x} << 16 | consumer);
    } else {
      const auto guard = value_after_download(node, object::kGuardTime, 0);
      const auto factor = value_after_download(node, object::kLifeTimeFactor, 0);
      if (guard && factor && *guard != 0 && *factor != 0) {
        guard_time_ms = static_cast<std::uint16_t>(std::min<std::uint32_t>(*guard, 0xFFFF));
        retry_factor = static_cast<std::uint8_t>(std::min<std::uint32_t>(*factor, 0xFF));
      }
    }
    assignment[x] = SlaveAssignment::make(SlaveAssignment::kSlave | SlaveAssignment::kBootSlave |
                                              SlaveAssignment::kMandatory,
                                          retry_factor, guard_time_ms)
                        .value;
    // CiA 302-2 §3.5 a: 0 = the configuration is not verified. A device whose DCF has no
    // writable 1020h sub 1/2 refuses the master's 1020h writes after the download (0602 0000,
    // 0601 0002): it is downloaded at every boot instead.
    if (!node.dcf || has_verify_configuration(*node.dcf)) {
      const ConfigurationStamp stamp = configuration_stamp(node_concise_dcf(node));
      date[x] = stamp.days;
      time[x] = stamp.ms;
    }
    if (!node.dcf) continue;
    const DeviceIdentity identity = identity_of(*node.dcf, node.node_id);
    device_type[x] = identity.device_type.value_or(0);
    vendor[x] = identity.vendor_id.value_or(0);
    product[x] = identity.product_code.value_or(0);
    revision[x] = identity.revision_number.value_or(0);
  }

  DeviceDescription master;
  master.file_info.set("FileName", "master.dcf");
  master.file_info.set("Description", "NMT master derived from the network description");
  master.device_info.set("VendorName", "");
  master.device_info.set("ProductName", "CANopen manager");
  master.device_info.set("SimpleBootUpMaster", "1");
  master.device_info.set("SimpleBootUpSlave", "0");
  DeviceCommissioning commissioning;
  commissioning.canopen_manager = true;
  master.commissioning = std::move(commissioning);

  auto add = [&master](Object object) { master.objects.emplace(object.index, std::move(object)); };
  add(make_var(object::kDeviceType, "Device type", DataType::Unsigned32, AccessType::Ro, 0));
  add(make_var(object::kErrorRegister, "Error register", DataType::Unsigned8, AccessType::Ro, 0));
  {
    std::map<std::uint8_t, std::uint32_t> entries;
    for (std::size_t i = 0; i < consumers.size(); ++i) {
      entries[static_cast<std::uint8_t>(i + 1)] = consumers[i];
    }
    Object heartbeat = make_node_array(object::kConsumerHeartbeatTime, "Consumer heartbeat time",
                                       "Consumer heartbeat time", entries);
    master.objects.emplace(heartbeat.index, std::move(heartbeat));
  }
  {
    Object identity;
    identity.index = object::kIdentity;
    identity.name = "Identity object";
    identity.object_type = ObjectType::Record;
    identity.sub_number = 2;
    identity.subs.emplace(
        0, make_entry(0, "Highest sub-index supported", DataType::Unsigned8, AccessType::Ro, 1));
    identity.subs.emplace(1, make_entry(1, "Vendor-ID", DataType::Unsigned32, AccessType::Ro, 0));
    add(std::move(identity));
  }
  add(make_node_array(object::kExpectedConfigurationDate, "Expected configuration date",
                      "Expected configuration date node", date));
  add(make_node_array(object::kExpectedConfigurationTime, "Expected configuration time",
                      "Expected configuration time node", time));
  Object startup =
      make_var(object::kNmtStartup, "NMT startup", DataType::Unsigned32, AccessType::Rw, 0);
  startup.subs.at(0).parameter_value = hex(NmtStartup::kMaster, 8);
  add(std::move(startup));
  add(make_node_array(object::kSlaveAssignment, "NMT slave assignment", "NMT slave assignment node",
                      assignment));
  add(make_node_array(object::kDeviceTypeIdentification, "Device type identification",
                      "Device type identification node", device_type));
  add(make_node_array(object::kVendorIdentification, "Vendor identification",
                      "Vendor identification node", vendor));
  add(make_node_array(object::kProductCode, "Product code", "Product code node", product));
  add(make_node_array(object::kRevisionNumber, "Revision number", "Revision number node",
                      revision));
  for (const auto& node : nodes) {
    if (node.program) set_expected_program(master, node.node_id, *node.program);
  }
  return master;
}

}  // namespace cfg
