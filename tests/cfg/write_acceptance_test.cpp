// cfg/write_acceptance.hpp: the write rules of a CiA 301 device, and a DCF's download run through
// them. Files in tests/data/write_refusal (README there): one DCF per rule, each configuring one
// write a device refuses; the lines asserted are those files'. The abort codes are those of the
// CiA 301 abort code table (§7.2.4.3.17; CiA 301 is not among spec/, the codes are its public
// ones), the PDO rules those of CiA 301 §7.5.2.35-38.
#include "cfg/write_acceptance.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/object_address.hpp"
#include "test_paths.hpp"

namespace {

using ::testing::HasSubstr;

std::string data(const std::string& name) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/write_refusal/" + name;
}

cfg::DeviceDescription read_dcf(const std::string& path) {
  auto read = cfg::read_device_file(path);
  EXPECT_TRUE(read.device.has_value()) << read.diagnostics.format();
  return read.device ? std::move(*read.device) : cfg::DeviceDescription{};
}

// What `cfgmgr check FILE` adds for the file's own download: its writes as the master sends them
// (concise_writes_from_dcf, PDO-safe order) through check_download.
cfg::Diagnostics download_findings(const std::string& name) {
  const cfg::DeviceDescription dcf = read_dcf(data(name));
  cfg::ConciseOptions options;
  options.file_name = data(name);
  cfg::Diagnostics ignored;
  const auto writes = cfg::concise_writes_from_dcf(dcf, options, ignored);
  EXPECT_TRUE(writes.has_value()) << ignored.format();
  cfg::Diagnostics out;
  if (writes) check_download(dcf, *cfg::NodeId::from(5), *writes, data(name), "", out);
  return out;
}

struct Refusal {
  const char* file;
  const char* object;  // the refused write
  const char* code;    // CiA 301 abort code, as the standard writes it
  int line;            // of the DCF value the write comes from
  const char* words;
  std::size_t count = 1;  // findings of the file: the first is the refusal asserted
};

class DownloadRefusal : public ::testing::TestWithParam<Refusal> {};

TEST_P(DownloadRefusal, IsAWarningAtTheValuesLineNamingTheAbortCode) {
  const Refusal& r = GetParam();
  const cfg::Diagnostics d = download_findings(r.file);
  ASSERT_EQ(d.size(), r.count) << d.format();
  const cfg::Diagnostic& found = d.items()[0];
  // Tolerant: the file is usable, the download will fail there (strict makes it an error).
  EXPECT_EQ(found.severity, cfg::Severity::Warning);
  EXPECT_EQ(found.file, data(r.file));
  EXPECT_EQ(found.line, r.line) << found.message;
  EXPECT_EQ(found.message.rfind(std::string(r.object) + " = ", 0), 0U) << found.message;
  EXPECT_THAT(found.message, HasSubstr("refused with SDO abort " + std::string(r.code)));
  EXPECT_THAT(found.message, HasSubstr(r.words));
  EXPECT_THAT(found.message, HasSubstr("some vendor devices are laxer"));
}

INSTANTIATE_TEST_SUITE_P(
    CiA301, DownloadRefusal,
    ::testing::Values(
        // §7.5.2.36 step 3: an entry whose length is not the object's: 32 bits of an UNSIGNED64
        // (the Elmo case of the issue).
        Refusal{"mapping_length.dcf", "1600h sub 01h", "0604 0041", 237,
                "maps 2003h sub 00h with 32 bits, but its type UNSIGNED64 has 64"},
        // An object with PDOMapping=0 (CiA 306 §4.6.3).
        Refusal{"not_mappable.dcf", "1A00h sub 01h", "0604 0041", 319,
                "TPDO 1 maps 2001h sub 00h, which is not mappable"},
        // An object the device does not have: "object does not exist" (0602 0000).
        Refusal{"missing_object.dcf", "1600h sub 01h", "0602 0000", 237,
                "which the device does not have"},
        // §7.5.2.36: 16 + 16 + 64 bits exceed the 64 bits of a CAN frame, refused when sub 0 = 3
        // validates them.
        Refusal{"pdo_length.dcf", "1600h sub 00h", "0604 0042", 228, "96 bits"},
        // "value of parameter written too high" against HighLimit=100.
        Refusal{"above_high_limit.dcf", "2002h sub 00h", "0609 0031", 352,
                "above its HighLimit 100"},
        // DSP 302 §6.2: the master makes TPDO 1 invalid (1800h sub 1 with bit 31) around its
        // mapping; the COB-ID is const: "attempt to write a read only object".
        Refusal{"mapping_while_valid.dcf", "1800h sub 01h", "0601 0002", 279,
                "its access type is const", 2},
        // §7.5.2.38: entries only while sub-index 0 is 0; here it is ro and 1.
        Refusal{"entry_while_counted.dcf", "1A00h sub 01h", "0800 0022", 319,
                "only while sub-index 0 is 0, and it is 1"},
        // §7.5.2.33 (1016h): one consumer heartbeat time per node; the device holds sub 2's
        // value (the DCF's) when sub 1 = node 2 arrives, and keeps sub 1's when sub 2 does: both
        // writes are refused.
        Refusal{"heartbeat_twice.dcf", "1016h sub 01h", "0604 0043", 96,
                "already consumes the heartbeat of node 2", 2}));

// §7.5.2.38: the mapping may change only while the PDO is invalid, which the refused COB-ID
// write left it not: the first write of the mapping (sub 0 = 0, line 310) is refused too.
TEST(DownloadCheck, AMappingWrittenWhileThePdoIsValidIsRefusedWith08000022) {
  const cfg::Diagnostics d = download_findings("mapping_while_valid.dcf");
  ASSERT_EQ(d.size(), 2U) << d.format();
  const cfg::Diagnostic& found = d.items()[1];
  EXPECT_EQ(found.line, 310);
  EXPECT_EQ(found.message.rfind("1A00h sub 00h = 0x00: ", 0), 0U) << found.message;
  EXPECT_THAT(found.message, HasSubstr("SDO abort 0800 0022"));
  EXPECT_THAT(found.message, HasSubstr("only while the PDO is invalid"));
}

TEST(DownloadCheck, ADcfWhoseWritesADeviceAcceptsHasNoFinding) {
  // RPDO 1 and TPDO 1 remapped in the PDO-safe order (DSP 302 §6.2), 2002h within its limits,
  // two consumer heartbeats of different nodes.
  const cfg::Diagnostics d = download_findings("accepted.dcf");
  EXPECT_TRUE(d.empty()) << d.format();
}

// The rules a download of a device's own DCF cannot meet (concise_writes_from_dcf never writes
// an ro entry, and encodes every value in its entry's type), against the entries a device built
// from accepted.dcf holds.
class DeviceWrite : public ::testing::Test {
 protected:
  void SetUp() override {
    dcf_ = read_dcf(data("accepted.dcf"));
    auto entries = cfg::device_entries(dcf_, 5);
    ASSERT_TRUE(entries) << entries.error().message;
    entries_ = std::move(entries).value();
  }
  cfg::WriteVerdict write(std::uint16_t index, std::uint8_t sub,
                          const std::vector<std::uint8_t>& data) const {
    return cfg::check_device_write(entries_, {&dcf_.dummy_usage}, index, sub, data);
  }
  cfg::DeviceDescription dcf_;
  cfg::DeviceEntries entries_;
};

TEST_F(DeviceWrite, ReadOnlyObjectIsRefusedWith06010002) {
  const auto v = write(0x1000, 0, {0x91, 0x01, 0x03, 0x00});  // 1000h is ro
  EXPECT_EQ(v.code, cfg::SdoAbort::WriteOfReadOnly);
  EXPECT_THAT(v.reason, HasSubstr("ro"));
}

TEST_F(DeviceWrite, LengthOtherThanTheTypesIsRefusedWith0607001213) {
  // 2000h is UNSIGNED16: 2 bytes.
  EXPECT_EQ(write(0x2000, 0, {1, 2, 3, 4}).code, cfg::SdoAbort::LengthTooHigh);
  EXPECT_EQ(write(0x2000, 0, {1}).code, cfg::SdoAbort::LengthTooLow);
  EXPECT_EQ(write(0x2000, 0, {1, 2}).code, cfg::SdoAbort::None);
}

TEST_F(DeviceWrite, MissingObjectAndSubIndexAre06020000And06090011) {
  EXPECT_EQ(write(0x2100, 0, {1, 2}).code, cfg::SdoAbort::ObjectDoesNotExist);
  EXPECT_EQ(write(0x1018, 9, {1, 2, 3, 4}).code, cfg::SdoAbort::SubIndexDoesNotExist);
}

TEST_F(DeviceWrite, BelowLowLimitIsRefusedWith06090032) {
  EXPECT_EQ(write(0x2002, 0, {0, 0}).code, cfg::SdoAbort::ValueTooLow);  // LowLimit=1
  EXPECT_EQ(write(0x2002, 0, {100, 0}).code, cfg::SdoAbort::None);       // HighLimit=100
}

TEST_F(DeviceWrite, ValidPdoCobIdChangesOnlyThroughInvalid) {
  // §7.5.2.35: 1400h sub 1 = 205h (valid): another identifier directly is 0609 0030; bit 31
  // first (destroying the PDO) is accepted.
  EXPECT_EQ(write(0x1400, 1, {0x06, 0x02, 0, 0}).code, cfg::SdoAbort::ValueRangeExceeded);
  EXPECT_EQ(write(0x1400, 1, {0x05, 0x02, 0, 0x80}).code, cfg::SdoAbort::None);
}

TEST_F(DeviceWrite, DummyEntriesAreForRpdosTheDummyUsageAllows) {
  // CiA 301 §7.4.7.1; [DummyUsage] of accepted.dcf allows 0005h-0007h. The PDO must be invalid
  // and its count 0 first.
  auto& cob = entries_.at(cfg::ObjectAddress{0x1400, 1}.key()).bytes;
  cob = {0x05, 0x02, 0, 0x80};
  entries_.at(cfg::ObjectAddress{0x1600, 0}.key()).bytes = {0};
  EXPECT_EQ(write(0x1600, 1, {0x08, 0x00, 0x05, 0x00}).code, cfg::SdoAbort::None);
  // 0002h (INTEGER8) is not in [DummyUsage].
  EXPECT_EQ(write(0x1600, 1, {0x08, 0x00, 0x02, 0x00}).code, cfg::SdoAbort::CannotBeMapped);
}

}  // namespace
