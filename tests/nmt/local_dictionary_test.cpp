// Runtime object dictionary: values from a device description, and the SDO access rules with
// the abort codes of the CiA 301 abort code table (public knowledge of CiA 301; not in spec/).
#include "nmt/slave/local_dictionary.hpp"

#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <filesystem>
#include <limits>
#include <type_traits>

#include "cfg/device_file.hpp"
#include "prerequisite.hpp"
#include "sdo_test_device.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using Bytes = std::vector<std::uint8_t>;
constexpr TimePoint kNow{};  // the time of an access only matters to the hooks

LocalDictionary make(std::uint8_t node_id = 5) {
  auto d =
      LocalDictionary::from_device(test_support::sdo_test_device(), *cfg::NodeId::from(node_id));
  EXPECT_TRUE(d.ok()) << (d.ok() ? "" : d.error().message);
  return std::move(d).value();
}

Bytes read(const LocalDictionary& d, std::uint16_t index, std::uint8_t sub) {
  Bytes out;
  EXPECT_EQ(d.read(index, sub, out, kNow), SdoAbort::None);
  return out;
}

Bytes real32(float v) {
  auto u = std::bit_cast<std::uint32_t>(v);
  return {static_cast<std::uint8_t>(u), static_cast<std::uint8_t>(u >> 8),
          static_cast<std::uint8_t>(u >> 16), static_cast<std::uint8_t>(u >> 24)};
}

// --- building ------------------------------------------------------------------------------

TEST(LocalDictionary, ValuesAreLittleEndianBytesOfTheConfiguredValue) {
  auto d = make(5);
  EXPECT_EQ(read(d, 0x1000, 0), (Bytes{0x91, 0x01, 0x02, 0x00}));  // 0x00020191
  EXPECT_EQ(read(d, 0x1017, 0), (Bytes{0x00, 0x00}));
  EXPECT_EQ(read(d, 0x1018, 0), (Bytes{0x04}));
  EXPECT_EQ(read(d, 0x2009, 0), (Bytes{8, 7, 6, 5, 4, 3, 2, 1}));
  EXPECT_EQ(read(d, 0x200A, 0), (Bytes{0xFE, 0xFF, 0xFF}));  // INTEGER24 -2: three bytes
  EXPECT_EQ(read(d, 0x1008, 0), (Bytes{'C', 'A', 'N', 'o', 'p', 'e', 'n', ' ', 't', 'e',
                                       's', 't', ' ', 'd', 'e', 'v', 'i', 'c', 'e', '!'}));
  EXPECT_TRUE(read(d, 0x2000, 0).empty());  // DOMAIN without a value
}

TEST(LocalDictionary, ResolvesNodeIdInValues) {
  // $NODEID+0x600 for node 5 is 0x605 (CiA 301 pre-defined connection set).
  EXPECT_EQ(read(make(5), 0x1200, 1), (Bytes{0x05, 0x06, 0x00, 0x00}));
  EXPECT_EQ(read(make(0x7F), 0x1200, 2), (Bytes{0xFF, 0x05, 0x00, 0x00}));
  EXPECT_EQ(read(make(5), 0x200C, 0), (Bytes{0x85, 0x01, 0x00, 0x00}));
  EXPECT_EQ(make(9).node_id(), 9);
}

TEST(LocalDictionary, ParameterValueWinsOverDefaultValue) {
  EXPECT_EQ(read(make(), 0x200D, 0), (Bytes{0x0D, 0x0C, 0x0B, 0x0A}));
}

TEST(LocalDictionary, KeepsAttributesOfEachEntry) {
  auto d = make();
  const auto* e = d.entry(0x2002, 0);
  ASSERT_NE(e, nullptr);
  EXPECT_EQ(e->basic_type, cfg::DataType::Integer16);
  EXPECT_EQ(e->access, cfg::AccessType::Rw);
  ASSERT_TRUE(e->low_limit && e->high_limit);
  EXPECT_EQ(e->low_limit->as_signed(), -100);
  EXPECT_EQ(e->high_limit->as_signed(), 100);
  EXPECT_EQ(e->fixed_size(), 2u);
  EXPECT_EQ(d.entry(0x2000, 0)->fixed_size(), std::nullopt);
  EXPECT_EQ(d.entry(0x2000, 0)->max_size, LocalDictionary::kDefaultMaxVariableSize);
  EXPECT_EQ(d.entry(0x2001, 1), nullptr);
  EXPECT_TRUE(d.has_object(0x1018));
  EXPECT_FALSE(d.has_object(0x1019));
}

// The node-ID is a cfg::NodeId: 0 and 128 cannot reach from_device (NodeId::from refuses them).
TEST(LocalDictionary, RejectsNodeIdOutsideOneTo127) {
  static_assert(!std::is_invocable_v<decltype(&LocalDictionary::from_device),
                                     const cfg::DeviceDescription&, int>);
  EXPECT_FALSE(cfg::NodeId::from(0).has_value());
  EXPECT_FALSE(cfg::NodeId::from(128).has_value());
}

TEST(LocalDictionary, RejectsValueThatDoesNotFitItsTypeNamingTheEntry) {
  auto device = test_support::sdo_test_device();
  device.sub(0x1017, 0)->default_value = "70000";  // UNSIGNED16 holds at most 65535
  auto d = LocalDictionary::from_device(device, *cfg::NodeId::from(1));
  ASSERT_FALSE(d.ok());
  // The one way messages write an address (cfg/object_address.hpp).
  EXPECT_NE(d.error().message.find("object 1017h sub 00h: "), std::string::npos)
      << d.error().message;
  EXPECT_NE(d.error().message.find("DefaultValue"), std::string::npos) << d.error().message;
}

// --- read ------------------------------------------------------------------------------------

TEST(LocalDictionary, ReadAbortsWithObjectDoesNotExist) {
  Bytes out;
  EXPECT_EQ(make().read(0x3000, 0, out, kNow), SdoAbort::ObjectDoesNotExist);
}

TEST(LocalDictionary, ReadAbortsWithSubIndexDoesNotExist) {
  Bytes out;
  EXPECT_EQ(make().read(0x1018, 5, out, kNow), SdoAbort::SubIndexDoesNotExist);
}

TEST(LocalDictionary, ReadOfWriteOnlyAborts) {
  Bytes out;
  EXPECT_EQ(make().read(0x2001, 0, out, kNow), SdoAbort::ReadOfWriteOnly);
}

// --- write: existence and access -------------------------------------------------------------

TEST(LocalDictionary, WriteAbortsWithObjectOrSubIndexDoesNotExist) {
  auto d = make();
  EXPECT_EQ(d.write(0x3000, 0, Bytes{1}, kNow), SdoAbort::ObjectDoesNotExist);
  EXPECT_EQ(d.write(0x1018, 9, Bytes{1, 0, 0, 0}, kNow), SdoAbort::SubIndexDoesNotExist);
}

TEST(LocalDictionary, WriteOfReadOnlyAndConstAborts) {
  auto d = make();
  EXPECT_EQ(d.write(0x1000, 0, Bytes{0, 0, 0, 0}, kNow), SdoAbort::WriteOfReadOnly);
  EXPECT_EQ(d.write(0x2006, 0, Bytes{0, 0}, kNow), SdoAbort::WriteOfReadOnly);  // const
  EXPECT_EQ(read(d, 0x2006, 0), (Bytes{0x34, 0x12}));
}

TEST(LocalDictionary, WritesToRwRwwRwrAndWo) {
  auto d = make();
  EXPECT_EQ(d.write(0x1017, 0, Bytes{0xE8, 0x03}, kNow), SdoAbort::None);
  EXPECT_EQ(read(d, 0x1017, 0), (Bytes{0xE8, 0x03}));
  EXPECT_EQ(d.write(0x200C, 0, Bytes{1, 2, 3, 4}, kNow), SdoAbort::None);  // rww
  EXPECT_EQ(d.write(0x200D, 0, Bytes{1, 2, 3, 4}, kNow), SdoAbort::None);  // rwr
  EXPECT_EQ(d.write(0x2001, 0, Bytes{7}, kNow), SdoAbort::None);           // wo
  EXPECT_EQ(d.get_unsigned(0x2001, 0), 7u);
}

// --- write: sizes ----------------------------------------------------------------------------

TEST(LocalDictionary, FixedSizeWriteTooLongAbortsWithLengthTooHigh) {
  auto d = make();
  EXPECT_EQ(d.write(0x1017, 0, Bytes{1, 2, 3}, kNow), SdoAbort::LengthTooHigh);
  EXPECT_EQ(d.write(0x200A, 0, Bytes{1, 2, 3, 4}, kNow), SdoAbort::LengthTooHigh);  // INTEGER24
  EXPECT_EQ(read(d, 0x1017, 0), (Bytes{0, 0}));
}

TEST(LocalDictionary, FixedSizeWriteTooShortAbortsWithLengthTooLow) {
  auto d = make();
  EXPECT_EQ(d.write(0x1017, 0, Bytes{1}, kNow), SdoAbort::LengthTooLow);
  EXPECT_EQ(d.write(0x2009, 0, Bytes{1, 2, 3, 4, 5, 6, 7}, kNow), SdoAbort::LengthTooLow);
  EXPECT_EQ(d.write(0x2004, 0, Bytes{}, kNow), SdoAbort::LengthTooLow);
}

TEST(LocalDictionary, StringsMayChangeLength) {
  auto d = make();
  const Bytes text{'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd'};
  EXPECT_EQ(d.write(0x2005, 0, text, kNow), SdoAbort::None);
  EXPECT_EQ(read(d, 0x2005, 0), text);
  EXPECT_EQ(d.write(0x2005, 0, Bytes{}, kNow), SdoAbort::None);
  EXPECT_TRUE(read(d, 0x2005, 0).empty());
}

TEST(LocalDictionary, DomainWriteAboveItsSizeLimitAbortsWithLengthTooHigh) {
  auto d = make();
  ASSERT_TRUE(d.set_max_size(0x2000, 0, 16));
  EXPECT_EQ(d.write(0x2000, 0, Bytes(17, 0xAA), kNow), SdoAbort::LengthTooHigh);
  EXPECT_EQ(d.write(0x2000, 0, Bytes(16, 0xAA), kNow), SdoAbort::None);
  EXPECT_EQ(read(d, 0x2000, 0), Bytes(16, 0xAA));
  EXPECT_EQ(d.check_write(0x2000, 0, 17), SdoAbort::LengthTooHigh);
  EXPECT_FALSE(d.set_max_size(0x1017, 0, 16));  // fixed size
}

TEST(LocalDictionary, UnicodeStringOfOddLengthAbortsWithLengthMismatch) {
  auto d = make();
  EXPECT_EQ(d.write(0x200B, 0, Bytes{'A', 0, 'B'}, kNow), SdoAbort::LengthMismatch);
  EXPECT_EQ(d.write(0x200B, 0, Bytes{'A', 0, 'B', 0}, kNow), SdoAbort::None);
}

// --- write: values ---------------------------------------------------------------------------

TEST(LocalDictionary, ValueAboveHighLimitAbortsWithValueTooHigh) {
  auto d = make();
  EXPECT_EQ(d.write(0x2002, 0, Bytes{101, 0}, kNow),
            SdoAbort::ValueTooHigh);  // INTEGER16 101 > 100
  EXPECT_EQ(d.write(0x2003, 0, Bytes{0xE9, 0x03, 0, 0}, kNow), SdoAbort::ValueTooHigh);  // 1001
  EXPECT_EQ(d.write(0x2008, 0, real32(2.75f), kNow), SdoAbort::ValueTooHigh);
}

TEST(LocalDictionary, ValueBelowLowLimitAbortsWithValueTooLow) {
  auto d = make();
  EXPECT_EQ(d.write(0x2002, 0, Bytes{0x9B, 0xFF}, kNow), SdoAbort::ValueTooLow);  // -101
  EXPECT_EQ(d.write(0x2003, 0, Bytes{9, 0, 0, 0}, kNow), SdoAbort::ValueTooLow);
  EXPECT_EQ(d.write(0x2008, 0, real32(-2.0f), kNow), SdoAbort::ValueTooLow);
}

TEST(LocalDictionary, ValuesAtTheLimitsAreAccepted) {
  auto d = make();
  EXPECT_EQ(d.write(0x2002, 0, Bytes{100, 0}, kNow), SdoAbort::None);
  EXPECT_EQ(d.write(0x2002, 0, Bytes{0x9C, 0xFF}, kNow), SdoAbort::None);  // -100
  EXPECT_EQ(d.write(0x2003, 0, Bytes{0xE8, 0x03, 0, 0}, kNow), SdoAbort::None);
  EXPECT_EQ(d.write(0x2008, 0, real32(-1.5f), kNow), SdoAbort::None);
}

TEST(LocalDictionary, HighLimitBelowLowLimitAbortsWithMaxLessThanMin) {
  EXPECT_EQ(make().write(0x2007, 0, Bytes{7}, kNow), SdoAbort::MaxLessThanMin);
}

TEST(LocalDictionary, BooleanOtherThanZeroOrOneAbortsWithValueRangeExceeded) {
  auto d = make();
  EXPECT_EQ(d.write(0x2004, 0, Bytes{2}, kNow), SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(d.write(0x2004, 0, Bytes{1}, kNow), SdoAbort::None);
}

TEST(LocalDictionary, NanIsOutsideEveryRange) {
  EXPECT_EQ(make().write(0x2008, 0, real32(std::numeric_limits<float>::quiet_NaN()), kNow),
            SdoAbort::ValueRangeExceeded);
}

// --- hooks -----------------------------------------------------------------------------------

TEST(LocalDictionary, WriteHookCanRejectAndValueStays) {
  auto d = make();
  Bytes seen;
  d.add_write_hook(
      [&](std::uint16_t index, std::uint8_t, std::span<const std::uint8_t> data, TimePoint) {
        seen.assign(data.begin(), data.end());
        return index == 0x1017 ? SdoAbort::DeviceState : SdoAbort::None;
      });
  int observed = 0;
  d.add_write_observer(
      [&](std::uint16_t, std::uint8_t, std::span<const std::uint8_t>, TimePoint) { ++observed; });
  EXPECT_EQ(d.write(0x1017, 0, Bytes{0x10, 0x00}, kNow), SdoAbort::DeviceState);
  EXPECT_EQ(seen, (Bytes{0x10, 0x00}));
  EXPECT_EQ(read(d, 0x1017, 0), (Bytes{0, 0}));
  EXPECT_EQ(observed, 0);
  EXPECT_EQ(d.write(0x2002, 0, Bytes{5, 0}, kNow), SdoAbort::None);
  EXPECT_EQ(observed, 1);
}

TEST(LocalDictionary, WriteHookSeesOnlyValuesThatPassedTheChecks) {
  auto d = make();
  int hook_calls = 0;
  d.add_write_hook([&](std::uint16_t, std::uint8_t, std::span<const std::uint8_t>, TimePoint) {
    ++hook_calls;
    return SdoAbort::None;
  });
  EXPECT_EQ(d.write(0x2002, 0, Bytes{101, 0}, kNow), SdoAbort::ValueTooHigh);
  EXPECT_EQ(d.write(0x1000, 0, Bytes{0, 0, 0, 0}, kNow), SdoAbort::WriteOfReadOnly);
  EXPECT_EQ(hook_calls, 0);
}

TEST(LocalDictionary, ObserverSeesTheStoredValueAfterCommit) {
  auto d = make();
  Bytes value_in_dictionary;
  d.add_write_observer(
      [&](std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t>, TimePoint) {
        auto b = d.get_bytes(index, sub);
        value_in_dictionary.assign(b->begin(), b->end());
      });
  EXPECT_EQ(d.write(0x1017, 0, Bytes{0xE8, 0x03}, kNow), SdoAbort::None);
  EXPECT_EQ(value_in_dictionary, (Bytes{0xE8, 0x03}));
}

TEST(LocalDictionary, ReadHookCanRefreshOrRefuse) {
  auto d = make();
  d.add_read_hook([&](std::uint16_t index, std::uint8_t sub, TimePoint) {
    if (index == 0x1001) d.set_unsigned(index, sub, 0x81);  // error register computed on read
    if (index == 0x2005) return SdoAbort::NoDataAvailable;
    return SdoAbort::None;
  });
  EXPECT_EQ(read(d, 0x1001, 0), (Bytes{0x81}));
  Bytes out{9};
  EXPECT_EQ(d.read(0x2005, 0, out, kNow), SdoAbort::NoDataAvailable);
}

TEST(LocalDictionary, HooksAndObserversGetTheTimeOfTheAccess) {
  auto d = make();
  std::vector<TimePoint> times;
  d.add_write_hook([&](auto, auto, auto, TimePoint now) {
    times.push_back(now);
    return SdoAbort::None;
  });
  d.add_write_observer([&](auto, auto, auto, TimePoint now) { times.push_back(now); });
  d.add_read_hook([&](auto, auto, TimePoint now) {
    times.push_back(now);
    return SdoAbort::None;
  });
  ASSERT_EQ(d.write(0x1017, 0, Bytes{1, 0}, TimePoint{std::chrono::milliseconds(3)}),
            SdoAbort::None);
  Bytes out;
  ASSERT_EQ(d.read(0x1017, 0, out, TimePoint{std::chrono::milliseconds(9)}), SdoAbort::None);
  EXPECT_EQ(times, (std::vector<TimePoint>{TimePoint{std::chrono::milliseconds(3)},
                                           TimePoint{std::chrono::milliseconds(3)},
                                           TimePoint{std::chrono::milliseconds(9)}}));
}

TEST(LocalDictionary, HookAddedFirstRunsBeforeTheOthersAndItsRefusalWins) {
  auto d = make();
  d.add_write_hook([](auto, auto, auto, auto) { return SdoAbort::DeviceState; });
  d.add_write_hook([](auto, auto, auto, auto) { return SdoAbort::HardwareError; },
                   LocalDictionary::HookPosition::First);
  EXPECT_EQ(d.write(0x1017, 0, Bytes{1, 0}, kNow), SdoAbort::HardwareError);
  d.add_read_hook([](auto, auto, auto) { return SdoAbort::General; });
  d.add_read_hook([](auto, auto, auto) { return SdoAbort::NoDataAvailable; },
                  LocalDictionary::HookPosition::First);
  Bytes out;
  EXPECT_EQ(d.read(0x1017, 0, out, kNow), SdoAbort::NoDataAvailable);
}

// --- unchecked accessors ---------------------------------------------------------------------

TEST(LocalDictionary, UncheckedSettersIgnoreAccessAndCallNoHooks) {
  auto d = make();
  int calls = 0;
  d.add_write_hook([&](auto, auto, auto, auto) {
    ++calls;
    return SdoAbort::General;
  });
  d.add_write_observer([&](auto, auto, auto, auto) { ++calls; });
  EXPECT_TRUE(d.set_unsigned(0x1001, 0, 0x11));  // ro for SDO, the device sets it
  EXPECT_EQ(d.get_unsigned(0x1001, 0), 0x11u);
  EXPECT_TRUE(d.set_bytes(0x1008, 0, Bytes{'x'}));
  EXPECT_EQ(read(d, 0x1008, 0), (Bytes{'x'}));
  EXPECT_EQ(calls, 0);
  EXPECT_FALSE(d.set_bytes(0x3000, 0, Bytes{1}));
  EXPECT_FALSE(d.set_unsigned(0x2005, 0, 1));  // VISIBLE_STRING has no fixed size
}

TEST(LocalDictionary, TypedGetters) {
  auto d = make(5);
  EXPECT_EQ(d.get_unsigned(0x1200, 1), 0x605u);
  EXPECT_EQ(d.get_unsigned(0x2005, 0), std::nullopt);  // a string
  EXPECT_EQ(d.get_unsigned(0x3000, 0), std::nullopt);
  auto v = d.get_value(0x200A, 0);
  ASSERT_TRUE(v.has_value());
  EXPECT_EQ(v->as_signed(), -2);
  EXPECT_EQ(d.get_bytes(0x1017, 0)->size(), 2u);
  EXPECT_FALSE(d.get_bytes(0x1017, 1).has_value());
}

TEST(LocalDictionary, InsertAddsEntriesTheDeviceImplements) {
  auto d = make();
  DictionaryEntry e;
  e.index = 0x5000;
  e.sub_index = 0;
  e.basic_type = cfg::DataType::Unsigned16;
  e.data_type = 0x0006;
  e.access = cfg::AccessType::Rw;
  e.bytes = {1, 2};
  d.insert(e);
  EXPECT_EQ(read(d, 0x5000, 0), (Bytes{1, 2}));
  EXPECT_EQ(d.write(0x5000, 0, Bytes{1, 2, 3}, kNow), SdoAbort::LengthTooHigh);
}

// --- real device files -----------------------------------------------------------------------

TEST(LocalDictionary, LoadsTheSampleIoModule) {
  auto read_result = cfg::read_device_file(std::string(CANOPEN_SAMPLES_DIR) + "/io_module.eds");
  ASSERT_TRUE(read_result.device.has_value()) << read_result.diagnostics.format();
  auto d = LocalDictionary::from_device(*read_result.device, *cfg::NodeId::from(3));
  ASSERT_TRUE(d.ok()) << d.error().message;
  // samples/io_module.eds [1000] DefaultValue=0x000F0191.
  EXPECT_EQ(read(*d, 0x1000, 0), (Bytes{0x91, 0x01, 0x0F, 0x00}));
}

TEST(LocalDictionary, CorpusFilesLoadOrFailNamingAnEntry) {
  namespace fs = std::filesystem;
  const fs::path corpus = CANOPEN_CORPUS_DIR;
  if (!fs::is_directory(corpus)) PREREQUISITE_MISSING("corpus not found at ", corpus);
  int loaded = 0;
  for (const auto& file : fs::recursive_directory_iterator(corpus)) {
    const auto ext = file.path().extension().string();
    if (ext != ".eds" && ext != ".EDS" && ext != ".dcf" && ext != ".DCF") continue;
    auto r = cfg::read_device_file(file.path().string());
    if (!r.device) continue;
    const std::uint8_t node = r.device->node_id().value_or(1);
    auto d = LocalDictionary::from_device(*r.device,
                                          cfg::NodeId::from(node).value_or(*cfg::NodeId::from(1)));
    if (d.ok()) {
      ++loaded;
      // Every value of a fixed-size type has its size.
      for (const auto& [key, e] : d->entries()) {
        if (auto size = e.fixed_size()) {
          EXPECT_EQ(e.bytes.size(), *size) << file.path();
        }
      }
    } else {
      EXPECT_EQ(d.error().message.rfind("object ", 0), 0u)
          << file.path() << ": " << d.error().message;
      EXPECT_NE(d.error().message.find("h sub "), std::string::npos)
          << file.path() << ": " << d.error().message;
    }
  }
  EXPECT_GT(loaded, 0);
}

}  // namespace
}  // namespace nmt
