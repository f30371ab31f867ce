// What a network scan makes of what it read (cfg/device_scan.hpp).
#include "cfg/device_scan.hpp"

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <set>
#include <system_error>

#include "cfg/data_type.hpp"
#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "ini_scanner.hpp"

namespace cfg {
namespace {

namespace fs = std::filesystem;

constexpr std::uint8_t kVendorSub = 1;
constexpr std::uint8_t kProductSub = 2;
constexpr std::uint8_t kRevisionSub = 3;
constexpr std::uint8_t kSerialSub = 4;
// CiA 306 §4.6.3 ObjFlags bit 1: "refuse read on scan".
constexpr std::uint32_t kRefuseReadOnScan = 0x2;

std::optional<std::uint32_t> number(std::string_view text) {
  text = detail::trim_blanks(text);
  if (text.empty()) return std::nullopt;
  auto value = parse_value(DataType::Unsigned32, text);
  if (!value) return std::nullopt;
  return static_cast<std::uint32_t>(value->as_unsigned());
}

std::optional<std::uint32_t> device_info(const DeviceDescription& eds, std::string_view key) {
  const std::string* text = eds.device_info.find(key);
  return text != nullptr ? number(*text) : std::nullopt;
}

// A 1018h DefaultValue. Vendors do not write $NODEID here; were one to, it would not be a number
// a device reports whatever its node-ID, so it is not one to match on.
std::optional<std::uint32_t> identity_default(const DeviceDescription& eds, std::uint8_t sub) {
  const SubObject* entry = eds.sub(object::kIdentity, sub);
  if (entry == nullptr || !entry->default_value || mentions_node_id(*entry->default_value)) {
    return std::nullopt;
  }
  return number(*entry->default_value);
}

// The numbers a file gives for one identity field, 0 ("not given" in vendor files) left out.
std::vector<std::uint32_t> numbers_given(std::initializer_list<std::optional<std::uint32_t>> all) {
  std::vector<std::uint32_t> out;
  for (const auto& n : all) {
    if (n && *n != 0 && std::find(out.begin(), out.end(), *n) == out.end()) out.push_back(*n);
  }
  return out;
}

bool contains(const std::vector<std::uint32_t>& numbers, std::optional<std::uint32_t> n) {
  return n && std::find(numbers.begin(), numbers.end(), *n) != numbers.end();
}

bool has_eds_extension(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".eds";
}

std::string hex32(std::uint32_t value) {
  return hex(value, 8);
}
std::string hex32(std::optional<std::uint32_t> value) {
  return value ? hex(*value, 8) : std::string("(not reported)");
}

// As an EDS: no value configured for a node, no commissioning.
void drop_configuration(DeviceDescription& eds) {
  eds.commissioning.reset();
  for (auto& [index, object] : eds.objects) {
    for (auto& [sub_index, sub] : object.subs) {
      sub.parameter_value.reset();
      sub.denotation.reset();
      sub.parameter_value_line = 0;
    }
  }
}

bool is_command(std::uint16_t index) {
  return index == object::kPreDefinedErrorField || index == object::kStoreParameters ||
         index == object::kRestoreDefaultParameters || index == object::kProgramControl;
}

bool is_domain(const SubObject& sub) {
  return sub.object_type == ObjectType::Domain ||
         sub.data_type == static_cast<std::uint16_t>(DataType::Domain);
}

bool is_scanned(const Object& object, const SubObject& sub) {
  if (object.index < 0x1000 || is_command(object.index) ||
      object.index == object::kVerifyConfiguration) {
    return false;
  }
  // rww: a process output (CiA 306, "write on process output"), not configuration.
  if (sub.access != AccessType::Rw && sub.access != AccessType::Rwr) return false;
  if (is_domain(sub) || !sub.basic_type()) return false;
  const std::uint32_t flags = sub.obj_flags.value_or(0) | object.obj_flags.value_or(0);
  return (flags & kRefuseReadOnScan) == 0;
}

bool is_identity(ObjectAddress address) {
  return (address.index == object::kDeviceType && address.sub_index == 0) ||
         (address.index == object::kIdentity && address.sub_index >= kVendorSub &&
          address.sub_index <= kRevisionSub);
}

SubObject identity_entry(std::uint8_t sub_index, std::string name, DataType type) {
  SubObject sub;
  sub.sub_index = sub_index;
  sub.name = std::move(name);
  sub.data_type = static_cast<std::uint16_t>(type);
  sub.access = AccessType::Ro;
  return sub;
}

// 1018h sub `sub_index` of `dcf`, made (with the record and its sub 0) when the file has none.
SubObject& identity_sub(DeviceDescription& dcf, std::uint8_t sub_index) {
  static constexpr const char* kNames[] = {"Highest sub-index supported", "Vendor-ID",
                                           "Product code", "Revision number", "Serial number"};
  Object& object = dcf.objects[object::kIdentity];
  if (object.index != object::kIdentity || object.subs.empty()) {
    object.index = object::kIdentity;
    object.name = "Identity object";
    object.object_type = ObjectType::Record;
    object.subs.emplace(0, identity_entry(0, kNames[0], DataType::Unsigned8));
  }
  auto it = object.subs.find(sub_index);
  if (it == object.subs.end()) {
    it = object.subs
             .emplace(sub_index, identity_entry(sub_index, kNames[sub_index], DataType::Unsigned32))
             .first;
  }
  // Sub 0 says the highest sub-index there (CiA 301 §7.4.3); the records' sub 0 value of the
  // EDS stays when it is higher.
  SubObject& count = object.subs.at(0);
  const std::uint8_t highest = object.subs.rbegin()->first;
  const auto given = count.default_value ? number(*count.default_value) : std::nullopt;
  if (!given || *given < highest) count.default_value = hex(highest, 2);
  object.sub_number = static_cast<std::uint8_t>(object.subs.size());
  return it->second;
}

struct Rank {
  int tier = 0;  // 0 exact, 1 same major lower, 2 same major higher, 3 other, 4 none
  std::uint64_t distance = 0;
  bool operator<(const Rank& o) const {
    return tier != o.tier ? tier < o.tier : distance < o.distance;
  }
};

Rank rank(std::optional<std::uint32_t> file, std::optional<std::uint32_t> device) {
  if (!file) return {4, 0};
  if (!device) return {1, 0xFFFFFFFFULL - *file};  // the highest revision first
  if (*file == *device) return {0, 0};
  const std::uint32_t major = *device >> 16;
  const std::uint32_t minor = *device & 0xFFFF;
  if ((*file >> 16) == major) {
    const std::uint32_t file_minor = *file & 0xFFFF;
    if (file_minor < minor) return {1, minor - file_minor};
    return {2, file_minor - minor};
  }
  // Distance doubled, +1 for a higher file, so that the lower of two equally distant wins.
  const std::uint64_t d = *file > *device ? *file - *device : *device - *file;
  return {3, 2 * d + (*file > *device ? 1 : 0)};
}

std::string_view tier_words(int tier) {
  switch (tier) {
    case 1:
      return "same major revision, lower minor";
    case 2:
      return "same major revision, higher minor";
    case 3:
      return "another major revision";
    default:
      return "the file gives no revision";
  }
}

}  // namespace

// --- the library ---------------------------------------------------------------------------------

EdsLibrary EdsLibrary::load(const std::string& directory, Diagnostics& diagnostics) {
  EdsLibrary library;
  std::error_code ec;
  fs::recursive_directory_iterator it(directory, ec);
  if (ec) {
    diagnostics.add(directory, 0, Severity::Error,
                    "cannot read the EDS directory: " + ec.message());
    return library;
  }
  std::vector<std::string> paths;
  for (const fs::recursive_directory_iterator end; it != end; it.increment(ec)) {
    if (ec) {
      diagnostics.add(directory, 0, Severity::Warning,
                      "part of the EDS directory could not be read: " + ec.message());
      break;
    }
    std::error_code type_error;
    if (it->is_regular_file(type_error) && has_eds_extension(it->path())) {
      paths.push_back(it->path().string());
    }
  }
  std::sort(paths.begin(), paths.end());
  for (const auto& path : paths) {
    ReadOptions options;
    options.file_name = path;
    ReadResult read = read_device_file(path, options);
    if (read.ok()) {
      library.add(std::move(*read.device), path);
      continue;
    }
    // Errors of a file nobody may need: warnings, so that the scan goes on (see the header).
    for (const auto& d : read.diagnostics.items()) {
      if (d.severity == Severity::Error) {
        diagnostics.add(d.file, d.line, Severity::Warning, d.message);
      }
    }
    diagnostics.add(path, 0, Severity::Warning,
                    "not in the EDS library: the file has errors; a device it describes is "
                    "reported as without EDS");
  }
  return library;
}

void EdsLibrary::add(DeviceDescription eds, std::string path) {
  drop_configuration(eds);
  File file;
  file.vendor_ids =
      numbers_given({device_info(eds, "VendorNumber"), identity_default(eds, kVendorSub)});
  file.product_codes =
      numbers_given({device_info(eds, "ProductNumber"), identity_default(eds, kProductSub)});
  file.revision = device_info(eds, "RevisionNumber");
  if (!file.revision) file.revision = identity_default(eds, kRevisionSub);
  file.path = std::move(path);
  file.eds = std::move(eds);
  files_.push_back(std::move(file));
}

std::optional<EdsLibrary::Match> EdsLibrary::match(const DeviceIdentity& identity) const {
  if (!identity.vendor_id || !identity.product_code) return std::nullopt;
  const File* best = nullptr;
  Rank best_rank;
  for (const auto& file : files_) {
    if (!contains(file.vendor_ids, identity.vendor_id) ||
        !contains(file.product_codes, identity.product_code)) {
      continue;
    }
    const Rank r = rank(file.revision, identity.revision_number);
    if (best == nullptr || r < best_rank) {  // equal: the first path stays
      best = &file;
      best_rank = r;
    }
  }
  if (best == nullptr) return std::nullopt;
  Match match{&best->eds, best->path, best_rank.tier == 0, {}};
  if (best_rank.tier != 0) {
    const std::string found = best->revision ? hex32(*best->revision) : std::string("none");
    match.note = (identity.revision_number
                      ? "revision " + hex32(*identity.revision_number) + " not in the library"
                      : std::string("the device reports no revision (1018h sub 03h)")) +
                 "; nearest " + found + " (" +
                 std::string(identity.revision_number ? tier_words(best_rank.tier)
                                                      : "the highest in the library") +
                 ") in " + best->path;
  }
  return match;
}

std::string EdsLibrary::missing(const DeviceIdentity& identity) const {
  std::string line = "no EDS for vendor-ID " + hex32(identity.vendor_id) + ", product code " +
                     hex32(identity.product_code) + ", revision " + hex32(identity.revision_number);
  std::string others;
  for (const auto& file : files_) {
    if (!contains(file.vendor_ids, identity.vendor_id)) continue;
    others += others.empty() ? "" : ", ";
    others += file.product_codes.empty() ? std::string("no product code")
                                         : hex32(file.product_codes.front());
    others += " rev " + (file.revision ? hex32(*file.revision) : std::string("none"));
    others += " (" + file.path + ")";
  }
  if (!others.empty())
    return line + "; the library has, of the same vendor, other products: " + others;
  return line + "; the library has no file of vendor-ID " + hex32(identity.vendor_id) + " (" +
         std::to_string(files_.size()) + (files_.size() == 1 ? " file)" : " files)");
}

// --- the entries and the DCFs --------------------------------------------------------------------

std::vector<ObjectAddress> entries_to_scan(const DeviceDescription& eds) {
  std::vector<ObjectAddress> out;
  for (const auto& [index, object] : eds.objects) {
    for (const auto& [sub_index, sub] : object.subs) {
      if (is_scanned(object, sub)) out.push_back({index, sub_index});
    }
  }
  return out;
}

std::string scan_dcf_file_name(NodeId node) {
  return "node" + std::to_string(node.value()) + ".dcf";
}

DeviceDescription as_found_dcf(const DeviceDescription& eds, NodeId node,
                               const std::map<ObjectAddress, std::vector<std::uint8_t>>& values,
                               Diagnostics& diagnostics) {
  DeviceDescription dcf = eds;
  drop_configuration(dcf);
  dcf.file_info.set("FileName", scan_dcf_file_name(node));
  DeviceCommissioning commissioning;
  commissioning.node_id = node.value();
  const std::string* product = eds.device_info.find("ProductName");
  commissioning.node_name =
      product != nullptr && !product->empty() ? *product : "node " + std::to_string(node.value());
  dcf.commissioning = std::move(commissioning);

  const auto warn = [&](ObjectAddress address, const std::string& why) {
    diagnostics.add("", 0, Severity::Warning,
                    "node " + std::to_string(node.value()) + ": " + to_string(address) +
                        " not recorded: " + why);
  };
  for (const auto& [address, bytes] : values) {
    if (address.index == object::kIdentity &&
        (address.sub_index == 0 || address.sub_index == kSerialSub)) {
      continue;  // sub 0 is the EDS's; the serial number belongs to this device only
    }
    const bool identity = is_identity(address);
    SubObject* sub = identity && address.index == object::kIdentity
                         ? &identity_sub(dcf, address.sub_index)
                         : dcf.sub(address.index, address.sub_index);
    if (sub == nullptr) {
      warn(address, "not an entry of the EDS");
      continue;
    }
    const Object& object = *dcf.object(address.index);
    if (!identity && !is_scanned(object, *sub)) {
      warn(address, "not an entry a scan records (see entries_to_scan)");
      continue;
    }
    const auto type = sub->basic_type();
    if (!type) {
      warn(address, "its DataType is not a basic type");
      continue;
    }
    auto value = decode(*type, bytes);
    if (!value) {
      warn(address, value.error().message);
      continue;
    }
    // CiA 301 §7.3.5: a default that follows from the node-ID is the device's own; the DCF keeps
    // $NODEID so that a replacement at another node-ID gets its own.
    if (sub->default_value && mentions_node_id(*sub->default_value)) {
      auto derived = parse_value(*type, *sub->default_value, node.value());
      if (derived && *derived == *value) continue;
    }
    sub->parameter_value = format_value(*value);
  }
  return dcf;
}

DeviceDescription identity_only_dcf(NodeId node, const DeviceIdentity& identity) {
  DeviceDescription dcf;
  const std::string file = scan_dcf_file_name(node);
  dcf.file_info.set("FileName", file);
  dcf.file_info.set("FileVersion", "1");
  dcf.file_info.set("FileRevision", "0");
  dcf.file_info.set("EDSVersion", "4.0");
  dcf.file_info.set("Description",
                    "Identity of node " + std::to_string(node.value()) +
                        " as found by a scan; no EDS described it, nothing is configured");
  dcf.device_info.set("VendorName", "");
  dcf.device_info.set("ProductName", "");
  if (identity.vendor_id) dcf.device_info.set("VendorNumber", hex32(*identity.vendor_id));
  if (identity.product_code) dcf.device_info.set("ProductNumber", hex32(*identity.product_code));
  if (identity.revision_number) {
    dcf.device_info.set("RevisionNumber", hex32(*identity.revision_number));
  }
  dcf.device_info.set("SimpleBootUpMaster", "0");
  dcf.device_info.set("SimpleBootUpSlave", "1");

  const auto var = [&dcf](std::uint16_t index, std::string name, DataType type,
                          std::optional<std::uint32_t> value) {
    Object object;
    object.index = index;
    object.name = name;
    object.object_type = ObjectType::Var;
    SubObject sub = identity_entry(0, std::move(name), type);
    if (value) sub.parameter_value = hex(*value, type == DataType::Unsigned8 ? 2 : 8);
    object.subs.emplace(0, std::move(sub));
    dcf.objects.emplace(index, std::move(object));
  };
  var(object::kDeviceType, "Device type", DataType::Unsigned32, identity.device_type);
  var(object::kErrorRegister, "Error register", DataType::Unsigned8, std::nullopt);
  dcf.sub(object::kErrorRegister, 0)->default_value = "0x00";
  const std::optional<std::uint32_t> fields[] = {identity.vendor_id, identity.product_code,
                                                 identity.revision_number};
  for (std::uint8_t sub = kVendorSub; sub <= kRevisionSub; ++sub) {
    if (fields[sub - 1]) {
      identity_sub(dcf, sub).parameter_value = hex32(*fields[sub - 1]);
    }
  }
  DeviceCommissioning commissioning;
  commissioning.node_id = node.value();
  commissioning.node_name = "node " + std::to_string(node.value());
  dcf.commissioning = std::move(commissioning);
  return dcf;
}

namespace {
// A value on one line: a line break would end the key (CiA 306 files are line based).
std::string one_line(std::string_view text) {
  std::string out(text);
  std::replace_if(
      out.begin(), out.end(), [](char c) { return c == '\r' || c == '\n'; }, ' ');
  return out;
}
}  // namespace

std::string scan_project(std::string_view net_name, std::vector<ScanProjectNode> nodes) {
  std::sort(nodes.begin(), nodes.end(),
            [](const ScanProjectNode& a, const ScanProjectNode& b) { return a.node < b.node; });
  std::string text = "[Topology]\r\n";
  text += "NetName=" + one_line(net_name) + "\r\n";
  text += "Nodes=" + hex(nodes.size(), 2) + "\r\n";
  for (const auto& n : nodes) {
    const std::string prefix = "Node" + std::to_string(n.node.value());
    text += prefix + "Present=0x01\r\n";
    if (!n.name.empty()) text += prefix + "Name=" + one_line(n.name) + "\r\n";
    text += prefix + "DCFName=" + one_line(n.dcf_file) + "\r\n";
  }
  return text;
}

}  // namespace cfg
