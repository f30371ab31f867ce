// Concise DCF (DSP 302 v3.2.1 §6.2): the stream layout, the streaming decoder's rejections, and
// the writes a DCF configures. The stream layout as the spec gives it:
//   Number of supported entries  UNSIGNED32
//   Index 1                      UNSIGNED16
//   Sub-index 1                  UNSIGNED8
//   Data size of parameter 1     UNSIGNED32
//   Data of parameter 1          DOMAIN
//   ... up to entry n
// "The Data Size is counting bytes (i.e. Unsigned16 has size 2; size of Boolean is given as 1)."
#include "cfg/concise_dcf.hpp"
#include "cfg/bytes.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "concise_test_support.hpp"
#include "prerequisite.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

using test_support::le;
using test_support::read_bytes;
using test_support::u16;
using test_support::u32;
using test_support::u8;
using ::testing::ElementsAre;
using ::testing::HasSubstr;
using ::testing::IsEmpty;
using ::testing::Not;

using Bytes = std::vector<std::uint8_t>;

std::string corpus(const std::string& relative) {
  return std::string(CANOPEN_CORPUS_DIR) + "/" + relative;
}

// The stream of one entry 1017h sub 0, size 2, value 1000 (heartbeat producer time 1000 ms),
// written out field by field from the DSP 302 §6.2 table.
const Bytes kHeartbeat1000 = {
    0x01, 0x00, 0x00, 0x00,  // number of entries: 1
    0x17, 0x10,              // index 1017h
    0x00,                    // sub-index 0
    0x02, 0x00, 0x00, 0x00,  // data size 2 (UNSIGNED16)
    0xE8, 0x03,              // 1000
};

// Feeds `bytes` in chunks whose sizes come from `chunk_size(i)` and collects the entries.
template <class ChunkSize>
Result<std::vector<ObjectWrite>> decode_chunked(const Bytes& bytes, ChunkSize chunk_size) {
  std::vector<ObjectWrite> entries;
  ConciseDcfDecoder decoder(
      [&](std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> d) {
        entries.push_back({index, sub, {d.begin(), d.end()}});
      });
  std::size_t pos = 0;
  for (int i = 0; pos < bytes.size(); ++i) {
    std::size_t n = std::min(chunk_size(i), bytes.size() - pos);
    if (auto s = decoder.feed(std::span(bytes).subspan(pos, n)); !s) return s.error();
    pos += n;
  }
  if (auto s = decoder.finish(); !s) return s.error();
  return entries;
}

// ---------------------------------------------------------------------------------------------
// Encoding and decoding

TEST(ConciseDcf, EncodesTheSpecLayoutLittleEndian) {
  std::vector<ObjectWrite> entries{u16(0x1017, 0, 1000)};
  EXPECT_EQ(encode_concise_dcf(entries), kHeartbeat1000);
}

TEST(ConciseDcf, DecodesTheSpecLayout) {
  auto entries = decode_concise_dcf(kHeartbeat1000);
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  EXPECT_THAT(*entries, ElementsAre(u16(0x1017, 0, 1000)));
}

TEST(ConciseDcf, EmptyDataSetIsACountOfZero) {
  // DSP 302 §6.2 application hint: "An empty data set can be written by the following concise
  // stream: Number of supported entries 0 (UNSIGNED32)".
  EXPECT_EQ(encode_concise_dcf({}), (Bytes{0, 0, 0, 0}));
  auto entries = decode_concise_dcf(Bytes{0, 0, 0, 0});
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  EXPECT_THAT(*entries, IsEmpty());
}

TEST(ConciseDcf, BooleanHasSizeOne) {
  // DSP 302 §6.2: "size of Boolean is given as 1".
  std::vector<ObjectWrite> entries{{0x2000, 1, {0x01}}};
  EXPECT_EQ(encode_concise_dcf(entries),
            (Bytes{1, 0, 0, 0, 0x00, 0x20, 0x01, 0x01, 0, 0, 0, 0x01}));
}

TEST(ConciseDcf, ZeroSizeEntryIsDelivered) {
  // An empty VISIBLE_STRING / DOMAIN has data size 0.
  Bytes stream{2, 0, 0, 0, 0x08, 0x10, 0x00, 0, 0, 0, 0, 0x17, 0x10, 0x00, 2, 0, 0, 0, 0xE8, 0x03};
  auto entries = decode_concise_dcf(stream);
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  EXPECT_THAT(*entries, ElementsAre(ObjectWrite{0x1008, 0, {}}, u16(0x1017, 0, 1000)));
  EXPECT_EQ(encode_concise_dcf(*entries), stream);
}

// The two 13-byte streams other stacks use in their unit tests (corpus/_derived, described in
// MANIFEST.tsv): CanFestival's TestMaster 1F22h sub 2 and lely's CO_DevDCF buffer.
TEST(ConciseDcf, DecodesCanFestivalKerneltestStream) {
  const auto path = corpus("_derived/canfestival_kerneltest_TestMaster_obj1F22_sub2.bin");
  if (!std::filesystem::exists(path)) PREREQUISITE_MISSING("corpus not found: ", path);
  const Bytes bytes = read_bytes(path);
  auto entries = decode_concise_dcf(bytes);
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  // MANIFEST.tsv: "1017h/00 size 2 value 1000".
  EXPECT_THAT(*entries, ElementsAre(u16(0x1017, 0, 1000)));
  EXPECT_EQ(encode_concise_dcf(*entries), bytes);
}

TEST(ConciseDcf, DecodesLelyDevDcfStream) {
  const auto path = corpus("_derived/lely_test-dev_CoDevDCF_buf.bin");
  if (!std::filesystem::exists(path)) PREREQUISITE_MISSING("corpus not found: ", path);
  const Bytes bytes = read_bytes(path);
  auto entries = decode_concise_dcf(bytes);
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  // MANIFEST.tsv: "1 entry 1234h/ABh size 2 value 0x0987".
  EXPECT_THAT(*entries, ElementsAre(u16(0x1234, 0xAB, 0x0987)));
  EXPECT_EQ(encode_concise_dcf(*entries), bytes);
}

// Every concise DCF of the corpus decodes, with the entry count MANIFEST.tsv records for it
// ("concise-dcf entries=N", counted by the corpus' own tooling), and encodes back to its bytes.
TEST(ConciseDcf, DecodesEveryCorpusStreamWithTheManifestEntryCount) {
  const auto manifest_path = corpus("MANIFEST.tsv");
  if (!std::filesystem::exists(manifest_path))
    PREREQUISITE_MISSING("corpus not found: ", manifest_path);
  std::istringstream manifest(test_support::read_text(manifest_path));
  std::string line;
  int checked = 0;
  while (std::getline(manifest, line)) {
    const std::string file = line.substr(0, line.find('\t'));
    if (file.size() < 4 || file.substr(file.size() - 4) != ".bin") continue;
    const Bytes bytes = read_bytes(corpus(file));
    ASSERT_GE(bytes.size(), 4U) << file;
    // Sets the manifest gives no count for (dcfgen's output added later): the count the
    // stream's first UNSIGNED32 declares (DSP 302 §6.1), which the decoder must reach exactly.
    const auto key = line.find("concise-dcf entries=");
    const std::size_t expected =
        key != std::string::npos ? std::stoul(line.substr(key + 20)) : cfg::load_le32(bytes);
    auto entries = decode_concise_dcf(bytes);
    ASSERT_TRUE(entries.ok()) << file << ": " << entries.error().message;
    EXPECT_EQ(entries->size(), expected) << file;
    EXPECT_EQ(encode_concise_dcf(*entries), bytes) << file;
    // Byte-by-byte and random chunking give the same entries.
    auto one_by_one = decode_chunked(bytes, [](int) { return std::size_t{1}; });
    ASSERT_TRUE(one_by_one.ok()) << file;
    EXPECT_EQ(*one_by_one, *entries) << file;
    std::mt19937 rng(checked);
    auto random = decode_chunked(bytes, [&rng](int) { return std::size_t{rng() % 17}; });
    ASSERT_TRUE(random.ok()) << file;
    EXPECT_EQ(*random, *entries) << file;
    ++checked;
  }
  EXPECT_GE(checked, 9);  // MANIFEST.tsv lists 9 .bin files with an entry count, and more without
}

TEST(ConciseDcf, ChunkedFeedingGivesTheSameEntries) {
  std::vector<ObjectWrite> entries{u32(0x1400, 1, 0x80000202),
                                   u8(0x1600, 0, 0),
                                   {0x1F50, 1, Bytes(1000, 0x5A)},
                                   u16(0x1017, 0, 1000),
                                   {0x1008, 0, {}}};
  const Bytes stream = encode_concise_dcf(entries);
  for (std::size_t chunk : {1u, 2u, 3u, 6u, 7u, 11u, 64u, 4096u}) {
    auto decoded = decode_chunked(stream, [chunk](int) { return chunk; });
    ASSERT_TRUE(decoded.ok()) << chunk << ": " << decoded.error().message;
    EXPECT_EQ(*decoded, entries) << "chunk size " << chunk;
  }
}

TEST(ConciseDcf, EmptyChunksAreHarmless) {
  ConciseDcfDecoder decoder([](std::uint16_t, std::uint8_t, std::span<const std::uint8_t>) {});
  EXPECT_TRUE(decoder.feed({}).ok());
  EXPECT_TRUE(decoder.feed(kHeartbeat1000).ok());
  EXPECT_TRUE(decoder.feed({}).ok());
  EXPECT_TRUE(decoder.finish().ok());
  EXPECT_EQ(decoder.entries_read(), 1u);
  EXPECT_EQ(decoder.entries_announced(), 1u);
  EXPECT_EQ(decoder.bytes_consumed(), 13u);
}

// ---------------------------------------------------------------------------------------------
// Rejections, each naming the byte offset (counted from 0)

TEST(ConciseDcf, RejectsStreamEndingInsideTheCount) {
  auto r = decode_concise_dcf(Bytes{0x01, 0x00});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("truncated"));
  EXPECT_THAT(r.error().message, HasSubstr("byte offset 2"));
  EXPECT_THAT(r.error().message, HasSubstr("entry count"));
}

TEST(ConciseDcf, RejectsEmptyInput) {
  auto r = decode_concise_dcf(Bytes{});
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("byte offset 0"));
}

TEST(ConciseDcf, RejectsCountLargerThanData) {
  Bytes stream = kHeartbeat1000;
  stream[0] = 2;  // two entries announced, one present
  auto r = decode_concise_dcf(stream);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("2 entries announced"));
  EXPECT_THAT(r.error().message, HasSubstr("byte offset 13 after 1"));
}

TEST(ConciseDcf, RejectsCountSmallerThanData) {
  Bytes stream = kHeartbeat1000;
  stream[0] = 0;  // nothing announced, an entry follows
  auto r = decode_concise_dcf(stream);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("trailing bytes"));
  EXPECT_THAT(r.error().message, HasSubstr("byte offset 4"));
}

TEST(ConciseDcf, RejectsTrailingBytes) {
  Bytes stream = kHeartbeat1000;
  stream.push_back(0x00);
  auto r = decode_concise_dcf(stream);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("trailing bytes: byte offset 13"));
  EXPECT_THAT(r.error().message, HasSubstr("1 announced"));
}

TEST(ConciseDcf, RejectsStreamEndingInsideAnEntryHeader) {
  Bytes stream = kHeartbeat1000;
  stream[0] = 2;
  stream.insert(stream.end(), {0x18, 0x10, 0x01});  // 3 of the 7 header bytes of entry 2
  auto r = decode_concise_dcf(stream);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("byte offset 16"));
  EXPECT_THAT(r.error().message, HasSubstr("header of entry 2 of 2 (starts at byte offset 13)"));
}

TEST(ConciseDcf, RejectsStreamEndingInsideEntryData) {
  Bytes stream(kHeartbeat1000.begin(), kHeartbeat1000.end() - 1);  // 1 of 2 data bytes
  auto r = decode_concise_dcf(stream);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("byte offset 12"));
  EXPECT_THAT(r.error().message, HasSubstr("entry 1 of 1 (starts at byte offset 4)"));
  EXPECT_THAT(r.error().message, HasSubstr("1017h sub 00h announces 2 bytes, 1 present"));
}

TEST(ConciseDcf, HugeAnnouncedSizeIsNotTrusted) {
  // Size FFFFFFFFh and 3 data bytes: the decoder must not allocate 4 GiB, just say what is
  // missing.
  Bytes stream{1, 0, 0, 0, 0x50, 0x1F, 0x01, 0xFF, 0xFF, 0xFF, 0xFF, 0xAA, 0xBB, 0xCC};
  auto r = decode_concise_dcf(stream);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("1F50h sub 01h announces 4294967295 bytes, 3 present"));
}

TEST(ConciseDcf, HugeAnnouncedCountIsNotTrusted) {
  Bytes stream = kHeartbeat1000;
  stream[0] = stream[1] = stream[2] = stream[3] = 0xFF;
  auto r = decode_concise_dcf(stream);
  ASSERT_FALSE(r.ok());
  EXPECT_THAT(r.error().message, HasSubstr("4294967295 entries announced"));
}

TEST(ConciseDcf, DecoderStaysFailedAfterAnError) {
  int delivered = 0;
  ConciseDcfDecoder decoder(
      [&delivered](std::uint16_t, std::uint8_t, std::span<const std::uint8_t>) { ++delivered; });
  Bytes stream = kHeartbeat1000;
  stream.push_back(0x42);
  auto first = decoder.feed(stream);
  ASSERT_FALSE(first.ok());
  EXPECT_EQ(delivered, 1);  // the good entry came before the bad byte
  auto again = decoder.feed(kHeartbeat1000);
  ASSERT_FALSE(again.ok());
  EXPECT_EQ(again.error(), first.error());
  auto finished = decoder.finish();
  ASSERT_FALSE(finished.ok());
  EXPECT_EQ(finished.error(), first.error());
  EXPECT_EQ(delivered, 1);
}

TEST(ConciseDcf, TruncationIsFoundWhicheverChunkEndsTheStream) {
  const Bytes full = encode_concise_dcf(std::vector<ObjectWrite>{
      u32(0x1400, 1, 0x202), {0x1008, 0, {'a', 'b', 'c'}}, u16(0x1017, 0, 1000)});
  for (std::size_t cut = 0; cut < full.size(); ++cut) {
    Bytes truncated(full.begin(), full.begin() + static_cast<std::ptrdiff_t>(cut));
    auto r = decode_chunked(truncated, [](int) { return std::size_t{1}; });
    ASSERT_FALSE(r.ok()) << "cut at " << cut;
    EXPECT_THAT(r.error().message, HasSubstr("byte offset " + std::to_string(cut))) << cut;
  }
}

// ---------------------------------------------------------------------------------------------
// DCF -> writes

// One value-carrying entry of a hand-written DCF. Sub-index 0 alone makes a VAR; more
// sub-indices make a RECORD.
struct Entry {
  std::uint16_t index;
  std::uint8_t sub;
  DataType type;
  AccessType access;
  std::optional<std::string> parameter_value;
  std::optional<std::string> default_value;
  int line = 0;
};

DeviceDescription make_dcf(std::initializer_list<Entry> entries,
                           std::optional<std::uint8_t> node_id = std::nullopt) {
  DeviceDescription dcf;
  for (const auto& e : entries) {
    Object& object = dcf.objects[e.index];
    object.index = e.index;
    object.line = e.line;
    SubObject sub;
    sub.sub_index = e.sub;
    sub.data_type = static_cast<std::uint16_t>(e.type);
    sub.access = e.access;
    sub.parameter_value = e.parameter_value;
    sub.default_value = e.default_value;
    sub.line = e.line;
    object.subs[e.sub] = sub;
  }
  for (auto& [index, object] : dcf.objects) {
    bool var = object.subs.size() == 1 && object.subs.begin()->first == 0;
    object.object_type = var ? ObjectType::Var : ObjectType::Record;
  }
  if (node_id) {
    dcf.commissioning.emplace();
    dcf.commissioning->node_id = node_id;
  }
  return dcf;
}

ConciseOptions options(ConciseSelection selection = ConciseSelection::Configured) {
  ConciseOptions o;
  o.selection = selection;
  o.file_name = "dev.dcf";
  return o;
}

constexpr auto kRw = AccessType::Rw;
constexpr auto kRo = AccessType::Ro;
const std::nullopt_t none = std::nullopt;

TEST(ConciseWrites, TakesWritableParameterValuesOnly) {
  auto dcf = make_dcf({
      {0x1000, 0, DataType::Unsigned32, kRo, "0x00020192", none, 10},
      {0x1008, 0, DataType::VisibleString, AccessType::Const, "drive", none, 11},
      {0x1010, 1, DataType::Unsigned32, kRw, "0x65766173", none, 12},  // 'save'
      {0x1011, 1, DataType::Unsigned32, kRw, "0x64616F6C", none, 13},  // 'load'
      {0x1017, 0, DataType::Unsigned16, kRw, "1000", "0", 14},
      {0x1018, 1, DataType::Unsigned32, kRo, "0x1234", none, 15},
      {0x2000, 0, DataType::Unsigned8, kRw, none, "5", 16},
      {0x2001, 0, DataType::Unsigned8, AccessType::Wo, "7", none, 17},
      {0x2002, 0, DataType::Integer16, AccessType::Rwr, "-2", none, 18},
      {0x2003, 0, DataType::Integer16, AccessType::Rww, "-3", none, 19},
      {0x0007, 0, DataType::Unsigned32, kRw, "32", none, 20},  // data type definition area
  });
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_TRUE(diagnostics.empty()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u16(0x1017, 0, 1000), u8(0x2001, 0, 7), u16(0x2002, 0, 0xFFFE),
                                   u16(0x2003, 0, 0xFFFD)));
}

TEST(ConciseWrites, WithDefaultsAddsDefaultValues) {
  auto dcf = make_dcf({
      {0x1017, 0, DataType::Unsigned16, kRw, "1000", "0", 14},
      {0x2000, 0, DataType::Unsigned8, kRw, none, "5", 16},
      {0x2001, 0, DataType::Unsigned8, kRw, none, none, 17},
      {0x2002, 0, DataType::Unsigned8, kRo, none, "9", 18},
  });
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(ConciseSelection::WithDefaults), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u16(0x1017, 0, 1000), u8(0x2000, 0, 5)));
}

TEST(ConciseWrites, ChangedOnlyComparesValuesNotText) {
  auto dcf = make_dcf({
      {0x1017, 0, DataType::Unsigned16, kRw, "0x3E8", "1000", 14},  // same value
      {0x1016, 1, DataType::Unsigned32, kRw, "0x000201F4", "0", 15},
      {0x2000, 0, DataType::Unsigned8, kRw, "010", "8", 16},  // octal 010 == 8
      {0x2001, 0, DataType::Real32, kRw, "1.50", "1.5", 17},
      {0x2002, 0, DataType::VisibleString, kRw, "abc", "abc", 18},
      {0x2003, 0, DataType::Integer8, kRw, "-3", "0", 19},
      {0x2004, 0, DataType::Unsigned8, kRw, "4", none, 20},  // no default: changed
  });
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(ConciseSelection::ChangedOnly), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes,
              ElementsAre(u32(0x1016, 1, 0x000201F4), u8(0x2003, 0, 0xFD), u8(0x2004, 0, 4)));
}

TEST(ConciseWrites, EmptyParameterValueMeansNotConfigured) {
  auto dcf = make_dcf({{0x2000, 0, DataType::Unsigned8, kRw, "", "5", 16},
                       {0x2001, 0, DataType::Unsigned8, kRw, "  ", none, 17}});
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, IsEmpty());
}

TEST(ConciseWrites, RefuseWriteOnDownloadFlagIsHonoured) {
  // CiA 306 ObjFlags bit 0; e.g. 1003h sub 0, where writing 0 clears the error history.
  auto dcf = make_dcf({{0x1003, 0, DataType::Unsigned8, kRw, "0", none, 30},
                       {0x1017, 0, DataType::Unsigned16, kRw, "100", none, 31}});
  dcf.objects[0x1003].subs[0].obj_flags = 0x1;
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u16(0x1017, 0, 100)));
  ASSERT_EQ(diagnostics.size(), 1u);
  EXPECT_EQ(diagnostics.items()[0].severity, Severity::Note);
  EXPECT_EQ(diagnostics.items()[0].line, 30);
}

// CiA 301 §7.5.2.17: the device's EMCY is valid at its DefaultValue (85h at node 5), so a stream
// that moves it writes 1014h "not valid" first; a device refuses the change otherwise.
TEST(ConciseWrites, AMovedEmcyCobIdIsWrittenNotValidFirst) {
  auto dcf = make_dcf({{0x1014, 0, DataType::Unsigned32, kRw, "0xA5", "$NODEID+0x80", 40}}, 5);
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u32(0x1014, 0, 0x800000A5), u32(0x1014, 0, 0xA5)));
}

TEST(ConciseWrites, NodeIdComesFromCommissioningOrOptions) {
  // DefaultValue as an EDS gives it: the device has this EMCY COB-ID already, so no "not
  // valid" write goes before it (CiA 301 §7.5.2.17, download_order.hpp).
  auto dcf =
      make_dcf({{0x1014, 0, DataType::Unsigned32, kRw, "$NODEID+0x80", "$NODEID+0x80", 40}}, 5);
  Diagnostics diagnostics;
  auto from_dcf = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(from_dcf.has_value()) << diagnostics.format();
  EXPECT_THAT(*from_dcf, ElementsAre(u32(0x1014, 0, 0x85)));  // CiA 301 EMCY 80h + node-ID

  auto o = options();
  o.node_id = 7;
  auto from_options = concise_writes_from_dcf(dcf, o, diagnostics);
  ASSERT_TRUE(from_options.has_value()) << diagnostics.format();
  EXPECT_THAT(*from_options, ElementsAre(u32(0x1014, 0, 0x87)));
}

TEST(ConciseWrites, MissingNodeIdIsAnErrorWithFileAndLine) {
  auto dcf = make_dcf({{0x1014, 0, DataType::Unsigned32, kRw, "$NODEID+0x80", none, 40},
                       {0x1017, 0, DataType::Unsigned16, kRw, "1000", none, 41}});
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  EXPECT_FALSE(writes.has_value());
  ASSERT_EQ(diagnostics.count(Severity::Error), 1u) << diagnostics.format();
  EXPECT_THAT(diagnostics.items()[0].format(), HasSubstr("dev.dcf:40: error: [1014]"));
  EXPECT_THAT(diagnostics.items()[0].message, HasSubstr("no node-ID"));
  // The library speaks of its own parameters; how a user gives a node-ID is the caller's hint.
  EXPECT_THAT(diagnostics.items()[0].message, Not(HasSubstr("--node-id")));
  ConciseOptions hinted = options();
  hinted.node_id_hint = "give one with --node-id N";
  Diagnostics with_hint;
  EXPECT_FALSE(concise_writes_from_dcf(dcf, hinted, with_hint).has_value());
  ASSERT_EQ(with_hint.count(Severity::Error), 1u) << with_hint.format();
  EXPECT_THAT(with_hint.items()[0].message, HasSubstr("no node-ID"));
  EXPECT_THAT(with_hint.items()[0].message, HasSubstr("; give one with --node-id N"));
}

// What the concise stage says about a value names the line of the value's own key,
// as read from the file (ParameterValue=, DefaultValue=, an entry of [xxxxValue]), not the
// line of its section. No node-ID is known, so every $NODEID value is an error (DSP 302 §6.2
// needs the node-ID to compute it).
TEST(ConciseWrites, DiagnosticsNameTheLineOfTheValueKey) {
  const std::string text =
      "[1014]\n"                       // 1
      "ParameterName=COB-ID EMCY\n"    // 2
      "ObjectType=0x7\n"               // 3
      "DataType=0x0007\n"              // 4
      "AccessType=rw\n"                // 5
      "DefaultValue=$NODEID+0x80\n"    // 6
      "ParameterValue=$NODEID+0x81\n"  // 7
      "[1012]\n"                       // 8
      "ParameterName=COB-ID TIME\n"    // 9
      "ObjectType=0x7\n"               // 10
      "DataType=0x0007\n"              // 11
      "AccessType=rw\n"                // 12
      "\n"                             // 13
      "DefaultValue=$NODEID+0x100\n"   // 14
      "[2000]\n"                       // 15
      "ParameterName=Offsets\n"        // 16
      "ObjectType=0x8\n"               // 17
      "DataType=0x0007\n"              // 18
      "AccessType=rw\n"                // 19
      "CompactSubObj=2\n"              // 20
      "[2000Value]\n"                  // 21
      "NrOfEntries=1\n"                // 22
      "1=$NODEID\n";                   // 23
  ReadOptions read_options;
  read_options.file_name = "dev.dcf";
  auto read = parse_device_description(text, read_options);
  ASSERT_TRUE(read.device.has_value()) << read.diagnostics.format();

  Diagnostics configured;
  EXPECT_FALSE(concise_writes_from_dcf(*read.device, options(), configured).has_value());
  std::vector<int> lines;
  for (const auto& d : configured.items()) lines.push_back(d.line);
  EXPECT_THAT(lines, ElementsAre(7, 23)) << configured.format();  // 1014h, then 2000h sub 1
  EXPECT_THAT(configured.items()[0].format(), HasSubstr("dev.dcf:7: error: [1014] ParameterValue"));

  Diagnostics with_defaults;
  EXPECT_FALSE(
      concise_writes_from_dcf(*read.device, options(ConciseSelection::WithDefaults), with_defaults)
          .has_value());
  lines.clear();
  for (const auto& d : with_defaults.items()) lines.push_back(d.line);
  // By index: 1012h DefaultValue (line 14), 1014h ParameterValue, 2000h sub 1.
  EXPECT_THAT(lines, ElementsAre(14, 7, 23)) << with_defaults.format();
}

TEST(ConciseWrites, NodeIdIsNotNeededWhenNoValueUsesIt) {
  auto dcf = make_dcf({{0x1017, 0, DataType::Unsigned16, kRw, "1000", none, 41},
                       {0x1014, 0, DataType::Unsigned32, kRw, none, "$NODEID+0x80", 40}});
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u16(0x1017, 0, 1000)));
}

TEST(ConciseWrites, NodeIdOutsideOneTo127IsRejected) {
  auto dcf = make_dcf({{0x1017, 0, DataType::Unsigned16, kRw, "1000", none, 41}});
  for (int id : {0, 128, 255}) {
    auto o = options();
    o.node_id = static_cast<std::uint8_t>(id);
    Diagnostics diagnostics;
    EXPECT_FALSE(concise_writes_from_dcf(dcf, o, diagnostics).has_value()) << id;
    EXPECT_TRUE(diagnostics.has_errors()) << id;
  }
}

TEST(ConciseWrites, ValuesThatCannotBeEncodedAreErrorsNeverZeroOrTruncated) {
  auto dcf = make_dcf({
      {0x2000, 0, DataType::Unsigned8, kRw, "256", none, 50},         // out of range
      {0x2001, 0, DataType::Unsigned16, kRw, "twelve", none, 51},     // not a number
      {0x2002, 0, DataType::Integer8, kRw, "-129", none, 52},         // out of range
      {0x2003, 0, DataType::Unsigned24, kRw, "0x1000000", none, 53},  // 25 bits
      {0x2004, 0, DataType::Unsigned16, kRw, "1000", none, 54},       // fine
  });
  dcf.objects[0x2005] = dcf.objects[0x2004];
  dcf.objects[0x2005].index = 0x2005;
  dcf.objects[0x2005].subs[0].data_type = 0x0020;  // PDO_COMMUNICATION_PARAMETER: not basic
  dcf.objects[0x2005].subs[0].line = 55;
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  EXPECT_FALSE(writes.has_value());
  ASSERT_EQ(diagnostics.count(Severity::Error), 5u) << diagnostics.format();
  std::vector<int> lines;
  for (const auto& d : diagnostics.items()) lines.push_back(d.line);
  EXPECT_THAT(lines, ElementsAre(50, 51, 52, 53, 55));
  EXPECT_THAT(diagnostics.items()[0].format(), HasSubstr("dev.dcf:50: error: [2000]"));
  EXPECT_THAT(diagnostics.items()[4].message, HasSubstr("0x0020"));
}

TEST(ConciseWrites, VerifyConfigurationComesLast) {
  // CiA 301 1020h (configuration date, time): written after every other value, which would
  // reset it (DSP 302 v3.2.1 §6.3). lely dcfgen never writes 1020h at all.
  auto dcf = make_dcf({{0x1020, 1, DataType::Unsigned32, kRw, "14000", none, 1},
                       {0x1020, 2, DataType::Unsigned32, kRw, "36000000", none, 2},
                       {0x6081, 0, DataType::Unsigned32, kRw, "1000", none, 3}});
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes,
              ElementsAre(u32(0x6081, 0, 1000), u32(0x1020, 1, 14000), u32(0x1020, 2, 36000000)));
}

TEST(ConciseWrites, OddWidthIntegersHaveTheirOwnSize) {
  // CiA 301 §7.1.4/§7.1.5: INTEGER24 is 3 bytes, UNSIGNED40 5, ... (lely dcfgen pads these to
  // 4 or 8 bytes; see tests/cfg/dcfgen-differences.md).
  auto dcf = make_dcf({
      {0x2010, 0, DataType::Unsigned24, kRw, "0x123456", none, 1},
      {0x2011, 0, DataType::Integer24, kRw, "-2", none, 2},
      {0x2012, 0, DataType::Unsigned40, kRw, "0x123456789A", none, 3},
      {0x2013, 0, DataType::Integer40, kRw, "-549755813888", none, 4},  // -2^39, the minimum
      {0x2014, 0, DataType::Unsigned48, kRw, "0xA1A2A3A4A5A6", none, 5},
      {0x2015, 0, DataType::Integer48, kRw, "-1", none, 6},
      {0x2016, 0, DataType::Unsigned56, kRw, "0x01020304050607", none, 7},
      {0x2017, 0, DataType::Integer56, kRw, "36028797018963967", none, 8},  // 2^55-1, maximum
      {0x2018, 0, DataType::Unsigned64, kRw, "0xFFFFFFFFFFFFFFFF", none, 9},
  });
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes,
              ElementsAre(ObjectWrite{0x2010, 0, {0x56, 0x34, 0x12}},
                          ObjectWrite{0x2011, 0, {0xFE, 0xFF, 0xFF}},
                          ObjectWrite{0x2012, 0, {0x9A, 0x78, 0x56, 0x34, 0x12}},
                          ObjectWrite{0x2013, 0, {0x00, 0x00, 0x00, 0x00, 0x80}},
                          ObjectWrite{0x2014, 0, {0xA6, 0xA5, 0xA4, 0xA3, 0xA2, 0xA1}},
                          ObjectWrite{0x2015, 0, Bytes(6, 0xFF)},
                          ObjectWrite{0x2016, 0, {0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01}},
                          ObjectWrite{0x2017, 0, {0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0xFF, 0x7F}},
                          ObjectWrite{0x2018, 0, Bytes(8, 0xFF)}));
}

TEST(ConciseWrites, RealValuesAreIeee754NotTruncated) {
  // IEEE 754: 1.5f = 3FC00000h, 0.1f = 3DCCCCCDh (round to nearest), -2.25 = C002000000000000h.
  auto dcf = make_dcf({{0x2020, 0, DataType::Real32, kRw, "1.5", none, 1},
                       {0x2021, 0, DataType::Real32, kRw, "0.1", none, 2},
                       {0x2022, 0, DataType::Real64, kRw, "-2.25", none, 3}});
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u32(0x2020, 0, 0x3FC00000), u32(0x2021, 0, 0x3DCCCCCD),
                                   ObjectWrite{0x2022, 0, le(0xC002000000000000, 8)}));
}

TEST(ConciseWrites, StringsAreTheirBytes) {
  auto dcf = make_dcf({{0x2030, 0, DataType::VisibleString, kRw, "Axis 1", none, 1},
                       {0x2031, 0, DataType::OctetString, kRw, "0102FF", none, 2},
                       {0x2032, 0, DataType::UnicodeString, kRw, "Ab", none, 3}});
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(ObjectWrite{0x2030, 0, {'A', 'x', 'i', 's', ' ', '1'}},
                                   ObjectWrite{0x2031, 0, {0x01, 0x02, 0xFF}},
                                   ObjectWrite{0x2032, 0, {'A', 0, 'b', 0}}));  // UTF-16LE
}

class ConciseDomain : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::filesystem::temp_directory_path() /
           ("concise_domain_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
            "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(dir_ / "data");
    std::ofstream(dir_ / "data" / "program.bin", std::ios::binary).write("CAN\0\xFF", 5);
  }
  void TearDown() override { std::filesystem::remove_all(dir_); }
  std::filesystem::path dir_;
};

TEST_F(ConciseDomain, DataComesFromDownloadFileRelativeToBaseDir) {
  auto dcf = make_dcf({{0x1F50, 1, DataType::Domain, AccessType::Wo, none, none, 60},
                       {0x2040, 0, DataType::Domain, kRw, "DEADBEEF", none, 61}});
  dcf.objects[0x1F50].subs[1].download_file = "data/program.bin";
  auto o = options();
  o.base_dir = dir_.string();
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, o, diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(ObjectWrite{0x1F50, 1, {'C', 'A', 'N', 0x00, 0xFF}},
                                   ObjectWrite{0x2040, 0, {0xDE, 0xAD, 0xBE, 0xEF}}));
}

TEST_F(ConciseDomain, AbsoluteDownloadFileIgnoresBaseDir) {
  auto dcf = make_dcf({{0x1F50, 1, DataType::Domain, AccessType::Wo, none, none, 60}});
  dcf.objects[0x1F50].subs[1].download_file = (dir_ / "data" / "program.bin").string();
  auto o = options();
  o.base_dir = "/nonexistent";
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, o, diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_EQ(writes->at(0).data.size(), 5u);
}

TEST_F(ConciseDomain, MissingDownloadFileIsAnError) {
  auto dcf = make_dcf({{0x1F50, 1, DataType::Domain, AccessType::Wo, none, none, 60}});
  dcf.objects[0x1F50].subs[1].download_file = "data/missing.bin";
  auto o = options();
  o.base_dir = dir_.string();
  Diagnostics diagnostics;
  EXPECT_FALSE(concise_writes_from_dcf(dcf, o, diagnostics).has_value());
  ASSERT_EQ(diagnostics.count(Severity::Error), 1u);
  EXPECT_EQ(diagnostics.items()[0].line, 60);
  EXPECT_THAT(diagnostics.items()[0].message, HasSubstr("missing.bin"));
}

// RPDO 1 of node 3 configured in a DCF: the mapping and transmission type have ParameterValues,
// the COB-ID only its default. The writes follow DSP 302 §6.2 with the COB-ID from the DCF.
DeviceDescription rpdo1_dcf() {
  return make_dcf(
      {
          {0x1400, 0, DataType::Unsigned8, AccessType::Const, none, "2", 100},
          {0x1400, 1, DataType::Unsigned32, kRw, none, "$NODEID+0x200", 101},
          {0x1400, 2, DataType::Unsigned8, kRw, "1", "0xFF", 102},
          {0x1600, 0, DataType::Unsigned8, kRw, "2", "2", 110},
          {0x1600, 1, DataType::Unsigned32, kRw, "0x60400010", "0x60400010", 111},
          {0x1600, 2, DataType::Unsigned32, kRw, "0x607A0020", "0x60600008", 112},
          {0x6040, 0, DataType::Unsigned16, kRw, none, "0", 200},
      },
      3);
}

TEST(ConciseWrites, PdoWritesFollowDsp302OrderWithCobIdFromTheDcf) {
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(rpdo1_dcf(), options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_TRUE(diagnostics.empty()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u32(0x1400, 1, 0x80000203), u8(0x1400, 2, 1), u8(0x1600, 0, 0),
                                   u32(0x1600, 1, 0x60400010), u32(0x1600, 2, 0x607A0020),
                                   u8(0x1600, 0, 2), u32(0x1400, 1, 0x203)));
}

TEST(ConciseWrites, ChangedOnlyMappingEntryBringsItsCount) {
  // Only 1600h sub 2 differs from its default; the mapping must still be deactivated (sub 0 =
  // 0) and activated again with the DCF's count, and the PDO disabled around it.
  Diagnostics diagnostics;
  auto writes =
      concise_writes_from_dcf(rpdo1_dcf(), options(ConciseSelection::ChangedOnly), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes,
              ElementsAre(u32(0x1400, 1, 0x80000203), u8(0x1400, 2, 1), u8(0x1600, 0, 0),
                          u32(0x1600, 2, 0x607A0020), u8(0x1600, 0, 2), u32(0x1400, 1, 0x203)));
}

TEST(ConciseWrites, UnknownCobIdIsAWarning) {
  auto dcf = make_dcf({{0x1401, 2, DataType::Unsigned8, kRw, "1", none, 120}});
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u8(0x1401, 2, 1)));
  ASSERT_EQ(diagnostics.count(Severity::Warning), 1u) << diagnostics.format();
  EXPECT_EQ(diagnostics.items()[0].line, 120);
  EXPECT_THAT(diagnostics.items()[0].message, HasSubstr("1401h"));
}

TEST(ConciseWrites, ReadOnlyCobIdGetsNoPairAndNoWarning) {
  // DSP 302 §6.2 step 1: "Delete the PDO by setting bit 31 to 1 (if it is not readonly)".
  auto dcf = make_dcf({{0x1800, 1, DataType::Unsigned32, kRo, none, "0x181", 130},
                       {0x1800, 2, DataType::Unsigned8, kRw, "1", none, 131}});
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(dcf, options(), diagnostics);
  ASSERT_TRUE(writes.has_value()) << diagnostics.format();
  EXPECT_THAT(*writes, ElementsAre(u8(0x1800, 2, 1)));
  EXPECT_TRUE(diagnostics.empty()) << diagnostics.format();
}

TEST(ConciseWrites, CobIdNeededForThePairMustBeReadable) {
  auto dcf = make_dcf({{0x1800, 1, DataType::Unsigned32, kRw, none, "$NODEID+0x180", 130},
                       {0x1800, 2, DataType::Unsigned8, kRw, "1", none, 131}});
  Diagnostics diagnostics;  // no node-ID anywhere
  EXPECT_FALSE(concise_writes_from_dcf(dcf, options(), diagnostics).has_value());
  ASSERT_EQ(diagnostics.count(Severity::Error), 1u) << diagnostics.format();
  EXPECT_EQ(diagnostics.items()[0].line, 130);
}

}  // namespace
}  // namespace cfg
