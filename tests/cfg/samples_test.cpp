// The project's own sample device files (samples/): every one is strict-clean CiA 306, and they
// say what samples/network/README.md says they configure. CiA 306 and CiA 301 are not in spec/;
// the checks follow their public descriptions.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/value.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

namespace fs = std::filesystem;

const fs::path kSamples = CANOPEN_SAMPLES_DIR;

std::vector<fs::path> sample_files() {
  std::vector<fs::path> out;
  for (const auto& entry : fs::recursive_directory_iterator(kSamples)) {
    const auto ext = entry.path().extension();
    if (ext == ".eds" || ext == ".dcf") out.push_back(entry.path());
  }
  std::sort(out.begin(), out.end());
  return out;
}

DeviceDescription load(const fs::path& path) {
  ReadResult r = read_device_file(path.string(), {ReadMode::Strict, path.string()});
  EXPECT_TRUE(r.ok()) << r.diagnostics.format();
  EXPECT_TRUE(r.diagnostics.empty()) << r.diagnostics.format();
  return r.device.value_or(DeviceDescription{});
}

std::string read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream s;
  s << in.rdbuf();
  return s.str();
}

// The value an entry is configured with, parsed with the file's node-ID (EDS: node 1).
Value configured(const DeviceDescription& device, std::uint16_t index, std::uint8_t sub) {
  const SubObject* entry = device.sub(index, sub);
  EXPECT_NE(entry, nullptr) << std::hex << index << "sub" << int{sub};
  if (entry == nullptr || !entry->configured_value() || !entry->basic_type()) return {};
  auto v =
      parse_value(*entry->basic_type(), *entry->configured_value(), device.node_id().value_or(1));
  EXPECT_TRUE(v.ok()) << std::hex << index << "sub" << int{sub};
  return v.ok() ? v.value() : Value{};
}

TEST(Samples, TheNetworkHasTwoEdsAndThreeDcfs) {
  EXPECT_EQ(sample_files().size(), 5U);
}

TEST(Samples, EveryFileIsStrictCleanCia306) {
  for (const auto& path : sample_files()) {
    SCOPED_TRACE(path.string());
    load(path);
  }
}

TEST(Samples, EveryFileUsesCrlfLineEndings) {
  for (const auto& path : sample_files()) {
    SCOPED_TRACE(path.string());
    const std::string text = read_bytes(path);
    ASSERT_FALSE(text.empty());
    for (std::size_t i = 0; i < text.size(); ++i) {
      if (text[i] == '\n') {
        ASSERT_TRUE(i > 0 && text[i - 1] == '\r') << "bare LF at byte " << i;
      }
    }
  }
}

TEST(Samples, EveryValueParsesAsItsType) {
  for (const auto& path : sample_files()) {
    SCOPED_TRACE(path.string());
    const DeviceDescription device = load(path);
    for (const auto& [index, object] : device.objects) {
      for (const auto& [sub_index, sub] : object.subs) {
        const auto type = sub.basic_type();
        ASSERT_TRUE(type.has_value()) << std::hex << index << "sub" << int{sub_index};
        for (const auto* text :
             {&sub.default_value, &sub.parameter_value, &sub.low_limit, &sub.high_limit}) {
          if (!*text) continue;
          auto v = parse_value(*type, **text, device.node_id().value_or(1));
          EXPECT_TRUE(v.ok()) << std::hex << index << "sub" << int{sub_index} << " \"" << **text
                              << "\": " << v.error().message;
        }
      }
    }
  }
}

// CiA 301 §7.5.2 (1600h-17FFh, 1A00h-1BFFh): each mapping entry is index << 16 | sub-index << 8 |
// length in bits; the mapped entry must exist, be PDO-mappable and have that length, and a
// classical CAN PDO carries at most 64 bits.
TEST(Samples, EveryPdoMappingNamesAMappableEntryOfItsLength) {
  for (const auto& path : sample_files()) {
    SCOPED_TRACE(path.string());
    const DeviceDescription device = load(path);
    for (const auto& [index, object] : device.objects) {
      if (!((index >= 0x1600 && index <= 0x17FF) || (index >= 0x1A00 && index <= 0x1BFF))) {
        continue;
      }
      const std::uint64_t count = configured(device, index, 0).as_unsigned();
      std::uint64_t bits = 0;
      for (std::uint8_t i = 1; i <= count; ++i) {
        const std::uint64_t entry = configured(device, index, i).as_unsigned();
        const auto mapped_index = static_cast<std::uint16_t>(entry >> 16);
        const auto mapped_sub = static_cast<std::uint8_t>((entry >> 8) & 0xFF);
        const auto length = static_cast<unsigned>(entry & 0xFF);
        const SubObject* mapped = device.sub(mapped_index, mapped_sub);
        ASSERT_NE(mapped, nullptr) << std::hex << index << "sub" << int{i} << " = 0x" << entry;
        EXPECT_TRUE(mapped->pdo_mapping) << std::hex << mapped_index << "sub" << int{mapped_sub};
        ASSERT_TRUE(mapped->basic_type().has_value());
        EXPECT_EQ(length, data_type_info(*mapped->basic_type()).size_bytes * 8U)
            << std::hex << index << "sub" << int{i};
        bits += length;
      }
      EXPECT_LE(bits, 64U) << std::hex << index;
    }
  }
}

TEST(Samples, IoModuleIsACia401DeviceWithDigitalAndAnalogChannels) {
  const DeviceDescription eds = load(kSamples / "io_module.eds");
  // CiA 401: profile number 401 = 0x0191 in the low word of 1000h.
  EXPECT_EQ(configured(eds, 0x1000, 0).as_unsigned(), 0x000F0191U);
  EXPECT_EQ(eds.object(0x1018)->subs.size(), 5U);
  // Pre-defined connection set: TPDO1 at 180h + node-ID, EMCY at 80h + node-ID.
  EXPECT_EQ(*eds.sub(0x1800, 1)->default_value, "$NODEID+0x180");
  EXPECT_EQ(configured(eds, 0x1014, 0).as_unsigned(), 0x81U);
  for (std::uint16_t index : std::vector<std::uint16_t>{0x6000, 0x6200, 0x6401, 0x6411}) {
    EXPECT_NE(eds.object(index), nullptr) << std::hex << index;
  }
  EXPECT_EQ(eds.sub(0x6401, 1)->data_type, static_cast<std::uint16_t>(DataType::Integer16));
}

TEST(Samples, IoModuleNode2DcfConfiguresWhatTheReadmeSays) {
  const DeviceDescription dcf = load(kSamples / "network" / "io_module_node2.dcf");
  EXPECT_EQ(dcf.node_id(), 2);
  EXPECT_EQ(configured(dcf, 0x1017, 0).as_unsigned(), 1000U);  // heartbeat 1000 ms
  EXPECT_EQ(configured(dcf, 0x1A00, 0).as_unsigned(), 3U);
  EXPECT_EQ(configured(dcf, 0x1A00, 3).as_unsigned(), 0x64010110U);  // analog input 1, 16 bits
  EXPECT_EQ(configured(dcf, 0x1600, 2).as_unsigned(), 0x64110110U);  // analog output 1
  EXPECT_EQ(configured(dcf, 0x1802, 1).as_unsigned(), 0x3A2U);
  // An EDS default with $NODEID resolves with the DCF's node-ID: EMCY 80h + 2.
  EXPECT_EQ(configured(dcf, 0x1014, 0).as_unsigned(), 0x82U);
}

TEST(Samples, DriveExercisesCia306TypesAndCompactSubObj) {
  const DeviceDescription eds = load(kSamples / "drive.eds");
  EXPECT_EQ(configured(eds, 0x1000, 0).as_unsigned(), 0x00020192U);  // CiA 402 = 0x0192
  EXPECT_EQ(eds.sub(0x2001, 0)->data_type, static_cast<std::uint16_t>(DataType::Integer24));
  EXPECT_EQ(eds.sub(0x2002, 0)->data_type, static_cast<std::uint16_t>(DataType::Unsigned40));
  EXPECT_EQ(eds.sub(0x2003, 0)->data_type, static_cast<std::uint16_t>(DataType::Real32));
  EXPECT_EQ(eds.sub(0x2004, 0)->data_type, static_cast<std::uint16_t>(DataType::VisibleString));
  EXPECT_EQ(eds.sub(0x2005, 0)->data_type, static_cast<std::uint16_t>(DataType::Domain));
  const Object* limits = eds.object(0x2010);
  ASSERT_NE(limits, nullptr);
  EXPECT_EQ(limits->compact_sub_obj, 3);
  ASSERT_EQ(limits->subs.size(), 4U);  // sub-index 0 plus 3 expanded entries
  EXPECT_EQ(limits->sub(2)->name, "Peak current limit (mA)");  // from [2010Name]
}

TEST(Samples, DriveNode3DcfConfiguresWhatTheReadmeSays) {
  const DeviceDescription dcf = load(kSamples / "network" / "drive_node3.dcf");
  EXPECT_EQ(dcf.node_id(), 3);
  EXPECT_EQ(configured(dcf, 0x1017, 0).as_unsigned(), 500U);
  EXPECT_EQ(configured(dcf, 0x6060, 0).as_signed(), 3);  // CiA 402: 3 = profile velocity mode
  EXPECT_EQ(configured(dcf, 0x1601, 2).as_unsigned(), 0x60FF0020U);  // target velocity
  EXPECT_EQ(configured(dcf, 0x1A01, 2).as_unsigned(), 0x606C0020U);  // velocity actual value
  EXPECT_EQ(configured(dcf, 0x2003, 0).as_real(), 0.125);
  EXPECT_EQ(configured(dcf, 0x2010, 2).as_unsigned(), 8000U);  // from [2010Value]
}

}  // namespace
}  // namespace cfg
