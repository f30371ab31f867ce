// libFuzzer target: arbitrary text to cfg::parse_value for every basic type.
// Input: byte 0 selects the type (and whether a node-ID is known), the rest is the value text.
// Checks the promises of cfg/value.hpp: no crash; an accepted value encodes to the type's size,
// decodes back to itself, and format_value's text parses back to the same value.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <optional>
#include <string_view>

#include "cfg/data_type.hpp"
#include "cfg/value.hpp"

namespace {

constexpr cfg::DataType kTypes[] = {
    cfg::DataType::Boolean,        cfg::DataType::Integer8,      cfg::DataType::Integer16,
    cfg::DataType::Integer32,      cfg::DataType::Unsigned8,     cfg::DataType::Unsigned16,
    cfg::DataType::Unsigned32,     cfg::DataType::Real32,        cfg::DataType::VisibleString,
    cfg::DataType::OctetString,    cfg::DataType::UnicodeString, cfg::DataType::TimeOfDay,
    cfg::DataType::TimeDifference, cfg::DataType::Domain,        cfg::DataType::Integer24,
    cfg::DataType::Real64,         cfg::DataType::Integer40,     cfg::DataType::Integer48,
    cfg::DataType::Integer56,      cfg::DataType::Integer64,     cfg::DataType::Unsigned24,
    cfg::DataType::Unsigned40,     cfg::DataType::Unsigned48,    cfg::DataType::Unsigned56,
    cfg::DataType::Unsigned64,
};
constexpr std::size_t kTypeCount = sizeof(kTypes) / sizeof(kTypes[0]);

bool is_nan(const cfg::Value& v) {
  return cfg::data_type_info(v.type()).type_class == cfg::TypeClass::Real &&
         std::isnan(v.as_real());
}

void check(bool condition) {
  if (!condition) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  const cfg::DataType type = kTypes[data[0] % kTypeCount];
  const std::optional<std::uint8_t> node_id =
      (data[0] / kTypeCount) % 2 == 0 ? std::optional<std::uint8_t>(0x7F) : std::nullopt;
  const std::string_view text(reinterpret_cast<const char*>(data + 1), size - 1);

  auto parsed = cfg::parse_value(type, text, node_id);
  if (!parsed) {
    check(!parsed.error().message.empty());
    return 0;
  }
  const cfg::Value& value = parsed.value();
  check(value.type() == type);

  const auto bytes = cfg::encode(value);
  const auto& info = cfg::data_type_info(type);
  if (info.size_bytes != 0) check(bytes.size() == info.size_bytes);
  auto decoded = cfg::decode(type, bytes);
  check(decoded.ok());
  if (!is_nan(value)) check(decoded.value() == value);

  auto reparsed = cfg::parse_value(type, cfg::format_value(value));
  check(reparsed.ok());
  if (!is_nan(value)) check(reparsed.value() == value);
  (void)cfg::describe_value(value);
  return 0;
}
