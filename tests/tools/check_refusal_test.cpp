// `cfgmgr check FILE.dcf` predicts the refusal `cfgmgr push --bus sim:` meets: the check runs the
// file's download through the write rules of a CiA 301 device (cfg/write_acceptance.hpp), the
// same rules the simulated devices answer with. For each DCF of tests/data/write_refusal (README
// there) the check names the object and the abort code (CiA 301 §7.2.4.3.17 table), and a push
// of a network of that one node fails it with status J (CiA 302-2 §3.8, Table 1: "configuration
// download failed") on that object with that code.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "prerequisite.hpp"
#include "push_test_support.hpp"

namespace {

using push_test::nodes_of;
using push_test::parse_json;
using ::testing::HasSubstr;
using tool_test::cfgmgr;
using tool_test::ScratchDir;

const tool_test::DataDir data("write_refusal");

struct Refusal {
  const char* file;
  const char* object;
  const char* code;  // as CiA 301 writes it: "0604 0041"
  int line;
};

// A project file (CiA 306-3) of one node, `node`, given by `dcf`.
std::string one_node_network(const ScratchDir& dir, const std::string& dcf, int node = 5) {
  const std::string cpj = dir / "net.cpj";
  const std::string n = "Node" + std::to_string(node);
  std::ofstream out(cpj);
  out << "[Topology]\nNetName=refusal\nNodes=0x01\n"
      << n << "Present=0x01\n"
      << n << "Name=refusal\n"
      << n << "DCFName=" << dcf << "\n";
  return cpj;
}

class CheckPredictsPush : public ::testing::TestWithParam<Refusal> {};

TEST_P(CheckPredictsPush, CheckWarnsAtTheObjectAndPushFailsWithJThere) {
  const Refusal& r = GetParam();
  ScratchDir dir;
  const std::string file = data(r.file);
  const std::string at = file + ":" + std::to_string(r.line) + ": ";
  const std::string what = std::string(r.object) + " = ";
  const std::string code = std::string("refused with SDO abort ") + r.code;

  // Tolerant: a warning; the file is usable (exit 0).
  const auto tolerant = cfgmgr(dir, {"check", file});
  EXPECT_EQ(tolerant.exit_code, 0) << tolerant.err;
  EXPECT_THAT(tolerant.err, HasSubstr(at + "warning: " + what));
  EXPECT_THAT(tolerant.err, HasSubstr(code));
  // Strict: an error (exit 1).
  const auto strict = cfgmgr(dir, {"check", "--strict", file});
  EXPECT_EQ(strict.exit_code, 1) << strict.err;
  EXPECT_THAT(strict.err, HasSubstr(at + "error: " + what));

  // The network check of the node says the same, at the same line.
  const std::string cpj = one_node_network(dir, file);
  const auto network = cfgmgr(dir, {"check", cpj});
  EXPECT_THAT(network.err, HasSubstr(at + "warning: node 5 (refusal): " + what));
  EXPECT_THAT(network.err, HasSubstr(code));

  // The simulated device refuses that write: J, naming the object and the code.
  const std::string report = dir / "report.json";
  const auto push = cfgmgr(dir, {"push", cpj, "--bus", "sim:", "--json", report});
  // Node 5 is mandatory (a project file without master DCF: every present node is, README), and
  // a mandatory slave's error halts NMT start-up (CiA 302-2 §3.1 f): exit 4 (cfgmgr push --help).
  EXPECT_EQ(push.exit_code, 4) << push.out << push.err;
  const tool_test::Json json = parse_json(report);
  const auto nodes = nodes_of(json);
  ASSERT_TRUE(nodes.count(5)) << tool_test::slurp(report);
  const auto& node = *nodes.at(5);
  EXPECT_EQ(node.get("status")->string, "J");
  std::string digits(r.code);
  digits.erase(digits.find(' '), 1);
  EXPECT_THAT(node.get("message")->string, HasSubstr(r.object));
  EXPECT_THAT(node.get("message")->string, HasSubstr(digits));
}

INSTANTIATE_TEST_SUITE_P(
    WriteRefusal, CheckPredictsPush,
    ::testing::Values(Refusal{"mapping_length.dcf", "1600h sub 01h", "0604 0041", 237},
                      Refusal{"not_mappable.dcf", "1A00h sub 01h", "0604 0041", 319},
                      Refusal{"missing_object.dcf", "1600h sub 01h", "0602 0000", 237},
                      Refusal{"pdo_length.dcf", "1600h sub 00h", "0604 0042", 228},
                      Refusal{"above_high_limit.dcf", "2002h sub 00h", "0609 0031", 352},
                      Refusal{"mapping_while_valid.dcf", "1800h sub 01h", "0601 0002", 279},
                      Refusal{"entry_while_counted.dcf", "1A00h sub 01h", "0800 0022", 319},
                      Refusal{"heartbeat_twice.dcf", "1016h sub 01h", "0604 0043", 96}));

TEST(CheckPredictsPush, AFileADeviceAcceptsChecksCleanAndIsConfigured) {
  ScratchDir dir;
  const std::string file = data("accepted.dcf");
  const auto check = cfgmgr(dir, {"check", "--strict", file});
  EXPECT_EQ(check.exit_code, 0) << check.err;
  const std::string cpj = one_node_network(dir, file);
  const std::string report = dir / "report.json";
  const auto push = cfgmgr(dir, {"push", cpj, "--bus", "sim:", "--json", report});
  EXPECT_EQ(push.exit_code, 0) << push.err;
  const tool_test::Json json = parse_json(report);
  const auto nodes = nodes_of(json);
  ASSERT_TRUE(nodes.count(5));
  EXPECT_EQ(nodes.at(5)->get("result")->string, "configured");
}

// Corpus tier: the slave DCFs of the corpus that name their node-ID and whose files are all there
// (tests/cfg/corpus_test.cpp reads them all). The check predicts no refusal for any of them, and
// the simulated device built from each accepts its whole download: the master's too, which once
// wrote 1020h to devices without it (a J the check could not predict).
TEST(CheckPredictsPush, CorpusSlaveDcfsCheckWithoutRefusalAndAreConfiguredOnSim) {
  const std::filesystem::path corpus(CANOPEN_CORPUS_DIR);
  if (!std::filesystem::exists(corpus)) PREREQUISITE_MISSING("corpus not found at ", corpus);
  struct Slave {
    const char* file;
    int node;  // its [DeviceComissioning] NodeID
  };
  for (const Slave& slave :
       {Slave{"eds-dcf-net/modular_device.dcf", 3}, Slave{"lely-core/co-sdo-server.dcf", 1},
        Slave{"odrive-cia402-profile/odrive-canopen-cia402.dcf", 2}, Slave{"oresat/c3.dcf", 1}}) {
    SCOPED_TRACE(slave.file);
    ScratchDir dir;
    const std::string file = (corpus / slave.file).string();
    const auto check = cfgmgr(dir, {"check", file});
    EXPECT_EQ(check.err.find("refused with SDO abort"), std::string::npos) << check.err;
    const std::string cpj = one_node_network(dir, file, slave.node);
    const std::string report = dir / "report.json";
    const auto push = cfgmgr(dir, {"push", cpj, "--bus", "sim:", "--json", report});
    EXPECT_EQ(push.exit_code, 0) << push.out << push.err;
    const tool_test::Json json = parse_json(report);
    const auto nodes = nodes_of(json);
    ASSERT_TRUE(nodes.count(slave.node)) << tool_test::slurp(report);
    EXPECT_EQ(nodes.at(slave.node)->get("result")->string, "configured")
        << nodes.at(slave.node)->get("message")->string;
  }
}

}  // namespace
