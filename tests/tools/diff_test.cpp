// cfgmgr diff end to end on tests/data/diff (README there). Exit codes as diff(1).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "tool_test_support.hpp"

namespace {

using ::testing::HasSubstr;
using tool_test::cfgmgr;
using tool_test::Json;
using tool_test::JsonParser;
using tool_test::ScratchDir;

const tool_test::DataDir data("diff");

TEST(Diff, PrintsTheDifferingParametersInWordsAndExits1) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"diff", data("a.dcf"), data("b.dcf")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  // 1017h: ParameterValue 1000 in a.dcf (line 94), 500 in b.dcf.
  EXPECT_THAT(r.out, HasSubstr("1017h sub 00h Producer heartbeat time\n  " + data("a.dcf") +
                               ":94: 1000 (0x03E8)\n  " + data("b.dcf") + ":94: 500 (0x01F4)\n"));
  EXPECT_THAT(r.out, HasSubstr(": \"left arm\"\n"));
  EXPECT_THAT(r.out, HasSubstr(": 2.25\n"));
  EXPECT_THAT(r.out, HasSubstr("2003h Only in A: only in " + data("a.dcf")));
  EXPECT_THAT(r.out, HasSubstr("6 differences\n"));
}

TEST(Diff, SameFilesExit0) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"diff", data("a.dcf"), data("a.dcf")});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.out, "no differences\n");
}

TEST(Diff, JsonHasOneEntryPerDifference) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"diff", "--json", data("a.dcf"), data("b.dcf")});
  EXPECT_EQ(r.exit_code, 1);
  JsonParser parser(r.out);
  const auto json = parser.parse();
  ASSERT_TRUE(json) << parser.error() << "\n" << r.out;
  EXPECT_FALSE(json->get("same")->boolean);
  const auto& diffs = json->get("differences")->array;
  ASSERT_EQ(diffs.size(), 6U);
  const Json& cob = diffs[1];
  EXPECT_EQ(cob.get("index")->number, 0x1800);
  EXPECT_EQ(cob.get("sub_index")->number, 1);
  EXPECT_EQ(cob.get("kind")->string, "changed");
  EXPECT_EQ(cob.get("a")->get("value")->string, "386 (0x00000182)");  // $NODEID 2 + 0x180
  EXPECT_EQ(cob.get("b")->get("value")->string, "387 (0x00000183)");
  EXPECT_EQ(diffs[4].get("kind")->string, "only_in_a");
  EXPECT_TRUE(diffs[4].get("b")->is(Json::Kind::Null));
}

TEST(Diff, NodeIdOptionResolvesBothFilesAlike) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"diff", "--node-id", "5", data("a.dcf"), data("b.dcf")});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_THAT(r.out, ::testing::Not(HasSubstr("1800h sub 01h")));
  EXPECT_THAT(r.out, HasSubstr("5 differences\n"));
}

TEST(Diff, TroubleExits2) {
  ScratchDir dir;
  EXPECT_EQ(cfgmgr(dir, {"diff", data("a.dcf"), dir / "absent.dcf"}).exit_code, 2);
  EXPECT_EQ(cfgmgr(dir, {"diff", data("a.dcf")}).exit_code, 2);
  EXPECT_EQ(cfgmgr(dir, {"diff", "--node-id", "0", data("a.dcf"), data("b.dcf")}).exit_code, 2);
  const auto help = cfgmgr(dir, {"diff", "--help"});
  EXPECT_EQ(help.exit_code, 0);
  EXPECT_THAT(help.out, HasSubstr("Examples:"));
}

// CiA DSP 302 §8.4: [DynamicChannels] segments changed, removed and added (README in
// tests/data/diff); the objects of the two files are the same.
TEST(Diff, DynamicChannelSegmentsAreCompared) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"diff", data("channels_a.dcf"), data("channels_b.dcf")});
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_THAT(r.out,
              HasSubstr("[DynamicChannels] segment at 2010h\n  " + data("channels_a.dcf") +
                        " (segment 2): UNSIGNED16 ro 2010h-2011h, PPOffset 0, MaxCnt 16\n  " +
                        data("channels_b.dcf") +
                        " (segment 2): UNSIGNED16 ro 2010h-2011h, PPOffset 0, MaxCnt 24\n"));
  EXPECT_THAT(r.out, HasSubstr("[DynamicChannels] segment at 2020h: only in " +
                               data("channels_a.dcf") + " (segment 3): UNSIGNED32 ro 2020h"));
  EXPECT_THAT(r.out, HasSubstr("[DynamicChannels] segment at 2100h: only in " +
                               data("channels_b.dcf") + " (segment 3): UNSIGNED8 wo 2100h-2101h"));
  EXPECT_THAT(r.out, HasSubstr("3 differences\n"));

  const auto j = cfgmgr(dir, {"diff", "--json", data("channels_a.dcf"), data("channels_b.dcf")});
  EXPECT_EQ(j.exit_code, 1);
  JsonParser parser(j.out);
  const auto json = parser.parse();
  ASSERT_TRUE(json) << parser.error() << "\n" << j.out;
  EXPECT_FALSE(json->get("same")->boolean);
  EXPECT_TRUE(json->get("differences")->array.empty());
  const auto& segments = json->get("dynamic_channels")->array;
  ASSERT_EQ(segments.size(), 3U);
  EXPECT_EQ(segments[0].get("first_index")->number, 0x2010);
  EXPECT_EQ(segments[0].get("kind")->string, "changed");
  EXPECT_EQ(segments[1].get("kind")->string, "only_in_a");
  EXPECT_TRUE(segments[1].get("segment_b")->is(Json::Kind::Null));
  EXPECT_EQ(segments[2].get("kind")->string, "only_in_b");

  EXPECT_EQ(cfgmgr(dir, {"diff", data("channels_a.dcf"), data("channels_a.dcf")}).exit_code, 0);
}

}  // namespace
