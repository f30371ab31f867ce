// Dynamic index assignment for programmable devices (CiA DSP 302 §8.2): the network variables of a
// program (name, data type, direction) are allocated into the segments of the device's
// [DynamicChannels] (cfg::DynamicChannels in cfg/object_dictionary.hpp), each variable gets its
// index, sub-index and process-picture offset, and the resulting ARRAY objects are written into
// the device description, so that the writer produces the DCF of the programmed device (§8.5).
//
// Choices where §8.2 leaves room:
// - A variable goes into the first segment (in file order) of its data type and direction that
//   has room; inputs go into ro segments, outputs into wo and rww segments.
// - Within a segment, variable number p (0-based) is at index first + p / 254, sub-index
//   p % 254 + 1 (§8.2: arrays of 01h..FEh, then the next object), and at bit
//   8 * PPOffset + p * stride of the process picture, the stride being 8 * the type's size, or the
//   bit distance of a BOOLEAN segment. A BOOLEAN variable covers its bit (distance 1..7) or one
//   byte cell (distance 8 and more).
// - Inputs and outputs are two process pictures. A position whose bits overlap a variable already
//   allocated in the same picture (segments that mix types, all at PPOffset 0) is left out, as
//   §8.2 asks of configuration tools; positions left out count towards MaxCnt, which bounds the
//   segment's part of the process picture (MaxCnt x type size).
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/object_address.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"

namespace cfg {

/// DirN= of a dynamic channel segment (CiA DSP 302 §8.4): ro holds inputs (mapped into transmit
/// PDOs), wo and rww hold outputs (mapped into receive PDOs).
enum class SegmentDirection : std::uint8_t { Ro, Wo, Rww };
std::string_view to_string(SegmentDirection direction);  ///< "ro", "wo", "rww"
/// Case-insensitive ("RO" reads as ro).
std::optional<SegmentDirection> segment_direction_from_string(std::string_view text);

/// One segment of [DynamicChannels] (CiA DSP 302 §8.2, §8.4): a range of indices where network
/// variables of one data type and direction are allocated, as ARRAY objects of sub-index
/// 01h..FEh, and where they sit in the device's process picture.
struct DynamicSegment {
  std::uint16_t data_type = 0;  ///< TypeN: the DataType index of the variables (0001h BOOLEAN)
  SegmentDirection direction = SegmentDirection::Ro;  ///< DirN
  std::uint16_t first_index = 0;                      ///< RangeN, start index
  std::uint16_t last_index = 0;                       ///< RangeN, end index (inclusive)
  /// PPOffsetN: offset of the first variable in the process picture, in bytes.
  std::uint32_t pp_offset = 0;
  /// PPOffsetN's second number, BOOLEAN segments only: the distance of two variables in the
  /// process picture, in bits (1: packed, 8: one per byte). nullopt when not given.
  std::optional<std::uint32_t> bit_distance;
  std::uint32_t max_count = 0;            ///< MaxCntN: the most variables the segment holds
  std::optional<std::string> m_specific;  ///< MSpecificN, manufacturer-specific, verbatim
  bool operator==(const DynamicSegment&) const = default;
};

/// [DynamicChannels] (CiA DSP 302 §8.4): the segments, entry index N = position + 1.
struct DynamicChannels {
  std::vector<DynamicSegment> segments;
  bool operator==(const DynamicChannels&) const = default;
};

/// The segments a device description's [DynamicChannels] section describes (the model keeps the
/// section as it is written, a RawSection in other_sections; the reader checks it, with the line
/// of each fault, and this reads it the same way): segments in entry order, a segment with a
/// missing or unreadable key left out, a bit distance kept only on BOOLEAN segments. nullopt
/// when the description has no [DynamicChannels].
std::optional<DynamicChannels> dynamic_channels_of(const DeviceDescription& device);

/// [DeviceInfo] DynamicChannelsSupported bits (CiA DSP 302 §8.4); bits 4-31 are reserved.
namespace dynamic_channels_bit {
inline constexpr std::uint32_t kGeneralFacility = 1U << 0;     ///< allocates dynamic variables
inline constexpr std::uint32_t kPredefinedSegments = 1U << 2;  ///< DS-405 predefined segments
inline constexpr std::uint32_t kObjectsDescribed = 1U << 3;    ///< the EDS describes the objects
}  // namespace dynamic_channels_bit

/// [DeviceInfo] DynamicChannelsSupported (CiA DSP 302 §8.4: 0 when absent); nullopt when the
/// key's value is not a number.
std::optional<std::uint32_t> dynamic_channels_supported(const DeviceDescription& device);

/// The direction of a network variable (§8.2): an input of the device is read from the network
/// (mapped into a transmit PDO; ro segments); an output is written from the network (mapped into
/// a receive PDO; wo and rww segments).
enum class VariableDirection : std::uint8_t { Input, Output };
std::string_view to_string(VariableDirection direction);  ///< "in", "out"
/// "in"/"input"/"ro" and "out"/"output"/"wo"/"rww", case-insensitively.
std::optional<VariableDirection> variable_direction_from_string(std::string_view text);
/// The direction of the variables a segment holds: ro -> Input, wo and rww -> Output.
VariableDirection direction_of(const DynamicSegment& segment);

/// An EXTERN variable of a program (§8.1).
struct NetworkVariable {
  std::string name;             ///< the program's symbol; the sub-object's ParameterName
  std::uint16_t data_type = 0;  ///< DataType index (0005h UNSIGNED8, 0001h BOOLEAN, ...)
  VariableDirection direction = VariableDirection::Input;
  bool operator==(const NetworkVariable&) const = default;
};

/// Reads a variables file, the smallest form a user writes for `cfgmgr build --variables`: one
/// variable per line, `name,type,direction`, where type is a CiA 301 name (BOOLEAN, UNSIGNED8,
/// INTEGER16, REAL32, ..., any case) or a DataType number (0x0005), and direction is `in` or
/// `out` (variable_direction_from_string). Blanks around fields are ignored; blank lines and
/// lines starting with '#' are skipped, as is a first line `name,type,direction`. Lines end at
/// LF or CRLF. Fails at the first bad line with "FILE:LINE: what is wrong" (`file_name` as
/// given).
Result<std::vector<NetworkVariable>> parse_network_variables(std::string_view text,
                                                             std::string_view file_name);

/// Where a variable was allocated.
struct AllocatedVariable {
  NetworkVariable variable;
  std::size_t segment = 0;          ///< position in DynamicChannels::segments (entry index - 1)
  std::uint32_t position = 0;       ///< variable number in the segment, 0-based
  ObjectAddress address;            ///< index and sub-index (01h..FEh)
  std::uint64_t pp_bit_offset = 0;  ///< offset in the process picture, in bits
  std::uint32_t pp_byte_offset() const { return static_cast<std::uint32_t>(pp_bit_offset / 8); }
  unsigned pp_bit() const { return static_cast<unsigned>(pp_bit_offset % 8); }  ///< 0..7
};

/// The layout rules of §8.2 for one segment (the choices above). A segment is usable when its
/// range is not reversed, its type is a fixed-size basic type and a BOOLEAN segment has a bit
/// distance of at least 1; the functions below assume a usable segment.
bool is_usable(const DynamicSegment& segment);
/// How many variables fit: MaxCnt, at most 254 per index of the range.
std::uint32_t capacity(const DynamicSegment& segment);
/// Index and sub-index of variable number `position`.
ObjectAddress segment_address(const DynamicSegment& segment, std::uint32_t position);
/// The variable number at an index and sub-index, nullopt when the address is not of the
/// segment (outside the range, sub-index 00h or FFh, beyond capacity()).
std::optional<std::uint32_t> segment_position(const DynamicSegment& segment,
                                              const ObjectAddress& address);
/// Bits from one variable to the next; bits one variable covers.
std::uint32_t stride_bits(const DynamicSegment& segment);
std::uint32_t width_bits(const DynamicSegment& segment);
/// Offset of variable number `position` in the process picture, in bits.
std::uint64_t process_picture_bit_offset(const DynamicSegment& segment, std::uint32_t position);
/// The segment's part of the process picture in bytes, from PPOffset to the end of the last
/// variable capacity() allows (0 for an empty segment).
std::uint64_t segment_size_bytes(const DynamicSegment& segment);

/// Allocates `variables` in order (the choices above). Fails, naming the variable, when a name is
/// empty or given twice, a type is not a fixed-size basic type, no usable segment holds its type
/// and direction, or every such segment is full (MaxCnt reached or index range exhausted).
Result<std::vector<AllocatedVariable>> allocate_variables(
    const DynamicChannels& channels, std::span<const NetworkVariable> variables);

/// Adds the allocated variables to `device` as ARRAY objects (§8.5): one object per index,
/// "<TYPE> inputs"/"<TYPE> outputs", sub-index 00h "Highest sub-index supported" (UNSIGNED8 ro,
/// the highest sub-index used), and per variable a sub-object named after it, of its type,
/// AccessType as the segment's Dir (ro, wo, rww), PDO mappable, DefaultValue 0. `channels` are
/// the segments the allocation was made in. Fails, changing nothing, when an object the
/// allocation uses already exists in `device` (a DCF that is programmed already).
Status add_variable_objects(DeviceDescription& device, const DynamicChannels& channels,
                            std::span<const AllocatedVariable> allocation);

}  // namespace cfg
