// The PDO-safe download order: DSP 302 v3.2.1 §6.2 application hint ("1. Delete the PDO by
// setting bit 31 to 1 (if it is not readonly) 2. Configure Sub-Indexes 2 upwards of the
// Communication Parameters 3. Deactivate mapping by setting NrOfMappedObjects to 0 4. Configure
// the mapping entries 5. Create the PDO by writing a valid COB-ID with the bit 31 reset to 0").
#include "cfg/download_order.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "concise_test_support.hpp"
#include "prerequisite.hpp"
#include "test_paths.hpp"

namespace cfg {
namespace {

using test_support::u16;
using test_support::u32;
using test_support::u8;
using ::testing::ElementsAre;
using ::testing::ElementsAreArray;
using ::testing::IsEmpty;

// RPDO 1 of node 2: COB-ID 202h (CiA 301 pre-defined connection set), transmission type FFh,
// two mapped objects: 6040h (controlword, 16 bits) and 6060h (modes of operation, 8 bits).
std::vector<ObjectWrite> rpdo1_configuration() {
  return {u32(0x1600, 2, 0x60600008), u8(0x1400, 2, 0xFF), u8(0x1600, 0, 2), u32(0x1400, 1, 0x202),
          u32(0x1600, 1, 0x60400010)};
}

TEST(DownloadOrder, RpdoFollowsDsp302ApplicationHintSteps1To5) {
  auto order = order_for_download(rpdo1_configuration());
  EXPECT_THAT(order.writes,
              ElementsAre(u32(0x1400, 1, 0x80000202),                    // 1. delete the PDO
                          u8(0x1400, 2, 0xFF),                           // 2. comm sub 2 and up
                          u8(0x1600, 0, 0),                              // 3. deactivate mapping
                          u32(0x1600, 1, 0x60400010),                    // 4. mapping entries
                          u32(0x1600, 2, 0x60600008), u8(0x1600, 0, 2),  // 3'. activate mapping
                          u32(0x1400, 1, 0x202)));                       // 5. create the PDO
  EXPECT_TRUE(order.complete());
}

TEST(DownloadOrder, TpdoFollowsTheSameRule) {
  // TPDO 2 of node 5: COB-ID 285h, transmission type 1 (synchronous), inhibit time 100 x
  // 100 us, event timer 0, one mapped object 6064h (position actual value, 32 bits).
  std::vector<ObjectWrite> writes{u32(0x1A01, 1, 0x60640020), u16(0x1801, 5, 0),
                                  u8(0x1A01, 0, 1),           u32(0x1801, 1, 0x285),
                                  u16(0x1801, 3, 100),        u8(0x1801, 2, 1)};
  EXPECT_THAT(pdo_safe_order(writes),
              ElementsAre(u32(0x1801, 1, 0x80000285), u8(0x1801, 2, 1), u16(0x1801, 3, 100),
                          u16(0x1801, 5, 0), u8(0x1A01, 0, 0), u32(0x1A01, 1, 0x60640020),
                          u8(0x1A01, 0, 1), u32(0x1801, 1, 0x285)));
}

TEST(DownloadOrder, OtherObjectsInIndexThenSubIndexOrderWithPdosAtTheirCommIndex) {
  std::vector<ObjectWrite> writes{u32(0x6081, 0, 1000),       u16(0x1017, 0, 1000),
                                  u32(0x1016, 2, 0x000301F4), u32(0x1016, 1, 0x000201F4),
                                  u8(0x1800, 2, 1),           u8(0x1400, 2, 0xFE),
                                  u32(0x1F80, 0, 0x4)};
  auto order = order_for_download(writes, [](std::uint16_t comm_index) {
    return std::optional<std::uint32_t>(comm_index == 0x1400 ? 0x201u : 0x181u);
  });
  EXPECT_THAT(order.writes,
              ElementsAre(u32(0x1016, 1, 0x000201F4), u32(0x1016, 2, 0x000301F4),
                          u16(0x1017, 0, 1000), u32(0x1400, 1, 0x80000201), u8(0x1400, 2, 0xFE),
                          u32(0x1400, 1, 0x201), u32(0x1800, 1, 0x80000181), u8(0x1800, 2, 1),
                          u32(0x1800, 1, 0x181), u32(0x1F80, 0, 0x4), u32(0x6081, 0, 1000)));
}

// CiA 302-2 §3.5 d, DSP 302 v3.2.1 §6.3: after the configuration 1020h sub 1/2 = 1F26h/1F27h
// (when not 0), then 1010h sub 1 = 'save'.
TEST(DownloadPlan, IsThePdoSafeOrderThen1020hThen1010hSave) {
  const auto plan = plan_download(rpdo1_configuration(), {{14000, 3'600'000}, true});
  std::vector<ObjectWrite> expected = order_for_download(rpdo1_configuration()).writes;
  expected.push_back(u32(0x1020, 1, 14000));
  expected.push_back(u32(0x1020, 2, 3'600'000));
  expected.push_back(u32(0x1010, 1, 0x65766173));
  EXPECT_EQ(plan.writes, expected);
}

TEST(DownloadPlan, ZeroStampAndNoSaveAddNothing) {
  // §3.5 a: 1F26h/1F27h of 0 mean the configuration is not verified, so 1020h is not written.
  EXPECT_EQ(plan_download(rpdo1_configuration()).writes,
            order_for_download(rpdo1_configuration()).writes);
  const auto saved = plan_download(rpdo1_configuration(), {{}, true}).writes;
  ASSERT_FALSE(saved.empty());
  EXPECT_EQ(saved.back(), u32(0x1010, 1, 0x65766173));
  EXPECT_EQ(saved.size(), order_for_download(rpdo1_configuration()).writes.size() + 1);
}

TEST(DownloadOrder, VerifyConfigurationIsWrittenLast) {
  // DSP 302 v3.2.1 §6.3: "If any other command changes boot-up configuration values, the device
  // has to reset the object Verify Configuration to 0." 1020h sub 1 = date, sub 2 = time.
  std::vector<ObjectWrite> writes{u32(0x1020, 2, 36000000), u32(0x1020, 1, 14000),
                                  u32(0x6081, 0, 1000), u16(0x1017, 0, 1000), u8(0x1400, 2, 1)};
  auto lookup = [](std::uint16_t) { return std::optional<std::uint32_t>(0x202); };
  EXPECT_THAT(pdo_safe_order(writes, lookup),
              ElementsAre(u16(0x1017, 0, 1000), u32(0x1400, 1, 0x80000202), u8(0x1400, 2, 1),
                          u32(0x1400, 1, 0x202), u32(0x6081, 0, 1000), u32(0x1020, 1, 14000),
                          u32(0x1020, 2, 36000000)));
}

TEST(DownloadOrder, PdoWithOnlyMappingWrittenSortsAtItsCommIndex) {
  // TPDO 1 (1800h/1A00h) must come before TPDO 2 (1801h) even though only its mapping is
  // written, i.e. the group is keyed 1800h, not 1A00h.
  std::vector<ObjectWrite> writes{u8(0x1801, 2, 1), u8(0x1A00, 0, 1), u32(0x1A00, 1, 0x60410010)};
  auto lookup = [](std::uint16_t comm_index) {
    return std::optional<std::uint32_t>(0x180u + 0x100u * (comm_index - 0x1800u) + 3u);
  };
  EXPECT_THAT(pdo_safe_order(writes, lookup),
              ElementsAre(u32(0x1800, 1, 0x80000183), u8(0x1A00, 0, 0), u32(0x1A00, 1, 0x60410010),
                          u8(0x1A00, 0, 1), u32(0x1800, 1, 0x183), u32(0x1801, 1, 0x80000283),
                          u8(0x1801, 2, 1), u32(0x1801, 1, 0x283)));
}

TEST(DownloadOrder, CobIdFromLookupGivesTheInvalidValidPair) {
  std::vector<ObjectWrite> writes{u8(0x1600, 0, 1), u32(0x1600, 1, 0x60400010)};
  std::vector<std::uint16_t> asked;
  auto order = order_for_download(writes, [&asked](std::uint16_t comm_index) {
    asked.push_back(comm_index);
    return std::optional<std::uint32_t>(0x202);
  });
  EXPECT_THAT(asked, ElementsAre(0x1400));
  EXPECT_THAT(order.writes,
              ElementsAre(u32(0x1400, 1, 0x80000202), u8(0x1600, 0, 0), u32(0x1600, 1, 0x60400010),
                          u8(0x1600, 0, 1), u32(0x1400, 1, 0x202)));
  EXPECT_TRUE(order.complete());
}

TEST(DownloadOrder, LookupIsNotAskedWhenTheCobIdIsWritten) {
  bool asked = false;
  auto order = order_for_download(rpdo1_configuration(), [&asked](std::uint16_t) {
    asked = true;
    return std::optional<std::uint32_t>(0x999);
  });
  EXPECT_FALSE(asked);
  EXPECT_EQ(order.writes.front(), u32(0x1400, 1, 0x80000202));
  EXPECT_EQ(order.writes.back(), u32(0x1400, 1, 0x202));
}

TEST(DownloadOrder, PdoDisabledOnTheDeviceStaysDisabled) {
  // The device's COB-ID already has bit 31 set (PDO not valid, e.g. CiA 402 TPDO 3 defaults):
  // delete it again (harmless, and right if the device differs), but do not "create" it.
  std::vector<ObjectWrite> writes{u8(0x1802, 2, 1)};
  auto order = order_for_download(
      writes, [](std::uint16_t) { return std::optional<std::uint32_t>(0x80000382); });
  EXPECT_THAT(order.writes, ElementsAre(u32(0x1802, 1, 0x80000382), u8(0x1802, 2, 1)));
}

TEST(DownloadOrder, ConfiguredInvalidCobIdIsWrittenOnceFirst) {
  std::vector<ObjectWrite> writes{u8(0x1A03, 0, 0), u32(0x1803, 1, 0x80000484)};
  EXPECT_THAT(pdo_safe_order(writes), ElementsAre(u32(0x1803, 1, 0x80000484), u8(0x1A03, 0, 0)));
}

TEST(DownloadOrder, MappingCountZeroIsWrittenOnce) {
  std::vector<ObjectWrite> writes{u32(0x1400, 1, 0x202), u8(0x1600, 0, 0)};
  EXPECT_THAT(pdo_safe_order(writes),
              ElementsAre(u32(0x1400, 1, 0x80000202), u8(0x1600, 0, 0), u32(0x1400, 1, 0x202)));
}

TEST(DownloadOrder, OnlyTheCobIdChangesStillGoesThroughInvalid) {
  // CiA 301: bits 0-29 of a valid PDO's COB-ID must not change; the pair makes it legal.
  std::vector<ObjectWrite> writes{u32(0x1400, 1, 0x305)};
  EXPECT_THAT(pdo_safe_order(writes),
              ElementsAre(u32(0x1400, 1, 0x80000305), u32(0x1400, 1, 0x305)));
}

TEST(DownloadOrder, UnknownCobIdIsReportedAndTheRestStaysInPdoOrder) {
  std::vector<ObjectWrite> writes{u32(0x1601, 1, 0x607A0020), u8(0x1601, 0, 1), u8(0x1401, 2, 1)};
  auto without_lookup = order_for_download(writes);
  EXPECT_THAT(without_lookup.unknown_cob_id, ElementsAre(0x1401));
  EXPECT_THAT(without_lookup.unknown_mapping_count, IsEmpty());
  EXPECT_FALSE(without_lookup.complete());
  EXPECT_THAT(without_lookup.writes, ElementsAre(u8(0x1401, 2, 1), u8(0x1601, 0, 0),
                                                 u32(0x1601, 1, 0x607A0020), u8(0x1601, 0, 1)));

  auto lookup_does_not_know =
      order_for_download(writes, [](std::uint16_t) { return std::optional<std::uint32_t>(); });
  EXPECT_EQ(lookup_does_not_know.writes, without_lookup.writes);
  EXPECT_THAT(lookup_does_not_know.unknown_cob_id, ElementsAre(0x1401));
}

TEST(DownloadOrder, MappingEntriesWithoutCountAreReported) {
  std::vector<ObjectWrite> writes{u32(0x1800, 1, 0x182), u32(0x1A00, 2, 0x60610008)};
  auto order = order_for_download(writes);
  EXPECT_THAT(order.unknown_mapping_count, ElementsAre(0x1A00));
  EXPECT_THAT(order.unknown_cob_id, IsEmpty());
  EXPECT_THAT(order.writes, ElementsAre(u32(0x1800, 1, 0x80000182), u32(0x1A00, 2, 0x60610008),
                                        u32(0x1800, 1, 0x182)));
}

TEST(DownloadOrder, LastWriteOfAnEntryWins) {
  std::vector<ObjectWrite> writes{u16(0x1017, 0, 500), u16(0x1017, 0, 1000)};
  EXPECT_THAT(pdo_safe_order(writes), ElementsAre(u16(0x1017, 0, 1000)));
}

TEST(DownloadOrder, OrderingAnOrderedStreamGivesItBack) {
  auto once = pdo_safe_order(rpdo1_configuration());
  EXPECT_EQ(pdo_safe_order(once), once);
}

TEST(DownloadOrder, InputOrderDoesNotMatter) {
  auto writes = rpdo1_configuration();
  writes.push_back(u16(0x1017, 0, 1000));
  writes.push_back(u8(0x1A00, 0, 1));
  writes.push_back(u32(0x1A00, 1, 0x60410010));
  writes.push_back(u32(0x1800, 1, 0x182));
  const auto expected = pdo_safe_order(writes);
  std::mt19937 rng(302);
  for (int i = 0; i < 50; ++i) {
    std::shuffle(writes.begin(), writes.end(), rng);
    EXPECT_EQ(pdo_safe_order(writes), expected);
  }
}

// CiA 301 §7.5.2.17: 1014h's bits 0-29 may change only while bit 31 (EMCY not valid) is set, as a
// PDO's COB-ID; a device whose EMCY is valid at 84h refuses 0A4h written alone (0609 0030).
TEST(DownloadOrder, AValidEmcyCobIdIsWrittenInvalidFirst) {
  std::vector<ObjectWrite> writes{u16(0x1017, 0, 100), u32(0x1014, 0, 0xA4), u8(0x1001, 0, 0)};
  EXPECT_THAT(pdo_safe_order(writes), ElementsAre(u8(0x1001, 0, 0), u32(0x1014, 0, 0x800000A4),
                                                  u32(0x1014, 0, 0xA4), u16(0x1017, 0, 100)));
  // An EMCY configured not valid is written once; ordering an ordered stream gives it back.
  EXPECT_THAT(pdo_safe_order(std::vector<ObjectWrite>{u32(0x1014, 0, 0x80000084)}),
              ElementsAre(u32(0x1014, 0, 0x80000084)));
  const auto once = pdo_safe_order(writes);
  EXPECT_EQ(pdo_safe_order(once), once);
}

TEST(DownloadOrder, TheEmcyCobIdPairIsLeftOutWhereTheDeviceHasItOrHasNoValidEmcy) {
  const std::vector<ObjectWrite> writes{u32(0x1014, 0, 0xA4)};
  const auto device_has = [](std::uint32_t word) {
    return [word](std::uint16_t index) -> std::optional<std::uint32_t> {
      EXPECT_EQ(index, 0x1014);
      return word;
    };
  };
  EXPECT_THAT(pdo_safe_order(writes, device_has(0x84)),
              ElementsAre(u32(0x1014, 0, 0x800000A4), u32(0x1014, 0, 0xA4)));
  EXPECT_THAT(pdo_safe_order(writes, device_has(0xA4)), ElementsAre(u32(0x1014, 0, 0xA4)));
  EXPECT_THAT(pdo_safe_order(writes, device_has(0x80000084)), ElementsAre(u32(0x1014, 0, 0xA4)));
}

TEST(DownloadOrder, PdoIndicesCoverCiA301Ranges) {
  EXPECT_FALSE(pdo_indices_of(0x13FF).has_value());
  EXPECT_FALSE(pdo_indices_of(0x1C00).has_value());
  EXPECT_FALSE(pdo_indices_of(0x1017).has_value());
  auto check = [](std::uint16_t index, std::uint16_t comm, std::uint16_t mapping) {
    auto pdo = pdo_indices_of(index);
    ASSERT_TRUE(pdo.has_value()) << std::hex << index;
    EXPECT_EQ(pdo->comm_index, comm) << std::hex << index;
    EXPECT_EQ(pdo->mapping_index, mapping) << std::hex << index;
  };
  check(0x1400, 0x1400, 0x1600);
  check(0x15FF, 0x15FF, 0x17FF);
  check(0x1600, 0x1400, 0x1600);
  check(0x17FF, 0x15FF, 0x17FF);
  check(0x1800, 0x1800, 0x1A00);
  check(0x19FF, 0x19FF, 0x1BFF);
  check(0x1A00, 0x1800, 0x1A00);
  check(0x1BFF, 0x19FF, 0x1BFF);
}

// lely's dcfgen (an independent implementation) wrote prbt_joint_1.bin with the same rule:
// ordering its entries again must give the stream back byte for byte.
TEST(DownloadOrder, ReproducesTheOrderLelyDcfgenWroteForPilzPrbt) {
  const std::string path =
      std::string(CANOPEN_CORPUS_DIR) + "/ros_canopen-motion_controller_driver/prbt_joint_1.bin";
  if (!std::filesystem::exists(path)) PREREQUISITE_MISSING("corpus not found: ", path);
  auto entries = decode_concise_dcf(test_support::read_bytes(path));
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  ASSERT_EQ(entries->size(), 26u);  // MANIFEST.tsv: concise-dcf entries=26
  EXPECT_THAT(pdo_safe_order(*entries), ElementsAreArray(*entries));
}

// robot_control__joint_1.bin: the PDO part (its first 25 entries) is in the same order as ours;
// dcfgen then writes the yml's "sdo:" list in file order (60C2h, 6081h, 6083h, 6060h), where we
// write index order (6060h before 6081h). See tests/cfg/dcfgen-differences.md.
TEST(DownloadOrder, MatchesDcfgenPdoSequenceForRos2CanopenJoint) {
  const std::string path =
      std::string(CANOPEN_CORPUS_DIR) + "/starnus-ros2_canopen-build/robot_control__joint_1.bin";
  if (!std::filesystem::exists(path)) PREREQUISITE_MISSING("corpus not found: ", path);
  auto entries = decode_concise_dcf(test_support::read_bytes(path));
  ASSERT_TRUE(entries.ok()) << entries.error().message;
  ASSERT_EQ(entries->size(), 30u);  // MANIFEST.tsv: concise-dcf entries=30
  auto ordered = pdo_safe_order(*entries);
  ASSERT_EQ(ordered.size(), 30u);
  EXPECT_TRUE(std::equal(entries->begin(), entries->begin() + 25, ordered.begin()));
  EXPECT_THAT(std::vector<ObjectWrite>(ordered.begin() + 25, ordered.end()),
              ElementsAre(u8(0x6060, 0, 7), u32(0x6081, 0, 1000), u32(0x6083, 0, 2000),
                          u8(0x60C2, 1, 50), u8(0x60C2, 2, 0xFD)));
}

}  // namespace
}  // namespace cfg
