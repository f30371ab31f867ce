// cfgmgr sdo read|write end to end: the command line (usage errors, help) here; transfers over
// UDP multicast against `cfgmgr simulate` inside a private network namespace
// (tests/support/run_in_netns.sh): Sdo.EndToEndOverUdp re-runs this executable there with
// --gtest_filter=SdoInNetns.*; those tests skip anywhere else.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <csignal>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "tool_test_support.hpp"

namespace {

using namespace std::chrono_literals;
using ::testing::HasSubstr;
using tool_test::cfgmgr;
using tool_test::data_path;
using tool_test::Json;
using tool_test::JsonParser;
using tool_test::ScratchDir;

const std::string kDevice = data_path("sim_device.eds");
const std::string kUrl = test_support::udp_test_url("43181");

TEST(Sdo, HelpDocumentsActionsExamplesAndExitCodes) {
  ScratchDir dir;
  const auto r = cfgmgr(dir, {"sdo", "--help"});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_THAT(r.out, HasSubstr("read NODE INDEX[:SUB]"));
  EXPECT_THAT(r.out, HasSubstr("write NODE INDEX[:SUB] VALUE"));
  EXPECT_THAT(r.out, HasSubstr("Examples:"));
  EXPECT_THAT(r.out, HasSubstr("Exit codes:"));
  EXPECT_THAT(cfgmgr(dir, {"--help"}).out, HasSubstr("sdo"));
}

TEST(Sdo, UsageErrorsExit2BeforeTheBusIsOpened) {
  ScratchDir dir;
  const auto exit_of = [&](const std::vector<std::string>& args) {
    std::vector<std::string> all{"sdo"};
    all.insert(all.end(), args.begin(), args.end());
    return cfgmgr(dir, all);
  };
  EXPECT_EQ(exit_of({"read", "5", "1018:1"}).exit_code, 2);  // --bus is required
  const auto node = exit_of({"read", "--bus", kUrl, "128", "1018:1"});
  EXPECT_EQ(node.exit_code, 2);
  EXPECT_THAT(node.err, HasSubstr("NODE 128: expected a node-ID 1..127"));
  const auto address = exit_of({"read", "--bus", kUrl, "5", "10180:1"});
  EXPECT_EQ(address.exit_code, 2);
  EXPECT_THAT(address.err, HasSubstr("INDEX[:SUB] 10180:1"));
  EXPECT_EQ(exit_of({"read", "--bus", kUrl, "5", "1018:100"}).exit_code, 2);
  const auto type = exit_of({"read", "--bus", kUrl, "5", "1018:1", "--type", "u33"});
  EXPECT_EQ(type.exit_code, 2);
  EXPECT_THAT(type.err, HasSubstr("--type u33"));
  // A value needs a type; 70000 is no UNSIGNED16 (CiA 301 §7.1.4.2: 0..65535).
  const auto untyped = exit_of({"write", "--bus", kUrl, "5", "1017:0", "500"});
  EXPECT_EQ(untyped.exit_code, 2);
  EXPECT_THAT(untyped.err, HasSubstr("give its data type with --type"));
  EXPECT_EQ(exit_of({"write", "--bus", kUrl, "5", "1017:0", "70000", "--type", "u16"}).exit_code,
            2);
  EXPECT_EQ(exit_of({"write", "--bus", kUrl, "5", "1017:0"}).exit_code, 2);  // no value
  // sim_device.eds has no 1018h sub 07h to take a type from.
  const auto eds = exit_of({"read", "--bus", kUrl, "5", "1018:7", "--eds", kDevice});
  EXPECT_EQ(eds.exit_code, 2);
  EXPECT_THAT(eds.err, HasSubstr("has no 1018h sub 07h"));
  // The simulated bus has no node to talk to; a malformed URL is a usage error.
  EXPECT_EQ(exit_of({"read", "--bus", "sim:", "5", "1000"}).exit_code, 2);
  EXPECT_EQ(exit_of({"read", "--bus", "udp://10.0.0.1:43113", "5", "1000"}).exit_code, 2);
  // A response timeout that rounds to 0 us can never be met (SdoClient::check_start).
  const auto timeout = exit_of({"read", "--bus", kUrl, "5", "1000", "--sdo-timeout", "1e-7"});
  EXPECT_EQ(timeout.exit_code, 2);
  EXPECT_THAT(timeout.err, HasSubstr("--sdo-timeout"));
  EXPECT_EQ(exit_of({"read", "--bus", kUrl, "5", "1000", "--eds", dir / "absent.eds"}).exit_code,
            3);
}

// --------------------------------------------------------- over UDP, in a namespace ----------

TEST(Sdo, EndToEndOverUdp) {
  tool_test::run_in_private_netns("SdoInNetns.*");
}

// `cfgmgr simulate` with sim_device.eds as node 5, up once its boot-up (705#00) went out.
class SdoInNetns : public ::testing::Test {
 protected:
  void SetUp() override {
    REQUIRE_ISOLATED_MULTICAST();
    sim_.emplace("cfgmgr",
                 std::vector<std::string>{"simulate", "--bus", kUrl, "-v", kDevice + "@5"},
                 dir_ / "sim.out", dir_ / "sim.err");
    ASSERT_TRUE(sim_->started());
    // Its boot-up (700h + node 5, data 00h, CiA 301 §7.2.8.3.3) went out: it answers SDO now.
    ASSERT_TRUE(sim_->wait_for_output("tx  705#00", 5s)) << sim_->output();
  }
  void TearDown() override {
    if (sim_) {
      EXPECT_EQ(sim_->stop(SIGINT, 3000ms), 0);
    }
  }
  tool_test::RunResult sdo(std::vector<std::string> args) {
    args.insert(args.begin(), {"sdo", "--bus", kUrl});
    return cfgmgr(dir_, args);
  }
  static Json json_of(const tool_test::RunResult& r) { return tool_test::json_object_of(r.out); }

  ScratchDir dir_;
  std::optional<tool_test::SpawnedTool> sim_;
};

TEST_F(SdoInNetns, ReadsAValueTypedByTypeOrByTheEds) {
  // sim_device.eds [1018sub1] DefaultValue=0x7E57C0DE (UNSIGNED32, its vendor-ID).
  const auto typed = sdo({"read", "5", "1018:1", "--type", "u32"});
  EXPECT_EQ(typed.exit_code, 0) << typed.err;
  EXPECT_EQ(typed.out, "2119680222 (0x7E57C0DE)\n");
  const auto by_eds = sdo({"read", "5", "0x1018:0x01", "--eds", kDevice});
  EXPECT_EQ(by_eds.exit_code, 0) << by_eds.err;
  EXPECT_EQ(by_eds.out, typed.out);
  // Untyped: the bytes as they came, little-endian (CiA 301 §7.1).
  const auto untyped = sdo({"read", "5", "1018:1"});
  EXPECT_EQ(untyped.exit_code, 0) << untyped.err;
  EXPECT_EQ(untyped.out, "DE C0 57 7E (4 bytes)\n");
  // [2001] Device name, VISIBLE_STRING "SIM-8".
  const auto name = sdo({"read", "5", "2001", "--eds", kDevice, "--json"});
  EXPECT_EQ(name.exit_code, 0) << name.err;
  const Json json = json_of(name);
  EXPECT_TRUE(json.get("ok")->boolean);
  EXPECT_EQ(json.get("type")->string, "VISIBLE_STRING");
  EXPECT_EQ(json.get("value")->string, "SIM-8");
  EXPECT_EQ(json.get("hex")->string, "53494d2d38");
  EXPECT_EQ(json.get("protocol")->string, "segmented");  // 5 bytes: no expedited upload
  EXPECT_TRUE(json.get("abort")->is(Json::Kind::Null));
}

TEST_F(SdoInNetns, WritesThenReadsBack) {
  // 1017h Producer heartbeat time, UNSIGNED16 rw in sim_device.eds.
  const auto write = sdo({"write", "5", "1017:0", "250", "--eds", kDevice});
  EXPECT_EQ(write.exit_code, 0) << write.err;
  EXPECT_EQ(write.out, "");
  EXPECT_EQ(sdo({"read", "5", "1017", "-t", "u16"}).out, "250 (0x00FA)\n");
  // $NODEID in a value is NODE, as in the node's DCF (CiA 306 §4.6.3): 0x80 + 5.
  EXPECT_EQ(sdo({"write", "5", "1014", "$NODEID+0x80", "-t", "u32"}).exit_code, 0);
  EXPECT_EQ(sdo({"read", "5", "1014", "-t", "u32"}).out, "133 (0x00000085)\n");
}

TEST_F(SdoInNetns, LargeValuesGoByBlockTransfer) {
  // 2000 bytes (more than one 889-byte sub-block of 127 segments) into 2001h VISIBLE_STRING.
  std::string text;
  for (int i = 0; i < 2000; ++i) text += static_cast<char>('a' + i % 26);
  tool_test::write_file(dir_ / "long.txt", text);
  const auto write = sdo({"write", "5", "2001", "--file", dir_ / "long.txt", "--json"});
  EXPECT_EQ(write.exit_code, 0) << write.err;
  EXPECT_EQ(json_of(write).get("protocol")->string, "block");
  const auto read = sdo({"read", "5", "2001", "--block", "-o", dir_ / "back.txt"});
  EXPECT_EQ(read.exit_code, 0) << read.err;
  EXPECT_EQ(tool_test::slurp(dir_ / "back.txt"), text);
  const auto raw = sdo({"read", "5", "2001", "--raw"});
  EXPECT_EQ(raw.out, text);
}

TEST_F(SdoInNetns, AnAbortIsReportedInWordsWithExit1) {
  // CiA 301 §7.2.4.3.17 abort codes: 0609 0011 sub-index does not exist (1018h has sub 0-4),
  // 0601 0002 attempt to write a read only object (1000h is ro).
  const auto missing = sdo({"read", "5", "1018:5", "--type", "u32"});
  EXPECT_EQ(missing.exit_code, 1);
  EXPECT_THAT(missing.err, HasSubstr("node 5: 1018h sub 05h: read failed: SDO abort 0x06090011 "
                                     "(sub-index does not exist), sent by the device"));
  EXPECT_EQ(missing.out, "");
  const auto read_only = sdo({"write", "5", "1000", "0", "--type", "u32", "--json"});
  EXPECT_EQ(read_only.exit_code, 1);
  EXPECT_THAT(read_only.err, HasSubstr("0x06010002"));
  const Json json = json_of(read_only);
  EXPECT_FALSE(json.get("ok")->boolean);
  EXPECT_EQ(json.get("abort")->string, "0x06010002");
  EXPECT_EQ(json.get("aborted_by")->string, "device");
  // CiA 301 abort code table: 0601 0002 "Attempt to write a read only object".
  EXPECT_EQ(json.get("abort_text")->string, "attempt to write a read only object");
}

TEST_F(SdoInNetns, ANodeThatDoesNotAnswerTimesOutWithExit3) {
  // Nobody is node 9: the client gives up after --sdo-timeout with 0504 0000.
  const auto r = sdo({"read", "9", "1000", "--sdo-timeout", "0.2"});
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_THAT(r.err, HasSubstr("0x05040000"));
  EXPECT_THAT(r.err, HasSubstr("sent by this client"));
}

}  // namespace
