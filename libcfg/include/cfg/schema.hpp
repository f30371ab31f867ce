// Standard object definitions (schemas/*.eds) and a check of device files against them.
//
// A schema is an EDS written by this project that holds the standard's definition of objects:
// `cia301_communication` (CiA 301 communication objects 1000h-1BFFh) and `cia302_manager`
// (CiA 302 manager objects 102Ah, 1F20h-1F27h, 1F80h-1F91h). How a schema file is read:
// - DataType, ObjectType and AccessType of each entry are the standard's definition.
// - AccessType is the most the standard allows; a device may offer less (the standards say
//   "rw; ro/const/wo if rw is not supported"), so only access beyond it is reported.
// - An ARRAY lists sub-index 0 and element 1; element 1 stands for every element the schema does
//   not list (CiA 301: all elements of an ARRAY share one data type).
// - Ranges of like objects are given by one object: 1201h-127Fh by 1201h, 1280h-12FFh by 1280h,
//   1400h-15FFh by 1400h, 1600h-17FFh by 1600h, 1800h-19FFh by 1800h, 1A00h-1BFFh by 1A00h.
// - DefaultValue is informative and not checked.
#pragma once

#include <array>
#include <span>
#include <string>
#include <string_view>

#include "cfg/diagnostics.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"

namespace cfg {

/// Names of the schemas shipped in schemas/ (file `<name>.eds`).
inline constexpr std::string_view kCia301Schema = "cia301_communication";
inline constexpr std::string_view kCia302ManagerSchema = "cia302_manager";
/// Every schema shipped, for load_schemas().
inline constexpr std::array<std::string_view, 2> kStandardSchemas{kCia301Schema,
                                                                  kCia302ManagerSchema};

/// The environment variable that names the schema directory for find_schema_dir().
inline constexpr std::string_view kSchemaDirVariable = "CANOPEN_SCHEMA_DIR";

/// Finds the directory of the schemas, in this order:
///  1. $CANOPEN_SCHEMA_DIR when it is set (and not empty): that directory and no other;
///  2. the installed layout beside the running program (/proc/self/exe):
///     `<bindir>/../share/canopen/schemas` (the relative path is the one the build installs to;
///     the build tree has the same layout, a link to the source tree's schemas/).
/// A directory is found when it holds the file of every standard schema (kStandardSchemas).
/// Fails, with a message naming every place it looked and how to give the directory, when none
/// is found; never falls back to anything else.
Result<std::string> find_schema_dir();

/// Reads `<schema_dir>/<name>.eds` with the strict reader. Fails when the file cannot be read or
/// has any diagnostic (a schema must be clean); the message carries the diagnostics.
Result<DeviceDescription> load_schema(std::string_view name, const std::string& schema_dir);
/// The same from find_schema_dir(); fails with its message when no directory is found.
Result<DeviceDescription> load_schema(std::string_view name);

/// Loads several schemas (each as load_schema does) into one description holding the objects of
/// all of them, so that a device is checked once. Fails when a schema fails to load, or when two
/// schemas define the same index differently (cia302_manager repeats 1000h/1001h/1018h, which
/// CiA 306 requires in every EDS, from cia301_communication).
Result<DeviceDescription> load_schemas(std::span<const std::string_view> names,
                                       const std::string& schema_dir);
/// The same from find_schema_dir(); fails with its message when no directory is found.
Result<DeviceDescription> load_schemas(std::span<const std::string_view> names = kStandardSchemas);

/// Adds a warning to `diagnostics` for each object or sub-object of `device` that the schema
/// defines differently: ObjectType (VAR/DOMAIN vs ARRAY vs RECORD), DataType, or an AccessType
/// that allows more than the schema's (e.g. 1017h declared UNSIGNED32 where CiA 301 defines
/// UNSIGNED16; 1018h sub-index 1 declared rw where it is ro). Each warning names index,
/// sub-index, the device's value and the standard's, and carries `file_name` and the line of
/// the entry. Objects and sub-indices the schema does not define are not reported.
void check_against_schema(const DeviceDescription& device, const DeviceDescription& schema,
                          std::string_view file_name, Diagnostics& diagnostics);

}  // namespace cfg
