// The object dictionary model of CiA 306 electronic data sheets (EDS) and device configuration
// files (DCF): objects, sub-objects and every attribute the file format defines, plus the
// file-level sections. Values are kept as the text of the file ($NODEID stays symbolic until a
// node-ID is known); parse them with cfg::parse_value and the entry's data type.
#pragma once

#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "cfg/data_type.hpp"
#include "cfg/model_memory.hpp"
#include "cfg/optional_text.hpp"

namespace cfg {

/// ObjectType= (CiA 306 §4.6.3, codes from CiA 301 Table 42).
enum class ObjectType : std::uint8_t {
  Null = 0x0,
  Domain = 0x2,
  Deftype = 0x5,
  Defstruct = 0x6,
  Var = 0x7,
  Array = 0x8,
  Record = 0x9,
};
std::string_view to_string(ObjectType type);  ///< "VAR", "ARRAY", ...
std::optional<ObjectType> object_type_from_code(unsigned code);

/// AccessType= (CiA 306 §4.6.3): rwr is read/write with TPDO mapping in mind (read on process
/// input), rww read/write with RPDO mapping in mind (write on process output).
enum class AccessType : std::uint8_t { Ro, Wo, Rw, Rwr, Rww, Const };
std::string_view to_string(AccessType access);  ///< "ro", "wo", "rw", "rwr", "rww", "const"
/// Case-insensitive ("RW" and "rw" both work).
std::optional<AccessType> access_type_from_string(std::string_view text);
/// SDO may write it: rw, wo, rwr, rww.
bool is_writable(AccessType access);
/// SDO may read it: everything but wo.
bool is_readable(AccessType access);

/// One value-carrying entry: a sub-object of an ARRAY/RECORD, or the single entry (sub-index 0)
/// that carries the attributes of a VAR/DOMAIN object.
struct SubObject {
  std::uint8_t sub_index = 0;
  std::string name;  ///< ParameterName
  ObjectType object_type = ObjectType::Var;
  std::uint16_t data_type = 0;  ///< DataType= index; find_data_type() tells if it is basic
  AccessType access = AccessType::Rw;
  bool pdo_mapping = false;
  OptionalText default_value;    ///< DefaultValue, text as in the file
  OptionalText parameter_value;  ///< ParameterValue (DCF), text as in the file
  OptionalText low_limit;
  OptionalText high_limit;
  OptionalText denotation;                 ///< Denotation (DCF)
  OptionalText upload_file;                ///< UploadFile (DOMAIN)
  OptionalText download_file;              ///< DownloadFile (DOMAIN)
  std::optional<std::uint32_t> obj_flags;  ///< ObjFlags when written on a sub-object
  int line = 0;  ///< line of the defining section in the source file; 0 if not from a file
  /// Lines of the DefaultValue= and ParameterValue= keys that gave the values (for a value from
  /// [xxxxValue] or an expanded CompactSubObj, that key's line); 0 when not from a file. What is
  /// said about a value names its own line. 8 bytes per entry (SubObject is 128 bytes).
  int default_value_line = 0;
  int parameter_value_line = 0;

  /// The basic type, when DataType is one (nullopt for unknown or complex types).
  std::optional<DataType> basic_type() const;
  /// The value this entry is configured with: ParameterValue, else DefaultValue.
  const OptionalText& configured_value() const {
    return parameter_value ? parameter_value : default_value;
  }
  /// Every attribute but the lines (`line`, `default_value_line`, `parameter_value_line`).
  bool operator==(const SubObject& other) const;
};

/// The sub-objects of an object by sub-index: a std::map whose nodes a model read from a file
/// keeps in its arena (cfg/model_memory.hpp); used like any std::map.
using SubObjects = std::map<std::uint8_t, SubObject, std::less<std::uint8_t>,
                            ModelAllocator<std::pair<const std::uint8_t, SubObject>>>;

struct Object {
  std::uint16_t index = 0;
  std::string name;  ///< ParameterName
  ObjectType object_type = ObjectType::Var;
  std::optional<std::uint8_t> sub_number;       ///< SubNumber as written (ARRAY/RECORD)
  std::optional<std::uint8_t> compact_sub_obj;  ///< CompactSubObj as written
  std::optional<std::uint32_t> obj_flags;       ///< ObjFlags
  std::vector<std::uint16_t> object_links;      ///< [xxxxObjectLinks]
  /// VAR/DOMAIN: exactly one entry, at sub-index 0, with the object's data type, access and
  /// values. ARRAY/RECORD: the sub-objects, CompactSubObj already expanded.
  SubObjects subs;
  int line = 0;  ///< line of the [xxxx] section; 0 if not from a file

  bool is_var() const {
    return object_type == ObjectType::Var || object_type == ObjectType::Domain ||
           object_type == ObjectType::Deftype;
  }
  const SubObject* sub(std::uint8_t sub_index) const;
  SubObject* sub(std::uint8_t sub_index);
  bool operator==(const Object& other) const;  ///< every attribute but `line`
};

/// The objects of a device by index, a std::map like SubObjects.
using Objects = std::map<std::uint16_t, Object, std::less<std::uint16_t>,
                         ModelAllocator<std::pair<const std::uint16_t, Object>>>;

/// A key=value section kept in file order with its keys' spelling ([FileInfo], [DeviceInfo],
/// [DummyUsage], sections the model does not interpret). Keys compare case-insensitively.
struct KeyValues {
  std::vector<std::pair<std::string, std::string>> entries;

  const std::string* find(std::string_view key) const;
  /// Replaces the value of an existing key (keeping its place) or appends the key.
  void set(std::string_view key, std::string value);
  bool erase(std::string_view key);
  bool operator==(const KeyValues&) const = default;
};

/// [DeviceComissioning] (CiA 306 §4.7; the standard's own spelling, `DeviceCommissioning` is
/// accepted too). Only in DCFs.
struct DeviceCommissioning {
  std::optional<std::uint8_t> node_id;             ///< NodeID, 1..127
  std::string node_name;                           ///< NodeName
  std::optional<std::uint16_t> baudrate_kbps;      ///< Baudrate, in kbit/s
  std::optional<std::uint32_t> net_number;         ///< NetNumber
  std::string network_name;                        ///< NetworkName
  std::optional<bool> canopen_manager;             ///< CANopenManager
  std::optional<std::uint32_t> lss_serial_number;  ///< LSS_SerialNumber
  KeyValues other;  ///< keys the standard does not define, kept for the writer
  bool operator==(const DeviceCommissioning&) const = default;
};

/// A section the model does not interpret (modular device sections, vendor sections), kept so
/// the writer can write it back.
struct RawSection {
  std::string name;  ///< as written, without brackets
  KeyValues keys;
  bool operator==(const RawSection&) const = default;
};

/// Everything an EDS or DCF says about a device.
struct DeviceDescription {
  KeyValues file_info;                               ///< [FileInfo]
  KeyValues device_info;                             ///< [DeviceInfo]
  KeyValues dummy_usage;                             ///< [DummyUsage]
  std::optional<DeviceCommissioning> commissioning;  ///< [DeviceComissioning]
  std::vector<std::string> comments;                 ///< [Comments] Line1..LineN
  Objects objects;                                   ///< by index
  std::vector<RawSection> other_sections;            ///< in file order

  const Object* object(std::uint16_t index) const;
  Object* object(std::uint16_t index);
  const SubObject* sub(std::uint16_t index, std::uint8_t sub_index) const;
  SubObject* sub(std::uint16_t index, std::uint8_t sub_index);
  /// Node-ID from [DeviceComissioning], if the file has one.
  std::optional<std::uint8_t> node_id() const {
    return commissioning ? commissioning->node_id : std::nullopt;
  }
  bool operator==(const DeviceDescription&) const = default;
};

/// Which object list an index belongs in (CiA 306 §4.5): 1000h, 1001h, 1018h are mandatory,
/// 2000h-5FFFh are manufacturer-specific, the rest optional.
enum class ObjectList { Mandatory, Optional, Manufacturer };
ObjectList object_list_for(std::uint16_t index);
std::string_view to_string(ObjectList list);  ///< "MandatoryObjects", ...

/// Case-insensitive ASCII comparison, for section and key names.
bool iequals(std::string_view a, std::string_view b);

}  // namespace cfg
