// cfg::diff_parameters on tests/data/diff (README there): the parameter of an entry is the value
// a download writes, ParameterValue else DefaultValue (CiA 306 §4.6.3), compared typed.
#include "cfg/dcf_diff.hpp"

#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "test_paths.hpp"

namespace {

using Kind = cfg::ParameterDifference::Kind;

cfg::DeviceDescription read(const std::string& name) {
  auto r = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/diff/" + name);
  EXPECT_TRUE(r.ok()) << r.diagnostics.format();
  return r.device.value_or(cfg::DeviceDescription{});
}

const cfg::ParameterDifference* find(const std::vector<cfg::ParameterDifference>& diffs,
                                     std::uint16_t index, std::uint8_t sub) {
  for (const auto& d : diffs) {
    if (d.address == cfg::ObjectAddress{index, sub}) return &d;
  }
  return nullptr;
}

TEST(DcfDiff, ListsEveryParameterThatDiffersByIndexAndSubIndex) {
  const auto diffs = cfg::diff_parameters(read("a.dcf"), read("b.dcf"));
  std::vector<cfg::ObjectAddress> got;
  got.reserve(diffs.size());
  for (const auto& d : diffs) got.push_back(d.address);
  const std::vector<cfg::ObjectAddress> want = {{0x1017, 0}, {0x1800, 1}, {0x2000, 0},
                                                {0x2001, 0}, {0x2003, 0}, {0x2004, 0}};
  EXPECT_EQ(got, want);
}

TEST(DcfDiff, ValuesAreInWordsWithTheirLines) {
  const auto diffs = cfg::diff_parameters(read("a.dcf"), read("b.dcf"));
  const auto* heartbeat = find(diffs, 0x1017, 0);
  ASSERT_NE(heartbeat, nullptr);
  EXPECT_EQ(heartbeat->kind, Kind::Changed);
  EXPECT_EQ(heartbeat->name, "Producer heartbeat time");
  EXPECT_EQ(heartbeat->a->text, "1000 (0x03E8)");  // UNSIGNED16 1000
  EXPECT_EQ(heartbeat->b->text, "500 (0x01F4)");
  EXPECT_EQ(heartbeat->a->line, 94);  // a.dcf: ParameterValue=1000
  const auto* label = find(diffs, 0x2000, 0);
  ASSERT_NE(label, nullptr);
  EXPECT_EQ(label->a->text, "\"left arm\"");  // VISIBLE_STRING, quoted
  EXPECT_EQ(label->b->text, "\"right arm\"");
  const auto* gain = find(diffs, 0x2001, 0);
  ASSERT_NE(gain, nullptr);
  EXPECT_EQ(gain->a->text, "1.5");  // REAL32 as a number
  EXPECT_EQ(gain->b->text, "2.25");
}

// $NODEID+0x180 is 182h in node 2's file and 183h in node 3's: different parameters. With one
// node-ID for both, the same.
TEST(DcfDiff, NodeIdValuesAreResolvedWithEachFilesNodeId) {
  const auto own = cfg::diff_parameters(read("a.dcf"), read("b.dcf"));
  const auto* cob = find(own, 0x1800, 1);
  ASSERT_NE(cob, nullptr);
  EXPECT_EQ(cob->name, "TPDO 1 communication parameter / COB-ID used by TPDO");
  EXPECT_EQ(cob->a->text, "386 (0x00000182)");
  EXPECT_EQ(cob->b->text, "387 (0x00000183)");
  cfg::DiffOptions one;
  one.node_id_a = one.node_id_b = 5;
  EXPECT_EQ(find(cfg::diff_parameters(read("a.dcf"), read("b.dcf"), one), 0x1800, 1), nullptr);
}

// 1800h sub 2: 0x10 and 16 are one UNSIGNED8; 2002h: a's ParameterValue 250 and b's
// DefaultValue 250 (no ParameterValue) are what a download writes either way (CiA 306).
TEST(DcfDiff, EqualValuesWrittenDifferentlyAreNoDifference) {
  const auto diffs = cfg::diff_parameters(read("a.dcf"), read("b.dcf"));
  EXPECT_EQ(find(diffs, 0x1800, 2), nullptr);
  EXPECT_EQ(find(diffs, 0x2002, 0), nullptr);
}

TEST(DcfDiff, ObjectsInOneFileOnlyAreListedAsSuch) {
  const auto diffs = cfg::diff_parameters(read("a.dcf"), read("b.dcf"));
  const auto* a_only = find(diffs, 0x2003, 0);
  ASSERT_NE(a_only, nullptr);
  EXPECT_EQ(a_only->kind, Kind::OnlyInA);
  EXPECT_TRUE(a_only->whole_object);
  EXPECT_TRUE(a_only->a.has_value());
  EXPECT_FALSE(a_only->b.has_value());
  const auto* b_only = find(diffs, 0x2004, 0);
  ASSERT_NE(b_only, nullptr);
  EXPECT_EQ(b_only->kind, Kind::OnlyInB);
  EXPECT_EQ(b_only->name, "Only in B");
}

TEST(DcfDiff, AFileComparedWithItselfHasNoDifference) {
  EXPECT_TRUE(cfg::diff_parameters(read("a.dcf"), read("a.dcf")).empty());
}

// CiA DSP 302 §8.4 [DynamicChannels]: channels_b.dcf keeps the 2000h segment, changes MaxCnt of
// the 2010h one (16 -> 24), lacks the 2020h one and adds one at 2100h (tests/data/diff/README.md).
TEST(DcfDiff, DynamicChannelSegmentsAddedRemovedAndChanged_8_4) {
  const auto a = read("channels_a.dcf");
  const auto b = read("channels_b.dcf");
  // Same objects: no parameter differs, only the section.
  EXPECT_TRUE(cfg::diff_parameters(a, b).empty());
  const auto diffs = cfg::diff_dynamic_channels(a, b);
  ASSERT_EQ(diffs.size(), 3U);
  const auto& changed = diffs[0];
  EXPECT_EQ(changed.kind, Kind::Changed);
  EXPECT_EQ(changed.first_index, 0x2010);
  EXPECT_EQ(changed.segment_a, 2U);
  EXPECT_EQ(changed.segment_b, 2U);
  EXPECT_EQ(changed.a->text, "UNSIGNED16 ro 2010h-2011h, PPOffset 0, MaxCnt 16");
  EXPECT_EQ(changed.b->text, "UNSIGNED16 ro 2010h-2011h, PPOffset 0, MaxCnt 24");
  const auto& removed = diffs[1];
  EXPECT_EQ(removed.kind, Kind::OnlyInA);
  EXPECT_EQ(removed.first_index, 0x2020);
  EXPECT_EQ(removed.segment_a, 3U);
  EXPECT_EQ(removed.segment_b, 0U);
  EXPECT_EQ(removed.a->text, "UNSIGNED32 ro 2020h, PPOffset 0, MaxCnt 8");
  EXPECT_FALSE(removed.b.has_value());
  const auto& added = diffs[2];
  EXPECT_EQ(added.kind, Kind::OnlyInB);
  EXPECT_EQ(added.first_index, 0x2100);
  EXPECT_EQ(added.segment_b, 3U);
  EXPECT_EQ(added.b->text, "UNSIGNED8 wo 2100h-2101h, PPOffset 0, MaxCnt 16");
  EXPECT_FALSE(added.a.has_value());
}

TEST(DcfDiff, DynamicChannelsOnlyInOneFileAreEverySegmentAddedOrRemoved) {
  const auto diffs = cfg::diff_dynamic_channels(read("a.dcf"), read("channels_a.dcf"));
  ASSERT_EQ(diffs.size(), 3U);
  for (const auto& d : diffs) EXPECT_EQ(d.kind, Kind::OnlyInB);
  EXPECT_TRUE(cfg::diff_dynamic_channels(read("channels_a.dcf"), read("channels_a.dcf")).empty());
  EXPECT_TRUE(cfg::diff_dynamic_channels(read("a.dcf"), read("b.dcf")).empty());
}

}  // namespace
