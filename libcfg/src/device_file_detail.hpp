// Private to libcfg: rules the EDS/DCF reader and writer must agree on, so that reading what the
// writer wrote gives canonical_form() of the model.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "cfg/object_dictionary.hpp"

namespace cfg::detail {

/// Object types whose one entry (sub-index 0) lives in the object's own section.
constexpr bool var_like(ObjectType t) {
  return t == ObjectType::Var || t == ObjectType::Domain || t == ObjectType::Deftype ||
         t == ObjectType::Null;
}

/// Section names the reader interprets itself ([FileInfo], [1000], [1000sub1], [1000Value], ...);
/// any other name is kept as a RawSection.
bool is_reserved_section_name(std::string_view name);

/// [DeviceInfo] keys whose values are numbers (CiA 306 §4.4); the others are texts.
bool is_numeric_device_info_key(std::string_view key);

/// Where an inline comment starts: ';' or '#' at the start of the text or after a blank.
std::size_t find_inline_comment(std::string_view text);

/// `0180h`, `0000 0080h`: hex digits with an 'h' suffix (CiA 301 document style). Returns the
/// digits without group blanks, or nullopt if the text is not of that form.
std::optional<std::string> h_suffix_digits(std::string_view text);

/// How the reader stores the text of a DefaultValue/ParameterValue/LowLimit/HighLimit of an entry
/// with DataType `data_type`. `text` is trimmed. For types other than VISIBLE_STRING,
/// UNICODE_STRING and unknown types an inline comment is cut; an empty value of a fixed-size or
/// unknown type is "not given" (nullopt); 'h'-suffix hex of an integer type becomes 0x hex; a
/// 0x-prefixed OCTET_STRING/DOMAIN value loses its prefix (the digits are the same bytes).
struct NormalizedValue {
  std::optional<std::string> text;
  std::string_view comment;  ///< the cut comment ("" if none)
  bool h_suffix = false;     ///< text was 'h'-suffix hex
};
NormalizedValue normalize_value(std::string_view text, std::uint16_t data_type);

/// True only when `text` is one line without blanks at its ends and normalize_value(text,
/// data_type).text is `text` itself, as the reader's stored texts nearly always are; decided in
/// one pass without a copy (the writer's fast path). False when it is not, or may not be, so:
/// also for any text with ';' or '#' in it (then trim it and call normalize_value).
bool is_normalized_value(std::string_view text, std::uint16_t data_type);

}  // namespace cfg::detail
