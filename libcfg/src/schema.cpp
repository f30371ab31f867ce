#include "cfg/schema.hpp"

#include <array>
#include <cstdlib>
#include <filesystem>
#include <system_error>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"

// The schema directory seen from the directory of the installed programs (libcfg/CMakeLists.txt).
#ifndef CANOPEN_SCHEMA_DIR_FROM_PROGRAM
#error "libcfg/CMakeLists.txt defines CANOPEN_SCHEMA_DIR_FROM_PROGRAM"
#endif

namespace cfg {
namespace {

// Ranges of like objects, each checked against the schema's object for its first index
// (CiA 301 §7.5.2: SDO server 1200h-127Fh, SDO client 1280h-12FFh, RPDO 1400h-15FFh / 1600h-17FFh,
// TPDO 1800h-19FFh / 1A00h-1BFFh). 1200h itself, the default SDO, has its own entry.
struct IndexRange {
  std::uint16_t first;
  std::uint16_t last;
};
constexpr std::array<IndexRange, 6> kRanges{{
    {0x1201, 0x127F},
    {0x1280, 0x12FF},
    {0x1400, 0x15FF},
    {0x1600, 0x17FF},
    {0x1800, 0x19FF},
    {0x1A00, 0x1BFF},
}};

const Object* schema_object_for(const DeviceDescription& schema, std::uint16_t index) {
  if (const Object* exact = schema.object(index)) return exact;
  for (const auto& range : kRanges) {
    if (index >= range.first && index <= range.last) return schema.object(range.first);
  }
  return nullptr;
}

// CiA 301 §7.4.3: the elements of an ARRAY share one data type, so element 1 stands for the
// elements the schema does not list.
const SubObject* schema_sub_for(const Object& schema_object, std::uint8_t sub_index) {
  if (const SubObject* exact = schema_object.sub(sub_index)) return exact;
  if (schema_object.object_type == ObjectType::Array && sub_index >= 1) {
    return schema_object.sub(1);
  }
  return nullptr;
}

enum class Shape { Var, Array, Record, Other };

Shape shape_of(const Object& object) {
  if (object.is_var()) return Shape::Var;
  if (object.object_type == ObjectType::Array) return Shape::Array;
  if (object.object_type == ObjectType::Record) return Shape::Record;
  return Shape::Other;
}

std::string type_text(std::uint16_t data_type) {
  const DataTypeInfo* info = find_data_type(data_type);
  std::string code = "0x" + hex_digits(data_type, 4);
  return info == nullptr ? code : std::string(info->name) + " (" + code + ")";
}

std::string object_type_text(ObjectType type) {
  return std::string(to_string(type)) + " (0x" + hex_digits(static_cast<unsigned>(type), 1) + ")";
}

// The device may offer less access than the standard (CiA 301/302 "ro/const/wo, if rw is not
// supported") but not more: reading what the standard makes write-only, or writing what it
// makes read-only or constant.
bool allows_more(AccessType device, AccessType standard) {
  return (is_readable(device) && !is_readable(standard)) ||
         (is_writable(device) && !is_writable(standard));
}

// One disagreement of an entry, before it is worded; runs of sub-indices with the same
// disagreement (an array of 127 per-node entries) become one warning.
struct Finding {
  std::uint8_t sub_index;
  int line;
  std::string what;  // "DataType is UNSIGNED8 (0x0005), the standard defines ..."
};

std::vector<std::string> entry_findings(const SubObject& sub, const SubObject& standard) {
  std::vector<std::string> out;
  if (sub.data_type != standard.data_type) {
    out.push_back("DataType is " + type_text(sub.data_type) + ", the standard defines " +
                  type_text(standard.data_type));
  }
  if (allows_more(sub.access, standard.access)) {
    out.push_back("AccessType is " + std::string(to_string(sub.access)) +
                  ", the standard allows at most " + std::string(to_string(standard.access)));
  }
  return out;
}

void check_object(const Object& object, const Object& standard, std::string_view file_name,
                  Diagnostics& diagnostics) {
  auto warn = [&](int line, std::string message) {
    diagnostics.add(std::string(file_name), line, Severity::Warning, std::move(message));
  };
  const std::string where = hex_digits(object.index, 4) + "h";
  const Shape shape = shape_of(object);
  const Shape standard_shape = shape_of(standard);
  if (shape != standard_shape) {
    warn(object.line, where + ": ObjectType is " + object_type_text(object.object_type) +
                          ", the standard defines " + object_type_text(standard.object_type));
    // A VAR and an ARRAY/RECORD have nothing else in common to compare.
    if (shape == Shape::Var || standard_shape == Shape::Var) return;
  }
  if (shape == Shape::Var) {
    const SubObject* entry = object.sub(0);
    const SubObject* standard_entry = standard.sub(0);
    if (entry == nullptr || standard_entry == nullptr) return;
    for (auto& what : entry_findings(*entry, *standard_entry)) {
      what.insert(0, where + ": ");
      warn(entry->line > 0 ? entry->line : object.line, std::move(what));
    }
    return;
  }
  std::vector<Finding> findings;
  for (const auto& [sub_index, sub] : object.subs) {
    const SubObject* standard_sub = schema_sub_for(standard, sub_index);
    if (standard_sub == nullptr) continue;
    for (auto& what : entry_findings(sub, *standard_sub)) {
      findings.push_back({sub_index, sub.line > 0 ? sub.line : object.line, std::move(what)});
    }
  }
  // Findings are in sub-index order; merge each run of consecutive sub-indices saying the same.
  std::vector<bool> used(findings.size(), false);
  for (std::size_t i = 0; i < findings.size(); ++i) {
    if (used[i]) continue;
    unsigned last = findings[i].sub_index;
    for (std::size_t j = i + 1; j < findings.size(); ++j) {
      if (!used[j] && findings[j].what == findings[i].what && findings[j].sub_index == last + 1) {
        used[j] = true;
        last = findings[j].sub_index;
      }
    }
    const std::string subs = last == findings[i].sub_index
                                 ? " sub-index " + hex_digits(findings[i].sub_index, 2) + "h"
                                 : " sub-indices " + hex_digits(findings[i].sub_index, 2) + "h-" +
                                       hex_digits(last, 2) + "h";
    warn(findings[i].line, where + subs + ": " + findings[i].what);
  }
}

// True when `dir` holds the file of every standard schema.
bool holds_schemas(const std::filesystem::path& dir) {
  std::error_code ec;
  for (std::string_view name : kStandardSchemas) {
    if (!std::filesystem::is_regular_file(dir / (std::string(name) + ".eds"), ec)) return false;
  }
  return true;
}

Error no_schemas_in(const std::string& dir, const std::string& why) {
  return Error{"no schemas (" + std::string(kCia301Schema) + ".eds, " +
               std::string(kCia302ManagerSchema) + ".eds) in " + dir + " (" + why + ")"};
}

}  // namespace

Result<std::string> find_schema_dir() {
  const std::string variable(kSchemaDirVariable);
  if (const char* from_env = std::getenv(variable.c_str()); from_env != nullptr && *from_env) {
    if (holds_schemas(from_env)) return std::string(from_env);
    return no_schemas_in(from_env, "from " + variable);
  }
  std::error_code ec;
  const std::filesystem::path program = std::filesystem::read_symlink("/proc/self/exe", ec);
  if (ec) {
    return Error{"no schema directory: the running program's path is unknown (" + ec.message() +
                 "); set " + variable};
  }
  const std::filesystem::path beside =
      (program.parent_path() / CANOPEN_SCHEMA_DIR_FROM_PROGRAM).lexically_normal();
  if (holds_schemas(beside)) return beside.string();
  return no_schemas_in(beside.string(), "where they are installed beside " + program.string() +
                                            ", and " + variable + " is not set");
}

Result<DeviceDescription> load_schema(std::string_view name, const std::string& schema_dir) {
  const std::string path = schema_dir + "/" + std::string(name) + ".eds";
  ReadOptions options;
  options.mode = ReadMode::Strict;
  options.file_name = path;
  ReadResult read = read_device_file(path, options);
  if (!read.device || !read.diagnostics.empty()) {
    return Error{"schema " + std::string(name) + " is not clean:\n" + read.diagnostics.format()};
  }
  return std::move(*read.device);
}

Result<DeviceDescription> load_schema(std::string_view name) {
  auto dir = find_schema_dir();
  if (!dir) return dir.error();
  return load_schema(name, *dir);
}

Result<DeviceDescription> load_schemas(std::span<const std::string_view> names) {
  auto dir = find_schema_dir();
  if (!dir) return dir.error();
  return load_schemas(names, *dir);
}

Result<DeviceDescription> load_schemas(std::span<const std::string_view> names,
                                       const std::string& schema_dir) {
  DeviceDescription merged;
  for (std::string_view name : names) {
    auto schema = load_schema(name, schema_dir);
    if (!schema) return schema.error();
    for (auto& [index, object] : schema->objects) {
      auto [it, inserted] = merged.objects.emplace(index, object);
      if (!inserted && !(it->second == object)) {
        return Error{"schemas disagree on object " + hex_digits(index, 4) + "h (" +
                     std::string(name) + " and an earlier schema)"};
      }
    }
  }
  return merged;
}

void check_against_schema(const DeviceDescription& device, const DeviceDescription& schema,
                          std::string_view file_name, Diagnostics& diagnostics) {
  for (const auto& [index, object] : device.objects) {
    if (const Object* standard = schema_object_for(schema, index)) {
      check_object(object, *standard, file_name, diagnostics);
    }
  }
}

}  // namespace cfg
