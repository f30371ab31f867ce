// The SocketCAN driver against a real Linux CAN stack. Needs the CAN_RAW protocol and a vcan
// interface (vcan0, and vcan1 for the isolation test); each test skips with a message when they
// are missing. The VM tier (tests/vm) boots a kernel that has them and runs these tests there.
// Decoding of raw frames (flags, error frames) is tested without a kernel.
//
// Interfaces can be renamed with CANOPEN_TEST_CAN_IF and CANOPEN_TEST_CAN_IF2.
#include "nmt/io/socketcan_bus.hpp"

#include <gtest/gtest.h>
#include <linux/can.h>
#include <linux/can/error.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "heartbeat_stall.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "prerequisite.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;

CanFrame frame(std::string_view candump) {
  auto f = from_candump(candump);
  EXPECT_TRUE(f.has_value()) << candump;
  return f.value_or(CanFrame{});
}

std::string env_or(const char* name, const char* fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? v : fallback;
}

std::string can_if() {
  return env_or("CANOPEN_TEST_CAN_IF", "vcan0");
}
std::string can_if2() {
  return env_or("CANOPEN_TEST_CAN_IF2", "vcan1");
}

// Why SocketCAN tests cannot run here, or an empty string when they can.
std::string socketcan_unavailable(const std::string& ifname) {
  const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) {
    return "no SocketCAN in this kernel (socket(PF_CAN, SOCK_RAW, CAN_RAW) failed); the VM tier "
           "(ctest -L vm) runs these tests";
  }
  ::close(fd);
  if (if_nametoindex(ifname.c_str()) == 0) {
    return "interface " + ifname + " does not exist (ip link add dev " + ifname +
           " type vcan && ip link set " + ifname + " up)";
  }
  return {};
}

// SocketCAN with vcan is a prerequisite where the interfaces were set up for these tests: in the
// VM tier's guest (CANOPEN_VM_GUEST=1, tests/vm/guest-init.sh) or where CANOPEN_TEST_CAN_IF names
// one. On an ordinary host (no vcan module, no root) they skip plainly even under CI=true: the VM
// tier (ctest -L vm) is where they run.
bool socketcan_expected() {
  return env_or("CANOPEN_VM_GUEST", "0") == std::string("1") ||
         std::getenv("CANOPEN_TEST_CAN_IF") != nullptr;
}

#define SKIP_WITHOUT_SOCKETCAN(ifname)                            \
  do {                                                            \
    if (auto why = socketcan_unavailable(ifname); !why.empty()) { \
      if (!socketcan_expected()) GTEST_SKIP() << why;             \
      PREREQUISITE_MISSING(why);                                  \
    }                                                             \
  } while (0)

std::unique_ptr<SocketCanBus> open_or_fail(const std::string& ifname,
                                           const SocketCanOptions& options = {}) {
  auto bus = SocketCanBus::open(ifname, options);
  EXPECT_TRUE(bus.ok()) << (bus.ok() ? "" : bus.error().message);
  return bus.ok() ? std::move(bus).value() : nullptr;
}

// Receives up to `count` frames, each within `timeout`; stops early when none arrives.
std::vector<CanFrame> receive_frames(SocketCanBus& bus, std::size_t count, Duration timeout = 2s) {
  std::vector<CanFrame> out;
  while (out.size() < count) {
    auto r = bus.receive(timeout);
    EXPECT_TRUE(r.ok()) << (r.ok() ? "" : r.error().message);
    if (!r.ok() || !r->has_value()) break;
    out.push_back((*r)->frame);
  }
  return out;
}

std::vector<std::string> as_candump(const std::vector<CanFrame>& frames) {
  std::vector<std::string> out;
  out.reserve(frames.size());
  for (const auto& f : frames) out.push_back(to_candump(f));
  return out;
}

// Asserts that nothing (more) arrives within a short time.
void expect_silence(SocketCanBus& bus, Duration timeout = 100ms) {
  auto r = bus.receive(timeout);
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->has_value()) << "unexpected " << to_candump((*r)->frame);
}

class SocketCan : public ::testing::Test {
 protected:
  void SetUp() override {
    SKIP_WITHOUT_SOCKETCAN(can_if());
    tx_ = open_or_fail(can_if());
    rx_ = open_or_fail(can_if());
    ASSERT_TRUE(tx_ && rx_);
  }
  void send_all(const std::vector<std::string>& frames) {
    for (const auto& text : frames) {
      auto st = tx_->send(frame(text));
      ASSERT_TRUE(st.ok()) << text << ": " << st.error().message;
    }
  }
  std::unique_ptr<SocketCanBus> tx_;
  std::unique_ptr<SocketCanBus> rx_;
};

// ---------------------------------------------------------------------------------------------
// Decoding raw frames: linux/can.h flag bits and linux/can/error.h error frames. No kernel.

TEST(SocketCanDecode, ErrorFlagGivesErrorFrameWithClassInId) {
  // linux/can/error.h: controller problem class, details in data[1] (RX warning level).
  const std::array<std::uint8_t, 8> data{0, CAN_ERR_CRTL_RX_WARNING, 0, 0, 0, 0, 0, 0};
  auto f = decode_socketcan_frame(CAN_ERR_FLAG | CAN_ERR_CRTL, CAN_ERR_DLC, data);
  ASSERT_TRUE(f.has_value());
  EXPECT_TRUE(f->error);
  EXPECT_EQ(f->id, CAN_ERR_CRTL);
  // As candump -L prints an error frame (ERR flag 0x20000000 in an 8-digit id).
  EXPECT_EQ(to_candump(*f), "20000004#0004000000000000");
  EXPECT_EQ(*f, frame("20000004#0004000000000000"));
}

TEST(SocketCanDecode, ErrorFlagWinsOverExtendedFlag) {
  // cansend with an 8-digit id sets CAN_EFF_FLAG too; the error class must not lose bits.
  const std::array<std::uint8_t, 8> data{};
  auto f = decode_socketcan_frame(CAN_ERR_FLAG | CAN_EFF_FLAG | CAN_ERR_BUSOFF, 8, data);
  ASSERT_TRUE(f.has_value());
  EXPECT_TRUE(f->error);
  EXPECT_EQ(f->id, CAN_ERR_BUSOFF);
}

TEST(SocketCanDecode, ExtendedFlagGives29BitIdentifier) {
  const std::array<std::uint8_t, 2> data{0xAB, 0xCD};
  auto f = decode_socketcan_frame(CAN_EFF_FLAG | 0x12345678u, 2, data);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(*f, frame("12345678#ABCD"));
}

TEST(SocketCanDecode, StandardIdentifierKeepsOnly11Bits) {
  const std::array<std::uint8_t, 1> data{0x01};
  auto f = decode_socketcan_frame(0x705, 1, data);
  ASSERT_TRUE(f.has_value());
  EXPECT_EQ(*f, frame("705#01"));
  EXPECT_FALSE(f->extended);
}

TEST(SocketCanDecode, RemoteFrameKeepsDlcAndCarriesNoData) {
  // A remote frame has a DLC but no data field (ISO 11898-1); whatever is in the buffer is
  // not data.
  const std::array<std::uint8_t, 8> junk{1, 2, 3, 4, 5, 6, 7, 8};
  auto f = decode_socketcan_frame(CAN_RTR_FLAG | 0x701, 3, junk);
  ASSERT_TRUE(f.has_value());
  EXPECT_TRUE(f->rtr);
  EXPECT_EQ(f->dlc, 3);
  EXPECT_EQ(*f, frame("701#R3"));
}

TEST(SocketCanDecode, RejectsLengthAboveEightBytes) {
  const std::array<std::uint8_t, 64> data{};
  EXPECT_FALSE(decode_socketcan_frame(0x123, 9, data).has_value());
  EXPECT_FALSE(decode_socketcan_frame(0x123, 64, data).has_value());
}

TEST(SocketCanDecode, RejectsLengthLongerThanGivenData) {
  const std::array<std::uint8_t, 2> data{};
  EXPECT_FALSE(decode_socketcan_frame(0x123, 3, data).has_value());
}

// ---------------------------------------------------------------------------------------------
// Opening. These fail with a message with or without CAN support in the kernel.

TEST(SocketCanOpen, FailsWithMessageNamingMissingInterface) {
  auto bus = open_socketcan_bus("nosuchcan7");
  ASSERT_FALSE(bus.ok());
  EXPECT_NE(bus.error().message.find("socketcan:nosuchcan7"), std::string::npos)
      << bus.error().message;
}

TEST(SocketCanOpen, RejectsNameLongerThanTheKernelAllows) {
  auto bus = open_socketcan_bus(std::string(IFNAMSIZ, 'x'));
  ASSERT_FALSE(bus.ok());
  EXPECT_NE(bus.error().message.find("characters"), std::string::npos) << bus.error().message;
  EXPECT_FALSE(open_socketcan_bus("").ok());
}

TEST(SocketCanOpen, RefusesInterfaceThatIsNotCan) {
  SKIP_WITHOUT_SOCKETCAN(can_if());
  if (if_nametoindex("lo") == 0) PREREQUISITE_MISSING("no loopback interface");
  auto bus = open_socketcan_bus("lo");
  ASSERT_FALSE(bus.ok());
  EXPECT_NE(bus.error().message.find("socketcan:lo"), std::string::npos);
}

TEST_F(SocketCan, UrlNamesTheInterface) {
  EXPECT_EQ(tx_->url(), "socketcan:" + can_if());
}

// ---------------------------------------------------------------------------------------------
// Sending and receiving through the kernel (vcan loops every frame back to the other sockets).

TEST_F(SocketCan, SendsAndReceivesStandardFrame) {
  send_all({"605#2B171000E8030000"});
  auto got = receive_frames(*rx_, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(to_candump(got[0]), "605#2B171000E8030000");
}

TEST_F(SocketCan, SendsAndReceivesExtendedFrames) {
  send_all({"00000123#11", "1FFFFFFF#", "12345678#DEADBEEF"});
  EXPECT_EQ(as_candump(receive_frames(*rx_, 3)),
            (std::vector<std::string>{"00000123#11", "1FFFFFFF#", "12345678#DEADBEEF"}));
}

TEST_F(SocketCan, StandardAndExtendedWithSameNumberAreDifferentFrames) {
  send_all({"123#01", "00000123#01"});
  auto got = receive_frames(*rx_, 2);
  ASSERT_EQ(got.size(), 2u);
  EXPECT_FALSE(got[0].extended);
  EXPECT_TRUE(got[1].extended);
}

TEST_F(SocketCan, CarriesEveryLengthFromZeroToEightBytes) {
  std::vector<std::string> sent = {"100#",
                                   "101#01",
                                   "102#0102",
                                   "103#010203",
                                   "104#01020304",
                                   "105#0102030405",
                                   "106#010203040506",
                                   "107#01020304050607",
                                   "108#0102030405060708"};
  send_all(sent);
  EXPECT_EQ(as_candump(receive_frames(*rx_, sent.size())), sent);
}

TEST_F(SocketCan, CarriesRemoteFramesWithTheirDlc) {
  // CiA 301 node guarding: the master sends an RTR on 0x700 + node-id.
  send_all({"705#R", "701#R1", "00000705#R8"});
  auto got = receive_frames(*rx_, 3);
  ASSERT_EQ(got.size(), 3u);
  EXPECT_EQ(got[0], frame("705#R"));
  EXPECT_EQ(got[1], frame("701#R1"));
  EXPECT_EQ(got[2], frame("00000705#R8"));
  for (const auto& f : got) EXPECT_TRUE(f.rtr);
}

TEST_F(SocketCan, DoesNotReceiveItsOwnFramesByDefault) {
  send_all({"181#01"});
  ASSERT_EQ(receive_frames(*rx_, 1).size(), 1u);
  expect_silence(*tx_);
}

TEST_F(SocketCan, ReceivesItsOwnFramesWhenAsked) {
  SocketCanOptions options;
  options.receive_own_frames = true;
  auto self = open_or_fail(can_if(), options);
  ASSERT_TRUE(self);
  ASSERT_TRUE(self->send(frame("181#02")).ok());
  EXPECT_EQ(as_candump(receive_frames(*self, 1)), std::vector<std::string>{"181#02"});
}

TEST_F(SocketCan, ReceiveReturnsNothingAfterTheTimeout) {
  const auto start = std::chrono::steady_clock::now();
  auto r = rx_->receive(50ms);
  const auto waited = std::chrono::steady_clock::now() - start;
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->has_value());
  EXPECT_GE(waited, 50ms);
  EXPECT_LT(waited, 2s);
}

TEST_F(SocketCan, ZeroTimeoutDoesNotWait) {
  auto r = rx_->receive(Duration::zero());
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_FALSE(r->has_value());
}

// can.rst, "How to use SocketCAN" and socket(7), SO_TIMESTAMPNS: the kernel stamps a frame as it
// is received (CLOCK_REALTIME), so a frame read late keeps the time it arrived.
TEST_F(SocketCan, TimestampIsTheKernelReceiveTimeNotWhenTheFrameWasRead) {
  const TimePoint before = wall_clock_now();
  send_all({"080#"});  // CiA 301 SYNC
  const TimePoint sent = wall_clock_now();
  std::this_thread::sleep_for(300ms);  // the frame waits in the socket
  auto r = rx_->receive(2s);
  ASSERT_TRUE(r.ok() && r->has_value());
  EXPECT_EQ((*r)->clock, StampClock::Realtime);
  EXPECT_GE((*r)->timestamp, before);
  EXPECT_LE((*r)->timestamp, sent + 100ms);  // vcan forwards at once
}

// On vcan (in the VM tier): a 2 s stall of the event loop while a peer keeps sending
// heartbeats is no heartbeat loss; a peer that stops is (tests/support/heartbeat_stall.hpp).
TEST_F(SocketCan, HeartbeatsQueuedWhileTheLoopStallsCountAsInTimeAndARealLossIsSeen) {
  test_support::check_stall_is_not_a_heartbeat_loss(*rx_, std::move(tx_));
}

TEST_F(SocketCan, FramesOnAnotherInterfaceAreNotReceived) {
  SKIP_WITHOUT_SOCKETCAN(can_if2());
  auto other = open_or_fail(can_if2());
  ASSERT_TRUE(other);
  ASSERT_TRUE(other->send(frame("222#22")).ok());
  expect_silence(*rx_);
}

TEST_F(SocketCan, SendRejectsFramesThatAreNotClassicCan) {
  CanFrame too_long = frame("123#0102030405060708");
  too_long.dlc = 9;
  EXPECT_FALSE(tx_->send(too_long).ok());
  CanFrame big_id = frame("123#");
  big_id.id = 0x800;  // 11-bit identifiers end at 0x7FF
  EXPECT_FALSE(tx_->send(big_id).ok());
  CanFrame big_eff = frame("00000123#");
  big_eff.id = 0x20000000;  // 29-bit identifiers end at 0x1FFFFFFF
  EXPECT_FALSE(tx_->send(big_eff).ok());
  EXPECT_FALSE(tx_->send(frame("20000004#0004000000000000")).ok());  // an error frame
  expect_silence(*rx_);
}

// ---------------------------------------------------------------------------------------------
// Receive filters (can.rst, "RAW socket option CAN_RAW_FILTER").

TEST_F(SocketCan, FilterOnOneIdentifierPassesOnlyThatFrame) {
  const CanFilter only{0x123, CanFrame::kMaxStandardId, false, false};
  ASSERT_TRUE(rx_->set_filters(std::span(&only, 1)).ok());
  send_all({"124#01", "00000123#02", "123#03", "123#R"});
  // The extended 0x123 does not pass: the frame format is part of every filter.
  EXPECT_EQ(as_candump(receive_frames(*rx_, 2)), (std::vector<std::string>{"123#03", "123#R"}));
  expect_silence(*rx_);
}

TEST_F(SocketCan, MaskFilterPassesARange) {
  // CiA 301 default SDO server->client identifiers: 0x580 + node-id (0x581..0x5FF).
  const CanFilter sdo_tx{0x580, 0x780, false, false};
  ASSERT_TRUE(rx_->set_filters(std::span(&sdo_tx, 1)).ok());
  send_all({"57F#01", "581#02", "5FF#03", "600#04", "601#05"});
  EXPECT_EQ(as_candump(receive_frames(*rx_, 2)), (std::vector<std::string>{"581#02", "5FF#03"}));
  expect_silence(*rx_);
}

TEST_F(SocketCan, SeveralFiltersPassTheUnion) {
  const std::array<CanFilter, 2> filters{CanFilter{0x000, 0x7FF, false, false},  // NMT
                                         CanFilter{0x1ABCDE0, 0x1FFFFFF0, true, false}};
  ASSERT_TRUE(rx_->set_filters(filters).ok());
  send_all({"000#0105", "001#00", "01ABCDE7#AA", "01ABCDF0#BB"});
  EXPECT_EQ(as_candump(receive_frames(*rx_, 2)),
            (std::vector<std::string>{"000#0105", "01ABCDE7#AA"}));
  expect_silence(*rx_);
}

TEST_F(SocketCan, RtrFilterPassesOnlyRemoteFrames) {
  const CanFilter guarding{0x700, 0x780, false, true};
  ASSERT_TRUE(rx_->set_filters(std::span(&guarding, 1)).ok());
  send_all({"705#05", "705#R1"});
  EXPECT_EQ(as_candump(receive_frames(*rx_, 1)), std::vector<std::string>{"705#R1"});
  expect_silence(*rx_);
}

TEST_F(SocketCan, NoFiltersReceiveNothingUntilAllAreAcceptedAgain) {
  ASSERT_TRUE(rx_->set_filters({}).ok());
  send_all({"123#01"});
  expect_silence(*rx_);
  ASSERT_TRUE(rx_->accept_all_frames().ok());
  send_all({"123#02"});
  EXPECT_EQ(as_candump(receive_frames(*rx_, 1)), std::vector<std::string>{"123#02"});
}

TEST_F(SocketCan, RejectsMoreFiltersThanTheKernelAllows) {
  const std::vector<CanFilter> many(CAN_RAW_FILTER_MAX + 1);
  auto st = rx_->set_filters(many);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("at most"), std::string::npos) << st.error().message;
}

// ---------------------------------------------------------------------------------------------
// Many frames, and a full transmit queue. vcan forwards every frame at once (its qdisc is
// noqueue, whatever txqueuelen says), so its transmit queue never fills. The VM tier paces vcan0
// like a real bus with a token bucket (tc qdisc ... tbf rate 125kbit burst 80 limit 160) and sets
// CANOPEN_TEST_CAN_IF_RATE_LIMITED=1; there a burst fills the queue and the kernel answers
// ENOBUFS. Elsewhere the queue-full tests skip.

bool transmit_queue_can_fill() {
  return env_or("CANOPEN_TEST_CAN_IF_RATE_LIMITED", "0") == std::string("1");
}

// Not a prerequisite: whether the interface's transmit queue can fill is a property of the
// interface (plain vcan has none); the *TransmitQueue* tests skip plainly without it.
constexpr const char* kNeedsPacedInterface =
    "needs a rate-limited interface (CANOPEN_TEST_CAN_IF_RATE_LIMITED=1 after tc qdisc add dev "
    "vcan0 root tbf rate 125kbit burst 80 limit 160); the VM tier sets that up";

CanFrame numbered(std::uint32_t i) {
  const std::array<std::uint8_t, 4> bytes{
      static_cast<std::uint8_t>(i), static_cast<std::uint8_t>(i >> 8),
      static_cast<std::uint8_t>(i >> 16), static_cast<std::uint8_t>(i >> 24)};
  return CanFrame::make(0x200 + (i % 0x80), bytes);
}

// Reads frames on its own thread until `count` arrived or none came for 2 s.
class Collector {
 public:
  Collector(SocketCanBus& bus, std::size_t count)
      : thread_([this, &bus, count] {
          while (frames_.size() < count) {
            auto r = bus.receive(2s);
            if (!r.ok()) {
              error_ = r.error().message;
              return;
            }
            if (!r->has_value()) return;
            frames_.push_back((*r)->frame);
          }
        }) {}
  std::vector<CanFrame> join() {
    thread_.join();
    return std::move(frames_);
  }
  const std::string& error() const { return error_; }

 private:
  std::vector<CanFrame> frames_;
  std::string error_;
  std::thread thread_;
};

TEST_F(SocketCan, BurstOf1000FramesArrivesCompleteAndInOrder) {
  constexpr std::uint32_t kCount = 1000;
  Collector collector(*rx_, kCount);
  for (std::uint32_t i = 0; i < kCount; ++i) {
    auto st = tx_->send(numbered(i));
    ASSERT_TRUE(st.ok()) << "frame " << i << ": " << st.error().message;
  }
  auto got = collector.join();
  EXPECT_EQ(collector.error(), "");
  ASSERT_EQ(got.size(), kCount) << "queue-full waits: " << tx_->queue_full_waits()
                                << ", receiver overflows: " << rx_->receive_overflows();
  for (std::uint32_t i = 0; i < kCount; ++i) {
    ASSERT_EQ(got[i], numbered(i)) << "frame " << i;
  }
  EXPECT_EQ(rx_->receive_overflows(), 0u);
}

TEST_F(SocketCan, FullTransmitQueueMakesSendWaitNotDrop) {
  if (!transmit_queue_can_fill()) GTEST_SKIP() << kNeedsPacedInterface;
  constexpr std::uint32_t kCount = 500;
  Collector collector(*rx_, kCount);
  for (std::uint32_t i = 0; i < kCount; ++i) {
    auto st = tx_->send(numbered(i));
    ASSERT_TRUE(st.ok()) << "frame " << i << ": " << st.error().message;
  }
  auto got = collector.join();
  // The queue did fill (ENOBUFS was seen and waited out) ...
  EXPECT_GT(tx_->queue_full_waits(), 0u);
  // ... and still every frame arrived, in order.
  ASSERT_EQ(got.size(), kCount) << "receiver overflows: " << rx_->receive_overflows();
  for (std::uint32_t i = 0; i < kCount; ++i) ASSERT_EQ(got[i], numbered(i)) << "frame " << i;
}

// The transmit path survives a real controller: the event loop meets the full
// queue (ENOBUFS) of the paced vcan0 as back-pressure. Every frame of a burst goes out, in
// order, none is reported failed, and the loop keeps receiving while its queue holds frames.
struct Burst {
  using Event = NoEvent;
  using Output = Outbox<NoEvent>;
  bool on_frame(const CanFrame& f, TimePoint /*now*/, Output& /*out*/) {
    heard.push_back(to_candump(f));
    if (loop != nullptr) queued_when_heard = loop->counters().queued;
    return true;
  }
  void on_timer(TimePoint /*now*/, Output& /*out*/) {}
  std::optional<TimePoint> next_deadline() const { return std::nullopt; }
  const BusEventLoop* loop = nullptr;
  std::vector<std::string> heard;
  std::size_t queued_when_heard = 0;
};

TEST_F(SocketCan, TheEventLoopSendsABurstThroughAFullQueueInOrderWhileItKeepsReceiving) {
  if (!transmit_queue_can_fill()) GTEST_SKIP() << kNeedsPacedInterface;
  constexpr std::uint32_t kCount = 500;
  auto peer = open_or_fail(can_if());
  ASSERT_TRUE(peer);
  Collector collector(*rx_, kCount + 1);  // the burst and the peer's frame
  BusEventLoop loop(*tx_);
  Burst burst;
  burst.loop = &loop;
  EngineRef ref(burst);
  loop.add(ref);
  std::vector<BusEvent> reported;
  loop.set_bus_event_handler([&](const BusEvent& e, TimePoint) { reported.push_back(e); });
  ref.apply([&](Burst&, TimePoint, Burst::Output& out) {
    for (std::uint32_t i = 0; i < kCount; ++i) out.send(numbered(i));
  });
  std::thread peer_thread([&] {
    // Sent into the burst, not after a readiness signal: the loop's counters are its thread's
    // alone, and queued_when_heard below says whether it came while the burst was still queued.
    std::this_thread::sleep_for(50ms);
    EXPECT_TRUE(peer->send(frame("181#01")).ok());
  });
  auto sent = loop.run_until_sent(10s);
  peer_thread.join();
  ASSERT_TRUE(sent.ok()) << sent.error().message;
  auto got = collector.join();
  EXPECT_GT(loop.counters().queue_full, 0u) << "the transmit queue never filled";
  EXPECT_EQ(loop.counters().queued, 0u);
  EXPECT_TRUE(reported.empty()) << reported.front().text;
  EXPECT_EQ(burst.heard, std::vector<std::string>{"181#01"});
  EXPECT_GT(burst.queued_when_heard, 0u) << "the peer's frame came after the burst was out";
  std::vector<CanFrame> ours;
  for (const auto& f : got) {
    if (f.id != 0x181) ours.push_back(f);
  }
  ASSERT_EQ(ours.size(), kCount) << "receiver overflows: " << rx_->receive_overflows();
  for (std::uint32_t i = 0; i < kCount; ++i) ASSERT_EQ(ours[i], numbered(i)) << "frame " << i;
}

TEST_F(SocketCan, SendWithoutWaitTimeReportsEveryFrameItCouldNotSend) {
  if (!transmit_queue_can_fill()) GTEST_SKIP() << kNeedsPacedInterface;
  SocketCanOptions impatient;
  impatient.send_timeout = Duration::zero();
  auto tx = open_or_fail(can_if(), impatient);
  ASSERT_TRUE(tx);
  constexpr std::uint32_t kCount = 500;
  Collector collector(*rx_, kCount);
  std::vector<CanFrame> accepted;
  std::string last_error;
  for (std::uint32_t i = 0; i < kCount; ++i) {
    auto st = tx->send(numbered(i));
    if (st.ok()) {
      accepted.push_back(numbered(i));
    } else {
      last_error = st.error().message;
    }
  }
  auto got = collector.join();
  // Some frames found the queue full and were reported as not sent...
  ASSERT_LT(accepted.size(), kCount) << "the transmit queue never filled";
  EXPECT_NE(last_error.find("transmit queue full"), std::string::npos) << last_error;
  // ...and every frame send() accepted arrived: nothing was lost silently.
  EXPECT_EQ(as_candump(got), as_candump(accepted));
  EXPECT_EQ(rx_->receive_overflows(), 0u);
}

// ---------------------------------------------------------------------------------------------
// Error frames (can.rst, "Network Problem Notifications"). vcan has no CAN controller, so the
// kernel never generates error frames on it. What vcan does is loop back any frame a socket
// writes, including one with CAN_ERR_FLAG, and the CAN core delivers it only to sockets whose
// CAN_RAW_ERR_FILTER mask has its class bits. So injecting one through a plain raw socket
// tests the driver's error mask and receive path end to end; the kernel-generated case differs
// only in who wrote the frame.

// Writes an error frame with a raw socket of our own (the driver refuses to send one).
bool inject_error_frame(const std::string& ifname, canid_t error_class,
                        const std::array<std::uint8_t, 8>& data, std::string& why) {
  const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = static_cast<int>(if_nametoindex(ifname.c_str()));
  can_frame raw{};
  raw.can_id = CAN_ERR_FLAG | error_class;
  raw.len = CAN_ERR_DLC;
  std::copy(data.begin(), data.end(), raw.data);
  const bool ok = fd >= 0 && ::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr) == 0 &&
                  ::write(fd, &raw, sizeof raw) == static_cast<ssize_t>(sizeof raw);
  if (!ok) why = std::strerror(errno);
  if (fd >= 0) ::close(fd);
  return ok;
}

TEST_F(SocketCan, ReportsErrorFramesWithTheirClass) {
  // linux/can/error.h: controller problem, data[1] = reached warning level for RX errors.
  const std::array<std::uint8_t, 8> details{0, CAN_ERR_CRTL_RX_WARNING, 0, 0, 0, 0, 0, 0};
  std::string why;
  if (!inject_error_frame(can_if(), CAN_ERR_CRTL, details, why)) {
    // Not a prerequisite: whether a socket may write an error frame is the kernel's and the
    // interface's choice (vcan on Debian's 6.1 accepts it), which the test cannot change.
    GTEST_SKIP() << "this kernel does not let a socket write an error frame on " << can_if() << " ("
                 << why << "); decoding is covered by SocketCanDecode.*";
  }
  auto r = rx_->receive(2s);
  ASSERT_TRUE(r.ok()) << r.error().message;
  ASSERT_TRUE(r->has_value()) << "error frame not reported";
  EXPECT_TRUE((*r)->frame.error);
  EXPECT_EQ((*r)->frame.id, CAN_ERR_CRTL);
  EXPECT_EQ(to_candump((*r)->frame), "20000004#0004000000000000");  // as candump -L prints it
}

TEST_F(SocketCan, ErrorMaskSelectsWhichErrorClassesAreReported) {
  ASSERT_TRUE(rx_->set_error_mask(CAN_ERR_BUSOFF).ok());
  std::string why;
  if (!inject_error_frame(can_if(), CAN_ERR_CRTL, {}, why)) {
    // Not a prerequisite: the kernel's choice (ReportsErrorFramesWithTheirClass).
    GTEST_SKIP() << "cannot write an error frame on " << can_if() << " (" << why << ")";
  }
  ASSERT_TRUE(inject_error_frame(can_if(), CAN_ERR_BUSOFF, {}, why)) << why;
  auto got = receive_frames(*rx_, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].id, CAN_ERR_BUSOFF);  // the controller-problem frame was not reported
  expect_silence(*rx_);

  ASSERT_TRUE(rx_->set_error_mask(0).ok());
  ASSERT_TRUE(inject_error_frame(can_if(), CAN_ERR_BUSOFF, {}, why)) << why;
  expect_silence(*rx_);
}

TEST_F(SocketCan, DataFiltersDoNotHideErrorFrames) {
  // can.rst: error frames are selected by the error mask, not by CAN_RAW_FILTER.
  const CanFilter only{0x123, 0x7FF, false, false};
  ASSERT_TRUE(rx_->set_filters(std::span(&only, 1)).ok());
  std::string why;
  if (!inject_error_frame(can_if(), CAN_ERR_PROT, {}, why)) {
    // Not a prerequisite: the kernel's choice (ReportsErrorFramesWithTheirClass).
    GTEST_SKIP() << "cannot write an error frame on " << can_if() << " (" << why << ")";
  }
  auto got = receive_frames(*rx_, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_TRUE(got[0].error);
  EXPECT_EQ(got[0].id, CAN_ERR_PROT);
}

// ---------------------------------------------------------------------------------------------
// Interoperation with can-utils, an independent SocketCAN implementation: what our driver sends
// appears in candump, and what cansend sends arrives through our driver.

bool have_program(const std::string& name) {
  return std::system(("command -v " + name + " >/dev/null 2>&1").c_str()) == 0;
}

// Receivers registered without filters on `ifname` (procfs, can.rst "procfs content").
int unfiltered_receivers(const std::string& ifname) {
  std::ifstream in("/proc/net/can/rcvlist_all");
  std::string line;
  int count = 0;
  while (std::getline(in, line)) {
    std::istringstream words(line);
    std::string first;
    if (words >> first && first == ifname) ++count;
  }
  return count;
}

class CanUtils : public SocketCan {
 protected:
  void SetUp() override {
    SocketCan::SetUp();
    if (IsSkipped() || HasFatalFailure()) return;
    if (!have_program("candump") || !have_program("cansend")) {
      PREREQUISITE_MISSING("can-utils (candump, cansend) not installed");
    }
  }
};

TEST_F(CanUtils, FramesSentByOurDriverAppearInCandump) {
  const std::vector<std::string> sent = {
      "605#2B171000E8030000", "000#0100", "12345678#DEADBEEF", "705#R", "100#",
      "7FF#0102030405060708"};
  const int before = unfiltered_receivers(can_if());
  // -L: log format "(time) if id#data"; -n: exit after that many frames; -T: or after 5 s quiet.
  const std::string cmd =
      "candump -L -n " + std::to_string(sent.size()) + " -T 5000 " + can_if() + " 2>&1";
  FILE* out = ::popen(cmd.c_str(), "r");
  ASSERT_NE(out, nullptr);
  // candump opens its socket after it starts: wait until it is registered, not a fixed time.
  const auto give_up = std::chrono::steady_clock::now() + 10s;
  while (unfiltered_receivers(can_if()) <= before && std::chrono::steady_clock::now() < give_up) {
    std::this_thread::sleep_for(5ms);
  }
  const bool registered = unfiltered_receivers(can_if()) > before;
  if (registered) send_all(sent);
  std::vector<std::string> dumped;
  std::array<char, 256> line{};
  while (std::fgets(line.data(), line.size(), out) != nullptr) {
    std::istringstream words(line.data());
    std::string stamp, ifname, text;
    if (words >> stamp >> ifname >> text) dumped.push_back(text);
  }
  ::pclose(out);
  ASSERT_TRUE(registered) << "candump did not open its socket within 10 s";
  ASSERT_EQ(dumped.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i) {
    // Compare frames rather than text: candump versions differ in how they print a remote
    // frame's DLC.
    auto parsed = from_candump(dumped[i]);
    ASSERT_TRUE(parsed.has_value()) << dumped[i];
    EXPECT_EQ(*parsed, frame(sent[i])) << "candump printed " << dumped[i];
  }
}

TEST_F(CanUtils, FramesFromCansendArriveThroughOurDriver) {
  const std::vector<std::string> sent = {"181#0102", "1FFFFFFF#AABBCCDDEEFF0011", "080#", "701#R"};
  for (const auto& text : sent) {
    ASSERT_EQ(std::system(("cansend " + can_if() + " " + text).c_str()), 0) << text;
  }
  auto got = receive_frames(*rx_, sent.size());
  ASSERT_EQ(got.size(), sent.size());
  for (std::size_t i = 0; i < sent.size(); ++i) EXPECT_EQ(got[i], frame(sent[i])) << sent[i];
}

TEST_F(CanUtils, ErrorFrameFromCansendIsReported) {
  // cansend writes the ERR flag as given (8 digits also set CAN_EFF_FLAG, which the error
  // frame decoding ignores).
  if (std::system(("cansend " + can_if() + " 20000008#0000020000000000").c_str()) != 0) {
    // Not a prerequisite: the kernel's choice (ReportsErrorFramesWithTheirClass).
    GTEST_SKIP() << "cansend could not write an error frame on " << can_if();
  }
  auto got = receive_frames(*rx_, 1);
  ASSERT_EQ(got.size(), 1u);
  EXPECT_TRUE(got[0].error);
  EXPECT_EQ(got[0].id, CAN_ERR_PROT);
  EXPECT_EQ(got[0].data[2], CAN_ERR_PROT_FORM);  // linux/can/error.h: form error
}

}  // namespace
}  // namespace nmt
