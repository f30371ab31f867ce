// Several SDO server channels on one node (CiA 301 §7.5.2.33 server SDO parameter 1200h-127Fh)
// and client channels taken from 1280h-12FFh (§7.5.2.34). Device file:
// tests/data/sdo_channels.eds (written for these tests: 1201h/1202h with COB-IDs 80000000h,
// 1280h-1282h, 1008h = "SDO channel test device", 2001h a VISIBLE_STRING). Frames as candump
// strings; SDO bytes from CiA 301 §7.2.4.3 (expedited and segmented download/upload, abort
// transfer with the codes of Table 22).
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/object_index.hpp"
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/sdo/sdo_server.hpp"
#include "nmt/slave/local_dictionary.hpp"
#include "nmt/slave/slave_node.hpp"
#include "test_paths.hpp"

namespace nmt {
using namespace cfg::literals;

namespace {

// Powers `device` on at `now` (nothing it reports at power-on is looked at here).
template <class Device>
void power_on_at(Device& device, TimePoint now) {
  typename Device::Output out;
  device.start(now, out);
}

using Frames = std::vector<std::string>;

constexpr cfg::NodeId kNode = 5_node;

cfg::DeviceDescription channels_eds() {
  auto result = cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/sdo_channels.eds");
  EXPECT_TRUE(result.device.has_value()) << result.diagnostics.format();
  return result.device.value_or(cfg::DeviceDescription{});
}

// A node and what it answered to the last frame, as candump strings.
struct Node {
  std::unique_ptr<SlaveNode> node;
  Frames sent;

  explicit Node(const cfg::DeviceDescription& description = channels_eds()) {
    auto created = SlaveNode::create(description, kNode);
    EXPECT_TRUE(created.ok()) << (created.ok() ? "" : created.error().message);
    node = std::move(created).value();
    power_on_at(*node, TimePoint{});
    SlaveNode::Output out;
    node->on_timer(TimePoint{}, out);  // boot-up
  }
  // The frames the node answers to `candump`.
  Frames frame(std::string_view candump) {
    auto f = from_candump(candump);
    EXPECT_TRUE(f.has_value()) << candump;
    SlaveNode::Output out;
    node->on_frame(f.value_or(CanFrame{}), TimePoint{Duration{1000}}, out);
    Frames frames;
    for (const auto& sent_frame : out.frames) frames.push_back(to_candump(sent_frame));
    return frames;
  }
};

TEST(SdoChannels, NodeServesDefaultChannelAndEveryAdditionalServerEntryOfItsFile) {
  Node n;
  EXPECT_EQ(n.node->sdo_server_channels(), (std::vector<std::uint16_t>{0x1200, 0x1201, 0x1202}));
  ASSERT_NE(n.node->sdo_config(0x1201), nullptr);
  // The file's 80000000h: not valid (CiA 301 §7.5.2.33 bit 31).
  EXPECT_FALSE(n.node->sdo_config(0x1201)->request_cob_id.valid());
  EXPECT_EQ(n.node->sdo_config(0x1203), nullptr);
}

TEST(SdoChannels, AdditionalChannelAnswersOnlyOnceBothCobIdsAreValid_Cia301_7_5_2_33) {
  Node n;
  // 1201h sub 1 = 6E1h over the default channel: expedited download of 4 bytes (23h), confirmed
  // with 60h.
  EXPECT_EQ(n.frame("605#23011201E1060000"), Frames{"585#6001120100000000"});
  // Sub 2 still 80000000h: the channel does not exist yet.
  EXPECT_EQ(n.frame("6E1#4000100000000000"), Frames{});
  EXPECT_EQ(n.frame("605#23011202E2060000"), Frames{"585#6001120200000000"});
  // Now it answers on its own COB-IDs without a reset: upload of 1000h (0 in the file), 43h =
  // expedited, 4 bytes.
  EXPECT_EQ(n.frame("6E1#4000100000000000"), Frames{"6E2#4300100000000000"});
  // The default channel keeps answering on 605h/585h.
  EXPECT_EQ(n.frame("605#4000100000000000"), Frames{"585#4300100000000000"});
}

TEST(SdoChannels, CobIdOfAValidChannelChangesOnlyAfterBit31IsSet_Cia301_7_5_2_33) {
  Node n;
  n.frame("605#23011201E1060000");
  n.frame("605#23011202E2060000");
  // Bits 0-29 of a valid COB-ID: abort 0609 0030 (value range of parameter exceeded).
  EXPECT_EQ(n.frame("605#23011201E3060000"), Frames{"585#8001120130000906"});
  EXPECT_EQ(n.frame("6E1#4000100000000000"), Frames{"6E2#4300100000000000"});
  // Setting bit 31 is allowed and takes the channel down at once.
  EXPECT_EQ(n.frame("605#23011201E1060080"), Frames{"585#6001120100000000"});
  EXPECT_EQ(n.frame("6E1#4000100000000000"), Frames{});
  // While bit 31 is set the identifier may change; clearing it brings the channel back.
  EXPECT_EQ(n.frame("605#23011201E3060000"), Frames{"585#6001120100000000"});
  EXPECT_EQ(n.frame("6E3#4000100000000000"), Frames{"6E2#4300100000000000"});
}

TEST(SdoChannels, ChannelThatInvalidatesItselfConfirmsOnTheCobIdItWasAskedOn) {
  Node n;
  n.frame("605#23011201E1060000");
  n.frame("605#23011202E2060000");
  // 1201h sub 2 = 800006E2h written over 1201h itself: the confirmation still leaves on 6E2h.
  EXPECT_EQ(n.frame("6E1#23011202E2060080"), Frames{"6E2#6001120200000000"});
  EXPECT_EQ(n.frame("6E1#4000100000000000"), Frames{});
}

TEST(SdoChannels, DefaultChannelCobIdsAreFixedEvenWhenTheFileSaysRw_Cia301_7_5_2_33) {
  auto description = channels_eds();
  description.sub(0x1200, 1)->access = cfg::AccessType::Rw;
  Node n(description);
  // Another identifier: 0601 0002 (attempt to write a read only object).
  EXPECT_EQ(n.frame("605#2300120106060000"), Frames{"585#8000120102000106"});
  // The value it holds is accepted (a DCF download that writes every rw entry).
  EXPECT_EQ(n.frame("605#2300120105060000"), Frames{"585#6000120100000000"});
  EXPECT_EQ(n.frame("605#4000100000000000"), Frames{"585#4300100000000000"});
}

TEST(SdoChannels, ResetCommunicationRestoresTheChannelsOfTheFile_Cia301_7_3_2_2_1) {
  Node n;
  n.frame("605#23011201E1060000");
  n.frame("605#23011202E2060000");
  ASSERT_EQ(n.frame("6E1#4000100000000000"), Frames{"6E2#4300100000000000"});
  n.frame("000#8205");  // reset communication
  SlaveNode::Output out;
  n.node->on_timer(TimePoint{Duration{2000}}, out);  // boot-up
  EXPECT_EQ(n.frame("6E1#4000100000000000"), Frames{});
  EXPECT_FALSE(n.node->sdo_config(0x1201)->request_cob_id.valid());
}

// Two clients at the same time, one on the default channel (segmented upload of 1008h, 23 bytes)
// and one on 1201h (segmented download of 10 bytes to 2001h), frames interleaved: each channel
// keeps its own transfer state (toggle bit, offset). Segment bytes per CiA 301 §7.2.4.3.3-6:
// download segment ccs=0 t n c, upload segment response scs=0 t n c.
TEST(SdoChannels, TwoClientsOnTwoChannelsOfOneNodeDoNotDisturbEachOther) {
  Node n;
  n.frame("605#23011201E1060000");
  n.frame("605#23011202E2060000");

  // A: initiate upload 1008h; 41h = segmented, size indicated: 17h = 23 bytes.
  EXPECT_EQ(n.frame("605#4008100000000000"), Frames{"585#4108100017000000"});
  // B: initiate download 2001h, size indicated (21h), 10 bytes.
  EXPECT_EQ(n.frame("6E1#210120000A000000"), Frames{"6E2#6001200000000000"});
  // A: first segment (toggle 0): "SDO cha".
  EXPECT_EQ(n.frame("605#6000000000000000"), Frames{"585#0053444F20636861"});
  // B: first segment (toggle 0), 7 bytes "abcdefg".
  EXPECT_EQ(n.frame("6E1#0061626364656667"), Frames{"6E2#2000000000000000"});
  // A: toggle 1: "nnel te".
  EXPECT_EQ(n.frame("605#7000000000000000"), Frames{"585#106E6E656C207465"});
  // B: last segment, toggle 1, 4 bytes unused, c=1: 19h, "hij".
  EXPECT_EQ(n.frame("6E1#1968696A00000000"), Frames{"6E2#3000000000000000"});
  // A: toggle 0: "st devi"; toggle 1, last, 5 unused: 1Bh, "ce".
  EXPECT_EQ(n.frame("605#6000000000000000"), Frames{"585#0073742064657669"});
  EXPECT_EQ(n.frame("605#7000000000000000"), Frames{"585#1B63650000000000"});

  const auto stored = n.node->dictionary().get_bytes(0x2001, 0);
  ASSERT_TRUE(stored.has_value());
  EXPECT_EQ(std::string(stored->begin(), stored->end()), "abcdefghij");
}

TEST(SdoChannels, ServerEntryInsertedAfterCreationIsServedOnceWritten) {
  Node n;
  for (std::uint8_t sub = 1; sub <= 2; ++sub) {
    DictionaryEntry e;
    e.index = 0x1203;
    e.sub_index = sub;
    e.name = "COB-ID";
    e.data_type = 0x0007;
    e.basic_type = cfg::DataType::Unsigned32;
    e.bytes = {0x00, 0x00, 0x00, 0x80};  // 80000000h: not valid
    n.node->dictionary().insert(e);
  }
  EXPECT_EQ(n.frame("605#23031201E5060000"), Frames{"585#6003120100000000"});
  EXPECT_EQ(n.frame("605#23031202E6060000"), Frames{"585#6003120200000000"});
  EXPECT_EQ(n.node->sdo_server_channels(),
            (std::vector<std::uint16_t>{0x1200, 0x1201, 0x1202, 0x1203}));
  EXPECT_EQ(n.frame("6E5#4000100000000000"), Frames{"6E6#4300100000000000"});
}

TEST(SdoChannels, ClientChannelComesFromA1280hEntry_Cia301_7_5_2_34) {
  Node n;
  auto& dict = n.node->dictionary();
  EXPECT_FALSE(SdoClientConfig::from_dictionary(dict, 0x1281).has_value());  // 80000000h
  dict.set_unsigned(0x1281, 1, 0x6E1);
  dict.set_unsigned(0x1281, 2, 0x6E2);
  dict.set_unsigned(0x1281, 3, 7);
  const auto config = SdoClientConfig::from_dictionary(dict, 0x1281);
  ASSERT_TRUE(config.has_value());
  EXPECT_EQ(config->request_cob_id, cfg::CobId::standard(0x6E1));
  EXPECT_EQ(config->response_cob_id, cfg::CobId::standard(0x6E2));
  EXPECT_EQ(config->node_id, 7);
  // 29-bit identifiers keep bit 29.
  dict.set_unsigned(0x1281, 2, 0xA00006E2);
  EXPECT_FALSE(SdoClientConfig::from_dictionary(dict, 0x1281).has_value());  // bit 31
  dict.set_unsigned(0x1281, 2, 0x200006E2);
  EXPECT_EQ(SdoClientConfig::from_dictionary(dict, 0x1281)->response_cob_id.can_id(),
            (cfg::CanId{0x6E2, true}));
  // Not a client entry, or one the dictionary lacks.
  EXPECT_FALSE(SdoClientConfig::from_dictionary(dict, 0x1201).has_value());
  EXPECT_FALSE(SdoClientConfig::from_dictionary(dict, 0x1283).has_value());
}

TEST(SdoChannels, ClientEntryCobIdsFollowTheBit31Rule_Cia301_7_5_2_34) {
  Node n;
  EXPECT_EQ(n.frame("605#23801201E1060000"), Frames{"585#6080120100000000"});
  EXPECT_EQ(n.frame("605#23801201E3060000"), Frames{"585#8080120130000906"});
  EXPECT_EQ(n.frame("605#23801201E1060080"), Frames{"585#6080120100000000"});
}

}  // namespace
}  // namespace nmt
