// The NMT master's SDO transfer scheduler alone (master/sdo_transfer_scheduler.hpp) against a fake
// port, with exact times: the boot's window of transfers in flight (halved once per loss event,
// grown by one per window's worth of answers), the waiting queue, the repetition after a timeout
// (MasterOptions::sdo.retries), bus-load pacing from the frames' bit lengths (ISO 11898-1, as
// nmt::frame_bits counts them) at a given bit rate, the transfers held while the SDO manager gave
// a default SDO to an SRD (DSP 302 §7.1), refused starts, and the cancel of a try's transfers
// that leaves the SDO manager's and the application's running.
// Frames are CiA 301 §7.2.4.3 SDO frames on the default channels 600h/580h + node-ID.
#include "master/sdo_transfer_scheduler.hpp"

#include <gtest/gtest.h>

#include <map>
#include <set>
#include <string>
#include <vector>

#include "cfg/hex.hpp"
#include "nmt/protocol/frame_bits.hpp"

namespace nmt {
namespace {

using std::chrono::milliseconds;
using Scheduler = SdoTransferScheduler;

TimePoint at_ms(std::int64_t ms) {
  return TimePoint{milliseconds(ms)};
}
cfg::NodeId node(std::uint8_t n) {
  return *cfg::NodeId::from(n);
}

class FakePort final : public SdoTransferPort {
 public:
  std::set<std::uint8_t> given_out;               ///< default SDOs the SDO manager gave away
  std::map<std::uint8_t, std::uint64_t> running;  ///< each node's running boot try
  std::set<std::uint8_t> heard;  ///< nodes whose NMT state the master knows from their frames

  bool default_sdo_given_out(cfg::NodeId n) const override { return given_out.contains(n.value()); }
  bool boot_try_runs(cfg::NodeId n, std::uint64_t try_id) const override {
    const auto it = running.find(n.value());
    return it != running.end() && it->second == try_id;
  }
  bool heard_from(cfg::NodeId n) const override { return heard.contains(n.value()); }
};

// CiA 301 §7.2.4.3.5 initiate upload request of 1000h sub 0.
constexpr const char* kUpload1000 = "4000100000000000";
// The expedited answer with 4 bytes (1000h = 0x00000192).
constexpr const char* kAnswer1000 = "4300100092010000";
// CiA 301 §7.2.4.3.17 abort of 1000h sub 0 with 0504 0000 (protocol timed out).
constexpr const char* kTimeout1000 = "8000100000000405";

// The candump text of an SDO frame on COB-ID `base` + node-ID `n`.
std::string on(std::uint16_t base, std::uint8_t n, const char* data) {
  return cfg::hex_digits(base + n, 3) + "#" + data;
}

struct Rig {
  FakePort port;
  Scheduler::Settings settings;
  Scheduler scheduler{port, settings};
  Scheduler::Output out;
  std::vector<Scheduler::Event> events;

  explicit Rig(Scheduler::Settings s = {.sdo_timeout = milliseconds(100)})
      : settings(s), scheduler(port, s) {}

  // One boot upload of 1000h for `try_id` of node `n`.
  void boot_upload(std::uint8_t n, std::uint64_t try_id, TimePoint now, Duration timeout,
                   unsigned retries = 0) {
    port.running[n] = try_id;
    scheduler.start_boot(try_id,
                         {.node = node(n),
                          .object = {0x1000, 0},
                          .upload = true,
                          .timeout = timeout,
                          .retries = retries},
                         now, out);
  }

  // One upload of `object` by the SDO manager (`tag`) to node `n`, 100 ms for each response.
  void manager_upload(std::uint64_t tag, std::uint8_t n, cfg::ObjectAddress object, TimePoint now) {
    scheduler.start_manager(
        tag, {.node = node(n), .object = object, .upload = true, .timeout = milliseconds(100)}, now,
        out);
  }

  // The master's settle (NmtMaster::Impl::settle) without its other parts.
  void settle(TimePoint now) {
    for (;;) {
      if (scheduler.collect(now)) {
        while (scheduler.dispatch_next(now, out)) {
          for (auto& e : out.events) events.push_back(std::move(e));
          out.events.clear();
        }
        continue;
      }
      scheduler.release_held(now, out);
      scheduler.pump(now, out);
      if (scheduler.settled()) break;
    }
  }
  void frame(const std::string& candump, TimePoint now) {
    scheduler.pace_frame_of_others(*from_candump(candump), now);
    scheduler.on_frame(*from_candump(candump), now, out);
    settle(now);
  }
  void timer(TimePoint now) {
    scheduler.on_timer(now, out);
    settle(now);
  }
  std::vector<std::string> take_frames() {
    std::vector<std::string> texts;
    for (const auto& f : out.frames) texts.push_back(to_candump(f));
    out.frames.clear();
    return texts;
  }
  std::vector<Scheduler::Finished> finished() const {
    std::vector<Scheduler::Finished> list;
    for (const auto& e : events) {
      if (const auto* f = std::get_if<Scheduler::Finished>(&e)) list.push_back(*f);
    }
    return list;
  }
};

TEST(SdoTransferScheduler, BootTransfersBeyondTheWindowWaitUntilAnAnswerFreesAPlace) {
  Rig rig;
  // 129 uploads to one node: the window (128 at the start) takes 128 of them (the client runs
  // them one after the other, the first on the bus), the 129th waits in the scheduler.
  for (int i = 0; i < 129; ++i) rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.settle(at_ms(0));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 128U);
  EXPECT_EQ(rig.scheduler.waiting(), 1U);
  // Waiting with the window full: no deadline of its own (an answer frees a place), the
  // client's response timeout is the next.
  EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(100));

  rig.frame(on(0x580, 5, kAnswer1000), at_ms(10));
  // The answer ends one (its result to its try) and the next request goes out; the waiting one
  // takes the free place.
  ASSERT_EQ(rig.finished().size(), 1U);
  EXPECT_TRUE(rig.finished()[0].result.ok());
  EXPECT_EQ(rig.finished()[0].owner, Scheduler::Owner{Scheduler::BootTry{1}});
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  EXPECT_EQ(rig.scheduler.waiting(), 0U);
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 128U);
  // Grown by 1/128 and held at its maximum.
  EXPECT_DOUBLE_EQ(rig.scheduler.window(), 128.0);
}

TEST(SdoTransferScheduler, HalvesTheWindowOnceForOneLossEvent) {
  Rig rig;
  // Nodes 1 and 2 at 0 ms, with 100 ms and 150 ms to answer; neither answers.
  rig.boot_upload(1, 1, at_ms(0), milliseconds(100));
  rig.boot_upload(2, 1, at_ms(0), milliseconds(150));
  rig.settle(at_ms(0));
  EXPECT_EQ(rig.take_frames(),
            (std::vector<std::string>{on(0x600, 1, kUpload1000), on(0x600, 2, kUpload1000)}));

  rig.timer(at_ms(100));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 1, kTimeout1000)});
  EXPECT_DOUBLE_EQ(rig.scheduler.window(), 64.0);
  // Node 3 starts after the cut.
  rig.boot_upload(3, 1, at_ms(120), milliseconds(100));
  rig.settle(at_ms(120));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 3, kUpload1000)});

  // Node 2's request left before the cut: the same loss event, the window stays.
  rig.timer(at_ms(150));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 2, kTimeout1000)});
  EXPECT_DOUBLE_EQ(rig.scheduler.window(), 64.0);

  // Node 3's left after it: a new loss event.
  rig.timer(at_ms(220));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 3, kTimeout1000)});
  EXPECT_DOUBLE_EQ(rig.scheduler.window(), 32.0);

  // An answer grows it by one per window's worth: 1/32.
  rig.boot_upload(4, 1, at_ms(300), milliseconds(100));
  rig.settle(at_ms(300));
  rig.frame(on(0x580, 4, kAnswer1000), at_ms(310));
  EXPECT_DOUBLE_EQ(rig.scheduler.window(), 32.0 + 1.0 / 32.0);
  ASSERT_EQ(rig.finished().size(), 4U);
  for (int i = 0; i < 3; ++i) EXPECT_EQ(rig.finished()[i].result.abort, SdoAbort::Timeout);
}

TEST(SdoTransferScheduler, RepeatsATransferThatTimedOutUpToItsRetries) {
  Rig rig;
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100), 2);
  rig.settle(at_ms(0));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  // Each timeout: the client's abort, then the request again, two times; the owner sees
  // nothing until the third timeout.
  for (const auto t : {100, 200}) {
    SCOPED_TRACE(t);
    EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(t));
    rig.timer(at_ms(t));
    EXPECT_EQ(rig.take_frames(),
              (std::vector<std::string>{on(0x600, 5, kTimeout1000), on(0x600, 5, kUpload1000)}));
    EXPECT_TRUE(rig.finished().empty());
  }
  rig.timer(at_ms(300));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kTimeout1000)});
  ASSERT_EQ(rig.finished().size(), 1U);
  EXPECT_EQ(rig.finished()[0].result.abort, SdoAbort::Timeout);
  EXPECT_FALSE(rig.finished()[0].result.aborted_by_server);
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 0U);
  EXPECT_EQ(rig.scheduler.next_deadline(), std::nullopt);
}

TEST(SdoTransferScheduler, AnAbortOfTheServerIsNotRepeated) {
  Rig rig;
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100), 2);
  rig.settle(at_ms(0));
  rig.take_frames();
  // CiA 301 §7.2.4.3.17: the server aborts with 0602 0000 (object does not exist).
  rig.frame(on(0x580, 5, "8000100000000206"), at_ms(5));
  EXPECT_TRUE(rig.take_frames().empty());
  ASSERT_EQ(rig.finished().size(), 1U);
  EXPECT_EQ(rig.finished()[0].result.abort, SdoAbort::ObjectDoesNotExist);
  EXPECT_TRUE(rig.finished()[0].result.aborted_by_server);
}

TEST(SdoTransferScheduler, PacesBootRequestsToTheLoadLimitFromTheirBitLengths) {
  // 125 kbit/s, half the bus: 62 500 bit/s for the boot.
  Rig rig({.bitrate_bps = 125'000, .bus_load_limit = 0.5, .sdo_timeout = milliseconds(100)});
  const auto bits = [](const std::string& candump) {
    return static_cast<double>(frame_bits(*from_candump(candump)).total());
  };
  const auto paced = [](double b) {
    return Duration{static_cast<std::int64_t>(b / 62'500.0 * 1e6)};
  };
  // Two in the same call go out together; their requests and the answers they cause (as long
  // as the requests) are booked from now.
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.boot_upload(6, 1, at_ms(0), milliseconds(100));
  rig.settle(at_ms(0));
  const auto r5 = on(0x600, 5, kUpload1000);
  const auto r6 = on(0x600, 6, kUpload1000);
  EXPECT_EQ(rig.take_frames(), (std::vector<std::string>{r5, r6}));
  const TimePoint first_end = at_ms(0) + paced(2 * bits(r5) + 2 * bits(r6));
  EXPECT_EQ(rig.scheduler.paced_until(), first_end);

  // A third waits for the pacing: its deadline is the end of the booked time.
  rig.boot_upload(7, 1, at_ms(1), milliseconds(100));
  rig.settle(at_ms(1));
  EXPECT_TRUE(rig.take_frames().empty());
  EXPECT_EQ(rig.scheduler.waiting(), 1U);
  EXPECT_EQ(rig.scheduler.next_deadline(), first_end);

  // A heartbeat of another node meanwhile takes its share: the end moves by its bits.
  rig.frame("705#05", at_ms(2));
  const TimePoint second_end = first_end + paced(bits("705#05"));
  EXPECT_EQ(rig.scheduler.paced_until(), second_end);
  // An answer on a default channel (585h) was booked with its request.
  rig.frame(on(0x580, 5, kAnswer1000), at_ms(3));
  EXPECT_EQ(rig.scheduler.paced_until(), second_end);

  rig.timer(second_end - Duration{1});
  EXPECT_TRUE(rig.take_frames().empty());
  rig.timer(second_end);
  const auto r7 = on(0x600, 7, kUpload1000);
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{r7});
  EXPECT_EQ(rig.scheduler.paced_until(), second_end + paced(2 * bits(r7)));
}

TEST(SdoTransferScheduler, PacedTimeoutsDoNotHalveTheWindow) {
  Rig rig({.bitrate_bps = 125'000, .bus_load_limit = 0.5, .sdo_timeout = milliseconds(100)});
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.settle(at_ms(0));
  rig.timer(at_ms(100));
  ASSERT_EQ(rig.finished().size(), 1U);
  EXPECT_DOUBLE_EQ(rig.scheduler.window(), 128.0);
}

TEST(SdoTransferScheduler, HeldTransfersStartInOrderWhenTheDefaultSdoIsFree) {
  Rig rig;
  rig.port.given_out = {5, 6};
  rig.boot_upload(6, 1, at_ms(0), milliseconds(100));
  ASSERT_TRUE(
      rig.scheduler.start_application(node(5), {0x1018, 1}, true, {}, at_ms(0), rig.out).ok());
  rig.boot_upload(7, 1, at_ms(0), milliseconds(100));  // node 7's SDO is free
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.settle(at_ms(0));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 7, kUpload1000)});
  EXPECT_EQ(rig.scheduler.held(), 3U);

  // The SDO manager's own transfer to node 5 is not held: it manages that SDO.
  rig.manager_upload(9, 5, {0x1000, 0}, at_ms(1));
  rig.settle(at_ms(1));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});

  // Released in the order they came: node 6's boot upload, node 5's application upload (on the
  // bus once the manager's ends), node 5's boot upload behind it.
  rig.port.given_out.clear();
  rig.settle(at_ms(2));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 6, kUpload1000)});
  EXPECT_EQ(rig.scheduler.held(), 0U);
  rig.frame(on(0x580, 5, kAnswer1000), at_ms(3));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, "4018100100000000")});
  ASSERT_EQ(rig.finished().size(), 1U);
  EXPECT_EQ(rig.finished()[0].owner, Scheduler::Owner{Scheduler::Manager{9}});
  rig.frame(on(0x580, 5, "4318100178563412"), at_ms(4));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  ASSERT_EQ(rig.finished().size(), 2U);
  EXPECT_EQ(rig.finished()[1].owner, Scheduler::Owner{Scheduler::Application{1}});
  EXPECT_EQ(rig.finished()[1].result.data, (std::vector<std::uint8_t>{0x78, 0x56, 0x34, 0x12}));
}

TEST(SdoTransferScheduler, DropsAHeldTransferOfATryThatEnded) {
  Rig rig;
  rig.port.given_out = {5};
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.port.running[5] = 2;  // try 1 ended meanwhile
  rig.port.given_out.clear();
  rig.settle(at_ms(1));
  EXPECT_TRUE(rig.take_frames().empty());
  EXPECT_EQ(rig.scheduler.held(), 0U);
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 0U);
}

TEST(SdoTransferScheduler, ReportsARefusedStartWithTheClientsWords) {
  Rig rig;
  // A response timeout of 0: SdoClient::check_start refuses (nothing reaches the bus).
  rig.boot_upload(5, 1, at_ms(0), Duration{0});
  EXPECT_TRUE(rig.out.frames.empty());
  rig.settle(at_ms(0));
  EXPECT_TRUE(rig.take_frames().empty());
  const auto finished = rig.finished();
  ASSERT_EQ(finished.size(), 1U);
  const auto& r = finished[0].result;
  EXPECT_EQ(r.refusal, "the SDO response timeout must be positive (it is 0 us)");
  EXPECT_EQ(r.abort, SdoAbort::None);
  EXPECT_FALSE(r.ok());
  EXPECT_EQ(r.address, (cfg::ObjectAddress{0x1000, 0}));
  EXPECT_EQ(r.started, at_ms(0));
  EXPECT_EQ(r.finished, at_ms(0));

  // The application's start is checked at once: the error, and nothing started.
  Rig app({.sdo_timeout = Duration{0}});
  const auto id =
      app.scheduler.start_application(node(5), {0x1000, 0}, true, {}, at_ms(0), app.out);
  ASSERT_FALSE(id.ok());
  EXPECT_EQ(id.error().message, "node 5: the SDO response timeout must be positive (it is 0 us)");
  EXPECT_TRUE(app.out.empty());
  app.settle(at_ms(0));
  EXPECT_TRUE(app.events.empty());
}

// CiA 302-2 §3.3: the boot of a slave runs asynchronously to the other processes; DSP 302 §7.1:
// the SDO manager's accesses are its own. A boot try's end stops the boot's transfers only.
TEST(SdoTransferScheduler, ABootTrysEndStopsOnlyTheBootsTransfersToItsNode) {
  Rig rig;
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.manager_upload(3, 5, {0x1001, 0}, at_ms(0));
  ASSERT_TRUE(
      rig.scheduler.start_application(node(5), {0x1018, 1}, true, {}, at_ms(0), rig.out).ok());
  rig.boot_upload(6, 1, at_ms(0), milliseconds(100));
  rig.settle(at_ms(0));
  EXPECT_EQ(rig.take_frames(),
            (std::vector<std::string>{on(0x600, 5, kUpload1000), on(0x600, 6, kUpload1000)}));

  // The boot upload on the bus is aborted (0800 0000, general error); the client starts the
  // next, the manager's upload of 1001h, which goes on. Node 6 keeps its own.
  rig.port.running[5] = 2;
  rig.scheduler.cancel_boot(node(5), at_ms(10), rig.out);
  rig.settle(at_ms(10));
  EXPECT_EQ(rig.take_frames(), (std::vector<std::string>{on(0x600, 5, "8000100000000008"),
                                                         on(0x600, 5, "4001100000000000")}));
  EXPECT_TRUE(rig.finished().empty());
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 1U);
  // The manager gets its answer (1001h = 00h, one byte), then the application's upload goes on
  // the bus and gets its own.
  rig.frame(on(0x580, 5, "4F01100000000000"), at_ms(11));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, "4018100100000000")});
  rig.frame(on(0x580, 5, "4318100178563412"), at_ms(12));
  rig.frame(on(0x580, 6, kAnswer1000), at_ms(13));
  const auto finished = rig.finished();
  ASSERT_EQ(finished.size(), 3U);
  EXPECT_EQ(finished[0].owner, Scheduler::Owner{Scheduler::Manager{3}});
  EXPECT_TRUE(finished[0].result.ok());
  EXPECT_EQ(finished[0].result.data, std::vector<std::uint8_t>{0x00});
  EXPECT_EQ(finished[0].result.finished, at_ms(11));
  EXPECT_EQ(finished[1].owner, Scheduler::Owner{Scheduler::Application{1}});
  EXPECT_EQ(finished[1].result.data, (std::vector<std::uint8_t>{0x78, 0x56, 0x34, 0x12}));
  EXPECT_EQ(finished[2].node, node(6));
  EXPECT_EQ(finished[2].owner, Scheduler::Owner{Scheduler::BootTry{1}});
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 0U);
}

// The manager's transfer on the bus when the boot try ends, the boot's queued behind it: the
// boot's leaves the queue without a frame, the manager's gets its answer.
TEST(SdoTransferScheduler, TheManagersTransferOnTheBusGetsItsAnswerWhenABootTryOfItsNodeEnds) {
  Rig rig;
  rig.manager_upload(7, 5, {0x1F10, 0}, at_ms(0));
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.settle(at_ms(0));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, "40101F0000000000")});
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 1U);

  rig.port.running.erase(5);
  rig.scheduler.cancel_boot(node(5), at_ms(10), rig.out);
  rig.settle(at_ms(10));
  EXPECT_TRUE(rig.take_frames().empty());
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 0U);
  EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(100));  // the manager's response timeout

  // 1F10h = 0001 2801h (four bytes, expedited).
  rig.frame(on(0x580, 5, "43101F0001280100"), at_ms(20));
  EXPECT_TRUE(rig.take_frames().empty());
  ASSERT_EQ(rig.finished().size(), 1U);
  EXPECT_EQ(rig.finished()[0].owner, Scheduler::Owner{Scheduler::Manager{7}});
  EXPECT_TRUE(rig.finished()[0].result.ok());
  EXPECT_EQ(rig.finished()[0].result.data, (std::vector<std::uint8_t>{0x01, 0x28, 0x01, 0x00}));
  EXPECT_EQ(rig.scheduler.next_deadline(), std::nullopt);
}

// A manager whose tables were cleared (the master resets all nodes) has its transfers stopped:
// the one on the bus is aborted, and so is its next, which the client starts then; the boot's
// goes on.
TEST(SdoTransferScheduler, CancelManagerStopsOnlyTheManagersTransfers) {
  Rig rig;
  rig.manager_upload(7, 5, {0x1F10, 0}, at_ms(0));
  rig.manager_upload(8, 5, {0x1001, 0}, at_ms(0));
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.settle(at_ms(0));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, "40101F0000000000")});

  rig.scheduler.cancel_manager(node(5), at_ms(10), rig.out);
  rig.settle(at_ms(10));
  // 1F10h aborted (0800 0000); 1001h, next on the client, starts and is aborted at once; then
  // the boot's 1000h.
  EXPECT_EQ(
      rig.take_frames(),
      (std::vector<std::string>{on(0x600, 5, "80101F0000000008"), on(0x600, 5, "4001100000000000"),
                                on(0x600, 5, "8001100000000008"), on(0x600, 5, kUpload1000)}));
  EXPECT_TRUE(rig.finished().empty());
  rig.frame(on(0x580, 5, kAnswer1000), at_ms(11));
  ASSERT_EQ(rig.finished().size(), 1U);
  EXPECT_EQ(rig.finished()[0].owner, Scheduler::Owner{Scheduler::BootTry{1}});
}

TEST(SdoTransferScheduler, DropsTheResultOfATryThatEnded) {
  Rig rig;
  rig.boot_upload(5, 1, at_ms(0), milliseconds(100));
  rig.settle(at_ms(0));
  rig.take_frames();
  rig.port.running.erase(5);  // the try ended without cancelling (its verdict came otherwise)
  rig.frame(on(0x580, 5, kAnswer1000), at_ms(5));
  EXPECT_TRUE(rig.events.empty());
  EXPECT_EQ(rig.scheduler.boot_in_flight(), 0U);
}

// --- the learnt repetition (MasterOptions::sdo.repeat_floor, SdoTransferOptions::repeat_after)

// CiA 301 leaves the response timeout to the application: the boot repeats a slave's expedited
// request after 2 x its largest recent answer time, at least the floor, never before the slave
// answered once, each slave by its own answers.
TEST(SdoTransferScheduler, LearnsEachSlavesRepeatTimeFromItsOwnAnswers) {
  Rig rig({.sdo_timeout = milliseconds(500), .repeat_floor = milliseconds(20)});
  EXPECT_EQ(rig.scheduler.repeat_after(node(5), milliseconds(500)), std::nullopt);
  rig.boot_upload(5, 1, at_ms(0), milliseconds(500));
  rig.settle(at_ms(0));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  // Not answered yet: no repetition, the full timeout is the deadline.
  EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(500));
  rig.frame(on(0x580, 5, kAnswer1000), at_ms(3));  // 3 ms: 2 x 3 = 6 ms, below the floor
  EXPECT_EQ(rig.scheduler.repeat_after(node(5), milliseconds(500)), milliseconds(20));
  EXPECT_EQ(rig.scheduler.repeat_after(node(6), milliseconds(500)), std::nullopt);

  // Node 6 answers in 40 ms: its repetition comes after 80 ms.
  rig.boot_upload(6, 1, at_ms(10), milliseconds(500));
  rig.settle(at_ms(10));
  rig.take_frames();
  rig.frame(on(0x580, 6, kAnswer1000), at_ms(50));
  EXPECT_EQ(rig.scheduler.repeat_after(node(6), milliseconds(500)), milliseconds(80));
  EXPECT_EQ(rig.scheduler.repeat_after(node(5), milliseconds(500)), milliseconds(20));
  // Bounded above: a repetition not before the timeout is none.
  EXPECT_EQ(rig.scheduler.repeat_after(node(6), milliseconds(80)), std::nullopt);

  // Node 5's next request is repeated 20 ms after it went out, then answered.
  rig.boot_upload(5, 1, at_ms(100), milliseconds(500));
  rig.settle(at_ms(100));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(120));
  rig.timer(at_ms(120));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  rig.frame(on(0x580, 5, kAnswer1000), at_ms(122));
  ASSERT_EQ(rig.finished().size(), 3U);
  EXPECT_TRUE(rig.finished()[2].result.ok());
  EXPECT_EQ(rig.finished()[2].result.repeats, 1U);
  // A repeated request's answer may answer either copy: it is not learnt from.
  EXPECT_EQ(rig.scheduler.repeat_after(node(5), milliseconds(500)), milliseconds(20));
}

// A read changes nothing on the device: a slave that has not answered yet has its first read
// (1000h, CiA 302-2 §3.4) repeated by what the other slaves' answers taught; its writes are not.
TEST(SdoTransferScheduler, ASlavesFirstReadIsRepeatedByTheOtherSlavesAnswerTimes) {
  Rig rig({.sdo_timeout = milliseconds(500), .repeat_floor = milliseconds(20)});
  rig.port.heard = {5, 6, 7};
  // Nobody answered yet: no repetition at all.
  EXPECT_EQ(rig.scheduler.unanswered_read_repeat_after(milliseconds(500)), std::nullopt);
  rig.boot_upload(6, 1, at_ms(0), milliseconds(500));
  rig.settle(at_ms(0));
  rig.take_frames();
  rig.frame(on(0x580, 6, kAnswer1000), at_ms(15));  // node 6 answers in 15 ms: 30 ms
  EXPECT_EQ(rig.scheduler.unanswered_read_repeat_after(milliseconds(500)), milliseconds(30));
  EXPECT_EQ(rig.scheduler.repeat_after(node(5), milliseconds(500)), std::nullopt);
  // Node 5's first read: repeated 30 ms after it went out.
  rig.boot_upload(5, 1, at_ms(100), milliseconds(500));
  rig.settle(at_ms(100));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(130));
  rig.timer(at_ms(130));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  rig.frame(on(0x580, 5, kAnswer1000), at_ms(133));
  ASSERT_EQ(rig.finished().size(), 2U);
  EXPECT_TRUE(rig.finished()[1].result.ok());
  EXPECT_EQ(rig.finished()[1].result.repeats, 1U);
  // Node 7 has not answered: a write to it waits the full timeout, unrepeated.
  rig.port.running[7] = 1;
  rig.scheduler.start_boot(1,
                           {.node = node(7),
                            .object = {0x1017, 0},
                            .upload = false,
                            .data = {0xE8, 0x03},
                            .timeout = milliseconds(500)},
                           at_ms(200), rig.out);
  rig.settle(at_ms(200));
  rig.take_frames();
  EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(700));
  // Node 8 was never heard from (no boot-up, no heartbeat): likely absent, its read is not
  // multiplied (CiA 302-2 §3.4 b: status B after its retries, nothing more on the bus).
  rig.boot_upload(8, 1, at_ms(300), milliseconds(500));
  rig.settle(at_ms(300));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 8, kUpload1000)});
  EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(700));
}

// The window is the last Scheduler::kAnswerWindow answers: a slow answer is forgotten after it.
TEST(SdoTransferScheduler, ForgetsAnAnswerTimeAfterTheWindowOfAnswers) {
  Rig rig({.sdo_timeout = milliseconds(500), .repeat_floor = milliseconds(20)});
  TimePoint t = at_ms(0);
  const auto answered_after = [&](milliseconds took) {
    rig.boot_upload(5, 1, t, milliseconds(500));
    rig.settle(t);
    rig.take_frames();
    t += took;
    rig.frame(on(0x580, 5, kAnswer1000), t);
  };
  answered_after(milliseconds(30));
  EXPECT_EQ(rig.scheduler.repeat_after(node(5), milliseconds(500)), milliseconds(60));
  for (std::size_t i = 1; i < Scheduler::kAnswerWindow; ++i) answered_after(milliseconds(2));
  EXPECT_EQ(rig.scheduler.repeat_after(node(5), milliseconds(500)), milliseconds(60));
  answered_after(milliseconds(2));
  EXPECT_EQ(rig.scheduler.repeat_after(node(5), milliseconds(500)), milliseconds(20));
}

// The application's transfers keep their own timeout alone (no repetition): only the boot's
// are repeated.
TEST(SdoTransferScheduler, TheApplicationsTransfersAreNotRepeated) {
  Rig rig({.sdo_timeout = milliseconds(500), .repeat_floor = milliseconds(20)});
  rig.boot_upload(5, 1, at_ms(0), milliseconds(500));
  rig.settle(at_ms(0));
  rig.frame(on(0x580, 5, kAnswer1000), at_ms(2));
  rig.take_frames();
  ASSERT_TRUE(
      rig.scheduler.start_application(node(5), {0x1000, 0}, true, {}, at_ms(10), rig.out).ok());
  rig.settle(at_ms(10));
  EXPECT_EQ(rig.take_frames(), std::vector<std::string>{on(0x600, 5, kUpload1000)});
  EXPECT_EQ(rig.scheduler.next_deadline(), at_ms(510));
}

}  // namespace
}  // namespace nmt
