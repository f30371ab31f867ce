// Typed values of CiA 301 basic types: parsing from EDS/DCF text (CiA 306), encoding to the
// little-endian bytes sent by SDO and stored in a concise DCF, decoding, and formatting.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "cfg/data_type.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/result.hpp"

namespace cfg {

/// A value of one basic data type. Integers are held widened (int64/uint64) but always within
/// the range of their type when built through parse_value/decode/make_checked.
class Value {
 public:
  Value() = default;  ///< UNSIGNED8 0

  static Value from_bool(bool v) { return Value(DataType::Boolean, v); }
  static Value from_signed(DataType type, std::int64_t v) { return Value(type, v); }
  static Value from_unsigned(DataType type, std::uint64_t v) { return Value(type, v); }
  static Value from_real(DataType type, double v) { return Value(type, v); }
  /// Strings and DOMAIN: the encoded bytes (UNICODE_STRING: UTF-16LE bytes).
  static Value from_bytes(DataType type, std::string bytes) {
    return Value(type, std::move(bytes));
  }

  DataType type() const { return type_; }
  bool as_bool() const { return std::get<bool>(data_); }
  std::int64_t as_signed() const { return std::get<std::int64_t>(data_); }
  std::uint64_t as_unsigned() const { return std::get<std::uint64_t>(data_); }
  double as_real() const { return std::get<double>(data_); }
  const std::string& as_bytes() const { return std::get<std::string>(data_); }

  bool operator==(const Value&) const = default;

 private:
  using Data = std::variant<bool, std::int64_t, std::uint64_t, double, std::string>;
  Value(DataType type, Data data) : type_(type), data_(std::move(data)) {}

  DataType type_ = DataType::Unsigned8;
  Data data_ = std::uint64_t{0};
};

/// Smallest and largest value of an integer type (INTEGER24: -8388608 .. 8388607).
std::int64_t signed_min(DataType type);
std::int64_t signed_max(DataType type);
std::uint64_t unsigned_max(DataType type);

/// True when the text uses $NODEID (any case, e.g. "$NodeId + 0x180").
bool mentions_node_id(std::string_view text);

/// Parses value text of an EDS/DCF (CiA 306 §4.6.3): decimal, `0x` hex, octal with a leading 0,
/// negative decimals, REAL as decimal floating point, sums with `$NODEID` on either side
/// (`$NODEID+0x180`, `0x180 + $NodeId`). `text` is trimmed and free of comments. Strings are taken
/// as they are (VISIBLE_STRING bytes; UNICODE_STRING text is UTF-8 and becomes UTF-16LE);
/// OCTET_STRING and DOMAIN text is hex digit pairs, blanks allowed between pairs ("01 A2 FF"), or
/// one 0x-prefixed run of digits as vendor tools export them ("0x01A2FF"); an odd number of
/// digits is an error. As lely's DCFs write them, a REAL may be
/// given as the hex IEEE 754 bit pattern ("0x40490FDB" is pi as REAL32), and TIME_OF_DAY /
/// TIME_DIFFERENCE as "DAYS MS" as well as the 48-bit raw number. Fails with a message when the
/// text is not a value of the type, is out of its range, or needs a node-ID that was not given.
Result<Value> parse_value(DataType type, std::string_view text,
                          std::optional<std::uint8_t> node_id = std::nullopt);

/// For an entry whose DefaultValue uses $NODEID (the pre-defined connection set of CiA 301
/// §7.3.5: EMCY, PDO and default SDO COB-IDs): the node-ID (1..127) at which that default is
/// `value`, the smallest if several; nullopt when it is none's. What tells a value a device
/// derived from its node-ID (a DCF saved at node 1 records 1200h sub 1 = 0x601) from one set.
std::optional<std::uint8_t> node_id_of_default(DataType type, std::string_view default_text,
                                               std::string_view value_text);

struct DeviceDescription;

/// The node-ID at which a file's values of the pre-defined connection set were recorded (its
/// $NODEID DefaultValues with a plain ParameterValue): that of 1200h sub 1/2 when the file
/// gives them (the default SDO server's COB-IDs, which CiA 301 §7.3.5 fixes at 600h/580h +
/// node-ID, so they tell where a device was when its DCF was saved); else the one node-ID that
/// two or more such values agree on, unless one of them is at the file's own NodeID; else the
/// file's NodeID (nullopt without one). A lone value that is another node-ID's default (1014h =
/// 0A4h at node 4) is a deliberate setting, not a recording.
std::optional<std::uint8_t> recorded_node_id(const DeviceDescription& device);

/// True when `value_text` is `default_text` (a $NODEID expression) evaluated at `node_id`: a
/// value the device derives from its node-ID rather than one set on purpose.
bool is_default_at(DataType type, std::string_view default_text, std::string_view value_text,
                   std::uint8_t node_id);

/// Little-endian bytes with the exact size of the type (INTEGER24: 3 bytes, UNSIGNED40: 5).
std::vector<std::uint8_t> encode(const Value& value);

/// Reads bytes as a value of the type. Fixed-size types need exactly their size.
Result<Value> decode(DataType type, std::span<const std::uint8_t> bytes);

/// The value of a plain integer literal (cfg/integer_literal.hpp: no sign, no $NODEID) for
/// BOOLEAN, UNSIGNEDn or INTEGERn: what parse_value gives for the literal's text, range checks
/// and hex bit patterns of signed types included, without reading the text again. Fails for a
/// value out of range or another type.
Result<Value> integer_value(DataType type, IntegerLiteral literal);

/// Canonical EDS/DCF text that parse_value reads back to the same value: unsigned as 0x hex,
/// signed as decimal, REAL with enough digits to round-trip, BOOLEAN as 0/1, OCTET_STRING and
/// DOMAIN as hex pairs, strings as they are.
std::string format_value(const Value& value);

/// Orders two numeric values of the same type (signed, unsigned or REAL): <0, 0 or >0. nullopt
/// when they cannot be ordered: different types, a type that is not numeric, or a NaN (a REAL
/// limit or value that is NaN is outside every range). The one value comparison of both
/// libraries (limits in the reader, the schema checks, SDO range checks).
std::optional<int> compare_values(const Value& a, const Value& b);

/// Text for people: `1000 (0x000003E8)` for unsigned, `"text"` for strings, `-5` for signed.
std::string describe_value(const Value& value);

}  // namespace cfg
