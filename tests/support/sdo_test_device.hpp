// A device description written for the SDO and object dictionary tests: one entry per rule the
// tests exercise (access types, fixed and variable sizes, limits, $NODEID values).
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cfg/object_dictionary.hpp"

namespace test_support {

struct SubSpec {
  std::uint8_t sub = 0;
  cfg::DataType type = cfg::DataType::Unsigned8;
  cfg::AccessType access = cfg::AccessType::Rw;
  std::optional<std::string> default_value;
  std::optional<std::string> low_limit = std::nullopt;
  std::optional<std::string> high_limit = std::nullopt;
  std::optional<std::string> parameter_value = std::nullopt;
};

inline void add_var(cfg::DeviceDescription& d, std::uint16_t index, SubSpec spec) {
  cfg::Object o;
  o.index = index;
  o.object_type =
      spec.type == cfg::DataType::Domain ? cfg::ObjectType::Domain : cfg::ObjectType::Var;
  cfg::SubObject s;
  s.sub_index = 0;
  s.data_type = static_cast<std::uint16_t>(spec.type);
  s.access = spec.access;
  s.default_value = spec.default_value;
  s.parameter_value = spec.parameter_value;
  s.low_limit = spec.low_limit;
  s.high_limit = spec.high_limit;
  o.subs.emplace(0, s);
  d.objects.emplace(index, o);
}

inline void add_record(cfg::DeviceDescription& d, std::uint16_t index,
                       const std::vector<SubSpec>& subs) {
  cfg::Object o;
  o.index = index;
  o.object_type = cfg::ObjectType::Record;
  for (const auto& spec : subs) {
    cfg::SubObject s;
    s.sub_index = spec.sub;
    s.data_type = static_cast<std::uint16_t>(spec.type);
    s.access = spec.access;
    s.default_value = spec.default_value;
    s.parameter_value = spec.parameter_value;
    s.low_limit = spec.low_limit;
    s.high_limit = spec.high_limit;
    o.subs.emplace(spec.sub, s);
  }
  d.objects.emplace(index, o);
}

/// The test device. Values chosen so frames are easy to check by eye.
inline cfg::DeviceDescription sdo_test_device() {
  using cfg::AccessType;
  using cfg::DataType;
  cfg::DeviceDescription d;
  add_var(d, 0x1000, {0, DataType::Unsigned32, AccessType::Ro, "0x00020191"});
  add_var(d, 0x1001, {0, DataType::Unsigned8, AccessType::Ro, "0"});
  // 20 characters: "CANopen test device!"
  add_var(d, 0x1008, {0, DataType::VisibleString, AccessType::Const, "CANopen test device!"});
  add_var(d, 0x1017, {0, DataType::Unsigned16, AccessType::Rw, "0"});
  add_record(d, 0x1018,
             {{0, DataType::Unsigned8, AccessType::Ro, "4"},
              {1, DataType::Unsigned32, AccessType::Ro, "0x12345678"},
              {2, DataType::Unsigned32, AccessType::Ro, "0x00000401"},
              {3, DataType::Unsigned32, AccessType::Ro, "0x00010002"},
              {4, DataType::Unsigned32, AccessType::Ro, "0x0000CAFE"}});
  add_record(d, 0x1200,
             {{0, DataType::Unsigned8, AccessType::Ro, "2"},
              {1, DataType::Unsigned32, AccessType::Ro, "$NODEID+0x600"},
              {2, DataType::Unsigned32, AccessType::Ro, "$NODEID+0x580"}});
  add_var(d, 0x2000, {0, DataType::Domain, AccessType::Rw, std::nullopt});
  add_var(d, 0x2001, {0, DataType::Unsigned8, AccessType::Wo, "0"});
  add_var(d, 0x2002, {0, DataType::Integer16, AccessType::Rw, "0", "-100", "100"});
  add_var(d, 0x2003, {0, DataType::Unsigned32, AccessType::Rw, "10", "10", "1000"});
  add_var(d, 0x2004, {0, DataType::Boolean, AccessType::Rw, "0"});
  add_var(d, 0x2005, {0, DataType::VisibleString, AccessType::Rw, "abc"});
  add_var(d, 0x2006, {0, DataType::Unsigned16, AccessType::Const, "0x1234"});
  // HighLimit below LowLimit: every write is refused with 0609 0036.
  add_var(d, 0x2007, {0, DataType::Unsigned8, AccessType::Rw, "7", "10", "5"});
  add_var(d, 0x2008, {0, DataType::Real32, AccessType::Rw, "0", "-1.5", "2.5"});
  add_var(d, 0x2009, {0, DataType::Unsigned64, AccessType::Rw, "0x0102030405060708"});
  add_var(d, 0x200A, {0, DataType::Integer24, AccessType::Rw, "-2"});
  add_var(d, 0x200B, {0, DataType::UnicodeString, AccessType::Rw, std::nullopt});
  add_var(d, 0x200C, {0, DataType::Unsigned32, AccessType::Rww, "$NODEID+0x180"});
  add_var(d, 0x200D,
          {0, DataType::Unsigned32, AccessType::Rwr, "0x12345678", std::nullopt, std::nullopt,
           "0x0A0B0C0D"});
  return d;
}

}  // namespace test_support
