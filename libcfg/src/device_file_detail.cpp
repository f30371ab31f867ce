#include "device_file_detail.hpp"

#include <array>

#include "cfg/data_type.hpp"
#include "ini_scanner.hpp"

namespace cfg::detail {
namespace {

bool is_hex_digit(char c) {
  return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F');
}

}  // namespace

bool is_reserved_section_name(std::string_view name) {
  for (std::string_view known :
       {"FileInfo", "DeviceInfo", "DummyUsage", "Comments", "MandatoryObjects", "OptionalObjects",
        "ManufacturerObjects", "DeviceComissioning", "DeviceCommissioning"}) {
    if (iequals(name, known)) return true;
  }
  if (name.size() < 4) return false;
  for (std::size_t i = 0; i < 4; ++i) {
    if (!is_hex_digit(name[i])) return false;
  }
  const std::string_view rest = name.substr(4);
  return rest.empty() || (rest.size() >= 3 && iequals(rest.substr(0, 3), "sub")) ||
         iequals(rest, "Name") || iequals(rest, "Value") || iequals(rest, "Denotation") ||
         iequals(rest, "ObjectLinks");
}

bool is_numeric_device_info_key(std::string_view key) {
  for (std::string_view k : {"VendorNumber",      "ProductNumber", "RevisionNumber",
                             "BaudRate_10",       "BaudRate_20",   "BaudRate_50",
                             "BaudRate_125",      "BaudRate_250",  "BaudRate_500",
                             "BaudRate_800",      "BaudRate_1000", "SimpleBootUpMaster",
                             "SimpleBootUpSlave", "Granularity",   "DynamicChannelsSupported",
                             "GroupMessaging",    "NrOfRXPDO",     "NrOfTXPDO",
                             "LSS_Supported",     "CompactPDO"}) {
    if (iequals(k, key)) return true;
  }
  return false;
}

std::size_t find_inline_comment(std::string_view text) {
  for (std::size_t i = 0; i < text.size(); ++i) {
    if ((text[i] == ';' || text[i] == '#') && (i == 0 || is_blank(text[i - 1]))) return i;
  }
  return std::string_view::npos;
}

std::optional<std::string> h_suffix_digits(std::string_view text) {
  if (text.size() < 2 || (text.back() != 'h' && text.back() != 'H')) return std::nullopt;
  std::string digits;
  const std::string_view body = text.substr(0, text.size() - 1);
  for (std::size_t i = 0; i < body.size(); ++i) {
    const char c = body[i];
    if (is_hex_digit(c)) {
      digits.push_back(c);
    } else if (c == ' ' && i > 0 && i + 1 < body.size() && is_hex_digit(body[i - 1]) &&
               is_hex_digit(body[i + 1])) {
      continue;  // a blank between digit groups
    } else {
      return std::nullopt;
    }
  }
  if (digits.empty() || digits.size() > 16) return std::nullopt;
  return digits;
}

namespace {

bool is_free_text(const DataTypeInfo* info) {
  return info == nullptr || info->type_class == TypeClass::VisibleString ||
         info->type_class == TypeClass::UnicodeString;
}

}  // namespace

NormalizedValue normalize_value(std::string_view text, std::uint16_t data_type) {
  NormalizedValue out;
  const DataTypeInfo* info = find_data_type(data_type);
  const bool free_text = is_free_text(info);
  if (!free_text) {
    const std::size_t c = find_inline_comment(text);
    if (c != std::string_view::npos) {
      out.comment = text.substr(c);
      text = trim_blanks(text.substr(0, c));
    }
  }
  if (text.empty()) {
    if (info != nullptr && is_variable_size(info->type)) out.text.emplace();
    return out;
  }
  if (info != nullptr) {
    const TypeClass tc = info->type_class;
    if (tc == TypeClass::Signed || tc == TypeClass::Unsigned || tc == TypeClass::Boolean ||
        tc == TypeClass::Time) {
      if (auto digits = h_suffix_digits(text)) {
        out.h_suffix = true;
        out.text = "0x" + *digits;
        return out;
      }
    }
    // Vendor tools export DOMAIN/OCTET_STRING values as one 0x-prefixed run of hex digits; the
    // model keeps the digits, the form the writer writes (bytes unchanged).
    if ((tc == TypeClass::OctetString || tc == TypeClass::Domain) && text.size() > 2 &&
        text[0] == '0' && (text[1] == 'x' || text[1] == 'X') &&
        !trim_blanks(text.substr(2)).empty()) {
      out.text.emplace(trim_blanks(text.substr(2)));
      return out;
    }
  }
  out.text.emplace(text);
  return out;
}

// Each test mirrors one step of normalize_value above that could change the text.
bool is_normalized_value(std::string_view text, std::uint16_t data_type) {
  // One pass: a line break (the writer's one-line rule) or a ';'/'#' anywhere (an inline
  // comment starts with one) sends the text to the exact path.
  static constexpr std::array<bool, 256> kStop = [] {
    std::array<bool, 256> t{};
    for (const char c : {'\r', '\n', ';', '#'}) t[static_cast<unsigned char>(c)] = true;
    return t;
  }();
  for (const char c : text) {
    if (kStop[static_cast<unsigned char>(c)]) return false;
  }
  const DataTypeInfo* info = find_data_type(data_type);
  if (text.empty()) return info != nullptr && is_variable_size(info->type);  // kept as ""
  if (is_blank(text.front()) || is_blank(text.back())) return false;
  if (is_free_text(info)) return true;
  const TypeClass tc = info->type_class;
  if (tc == TypeClass::Signed || tc == TypeClass::Unsigned || tc == TypeClass::Boolean ||
      tc == TypeClass::Time) {
    return text.back() != 'h' && text.back() != 'H';  // maybe 'h'-suffix hex
  }
  if (tc == TypeClass::OctetString || tc == TypeClass::Domain) {
    return !(text.size() > 2 && text[0] == '0' && (text[1] == 'x' || text[1] == 'X'));
  }
  return true;
}

}  // namespace cfg::detail
