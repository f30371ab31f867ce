// The configuration manager (DSP 302 v3.2.1 §6; CiA 302-2 §3.5): SDO access to 1F20h-1F27h with
// the spec's abort codes, the download plan, and the store directory (persistence, corruption,
// crash safety).
#include "cfg/config_manager.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <thread>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/download_order.hpp"
#include "concise_test_support.hpp"
#include "scratch_dir.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {
using namespace cfg::literals;

namespace fs = std::filesystem;
using test_support::le;
using test_support::read_bytes;
using test_support::read_text;
using test_support::ScratchDir;
using test_support::u16;
using test_support::u32;
using test_support::u8;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;

using Bytes = std::vector<std::uint8_t>;

// CiA 301 §7.2.4.3.17 abort codes, written out as the spec's numbers.
constexpr std::uint32_t kAbortOutOfMemory = 0x05040005;
constexpr std::uint32_t kAbortReadOfWriteOnly = 0x06010001;
constexpr std::uint32_t kAbortWriteOfReadOnly = 0x06010002;
constexpr std::uint32_t kAbortNoObject = 0x06020000;
constexpr std::uint32_t kAbortLength = 0x06070010;
constexpr std::uint32_t kAbortNoSubIndex = 0x06090011;
constexpr std::uint32_t kAbortValueRange = 0x06090030;
constexpr std::uint32_t kAbortCannotStore = 0x08000020;
constexpr std::uint32_t kAbortDataSetEmpty = 0x08000024;  // DSP 302 §6 "Data set empty"

std::uint32_t code(SdoAbort abort) {
  return static_cast<std::uint32_t>(abort);
}

Bytes bytes_of(std::string_view text) {
  return {text.begin(), text.end()};
}

/// A small configuration: producer heartbeat and TPDO 1 remapped.
std::vector<ObjectWrite> sample_writes(std::uint16_t heartbeat_ms = 100) {
  return {u16(0x1017, 0, heartbeat_ms), u32(0x1800, 1, 0x182), u8(0x1A00, 0, 1),
          u32(0x1A00, 1, 0x60000108)};
}

std::string samples_dir() {
  return CANOPEN_SAMPLES_DIR;
}

ConfigManager open_store(const std::string& dir, StoreWriteHooks hooks = {}) {
  auto opened = ConfigManager::open(dir, std::move(hooks));
  EXPECT_TRUE(opened.ok()) << (opened.ok() ? "" : opened.error().message);
  return std::move(*opened);
}

// --- SDO access (DSP 302 §6) ----------------------------------------------------------------

TEST(ConfigManager, SubIndexZeroHolds127EntriesAnd128For1F25h) {
  // §6.1/§6.2/§6.3/§6.5: sub-index 0 is the maximum node-ID, 127; §6.4: 1F25h has 128.
  ConfigManager manager;
  for (const std::uint16_t index :
       std::vector<std::uint16_t>{0x1F20, 0x1F21, 0x1F22, 0x1F23, 0x1F24, 0x1F26, 0x1F27}) {
    const ConfigRead read = manager.read(index, 0);
    ASSERT_TRUE(read.ok()) << index;
    EXPECT_THAT(read.data, ElementsAre(127)) << index;
  }
  EXPECT_THAT(manager.read(0x1F25, 0).data, ElementsAre(128));
}

TEST(ConfigManager, EmptyConciseDcfReadsAsStreamWithCountZero) {
  // DSP 302 §6.2 application hint 2: no data stored reads as a valid stream, count 0.
  ConfigManager manager;
  const ConfigRead read = manager.read(0x1F22, 5);
  ASSERT_TRUE(read.ok());
  EXPECT_THAT(read.data, ElementsAre(0, 0, 0, 0));
}

TEST(ConfigManager, EmptyDcfAndEdsAbortDataSetEmpty) {
  // DSP 302 §6.1: reading 1F20h or 1F21h with nothing stored aborts 0800 0024h; §6.5 the same
  // for 1F23h, and 1F24h behaves as 1F21h.
  ConfigManager manager;
  for (const std::uint16_t index : std::vector<std::uint16_t>{0x1F20, 0x1F21, 0x1F23, 0x1F24}) {
    const ConfigRead read = manager.read(index, 9);
    EXPECT_EQ(code(read.abort), kAbortDataSetEmpty) << index;
    EXPECT_THAT(read.message, HasSubstr("data set empty"));
  }
}

TEST(ConfigManager, ConciseDcfWriteReadsBackTheSameStream) {
  ConfigManager manager;
  const Bytes stream = encode_concise_dcf(sample_writes());
  ASSERT_TRUE(manager.write(0x1F22, 3, stream).ok());
  EXPECT_EQ(manager.read(0x1F22, 3).data, stream);
  EXPECT_EQ(manager.concise(3_node), stream);
  // Another node is untouched.
  EXPECT_THAT(manager.read(0x1F22, 4).data, ElementsAre(0, 0, 0, 0));
}

TEST(ConfigManager, InvalidConciseStreamAbortsValueRangeWithTheDecodersMessage) {
  // Count 2, one entry: truncated.
  ConfigManager manager;
  Bytes stream = encode_concise_dcf(sample_writes());
  stream[0] = 5;
  const ConfigWrite write = manager.write(0x1F22, 3, stream);
  EXPECT_EQ(code(write.abort), kAbortValueRange);
  EXPECT_THAT(write.message, HasSubstr("announced"));
  EXPECT_FALSE(manager.has_configuration(3_node));
  // Bytes after the last announced entry are rejected too.
  Bytes trailing = encode_concise_dcf(sample_writes());
  trailing.push_back(0);
  EXPECT_EQ(code(manager.write(0x1F22, 3, trailing).abort), kAbortValueRange);
}

TEST(ConfigManager, EmptyDataSetStreamRemovesTheConciseDcf) {
  // DSP 302 §6.2 application hint 1: count 0 writes the empty data set.
  ConfigManager manager;
  ASSERT_TRUE(manager.write(0x1F22, 3, encode_concise_dcf(sample_writes())).ok());
  ASSERT_TRUE(manager.write(0x1F22, 3, Bytes{0, 0, 0, 0}).ok());
  EXPECT_FALSE(manager.has_configuration(3_node));
  EXPECT_THAT(manager.read(0x1F22, 3).data, ElementsAre(0, 0, 0, 0));
}

TEST(ConfigManager, DcfRoundTripsAndReadsStorageFormatZero) {
  const std::string text = read_text(samples_dir() + "/network/io_module_node2.dcf");
  ASSERT_FALSE(text.empty());
  ConfigManager manager;
  const ConfigWrite write = manager.write(0x1F20, 2, bytes_of(text));
  ASSERT_TRUE(write.ok()) << write.message;
  EXPECT_EQ(manager.read(0x1F20, 2).data, bytes_of(text));
  // §6.1: 00h = ASCII, not compressed (the external view; it is held compressed).
  EXPECT_THAT(manager.read(0x1F21, 2).data, ElementsAre(0));
  EXPECT_LT(manager.stored_bytes(), text.size() / 2);
}

TEST(ConfigManager, DcfThatIsNoDcfAbortsValueRange) {
  ConfigManager manager;
  const ConfigWrite write = manager.write(0x1F20, 2, bytes_of("no sections here\n"));
  EXPECT_EQ(code(write.abort), kAbortValueRange);
  EXPECT_THAT(write.message, HasSubstr("does not read"));
}

TEST(ConfigManager, StorageFormatOtherThanZeroIsReserved) {
  // §6.1: 01h..FFh reserved.
  ConfigManager manager;
  EXPECT_TRUE(manager.write(0x1F21, 2, Bytes{0}).ok());
  EXPECT_EQ(code(manager.write(0x1F21, 2, Bytes{1}).abort), kAbortValueRange);
  EXPECT_EQ(code(manager.write(0x1F24, 2, Bytes{0xFF}).abort), kAbortValueRange);
  EXPECT_EQ(code(manager.write(0x1F24, 2, Bytes{0, 0}).abort), kAbortLength);
}

TEST(ConfigManager, EdsRoundTrips) {
  const std::string text = read_text(samples_dir() + "/drive.eds");
  ASSERT_FALSE(text.empty());
  ConfigManager manager;
  ASSERT_TRUE(manager.write(0x1F23, 7, bytes_of(text)).ok());
  EXPECT_EQ(manager.read(0x1F23, 7).data, bytes_of(text));
  EXPECT_THAT(manager.read(0x1F24, 7).data, ElementsAre(0));
  // An EDS is no configuration.
  EXPECT_FALSE(manager.has_configuration(7_node));
}

TEST(ConfigManager, ExpectedDateAndTimeReadBackAndDefaultToZero) {
  // §6.3: 1F26h/1F27h sub i, UNSIGNED32.
  ConfigManager manager;
  EXPECT_THAT(manager.read(0x1F26, 4).data, ElementsAre(0, 0, 0, 0));
  ASSERT_TRUE(manager.write(0x1F26, 4, le(14000, 4)).ok());
  ASSERT_TRUE(manager.write(0x1F27, 4, le(3'600'000, 4)).ok());
  EXPECT_EQ(manager.read(0x1F26, 4).data, le(14000, 4));
  EXPECT_EQ(manager.read(0x1F27, 4).data, le(3'600'000, 4));
  EXPECT_EQ(manager.expected_stamp(4_node), (ConfigurationStamp{14000, 3'600'000}));
  // Milliseconds after midnight stay below 86 400 000.
  EXPECT_EQ(code(manager.write(0x1F27, 4, le(86'400'000, 4)).abort), kAbortValueRange);
  EXPECT_EQ(code(manager.write(0x1F26, 4, le(1, 2)).abort), kAbortLength);
}

TEST(ConfigManager, ConfigureSlaveTakesOnlyConf) {
  // §6.4: 'conf' = 666E 6F63h starts it; sub 1..7Fh for a node with nothing stored aborts
  // 0800 0024h; sub 80h returns without error even with nothing stored.
  ConfigManager manager;
  EXPECT_EQ(code(manager.write(0x1F25, 3, le(0x666E6F63, 4)).abort), kAbortDataSetEmpty);
  const ConfigWrite all_empty = manager.write(0x1F25, 0x80, le(0x666E6F63, 4));
  ASSERT_TRUE(all_empty.ok());
  EXPECT_THAT(all_empty.configure, IsEmpty());

  ASSERT_TRUE(manager.write(0x1F22, 3, encode_concise_dcf(sample_writes())).ok());
  ASSERT_TRUE(
      manager.write(0x1F20, 2, bytes_of(read_text(samples_dir() + "/network/io_module_node2.dcf")))
          .ok());
  const ConfigWrite one = manager.write(0x1F25, 3, le(0x666E6F63, 4));
  ASSERT_TRUE(one.ok());
  EXPECT_THAT(one.configure, ElementsAre(3_node));
  const ConfigWrite all = manager.write(0x1F25, 0x80, le(0x666E6F63, 4));
  ASSERT_TRUE(all.ok());
  EXPECT_THAT(all.configure, ElementsAre(2_node, 3_node));

  // Any other value ("save", or 'conf' byte-swapped) is refused.
  EXPECT_EQ(code(manager.write(0x1F25, 3, le(kSaveSignature, 4)).abort), kAbortCannotStore);
  EXPECT_EQ(code(manager.write(0x1F25, 3, le(0x636F6E66, 4)).abort), kAbortCannotStore);
  EXPECT_EQ(code(manager.write(0x1F25, 3, le(0x666E6F63, 2)).abort), kAbortLength);
  EXPECT_EQ(code(manager.read(0x1F25, 3).abort), kAbortReadOfWriteOnly);
}

TEST(ConfigManager, AddressesOutsideTheObjectsAbort) {
  ConfigManager manager;
  EXPECT_EQ(code(manager.read(0x1F28, 1).abort), kAbortNoObject);
  EXPECT_EQ(code(manager.write(0x1F1F, 1, Bytes{0}).abort), kAbortNoObject);
  EXPECT_EQ(code(manager.read(0x1F22, 0x80).abort), kAbortNoSubIndex);
  EXPECT_EQ(code(manager.write(0x1F25, 0x81, le(0x666E6F63, 4)).abort), kAbortNoSubIndex);
  EXPECT_EQ(code(manager.write(0x1F22, 0, Bytes{0, 0, 0, 0}).abort), kAbortWriteOfReadOnly);
}

// --- memory a peer can make the manager use (ConfigManagerLimits) --------------------------------

/// A concise DCF stream of `total` bytes: one DOMAIN entry (2002h) filling it (CiA 302 §5.2:
/// count, then index, sub-index, size and data of each entry: 4 + 7 bytes of framing).
Bytes concise_of_size(std::size_t total, std::uint8_t fill = 0x5A) {
  const Bytes stream =
      encode_concise_dcf(std::vector<ObjectWrite>{{0x2002, 0, Bytes(total - 11, fill)}});
  EXPECT_EQ(stream.size(), total);
  return stream;
}

TEST(ConfigManagerLimits, StreamOf1F22hWritesForEveryNodeStaysWithinTheTotalThenAbortsOutOfMemory) {
  ConfigManager manager;
  manager.set_limits({.max_entry_bytes = 4096, .max_total_bytes = 40 * 4096});
  // A tool writes the largest entry the manager takes for node after node, twice over.
  std::size_t accepted = 0;
  std::optional<unsigned> first_refused;
  for (int round = 0; round < 2; ++round) {
    for (unsigned n = 1; n <= 127; ++n) {
      const ConfigWrite write = manager.write(0x1F22, static_cast<std::uint8_t>(n),
                                              concise_of_size(4096, static_cast<std::uint8_t>(n)));
      EXPECT_LE(manager.value_bytes(), 40U * 4096);
      if (write.ok()) {
        ++accepted;
        continue;
      }
      EXPECT_EQ(code(write.abort), kAbortOutOfMemory) << "node " << n;
      EXPECT_THAT(write.message, HasSubstr("out of memory"));
      if (!first_refused) first_refused = n;
      EXPECT_FALSE(manager.has_configuration(*NodeId::from(n))) << "node " << n;
    }
  }
  // 40 nodes fit; the 41st is refused, and the second round replaces the 40 in place.
  EXPECT_EQ(first_refused, 41U);
  EXPECT_EQ(accepted, 80U);
  EXPECT_EQ(manager.value_bytes(), 40U * 4096);
  // Still working after the refusals: a node's entry is replaced, and a removal (the count-0
  // stream) makes room for another node.
  const Bytes smaller = concise_of_size(100);
  ASSERT_TRUE(manager.write(0x1F22, 1, smaller).ok());
  EXPECT_EQ(manager.read(0x1F22, 1).data, smaller);
  ASSERT_TRUE(manager.write(0x1F22, 2, Bytes{0, 0, 0, 0}).ok());
  ASSERT_TRUE(manager.write(0x1F22, 100, concise_of_size(4096)).ok());
  EXPECT_TRUE(manager.has_configuration(100_node));
}

TEST(ConfigManagerLimits, EntryLongerThanMaxEntryBytesAbortsOutOfMemoryWithoutTouchingTheStore) {
  ConfigManager manager;
  manager.set_limits({.max_entry_bytes = 1000, .max_total_bytes = 1 << 20});
  const Bytes kept = concise_of_size(1000);
  ASSERT_TRUE(manager.write(0x1F22, 5, kept).ok());
  EXPECT_EQ(code(manager.write(0x1F22, 5, concise_of_size(1001)).abort), kAbortOutOfMemory);
  EXPECT_EQ(manager.read(0x1F22, 5).data, kept);
  // 1F20h and 1F23h (texts) are limited by their length as written, compressed or not.
  const std::string text(1001, ' ');
  EXPECT_EQ(code(manager.write(0x1F20, 5, bytes_of(text)).abort), kAbortOutOfMemory);
  EXPECT_EQ(code(manager.write(0x1F23, 5, bytes_of(text)).abort), kAbortOutOfMemory);
  EXPECT_EQ(code(manager.read(0x1F23, 5).abort), kAbortDataSetEmpty);
}

TEST(ConfigManagerLimits, AdmitsAnswersForASizeBeforeTheDataIsThere) {
  // What an SDO server asks at the initiate request (indicated size) or as segments arrive.
  ConfigManager manager;
  manager.set_limits({.max_entry_bytes = 1000, .max_total_bytes = 1500});
  EXPECT_EQ(manager.admits(0x1F22, 5, 1000), SdoAbort::None);
  EXPECT_EQ(manager.admits(0x1F20, 5, 1001), SdoAbort::OutOfMemory);
  ASSERT_TRUE(manager.write(0x1F22, 5, concise_of_size(1000)).ok());
  // Node 6 has room for 500 more; node 5's own entry would be replaced, so it has 1000.
  EXPECT_EQ(manager.admits(0x1F22, 6, 500), SdoAbort::None);
  EXPECT_EQ(manager.admits(0x1F22, 6, 501), SdoAbort::OutOfMemory);
  EXPECT_EQ(manager.admits(0x1F22, 5, 1000), SdoAbort::None);
  EXPECT_EQ(manager.admits(0x1F23, 5, 501), SdoAbort::OutOfMemory);
  // Objects whose values are no files are not limited here.
  EXPECT_EQ(manager.admits(0x1F26, 5, 4), SdoAbort::None);
  EXPECT_EQ(manager.admits(0x1F25, 5, 1 << 30), SdoAbort::None);
}

// --- the download plan (CiA 302-2 §3.5) -------------------------------------------------------

TEST(ConfigManager, PlanIsTheStreamInPdoSafeOrderThen1020hAnd1010hSave) {
  ConfigManager manager;
  ASSERT_TRUE(manager.put_concise(5_node, encode_concise_dcf(sample_writes())).ok());
  ASSERT_TRUE(manager.set_expected_stamp(5_node, {14000, 3'600'000}).ok());
  auto plan = manager.download_plan(5_node);
  ASSERT_TRUE(plan.ok()) << plan.error().message;
  std::vector<ObjectWrite> expected = pdo_safe_order(sample_writes());
  // CiA 301 §7.5.2.19: 1020h sub 1 date, sub 2 time; §7.5.2.13: 1010h sub 1 'save'.
  expected.push_back(u32(0x1020, 1, 14000));
  expected.push_back(u32(0x1020, 2, 3'600'000));
  expected.push_back(u32(0x1010, 1, 0x65766173));
  EXPECT_EQ(plan->writes, expected);
  EXPECT_EQ(plan->source, DownloadPlan::Source::ConciseDcf);
  // The PDO-safe order around TPDO 1: COB-ID invalid first, valid last (DSP 302 §6.2 hint).
  EXPECT_EQ(plan->writes.front(), u16(0x1017, 0, 100));
  EXPECT_EQ(plan->writes[1], u32(0x1800, 1, 0x80000182));
}

TEST(ConfigManager, PlanWithoutStampOrSaveHasNoTail) {
  // §3.5 a: 1F26h/1F27h of 0 mean the configuration is not verified, so 1020h is not written.
  ConfigManager manager;
  ASSERT_TRUE(manager.put_concise(5_node, encode_concise_dcf(sample_writes())).ok());
  auto plan = manager.download_plan(5_node, PlanOptions{.save = false});
  ASSERT_TRUE(plan.ok());
  EXPECT_EQ(plan->writes, pdo_safe_order(sample_writes()));
}

TEST(ConfigManager, ConfigurationLeaves1020hAnd1010hToTheMaster) {
  // nmt::ConfigurationSource::configuration: without 1020h and 1010h, which the master adds.
  auto writes = sample_writes();
  writes.push_back(u32(0x1020, 1, 1));
  writes.push_back(u32(0x1010, 1, kSaveSignature));
  ConfigManager manager;
  ASSERT_TRUE(manager.put_concise(5_node, encode_concise_dcf(writes)).ok());
  EXPECT_EQ(manager.configuration(5_node), sample_writes());
  EXPECT_EQ(manager.configuration(6_node), std::nullopt);
  EXPECT_FALSE(manager.download_plan(6_node).ok());
}

TEST(ConfigManager, PlanFromDcfIsWhatDcf2ConciseGives) {
  const std::string path = samples_dir() + "/network/io_module_node2.dcf";
  ConfigManager manager;
  ASSERT_TRUE(manager.put_dcf(2_node, read_text(path)).ok());
  auto device = read_device_file(path);
  ASSERT_TRUE(device.ok());
  Diagnostics diagnostics;
  ConciseOptions options;
  options.node_id = 2;
  const auto expected = concise_writes_from_dcf(*device.device, options, diagnostics);
  ASSERT_TRUE(expected.has_value());
  EXPECT_EQ(manager.configuration(2_node), *expected);
  auto plan = manager.download_plan(2_node);
  ASSERT_TRUE(plan.ok());
  EXPECT_EQ(plan->source, DownloadPlan::Source::Dcf);
  EXPECT_EQ(plan->writes.back(), u32(0x1010, 1, kSaveSignature));
  // The concise DCF, when there is one, comes first.
  ASSERT_TRUE(manager.put_concise(2_node, encode_concise_dcf(sample_writes())).ok());
  EXPECT_EQ(manager.configuration(2_node), sample_writes());
}

// --- the store directory ----------------------------------------------------------------------

TEST(ConfigStore, EntriesSurviveReopeningTheDirectory) {
  ScratchDir dir;
  const std::string dcf = read_text(samples_dir() + "/network/drive_node3.dcf");
  const std::string eds = read_text(samples_dir() + "/drive.eds");
  {
    ConfigManager manager = open_store(dir.str());
    ASSERT_TRUE(manager.put_concise(1_node, encode_concise_dcf(sample_writes())).ok());
    ASSERT_TRUE(manager.put_dcf(3_node, dcf).ok());
    ASSERT_TRUE(manager.put_eds(3_node, eds).ok());
    ASSERT_TRUE(manager.set_expected_stamp(127_node, {14000, 1}).ok());
  }
  EXPECT_TRUE(fs::exists((dir / "1F22-01")));
  EXPECT_TRUE(fs::exists((dir / "1F20-03")));
  EXPECT_TRUE(fs::exists((dir / "1F23-03")));
  EXPECT_TRUE(fs::exists((dir / "1F26-7F")));
  ConfigManager again = open_store(dir.str());
  EXPECT_TRUE(again.problems().empty()) << again.problems().format();
  EXPECT_EQ(again.concise(1_node), encode_concise_dcf(sample_writes()));
  EXPECT_EQ(again.dcf(3_node), dcf);
  EXPECT_EQ(again.eds(3_node), eds);
  EXPECT_EQ(again.expected_stamp(127_node), (ConfigurationStamp{14000, 1}));
  EXPECT_THAT(again.configured_nodes(), ElementsAre(1_node, 3_node));
}

TEST(ConfigStore, RemovedEntriesStayRemoved) {
  ScratchDir dir;
  {
    ConfigManager manager = open_store(dir.str());
    ASSERT_TRUE(manager.put_concise(1_node, encode_concise_dcf(sample_writes())).ok());
    ASSERT_TRUE(manager.set_expected_stamp(1_node, {1, 1}).ok());
    ASSERT_TRUE(manager.write(0x1F22, 1, Bytes{0, 0, 0, 0}).ok());
    ASSERT_TRUE(manager.set_expected_stamp(1_node, {0, 0}).ok());
  }
  EXPECT_TRUE(fs::is_empty(dir.str()));
  ConfigManager again = open_store(dir.str());
  EXPECT_FALSE(again.has_configuration(1_node));
}

TEST(ConfigStore, FlippedByteIsReportedWithTheFileAndNeverUsed) {
  ScratchDir dir;
  {
    ConfigManager manager = open_store(dir.str());
    ASSERT_TRUE(manager.put_concise(1_node, encode_concise_dcf(sample_writes())).ok());
    ASSERT_TRUE(manager.put_concise(2_node, encode_concise_dcf(sample_writes(200))).ok());
  }
  // Flip one bit in the middle of node 1's file.
  Bytes file = read_bytes((dir / "1F22-01"));
  ASSERT_GT(file.size(), 30U);
  file[25] ^= 0x04;
  std::ofstream((dir / "1F22-01"), std::ios::binary | std::ios::trunc)
      .write(reinterpret_cast<const char*>(file.data()), static_cast<std::streamsize>(file.size()));

  ConfigManager again = open_store(dir.str());
  ASSERT_EQ(again.problems().size(), 1U);
  const Diagnostic& problem = again.problems().items()[0];
  EXPECT_EQ(problem.file, (dir / "1F22-01"));
  EXPECT_EQ(problem.severity, Severity::Error);
  EXPECT_THAT(problem.message, HasSubstr("CRC-32 mismatch"));
  EXPECT_FALSE(again.has_configuration(1_node));
  EXPECT_EQ(again.configuration(2_node), sample_writes(200));
}

TEST(ConfigStore, TruncatedAndMisnamedFilesAreReported) {
  ScratchDir dir;
  {
    ConfigManager manager = open_store(dir.str());
    ASSERT_TRUE(manager.put_concise(1_node, encode_concise_dcf(sample_writes())).ok());
    ASSERT_TRUE(manager.put_concise(2_node, encode_concise_dcf(sample_writes(200))).ok());
  }
  fs::resize_file((dir / "1F22-01"), fs::file_size((dir / "1F22-01")) - 3);
  fs::copy_file((dir / "1F22-02"), (dir / "1F22-03"));
  ConfigManager again = open_store(dir.str());
  ASSERT_EQ(again.problems().size(), 2U) << again.problems().format();
  EXPECT_THAT(again.problems().items()[0].message, HasSubstr("truncated"));
  EXPECT_THAT(again.problems().items()[1].message, HasSubstr("not what its name says"));
  EXPECT_THAT(again.configured_nodes(), ElementsAre(2_node));
}

TEST(ConfigStore, EntryWithAGoodChecksumButNoDcfInsideIsReported) {
  // A file another program wrote with a correct CRC: the content is checked as a write is.
  ScratchDir dir;
  const Bytes file = encode_store_entry({0x1F20, 4_node, bytes_of("not a DCF\n")});
  std::ofstream((dir / "1F20-04"), std::ios::binary)
      .write(reinterpret_cast<const char*>(file.data()), static_cast<std::streamsize>(file.size()));
  ConfigManager manager = open_store(dir.str());
  ASSERT_EQ(manager.problems().size(), 1U);
  EXPECT_THAT(manager.problems().items()[0].message, HasSubstr("does not read"));
  EXPECT_FALSE(manager.has_configuration(4_node));
  EXPECT_EQ(code(manager.read(0x1F20, 4).abort), kAbortDataSetEmpty);
}

TEST(ConfigStore, LeftoverTemporaryFilesAreRemovedAndOtherFilesIgnored) {
  ScratchDir dir;
  std::ofstream((dir / ".1F22-01.4242.tmp")) << "half a write";
  std::ofstream((dir / "README")) << "not an entry";
  ConfigManager manager = open_store(dir.str());
  EXPECT_TRUE(manager.problems().empty());
  EXPECT_FALSE(fs::exists((dir / ".1F22-01.4242.tmp")));
  EXPECT_TRUE(fs::exists((dir / "README")));
}

TEST(ConfigStore, FailedWriteAbortsAndKeepsTheOldValue) {
  // The rename cannot replace the entry (a directory has its name): works as root too.
  ScratchDir dir;
  ConfigManager manager = open_store(dir.str());
  ASSERT_TRUE(manager.put_concise(1_node, encode_concise_dcf(sample_writes())).ok());
  fs::remove((dir / "1F22-01"));
  fs::create_directories((dir / "1F22-01/x"));
  const ConfigWrite write = manager.write(0x1F22, 1, encode_concise_dcf(sample_writes(5)));
  EXPECT_EQ(code(write.abort), kAbortCannotStore);
  EXPECT_THAT(write.message, HasSubstr("1F22-01"));
  EXPECT_EQ(manager.configuration(1_node), sample_writes());
  // The failed write leaves no temporary file behind.
  for (const auto& file : fs::directory_iterator(dir.str())) {
    EXPECT_FALSE(file.path().filename().string().starts_with('.')) << file.path();
  }
}

TEST(ConfigStore, EntryFileRoundTripsAndRejectsDamage) {
  const StoreEntry entry{0x1F20, 9_node, bytes_of("[FileInfo]\nFileName=x.dcf\n")};
  const Bytes file = encode_store_entry(entry);
  auto decoded = decode_store_entry(file, "1F20-09");
  ASSERT_TRUE(decoded.ok()) << decoded.error().message;
  EXPECT_EQ(*decoded, entry);
  EXPECT_FALSE(decode_store_entry(file, "1F20-0A").ok());
  EXPECT_EQ(store_entry_file_name(0x1F26, 127_node), "1F26-7F");
  for (std::size_t i = 0; i < file.size(); ++i) {
    Bytes damaged = file;
    damaged[i] ^= 0x01;
    EXPECT_FALSE(decode_store_entry(damaged).ok()) << "byte " << i;
  }
}

// --- crash safety ------------------------------------------------------------------------------

/// The state every crash test starts from and checks: node 1 is rewritten, nodes 2..4 must
/// never change.
struct CrashFixture {
  Bytes a = encode_concise_dcf(sample_writes(100));
  Bytes b;
  Bytes other = encode_concise_dcf(sample_writes(300));
  std::string eds = "[FileInfo]\nFileName=x.eds\n" + std::string(3000, 'e');

  CrashFixture() {
    // A value of some size, so that a write takes many pieces.
    std::vector<ObjectWrite> many;
    for (std::uint8_t sub = 1; sub < 60; ++sub) many.push_back(u32(0x2000, sub, sub));
    b = encode_concise_dcf(many);
  }

  void seed(const std::string& dir) const {
    ConfigManager manager = open_store(dir);
    ASSERT_TRUE(manager.put_concise(1_node, a).ok());
    ASSERT_TRUE(manager.put_concise(2_node, other).ok());
    ASSERT_TRUE(manager.put_eds(3_node, eds).ok());
    ASSERT_TRUE(manager.set_expected_stamp(4_node, {14000, 5}).ok());
  }

  /// Node 1 holds one of `a`/`b` (which one returned), nothing is damaged, the others intact,
  /// and no temporary file survives the reopening.
  Bytes check(const std::string& dir) const {
    ConfigManager manager = open_store(dir);
    EXPECT_TRUE(manager.problems().empty()) << manager.problems().format();
    const auto value = manager.concise(1_node);
    EXPECT_TRUE(value == a || value == b);
    EXPECT_EQ(manager.concise(2_node), other);
    EXPECT_EQ(manager.eds(3_node), eds);
    EXPECT_EQ(manager.expected_stamp(4_node), (ConfigurationStamp{14000, 5}));
    for (const auto& file : fs::directory_iterator(dir)) {
      EXPECT_FALSE(file.path().filename().string().starts_with('.')) << file.path();
    }
    return value.value_or(Bytes{});
  }
};

TEST(ConfigStore, KilledWriterAtEveryStepLeavesOldOrNewValue) {
  // The writer is a child process that SIGKILLs itself at step k of a write (after each
  // 32-byte piece, after the fsync, the rename and the directory fsync), for every k.
  ScratchDir dir;
  CrashFixture fixture;
  fixture.seed(dir.str());
  Bytes current = fixture.a;
  bool saw_old = false;
  bool saw_new = false;
  for (int kill_at = 1;; ++kill_at) {
    const Bytes next = current == fixture.a ? fixture.b : fixture.a;
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      int step = 0;
      StoreWriteHooks hooks;
      hooks.chunk_bytes = 32;
      hooks.on_step = [&](StoreWriteHooks::Step, std::size_t) {
        if (++step == kill_at) ::raise(SIGKILL);
      };
      auto manager = ConfigManager::open(dir.str(), hooks);
      if (!manager) ::_exit(2);
      ::_exit(manager->put_concise(1_node, next).ok() ? 0 : 3);
    }
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    const bool killed = WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL;
    ASSERT_TRUE(killed || (WIFEXITED(status) && WEXITSTATUS(status) == 0)) << status;
    const Bytes found = fixture.check(dir.str());
    if (::testing::Test::HasFailure()) return;
    (found == current ? saw_old : saw_new) = true;
    // Once the rename is done the new value must be there, and before it the old one.
    current = found;
    if (!killed) break;  // the write completed: every step has been tried
    ASSERT_LT(kill_at, 1000) << "the write never completes";
  }
  EXPECT_TRUE(saw_old);
  EXPECT_TRUE(saw_new);
}

TEST(ConfigStore, KilledWriterAtRandomMomentsLeavesOldOrNewValue) {
  // A child rewrites node 1 in a loop (a, b, a, ...); it is killed after a random delay.
  ScratchDir dir;
  CrashFixture fixture;
  fixture.seed(dir.str());
  std::mt19937 random(1234);
  std::uniform_int_distribution<int> delay_us(0, 3000);
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(2);
  int runs = 0;
  while (runs < 40 && std::chrono::steady_clock::now() < deadline) {
    ++runs;
    const pid_t child = ::fork();
    ASSERT_GE(child, 0);
    if (child == 0) {
      StoreWriteHooks hooks;
      hooks.chunk_bytes = 64;
      auto manager = ConfigManager::open(dir.str(), hooks);
      if (!manager) ::_exit(2);
      for (bool flip = false;; flip = !flip) {
        if (!manager->put_concise(1_node, flip ? fixture.a : fixture.b).ok()) ::_exit(3);
      }
    }
    std::this_thread::sleep_for(std::chrono::microseconds(delay_us(random)));
    ::kill(child, SIGKILL);
    int status = 0;
    ASSERT_EQ(::waitpid(child, &status, 0), child);
    ASSERT_TRUE(WIFSIGNALED(status)) << "the writer stopped by itself: " << status;
    fixture.check(dir.str());
    if (::testing::Test::HasFailure()) return;
  }
  EXPECT_GE(runs, 10);
}

}  // namespace
}  // namespace cfg
