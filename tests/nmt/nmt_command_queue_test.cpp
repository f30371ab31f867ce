// The NMT master's command queue alone (master/nmt_command_queue.hpp): the NMT module control
// frame of CiA 301 §7.2.8.3.1 (COB-ID 000h, byte 0 the command specifier, byte 1 the node-ID,
// 0 for all nodes) and the NMT inhibit time of CiA 302-2 §6.1 (102Ah, multiples of 100 µs):
// "the minimum time between two NMT services".
#include "master/nmt_command_queue.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "cfg/master_objects.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace nmt {
namespace {

using std::chrono::milliseconds;
using Sent = NmtCommandQueue::Sent;

TimePoint at_ms(std::int64_t ms) {
  return TimePoint{milliseconds(ms)};
}
// The target byte 1 of the frame names: 0 all nodes, else that node-ID.
NmtTarget to(std::uint8_t byte) {
  return *NmtTarget::from_byte(byte);
}

template <class Output>
std::vector<std::string> texts_of(const Output& out) {
  std::vector<std::string> result;
  for (const auto& f : out.frames) result.push_back(to_candump(f));
  return result;
}
std::vector<std::string> texts(const NmtCommandQueue::Output& out) {
  return texts_of(out);
}

// 102Ah = 100 (x 100 µs): 10 ms.
constexpr Duration kTenMs = milliseconds(10);

TEST(NmtCommandQueue, FrameIsCobId000WithCommandSpecifierThenNodeId_301_7_2_8_3_1) {
  struct Case {
    NmtCommand command;
    std::uint8_t node;
    const char* candump;
  };
  for (const Case& c :
       {Case{NmtCommand::Start, 5, "000#0105"}, Case{NmtCommand::Stop, 5, "000#0205"},
        Case{NmtCommand::EnterPreOperational, 5, "000#8005"},
        Case{NmtCommand::ResetNode, 127, "000#817F"},
        Case{NmtCommand::ResetCommunication, 0, "000#8200"}}) {
    SCOPED_TRACE(c.candump);
    NmtCommandQueue queue;
    NmtCommandQueue::Output out;
    queue.queue(c.command, to(c.node));
    queue.on_timer(at_ms(1), out);
    ASSERT_EQ(out.frames.size(), 1U);
    const CanFrame& f = out.frames[0];
    EXPECT_EQ(f.id, 0x000U);
    EXPECT_FALSE(f.extended);
    EXPECT_FALSE(f.rtr);
    ASSERT_EQ(f.dlc, 2U);
    EXPECT_EQ(f.data[0], static_cast<std::uint8_t>(c.command));
    EXPECT_EQ(f.data[1], c.node);
    EXPECT_EQ(to_candump(f), c.candump);
    EXPECT_EQ(out.events, (std::vector<Sent>{{c.command, to(c.node)}}));
  }
}

TEST(NmtCommandQueue, QueuedCommandIsDueAtOnceAndNothingIsDueWhenEmpty) {
  NmtCommandQueue queue;
  EXPECT_EQ(queue.next_deadline(), std::nullopt);
  queue.queue(NmtCommand::Start, to(0));
  EXPECT_EQ(queue.next_deadline(), TimePoint{});  // engine.hpp rule 4: as soon as possible
  NmtCommandQueue::Output out;
  queue.on_timer(at_ms(7), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"000#0100"}));
  EXPECT_TRUE(queue.empty());
  EXPECT_EQ(queue.next_deadline(), std::nullopt);
}

TEST(NmtCommandQueue, WithoutInhibitTimeCommandsLeaveTogetherInTheOrderQueued_302_2_6_1) {
  NmtCommandQueue queue;
  queue.queue(NmtCommand::ResetCommunication, to(2));
  queue.queue(NmtCommand::ResetCommunication, to(3));
  queue.queue(NmtCommand::Start, to(2));
  EXPECT_EQ(queue.size(), 3U);
  NmtCommandQueue::Output out;
  queue.on_timer(at_ms(1), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"000#8202", "000#8203", "000#0102"}));
  EXPECT_EQ(out.events, (std::vector<Sent>{{NmtCommand::ResetCommunication, to(2)},
                                           {NmtCommand::ResetCommunication, to(3)},
                                           {NmtCommand::Start, to(2)}}));
}

TEST(NmtCommandQueue, CommandsAreAtLeastTheInhibitTimeApartInOrder_302_2_6_1) {
  NmtCommandQueue queue;
  queue.set_inhibit_time(kTenMs);
  queue.queue(NmtCommand::Stop, to(4));
  queue.queue(NmtCommand::Start, to(5));
  queue.queue(NmtCommand::ResetNode, to(6));
  NmtCommandQueue::Output out;
  queue.on_timer(at_ms(1000), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"000#0204"}));
  EXPECT_EQ(queue.next_deadline(), at_ms(1010));
  // A call before the deadline sends nothing (engine.hpp rule 3).
  out.clear();
  queue.on_timer(at_ms(1009), out);
  EXPECT_TRUE(out.empty());
  queue.on_timer(at_ms(1010), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"000#0105"}));
  EXPECT_EQ(queue.next_deadline(), at_ms(1020));
  out.clear();
  queue.on_timer(at_ms(1020), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"000#8106"}));
  EXPECT_EQ(out.events, (std::vector<Sent>{{NmtCommand::ResetNode, to(6)}}));
  EXPECT_EQ(queue.next_deadline(), std::nullopt);
}

TEST(NmtCommandQueue, CommandQueuedWhileInhibitedLeavesAtTheDeadline_302_2_6_1) {
  NmtCommandQueue queue;
  queue.set_inhibit_time(kTenMs);
  NmtCommandQueue::Output out;
  queue.queue(NmtCommand::ResetCommunication, to(0));
  queue.on_timer(at_ms(500), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"000#8200"}));
  out.clear();
  queue.queue(NmtCommand::Start, to(0));  // 3 ms later: inhibited
  EXPECT_EQ(queue.next_deadline(), at_ms(510));
  queue.on_timer(at_ms(503), out);
  EXPECT_TRUE(out.empty());
  queue.on_timer(at_ms(510), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"000#0100"}));
}

TEST(NmtCommandQueue, CommandQueuedAfterTheInhibitTimeLeavesAtOnce_302_2_6_1) {
  NmtCommandQueue queue;
  queue.set_inhibit_time(kTenMs);
  NmtCommandQueue::Output out;
  queue.queue(NmtCommand::Stop, to(9));
  queue.on_timer(at_ms(100), out);
  queue.queue(NmtCommand::Start, to(9));
  EXPECT_EQ(queue.next_deadline(), at_ms(110));
  out.clear();
  queue.on_timer(at_ms(250), out);
  EXPECT_EQ(texts(out), (std::vector<std::string>{"000#0109"}));
}

TEST(NmtCommandQueue, TakesNoFrame) {
  NmtCommandQueue queue;
  NmtCommandQueue::Output out;
  const auto frame = from_candump("000#0100");
  ASSERT_TRUE(frame.has_value());
  EXPECT_FALSE(queue.on_frame(*frame, at_ms(1), out));
  EXPECT_TRUE(out.empty());
}

// The composition: the master hands out a call's NMT commands before the call's SDO requests, so
// CiA 302-2 §3.1 d's reset communication of the other nodes leaves before the first request of
// §3.4 to a slave kept alive (which is not reset, so its boot starts at once); the master's own
// boot-up is the first frame of all.
TEST(NmtMasterCommandOrder, ResetsOfAStartUpLeaveBeforeItsSdoRequests_302_2_3_1_d) {
  using A = cfg::SlaveAssignment;
  for (std::uint32_t inhibit : {0U, 50U}) {
    SCOPED_TRACE(inhibit);
    auto created = NmtMaster::create(cfg::DeviceDescription{}, *cfg::NodeId::from(0x7F), {});
    ASSERT_TRUE(created.ok());
    NmtMaster master = std::move(created).value();
    auto& dict = master.dictionary();
    ASSERT_TRUE(dict.set_unsigned(0x1F80, 0, cfg::NmtStartup::kMaster));
    ASSERT_TRUE(dict.set_unsigned(0x1F81, 2, A::kSlave | A::kBootSlave | A::kKeepAlive));
    ASSERT_TRUE(dict.set_unsigned(0x102A, 0, inhibit));
    NmtMaster::Output out;
    master.start(at_ms(0), out);
    const auto frames = texts_of(out);
    ASSERT_GE(frames.size(), 3U);
    EXPECT_EQ(frames.front(), "77F#00");
    // §3.1 d with a slave kept alive: every other node-ID individually, from node 1 on; with an
    // inhibit time only the first in this call.
    EXPECT_EQ(frames[1], "000#8201");
    const auto request = std::find(frames.begin(), frames.end(), "602#4000100000000000");
    ASSERT_NE(request, frames.end());
    const auto last_nmt = std::find_if(frames.rbegin(), frames.rend(), [](const std::string& f) {
      return f.rfind("000#", 0) == 0;
    });
    ASSERT_NE(last_nmt, frames.rend());
    const auto last_nmt_index = frames.rend() - last_nmt - 1;
    EXPECT_LT(last_nmt_index, request - frames.begin());
    EXPECT_EQ(std::count_if(frames.begin(), frames.end(),
                            [](const std::string& f) { return f.rfind("000#", 0) == 0; }),
              inhibit == 0 ? 125 : 1);
  }
}

}  // namespace
}  // namespace nmt
