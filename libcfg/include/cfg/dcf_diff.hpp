// The parameters two device files configure differently: what `cfgmgr diff A.dcf B.dcf` prints.
// An entry's parameter is the value a download writes (CiA 306 §4.6.3: ParameterValue is the
// value configured for the device; without one, the DefaultValue stands; concise_writes_from_dcf
// takes the same one), compared as the typed value, so "0x10" and "16" are one UNSIGNED8 value.
// The segments of [DynamicChannels] (CiA DSP 302 §8.4) are compared too (diff_dynamic_channels).
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cfg/object_address.hpp"
#include "cfg/object_dictionary.hpp"

namespace cfg {

/// One side of a difference.
struct DiffSide {
  std::string text;  ///< the value in words (describe_value), or the file's text when it does
                     ///< not parse; "(no value)" when the entry has neither value
  int line = 0;      ///< line of the value's key, else of the entry's section; 0 if unknown
};

struct ParameterDifference {
  enum class Kind : std::uint8_t {
    Changed,  ///< both files have the entry; the values differ
    OnlyInA,  ///< the object (sub_index 0, `whole_object`) or sub-object is only in A
    OnlyInB,
  };
  Kind kind = Kind::Changed;
  ObjectAddress address;
  bool whole_object = false;  ///< OnlyInA/OnlyInB of an entire object
  std::string name;           ///< "Producer heartbeat time", "TPDO 1 mapping / Mapped object 1"
  std::optional<DiffSide> a;  ///< nullopt on the side that lacks it
  std::optional<DiffSide> b;
};

struct DiffOptions {
  /// $NODEID in values: each file's [DeviceComissioning] NodeID unless given here. When neither
  /// is known, values using $NODEID are compared as written.
  std::optional<std::uint8_t> node_id_a;
  std::optional<std::uint8_t> node_id_b;
};

/// The differences by ascending index and sub-index. Entries with a value in neither file are
/// not compared. Never throws on bad values: a value that does not parse is compared as text.
std::vector<ParameterDifference> diff_parameters(const DeviceDescription& a,
                                                 const DeviceDescription& b,
                                                 const DiffOptions& options = {});

/// One difference of [DynamicChannels] (CiA DSP 302 §8.4). Segments are matched by the start of
/// their range (RangeN; §8.4 forbids overlapping ranges, so it names a segment), not by N: a
/// segment inserted before the others is one added segment, not every later one changed.
struct SegmentDifference {
  ParameterDifference::Kind kind = ParameterDifference::Kind::Changed;
  std::uint16_t first_index = 0;  ///< the segment's RangeN start
  std::size_t segment_a = 0;      ///< N in A (1-based), 0 when only in B
  std::size_t segment_b = 0;      ///< N in B, 0 when only in A
  /// The segment in words ("UNSIGNED16 ro 2010h-2011h, PPOffset 0, MaxCnt 16"); line 0 (the
  /// model keeps no lines for the section). nullopt on the side that lacks it.
  std::optional<DiffSide> a;
  std::optional<DiffSide> b;
};

/// The [DynamicChannels] segments two descriptions declare differently (changed, removed, added),
/// by range start. A description without the section has no segments.
std::vector<SegmentDifference> diff_dynamic_channels(const DeviceDescription& a,
                                                     const DeviceDescription& b);

/// How messages name an entry: the object's name for a VAR, "object / sub-object" otherwise
/// ("TPDO 1 mapping / Mapped object 1").
std::string parameter_name(const Object& object, const SubObject& sub);

/// "changed", "only_in_a", "only_in_b": names for JSON.
std::string_view to_string(ParameterDifference::Kind kind);

}  // namespace cfg
