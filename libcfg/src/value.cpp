// Typed values of CiA 301 basic types: CiA 306 value text, little-endian encoding, formatting.
//
// Choices where CiA 306 leaves room (each one documented in cfg/value.hpp or here):
// - Signed types accept hex literals as the two's complement bit pattern of the type's width
//   ("0x80000000" is INTEGER32 -2147483648, "0xFFFFFFFFFFFFFFF6" is INTEGER64 -10), because real
//   device files write limits that way. Decimal text is range-checked as written.
// - TIME_OF_DAY / TIME_DIFFERENCE text is the 48-bit raw value (CiA 301 §7.1: 28 bits of
//   milliseconds, 4 reserved bits, 16 bits of days) written like an unsigned integer, or
//   "DAYS MS" as lely's DCFs write it.
// - REAL text may also be the hex IEEE 754 bit pattern, as lely's DCFs write it.
// - REAL text is decimal floating point (exponent allowed) plus "inf", "-inf" and "nan", so that
//   every value decode() can produce formats to text that reads back.
#include "cfg/value.hpp"

#include <array>
#include <bit>
#include <charconv>
#include <cmath>
#include <cstring>
#include <limits>
#include <system_error>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/object_dictionary.hpp"

namespace cfg {
namespace {

constexpr std::string_view kNodeIdToken = "$NODEID";

bool is_space(char c) {
  return c == ' ' || c == '\t' || c == '\r' || c == '\n' || c == '\f' || c == '\v';
}

std::string_view trim(std::string_view text) {
  while (!text.empty() && is_space(text.front())) text.remove_prefix(1);
  while (!text.empty() && is_space(text.back())) text.remove_suffix(1);
  return text;
}

std::string quoted(std::string_view text) {
  return "\"" + std::string(text) + "\"";
}

// One integer literal of CiA 306 (cfg/integer_literal.hpp); `whole` is the text a message quotes.
Result<IntegerLiteral> parse_literal(std::string_view text, std::string_view whole) {
  const IntegerLiteralResult r = parse_integer_literal(text);
  if (r.literal) return *r.literal;
  if (r.error == IntegerLiteralError::OutOfRange) {
    return Error{"value " + std::string(whole) + " does not fit in 64 bits"};
  }
  return Error{"invalid number " + quoted(whole)};
}

bool is_node_id_term(std::string_view term) {
  return iequals(term, kNodeIdToken);
}

// An integer as written: a magnitude with a sign, or a sum of terms with $NODEID.
struct IntegerText {
  std::uint64_t magnitude = 0;
  bool negative = false;
  bool is_hex = false;  // a single hex literal (bit pattern for signed types)
};

// CiA 306 §4.6.3 (and its DCF examples): "$NODEID+0x180"; real files also write the node-ID
// term second and put spaces around '+'. Exactly one $NODEID term, the others literals.
Result<IntegerText> parse_node_id_sum(std::string_view text, std::optional<std::uint8_t> node_id) {
  std::uint64_t sum = 0;
  int node_id_terms = 0;
  std::string_view rest = text;
  while (true) {
    const std::size_t plus = rest.find('+');
    const std::string_view term = trim(rest.substr(0, plus));
    std::uint64_t addend = 0;
    if (is_node_id_term(term)) {
      if (!node_id) return Error{quoted(text) + " needs a node-ID, and none is known here"};
      ++node_id_terms;
      addend = *node_id;
    } else {
      auto lit = parse_literal(term, text);
      if (!lit) return Error{"invalid $NODEID formula " + quoted(text)};
      addend = lit->value;
    }
    if (addend > std::numeric_limits<std::uint64_t>::max() - sum) {
      return Error{"value " + quoted(text) + " does not fit in 64 bits"};
    }
    sum += addend;
    if (plus == std::string_view::npos) break;
    rest = rest.substr(plus + 1);
  }
  if (node_id_terms != 1) return Error{"invalid $NODEID formula " + quoted(text)};
  return IntegerText{sum, false, false};
}

Result<IntegerText> parse_integer_text(std::string_view text, std::optional<std::uint8_t> node_id) {
  // Nearly every value is a plain literal (no sign, no $NODEID): read it as one first.
  if (const IntegerLiteralResult plain = parse_integer_literal(text); plain.literal) {
    return IntegerText{plain.literal->value, false, plain.literal->is_hex};
  }
  if (mentions_node_id(text)) return parse_node_id_sum(text, node_id);
  bool negative = false;
  std::string_view body = text;
  if (!body.empty() && body.front() == '-') {
    negative = true;
    body.remove_prefix(1);
  }
  auto lit = parse_literal(body, text);
  if (!lit) return lit.error();
  return IntegerText{lit->value, negative && lit->value != 0, lit->is_hex};
}

std::string range_text(DataType type) {
  const auto& info = data_type_info(type);
  if (info.type_class == TypeClass::Signed) {
    return std::to_string(signed_min(type)) + ".." + std::to_string(signed_max(type));
  }
  return "0.." + std::to_string(unsigned_max(type));
}

Error out_of_range(std::string_view value, DataType type) {
  return Error{"value " + std::string(value) + " out of range for " + std::string(to_string(type)) +
               " (" + range_text(type) + ")"};
}

Result<Value> unsigned_value(DataType type, std::uint64_t magnitude) {
  if (magnitude > unsigned_max(type)) return out_of_range(std::to_string(magnitude), type);
  if (type == DataType::Boolean) return Value::from_bool(magnitude != 0);
  return Value::from_unsigned(type, magnitude);
}

Result<Value> parse_unsigned(DataType type, std::string_view text,
                             std::optional<std::uint8_t> node_id) {
  auto parsed = parse_integer_text(text, node_id);
  if (!parsed) return parsed.error();
  if (parsed->negative) return out_of_range(text, type);
  return unsigned_value(type, parsed->magnitude);
}

// Two's complement value of the low `bits` bits of `pattern`.
std::int64_t sign_extend(std::uint64_t pattern, unsigned bits) {
  if (bits == 0 || bits >= 64) return std::bit_cast<std::int64_t>(pattern);
  const std::uint64_t sign = std::uint64_t{1} << (bits - 1);
  pattern &= (sign << 1) - 1;
  pattern = (pattern ^ sign) - sign;  // wraps modulo 2^64: the two's complement of the value
  return std::bit_cast<std::int64_t>(pattern);
}

// `text` is what a message quotes for a negative value out of range.
Result<Value> signed_value(DataType type, const IntegerText& parsed, std::string_view text) {
  const auto bits = static_cast<unsigned>(data_type_info(type).size_bytes) * 8U;
  const std::uint64_t width_max =
      bits == 64 ? std::numeric_limits<std::uint64_t>::max() : (std::uint64_t{1} << bits) - 1;
  if (parsed.is_hex && !parsed.negative && parsed.magnitude <= width_max) {
    return Value::from_signed(type, sign_extend(parsed.magnitude, bits));
  }
  const std::uint64_t max = static_cast<std::uint64_t>(signed_max(type));
  if (parsed.negative) {
    // |min| = max + 1
    if (parsed.magnitude > max + 1) return out_of_range(text, type);
    const std::int64_t v = parsed.magnitude == max + 1
                               ? signed_min(type)
                               : -static_cast<std::int64_t>(parsed.magnitude);
    return Value::from_signed(type, v);
  }
  if (parsed.magnitude > max) return out_of_range(std::to_string(parsed.magnitude), type);
  return Value::from_signed(type, static_cast<std::int64_t>(parsed.magnitude));
}

Result<Value> parse_signed(DataType type, std::string_view text,
                           std::optional<std::uint8_t> node_id) {
  auto parsed = parse_integer_text(text, node_id);
  if (!parsed) return parsed.error();
  return signed_value(type, *parsed, text);
}

Result<Value> parse_real(DataType type, std::string_view text) {
  if (mentions_node_id(text)) {
    return Error{"$NODEID formulas are for integer types, not " + std::string(to_string(type))};
  }
  auto bad = [&] {
    return Error{"invalid number " + quoted(text) + " for " + std::string(to_string(type))};
  };
  if (text.empty()) return bad();
  // A hex literal is the IEEE 754 bit pattern of the type's width, as lely's DCFs write REALs
  // ("0x40490FDB" is pi as REAL32); the same reading as hex for signed types above.
  if (text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X')) {
    auto lit = parse_literal(text, text);
    if (!lit) return bad();
    if (type == DataType::Real32) {
      if (lit->value > 0xFFFFFFFFu) return bad();
      return Value::from_real(
          type, static_cast<double>(std::bit_cast<float>(static_cast<std::uint32_t>(lit->value))));
    }
    return Value::from_real(type, std::bit_cast<double>(lit->value));
  }
  // from_chars takes no leading '+', and neither do we ("+1" is not CiA 306 syntax).
  double v = 0;
  auto [end, ec] =
      std::from_chars(text.data(), text.data() + text.size(), v, std::chars_format::general);
  if (end != text.data() + text.size()) return bad();
  if (ec == std::errc::result_out_of_range)
    return Error{"value " + std::string(text) + " out of range for " +
                 std::string(to_string(type))};
  if (ec != std::errc{}) return bad();
  if (type == DataType::Real32) {
    if (std::isfinite(v) && std::fabs(v) > static_cast<double>(std::numeric_limits<float>::max())) {
      // Values that round to FLT_MAX are still representable; beyond that, no binary32 exists.
      const float f = static_cast<float>(v);
      if (!std::isfinite(f)) {
        return Error{"value " + std::string(text) + " out of range for REAL32 (largest magnitude " +
                     "3.4028235e+38)"};
      }
    }
    // Keep what the bus will carry: the binary32 nearest to the text.
    v = static_cast<double>(static_cast<float>(v));
  }
  return Value::from_real(type, v);
}

// TIME_OF_DAY / TIME_DIFFERENCE: the 48-bit raw value, or "DAYS MS" as lely's DCFs write it
// (CiA 301 §7.1: milliseconds in bits 0-27, days in bits 32-47).
Result<Value> parse_time(DataType type, std::string_view text,
                         std::optional<std::uint8_t> node_id) {
  const std::size_t space = text.find_first_of(" \t");
  if (space == std::string_view::npos) return parse_unsigned(type, text, node_id);
  auto days = parse_unsigned(DataType::Unsigned16, trim(text.substr(0, space)), std::nullopt);
  auto ms = parse_unsigned(DataType::Unsigned32, trim(text.substr(space)), std::nullopt);
  if (!days || !ms || ms->as_unsigned() >= (std::uint64_t{1} << 28)) {
    return Error{"invalid " + std::string(to_string(type)) + " " + quoted(text) +
                 ": expected a 48-bit number or \"DAYS MS\" (days 0..65535, ms 0..268435455)"};
  }
  return Value::from_unsigned(type, days->as_unsigned() << 32 | ms->as_unsigned());
}

// OCTET_STRING / DOMAIN text: pairs of hex digits, blanks between pairs allowed ("01 A2 FF").
// Motor-controller vendor tools export these values as one 0x-prefixed run of digits
// ("0x04000037...", tens of thousands of digits on one line); the prefix is read the same way.
// Messages do not quote such a value whole: they say where it goes wrong.
Result<Value> parse_hex_bytes(DataType type, std::string_view text) {
  auto bad = [&](const std::string& why) {
    return Error{"invalid " + std::string(to_string(type)) + ": " + why +
                 "; expected pairs of hex digits, e.g. \"01 A2 FF\" or \"0x01A2FF\""};
  };
  std::string_view digits = text;
  if (digits.size() >= 2 && digits[0] == '0' && (digits[1] == 'x' || digits[1] == 'X')) {
    digits.remove_prefix(2);
    if (trim(digits).empty()) return bad("no digits after 0x");
  }
  std::string bytes;
  bytes.reserve(digits.size() / 2);
  std::size_t i = 0;
  while (i < digits.size()) {
    if (is_space(digits[i])) {
      ++i;
      continue;
    }
    const std::size_t at = i + (text.size() - digits.size());  // position in `text`
    const int hi = hex_digit_value(digits[i]);
    if (hi < 0) {
      return bad(quoted(digits.substr(i, 1)) + " at character " + std::to_string(at + 1) +
                 " is not a hex digit");
    }
    const int lo = i + 1 < digits.size() ? hex_digit_value(digits[i + 1]) : -1;
    if (lo < 0) {
      if (i + 1 == digits.size()) {
        return bad("an odd number of hex digits (the last one, at character " +
                   std::to_string(at + 1) + ", has no pair)");
      }
      return bad(quoted(digits.substr(i + 1, 1)) + " at character " + std::to_string(at + 2) +
                 " breaks the pair that starts at character " + std::to_string(at + 1));
    }
    bytes.push_back(static_cast<char>(hi * 16 + lo));
    i += 2;
  }
  return Value::from_bytes(type, std::move(bytes));
}

void put_utf16le(std::string& out, std::uint32_t unit) {
  out.push_back(static_cast<char>(unit & 0xFF));
  out.push_back(static_cast<char>((unit >> 8) & 0xFF));
}

Result<Value> parse_unicode(std::string_view text) {
  std::string out;
  std::size_t i = 0;
  auto bad = [&] {
    return Error{"UNICODE_STRING text is not valid UTF-8 at byte " + std::to_string(i)};
  };
  while (i < text.size()) {
    const auto b0 = static_cast<unsigned char>(text[i]);
    std::uint32_t cp = 0;
    int extra = 0;
    std::uint32_t min_cp = 0;
    if (b0 < 0x80) {
      cp = b0;
    } else if ((b0 & 0xE0) == 0xC0) {
      cp = b0 & 0x1FU;
      extra = 1;
      min_cp = 0x80;
    } else if ((b0 & 0xF0) == 0xE0) {
      cp = b0 & 0x0FU;
      extra = 2;
      min_cp = 0x800;
    } else if ((b0 & 0xF8) == 0xF0) {
      cp = b0 & 0x07U;
      extra = 3;
      min_cp = 0x10000;
    } else {
      return bad();
    }
    if (static_cast<std::size_t>(extra) >= text.size() - i) return bad();  // truncated sequence
    for (int k = 1; k <= extra; ++k) {
      const auto b = static_cast<unsigned char>(text[i + static_cast<std::size_t>(k)]);
      if ((b & 0xC0) != 0x80) return bad();
      cp = (cp << 6) | (b & 0x3FU);
    }
    // Overlong forms, UTF-16 surrogates and code points past U+10FFFF are not UTF-8 (RFC 3629).
    if (cp < min_cp || (cp >= 0xD800 && cp <= 0xDFFF) || cp > 0x10FFFF) return bad();
    if (cp >= 0x10000) {
      const std::uint32_t v = cp - 0x10000;
      put_utf16le(out, 0xD800 + (v >> 10));
      put_utf16le(out, 0xDC00 + (v & 0x3FF));
    } else {
      put_utf16le(out, cp);
    }
    i += 1 + static_cast<std::size_t>(extra);
  }
  return Value::from_bytes(DataType::UnicodeString, std::move(out));
}

void put_utf8(std::string& out, std::uint32_t cp) {
  if (cp < 0x80) {
    out.push_back(static_cast<char>(cp));
  } else if (cp < 0x800) {
    out.push_back(static_cast<char>(0xC0 | (cp >> 6)));
    out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  } else if (cp < 0x10000) {
    out.push_back(static_cast<char>(0xE0 | (cp >> 12)));
    out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  } else {
    out.push_back(static_cast<char>(0xF0 | (cp >> 18)));
    out.push_back(static_cast<char>(0x80 | ((cp >> 12) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | ((cp >> 6) & 0x3F)));
    out.push_back(static_cast<char>(0x80 | (cp & 0x3F)));
  }
}

// UTF-16LE bytes to UTF-8; unpaired surrogates (and an odd last byte) become U+FFFD.
std::string utf16le_to_utf8(const std::string& bytes) {
  std::string out;
  auto unit = [&](std::size_t i) {
    return static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) |
           static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8;
  };
  std::size_t i = 0;
  while (i + 1 < bytes.size()) {
    const std::uint32_t u = unit(i);
    i += 2;
    if (u >= 0xD800 && u <= 0xDBFF && i + 1 < bytes.size()) {
      const std::uint32_t low = unit(i);
      if (low >= 0xDC00 && low <= 0xDFFF) {
        i += 2;
        put_utf8(out, 0x10000 + ((u - 0xD800) << 10) + (low - 0xDC00));
        continue;
      }
    }
    put_utf8(out, (u >= 0xD800 && u <= 0xDFFF) ? 0xFFFD : u);
  }
  if (i < bytes.size()) put_utf8(out, 0xFFFD);
  return out;
}

std::string hex_pairs(const std::string& bytes, std::string_view separator,
                      std::size_t max_bytes = std::string::npos) {
  static constexpr char kDigits[] = "0123456789ABCDEF";
  std::string out;
  for (std::size_t i = 0; i < bytes.size() && i < max_bytes; ++i) {
    if (i > 0) out += separator;
    const auto b = static_cast<unsigned char>(bytes[i]);
    out.push_back(kDigits[b >> 4]);
    out.push_back(kDigits[b & 0xF]);
  }
  return out;
}

std::string format_real(const Value& value) {
  std::array<char, 64> buf{};
  std::to_chars_result r{};
  if (value.type() == DataType::Real32) {
    r = std::to_chars(buf.data(), buf.data() + buf.size(), static_cast<float>(value.as_real()));
  } else {
    r = std::to_chars(buf.data(), buf.data() + buf.size(), value.as_real());
  }
  return std::string(buf.data(), r.ptr);
}

}  // namespace

std::int64_t signed_min(DataType type) {
  const unsigned bits = static_cast<unsigned>(data_type_info(type).size_bytes) * 8U;
  if (bits == 0 || bits >= 64) return std::numeric_limits<std::int64_t>::min();
  return -(std::int64_t{1} << (bits - 1));
}

std::int64_t signed_max(DataType type) {
  const unsigned bits = static_cast<unsigned>(data_type_info(type).size_bytes) * 8U;
  if (bits == 0 || bits >= 64) return std::numeric_limits<std::int64_t>::max();
  return (std::int64_t{1} << (bits - 1)) - 1;
}

std::uint64_t unsigned_max(DataType type) {
  if (type == DataType::Boolean) return 1;
  const unsigned bits = static_cast<unsigned>(data_type_info(type).size_bytes) * 8U;
  if (bits == 0 || bits >= 64) return std::numeric_limits<std::uint64_t>::max();
  return (std::uint64_t{1} << bits) - 1;
}

bool mentions_node_id(std::string_view text) {
  // The token starts with '$', which nearly no value has: look for that byte first.
  for (std::size_t i = text.find('$'); i != std::string_view::npos; i = text.find('$', i + 1)) {
    if (iequals(text.substr(i, kNodeIdToken.size()), kNodeIdToken)) return true;
  }
  return false;
}

Result<Value> integer_value(DataType type, IntegerLiteral literal) {
  switch (data_type_info(type).type_class) {
    case TypeClass::Boolean:
    case TypeClass::Unsigned:
      return unsigned_value(type, literal.value);
    case TypeClass::Signed:
      return signed_value(type, IntegerText{literal.value, false, literal.is_hex}, {});
    default:
      return Error{std::string(to_string(type)) + " is not an integer type"};
  }
}

Result<Value> parse_value(DataType type, std::string_view text,
                          std::optional<std::uint8_t> node_id) {
  const auto& info = data_type_info(type);
  switch (info.type_class) {
    case TypeClass::VisibleString:
      return Value::from_bytes(type, std::string(text));
    case TypeClass::UnicodeString:
      return parse_unicode(text);
    case TypeClass::OctetString:
    case TypeClass::Domain:
      return parse_hex_bytes(type, text);
    default:
      break;
  }
  const std::string_view t = trim(text);
  if (t.empty()) return Error{"empty value for " + std::string(info.name)};
  switch (info.type_class) {
    case TypeClass::Boolean:
      if (iequals(t, "true")) return Value::from_bool(true);
      if (iequals(t, "false")) return Value::from_bool(false);
      return parse_unsigned(type, t, node_id);
    case TypeClass::Unsigned:
      return parse_unsigned(type, t, node_id);
    case TypeClass::Time:
      return parse_time(type, t, node_id);
    case TypeClass::Signed:
      return parse_signed(type, t, node_id);
    case TypeClass::Real:
      return parse_real(type, t);
    default:
      break;
  }
  return Error{"cannot parse a value of type " + std::string(info.name)};
}

std::vector<std::uint8_t> encode(const Value& value) {
  const auto& info = data_type_info(value.type());
  std::vector<std::uint8_t> out;
  out.reserve(info.size_bytes);  // one allocation for fixed-size types
  auto put_le = [&](std::uint64_t bits, std::size_t size) { append_le(out, bits, size); };
  switch (info.type_class) {
    case TypeClass::Boolean:
      out.push_back(value.as_bool() ? 1 : 0);
      break;
    case TypeClass::Signed:
      put_le(std::bit_cast<std::uint64_t>(value.as_signed()), info.size_bytes);
      break;
    case TypeClass::Unsigned:
    case TypeClass::Time:
      put_le(value.as_unsigned(), info.size_bytes);
      break;
    case TypeClass::Real:
      if (value.type() == DataType::Real32) {
        put_le(std::bit_cast<std::uint32_t>(static_cast<float>(value.as_real())), 4);
      } else {
        put_le(std::bit_cast<std::uint64_t>(value.as_real()), 8);
      }
      break;
    case TypeClass::VisibleString:
    case TypeClass::OctetString:
    case TypeClass::UnicodeString:
    case TypeClass::Domain:
      out.assign(value.as_bytes().begin(), value.as_bytes().end());
      break;
  }
  return out;
}

Result<Value> decode(DataType type, std::span<const std::uint8_t> bytes) {
  const auto& info = data_type_info(type);
  if (info.size_bytes != 0 && bytes.size() != info.size_bytes) {
    return Error{std::string(info.name) + " needs " + std::to_string(info.size_bytes) +
                 " byte(s), got " + std::to_string(bytes.size())};
  }
  // Fixed-size types are 1..8 bytes (CiA 301 §7.1); the size was checked above.
  const std::uint64_t le = info.size_bytes != 0 ? load_le(bytes, bytes.size()) : 0;
  switch (info.type_class) {
    case TypeClass::Boolean:
      if (le > 1) return Error{"BOOLEAN byte " + hex(le, 2) + " is neither 0 nor 1"};
      return Value::from_bool(le == 1);
    case TypeClass::Signed:
      return Value::from_signed(type, sign_extend(le, info.size_bytes * 8U));
    case TypeClass::Unsigned:
    case TypeClass::Time:
      return Value::from_unsigned(type, le);
    case TypeClass::Real:
      if (type == DataType::Real32) {
        return Value::from_real(
            type, static_cast<double>(std::bit_cast<float>(static_cast<std::uint32_t>(le))));
      }
      return Value::from_real(type, std::bit_cast<double>(le));
    case TypeClass::UnicodeString:
      if (bytes.size() % 2 != 0) {
        return Error{"UNICODE_STRING needs an even number of bytes (UTF-16), got " +
                     std::to_string(bytes.size())};
      }
      [[fallthrough]];
    case TypeClass::VisibleString:
    case TypeClass::OctetString:
    case TypeClass::Domain:
      return Value::from_bytes(type, std::string(bytes.begin(), bytes.end()));
  }
  return Error{"cannot decode a value of type " + std::string(info.name)};
}

std::string format_value(const Value& value) {
  switch (data_type_info(value.type()).type_class) {
    case TypeClass::Boolean:
      return value.as_bool() ? "1" : "0";
    case TypeClass::Signed:
      return std::to_string(value.as_signed());
    case TypeClass::Unsigned:
    case TypeClass::Time:
      return hex(value.as_unsigned());
    case TypeClass::Real:
      return format_real(value);
    case TypeClass::VisibleString:
      return value.as_bytes();
    case TypeClass::UnicodeString:
      return utf16le_to_utf8(value.as_bytes());
    case TypeClass::OctetString:
    case TypeClass::Domain:
      return hex_pairs(value.as_bytes(), "");
  }
  return {};
}

std::string describe_value(const Value& value) {
  const auto& info = data_type_info(value.type());
  switch (info.type_class) {
    case TypeClass::Boolean:
      return value.as_bool() ? "true" : "false";
    case TypeClass::Signed:
      return std::to_string(value.as_signed());
    case TypeClass::Unsigned:
    case TypeClass::Time:
      return std::to_string(value.as_unsigned()) + " (" +
             hex(value.as_unsigned(), info.size_bytes * 2) + ")";
    case TypeClass::Real:
      return format_real(value);
    case TypeClass::VisibleString:
    case TypeClass::UnicodeString: {
      const std::string text = info.type_class == TypeClass::UnicodeString
                                   ? utf16le_to_utf8(value.as_bytes())
                                   : value.as_bytes();
      std::string out = "\"";
      for (char c : text) {
        const auto b = static_cast<unsigned char>(c);
        if (b < 0x20 || b == 0x7F) {
          out += "\\x" + hex(b, 2).substr(2);
        } else if (c == '"' || c == '\\') {
          out += '\\';
          out += c;
        } else {
          out += c;
        }
      }
      return out + "\"";
    }
    case TypeClass::OctetString:
    case TypeClass::Domain: {
      constexpr std::size_t kShown = 32;
      const auto& bytes = value.as_bytes();
      std::string out = hex_pairs(bytes, " ", kShown);
      if (bytes.size() > kShown) out += " ...";
      return out + (out.empty() ? "" : " ") + "(" + std::to_string(bytes.size()) + " byte" +
             (bytes.size() == 1 ? "" : "s") + ")";
    }
  }
  return {};
}

std::optional<int> compare_values(const Value& a, const Value& b) {
  if (a.type() != b.type()) return std::nullopt;
  auto order = [](auto x, auto y) { return x < y ? -1 : (x > y ? 1 : 0); };
  switch (data_type_info(a.type()).type_class) {
    case TypeClass::Signed:
      return order(a.as_signed(), b.as_signed());
    case TypeClass::Unsigned:
      return order(a.as_unsigned(), b.as_unsigned());
    case TypeClass::Real: {
      const double x = a.as_real(), y = b.as_real();
      if (std::isnan(x) || std::isnan(y)) return std::nullopt;
      return order(x, y);
    }
    default:
      return std::nullopt;
  }
}

std::optional<std::uint8_t> node_id_of_default(DataType type, std::string_view default_text,
                                               std::string_view value_text) {
  if (!mentions_node_id(default_text) || mentions_node_id(value_text)) return std::nullopt;
  const auto value = parse_value(type, value_text);
  if (!value) return std::nullopt;
  for (unsigned n = 1; n <= 127; ++n) {
    const auto at = parse_value(type, default_text, static_cast<std::uint8_t>(n));
    if (at && *at == *value) return static_cast<std::uint8_t>(n);
  }
  return std::nullopt;
}

bool is_default_at(DataType type, std::string_view default_text, std::string_view value_text,
                   std::uint8_t node_id) {
  if (!mentions_node_id(default_text) || mentions_node_id(value_text)) return false;
  const auto value = parse_value(type, value_text);
  const auto at = parse_value(type, default_text, node_id);
  return value && at && *value == *at;
}

std::optional<std::uint8_t> recorded_node_id(const DeviceDescription& device) {
  const std::optional<std::uint8_t> own = device.node_id();
  std::optional<std::uint8_t> sdo_server, agreed;
  unsigned agreeing = 0;
  bool disagree = false, at_own = false;
  for (const auto& [index, object] : device.objects) {
    for (const auto& [sub_index, sub] : object.subs) {
      if (!sub.parameter_value || !sub.default_value) continue;
      const auto type = sub.basic_type();
      if (!type) continue;
      const auto at = node_id_of_default(*type, *sub.default_value, *sub.parameter_value);
      if (!at) continue;
      if (index == 0x1200 && (sub_index == 1 || sub_index == 2) && !sdo_server) sdo_server = at;
      if (own && *at == *own) at_own = true;
      if (!agreed) agreed = at;
      if (*agreed == *at) {
        ++agreeing;
      } else {
        disagree = true;
      }
    }
  }
  if (sdo_server) return sdo_server;
  if (agreed && agreeing >= 2 && !disagree && !at_own) return agreed;
  return own;
}

}  // namespace cfg
