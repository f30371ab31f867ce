// The application program of a node in the network description (DSP 302 §9 program
// download, §5.2 1F81h bits 5/6, 1F53h/1F54h): our NodeXProgramFile=/NodeXProgramVersion= keys
// (CiA 306-3 has none), the master's objects made from them, command-line overrides and
// check_programs. Files in tests/data/program (README there).
#include <gtest/gtest.h>

#include <string>

#include "cfg/master_objects.hpp"
#include "cfg/network.hpp"
#include "cfg/object_index.hpp"
#include "cfg/value.hpp"
#include "test_paths.hpp"

namespace {

std::string data(const std::string& name) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/program/" + name;
}

std::uint64_t entry(const cfg::DeviceDescription& dcf, std::uint16_t index, std::uint8_t sub) {
  const cfg::SubObject* s = dcf.sub(index, sub);
  if (s == nullptr || !s->configured_value()) return ~0ULL;
  auto value = cfg::parse_value(cfg::DataType::Unsigned32, *s->configured_value());
  return value ? value->as_unsigned() : ~0ULL;
}

TEST(NetworkProgram, TheProjectFileGivesImageAndVersionAndTheDerivedMasterChecksAndUpdates) {
  const auto load = cfg::load_network(data("program.cpj"));
  ASSERT_TRUE(load.ok());
  const cfg::NetworkNode* node = load.network->find(*cfg::NodeId::from(3));
  ASSERT_NE(node, nullptr);
  ASSERT_TRUE(node->program);
  EXPECT_EQ(node->program->file, data("drive_v2.img"));
  EXPECT_EQ(node->program->image.size(), 1012U);
  // 2026-11-27: 15671 days after 1984-01-01 (DSP 302 §9); 08:15 = 29 700 000 ms.
  EXPECT_EQ(node->program->version, (cfg::ProgramVersion{15671, 29'700'000}));
  const auto& master = load.network->master;
  EXPECT_EQ(entry(master, cfg::object::kExpectedApplicationSwDate, 3), 15671U);
  EXPECT_EQ(entry(master, cfg::object::kExpectedApplicationSwTime, 3), 29'700'000U);
  EXPECT_EQ(entry(master, cfg::object::kSlaveAssignment, 3),
            0x0DU | cfg::SlaveAssignment::kVerifySoftware | cfg::SlaveAssignment::kUpdateSoftware);
  EXPECT_EQ(cfg::expected_program_version(*load.network, *cfg::NodeId::from(3)),
            (cfg::ProgramVersion{15671, 29'700'000}));
  cfg::Diagnostics diagnostics;
  cfg::check_programs(*load.network, diagnostics);
  EXPECT_TRUE(diagnostics.empty());
}

TEST(NetworkProgram, AnOverrideReplacesTheVersionAndKeepsTheImage) {
  auto load = cfg::load_network(data("program.cpj"));
  ASSERT_TRUE(load.ok());
  ASSERT_TRUE(cfg::set_node_program(*load.network, *cfg::NodeId::from(3), "",
                                    cfg::ProgramVersion{15188, 27'000'000}));
  const auto& master = load.network->master;
  EXPECT_EQ(entry(master, cfg::object::kExpectedApplicationSwDate, 3), 15188U);
  EXPECT_EQ(load.network->find(*cfg::NodeId::from(3))->program->image.size(), 1012U);
  EXPECT_FALSE(cfg::set_node_program(*load.network, *cfg::NodeId::from(9), "", std::nullopt));
}

// Issue 33: master_bit5.dcf's 1F81h sub 3 = 2Dh (line 191) leaves bit 6 clear: no automatic
// software update of node 3 (CiA 302-2 Table 24). An image from the command line is refused
// naming that line, instead of setting the bit behind the DCF's back; a version alone is not.
TEST(NetworkProgram, AnImageForANodeWhoseMasterDcfForbidsTheUpdateIsRefused) {
  auto load = cfg::load_network(data("master_bit5.dcf"));
  ASSERT_TRUE(load.ok());
  const auto refused =
      cfg::set_node_program(*load.network, *cfg::NodeId::from(3), data("drive_v2.img"), {});
  ASSERT_FALSE(refused);
  EXPECT_NE(refused.error().message.find("master_bit5.dcf:191: 1F81h sub 3 = 0x0000002D clears "
                                         "bit 6 (automatic software update not allowed"),
            std::string::npos)
      << refused.error().message;
  EXPECT_EQ(entry(load.network->master, cfg::object::kSlaveAssignment, 3), 0x2DU) << "unchanged";
  EXPECT_TRUE(cfg::set_node_program(*load.network, *cfg::NodeId::from(3), "",
                                    cfg::ProgramVersion{15188, 27'000'000}));
}

TEST(NetworkProgram, Bit5WithoutExpectedVersionInAMasterDcfIsStatusGsCase) {
  const auto load = cfg::load_network(data("master_bit5.dcf"));
  ASSERT_TRUE(load.ok());
  EXPECT_EQ(cfg::expected_program_version(*load.network, *cfg::NodeId::from(3)), std::nullopt);
  cfg::Diagnostics diagnostics;
  cfg::check_programs(*load.network, diagnostics);
  ASSERT_EQ(diagnostics.size(), 1U);
  EXPECT_EQ(diagnostics.items()[0].line, 191);
  EXPECT_EQ(diagnostics.items()[0].severity, cfg::Severity::Error);
}

}  // namespace
