// SDO client and server talking over the simulated bus: block transfers of 1000+ bytes,
// retransmission after lost frames, fallback to segmented, timeouts, many nodes at once.
// Protocol from public knowledge of CiA 301 §7.2.4 (not in spec/).
#include <gtest/gtest.h>

#include <memory>
#include <string>
#include <vector>

#include "nmt/sdo/sdo.hpp"
#include "nmt/sim/fault_injection.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "sdo_test_device.hpp"
#include "started.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

// A node that only serves SDO: the dictionary and the server engine on the bus, wrapped so a
// test can make it slow (Delayed with no delay changes nothing).
struct ServerNode {
  explicit ServerNode(std::uint8_t node_id, SdoServerConfig config)
      : dict(LocalDictionary::from_device(test_support::sdo_test_device(),
                                          *cfg::NodeId::from(node_id))
                 .value()),
        node(Duration{0}, dict, config) {}
  explicit ServerNode(std::uint8_t node_id)
      : ServerNode(node_id, SdoServerConfig::for_node(*cfg::NodeId::from(node_id))) {}
  SdoServer& sdo() { return node.engine().engine(); }
  LocalDictionary dict;
  SimEngineNode<Delayed<SdoServer>> node;
};

Bytes pattern(std::size_t n, unsigned seed = 1) {
  Bytes b(n);
  for (std::size_t i = 0; i < n; ++i) b[i] = static_cast<std::uint8_t>(i * 7 + seed * 13 + i / 256);
  return b;
}

SdoTransferOptions block_mode() {
  SdoTransferOptions o;
  o.mode = SdoMode::Block;
  return o;
}

class SdoTransferTest : public ::testing::Test {
 protected:
  SimBus bus{1'000'000};
  ServerNode server{5};
  SimEngineNode<SdoClientMux> client;
  std::vector<std::string> trace;
  std::vector<SdoResult> results;  // the client's events, in order

  void SetUp() override {
    bus.attach(server.node);
    bus.attach(client);
    bus.add_observer([this](const CanFrame& f, TimePoint) { trace.push_back(to_candump(f)); });
    client.set_event_handler([this](const SdoResult& r, TimePoint) { results.push_back(r); });
  }
  SdoResult run_download(std::uint16_t index, std::uint8_t sub, Bytes data,
                         SdoTransferOptions o = {}) {
    results.clear();
    client.apply([&](SdoClientMux& m, TimePoint now, SdoClientMux::Output& out) {
      test_support::started(
          m.client(*cfg::NodeId::from(5)).download(index, sub, std::move(data), now, out, o));
    });
    EXPECT_TRUE(bus.run_until_idle(bus.now() + 60s));
    EXPECT_EQ(results.size(), 1u);
    return results.empty() ? SdoResult{} : results.back();
  }
  SdoResult run_upload(std::uint16_t index, std::uint8_t sub, SdoTransferOptions o = {}) {
    results.clear();
    client.apply([&](SdoClientMux& m, TimePoint now, SdoClientMux::Output& out) {
      test_support::started(m.client(*cfg::NodeId::from(5)).upload(index, sub, now, out, o));
    });
    EXPECT_TRUE(bus.run_until_idle(bus.now() + 60s));
    EXPECT_EQ(results.size(), 1u);
    return results.empty() ? SdoResult{} : results.back();
  }
  int count(std::string_view prefix) const {
    int n = 0;
    for (const auto& t : trace) n += t.rfind(prefix, 0) == 0 ? 1 : 0;
    return n;
  }
};

TEST_F(SdoTransferTest, ExpeditedDownloadFrameExactOnTheBus) {
  auto r = run_download(0x1017, 0, {0xE8, 0x03});
  EXPECT_TRUE(r.ok()) << r.abort;
  EXPECT_EQ(trace, (std::vector<std::string>{"605#2B171000E8030000", "585#6017100000000000"}));
  EXPECT_EQ(server.dict.get_unsigned(0x1017, 0), 1000u);
  // Two frames of 119 and 114 bits (stuffing included) at 1 us per bit.
  EXPECT_GT(r.finished - r.started, 200us);
  EXPECT_LT(r.finished - r.started, 250us);
}

TEST_F(SdoTransferTest, ADownloadStartedThroughTheApiIsOnTheBusAtTheNextStep) {
  // Engine rule 5 (nmt/engine.hpp): no timer stands between download() and the bus. The next
  // two events are the arbitration of the initiate request and its end of frame.
  const auto before = bus.events_processed();
  client.apply([&](SdoClientMux& m, TimePoint now, SdoClientMux::Output& out) {
    test_support::started(
        m.client(*cfg::NodeId::from(5)).download(0x1017, 0, {0xE8, 0x03}, now, out));
  });
  EXPECT_EQ(client.engine().next_deadline(), bus.now() + 1s);  // the response timeout
  ASSERT_TRUE(bus.step());
  ASSERT_TRUE(bus.step());
  EXPECT_EQ(bus.events_processed() - before, 2u);
  EXPECT_EQ(trace, std::vector<std::string>{"605#2B171000E8030000"});
}

TEST_F(SdoTransferTest, BlockDownloadAndUploadOfFifteenHundredBytes) {
  const Bytes data = pattern(1500);
  auto down = run_download(0x2000, 0, data, block_mode());
  ASSERT_TRUE(down.ok()) << down.abort;
  EXPECT_EQ(down.protocol, SdoProtocol::Block);
  EXPECT_FALSE(down.fell_back);
  auto stored = server.dict.get_bytes(0x2000, 0);
  EXPECT_EQ(Bytes(stored->begin(), stored->end()), data);
  // 1500 bytes = 215 segments: blocks of 127 and 88 segments, two acknowledgements.
  EXPECT_EQ(count("585#A2"), 2);

  trace.clear();
  auto up = run_upload(0x2000, 0, block_mode());
  ASSERT_TRUE(up.ok()) << up.abort;
  EXPECT_EQ(up.data, data);
  EXPECT_EQ(up.protocol, SdoProtocol::Block);
  EXPECT_EQ(count("605#A2"), 2);
}

TEST_F(SdoTransferTest, SegmentedTransfersOfAThousandBytes) {
  const Bytes data = pattern(1000, 3);
  ASSERT_TRUE(run_download(0x2000, 0, data).ok());
  auto up = run_upload(0x2000, 0);
  ASSERT_TRUE(up.ok()) << up.abort;
  EXPECT_EQ(up.data, data);
  EXPECT_EQ(up.protocol, SdoProtocol::Segmented);
}

TEST_F(SdoTransferTest, BlockDownloadRetransmitsAfterLostSegment) {
  // Drop the fifth segment of the first sub-block, once.
  bool dropped = false;
  bus.set_filter([&](const CanFrame& f, TimePoint) {
    if (!dropped && f.id == 0x605 && f.data[0] == 0x05) {
      dropped = true;
      return FrameFate::drop();
    }
    return FrameFate::deliver();
  });
  const Bytes data = pattern(2000, 5);
  auto r = run_download(0x2000, 0, data, block_mode());
  ASSERT_TRUE(dropped);
  ASSERT_TRUE(r.ok()) << r.abort;
  auto stored = server.dict.get_bytes(0x2000, 0);
  EXPECT_EQ(Bytes(stored->begin(), stored->end()), data);
  // The server acknowledged segment 4 as the last one received in order.
  EXPECT_EQ(count("585#A2047F"), 1);
}

TEST_F(SdoTransferTest, BlockUploadRetransmitsAfterLostSegment) {
  const Bytes data = pattern(1200, 9);
  ASSERT_TRUE(server.dict.set_bytes(0x2000, 0, data));
  int seen = 0;
  bus.set_filter([&](const CanFrame& f, TimePoint) {
    // The 30th segment from the server (sequence number 30 of the first sub-block).
    if (f.id == 0x585 && (f.data[0] & 0x7F) == 30 && seen++ == 0) return FrameFate::drop();
    return FrameFate::deliver();
  });
  auto r = run_upload(0x2000, 0, block_mode());
  ASSERT_TRUE(r.ok()) << r.abort;
  EXPECT_EQ(r.data, data);
  EXPECT_EQ(count("605#A21D7F"), 1);  // ack 29
}

TEST_F(SdoTransferTest, FallsBackToSegmentedWhenServerDoesNotDoBlock) {
  auto config = server.sdo().config();
  config.block_transfer = false;
  server.sdo().set_config(config);
  const Bytes data = pattern(100);
  auto r = run_download(0x2000, 0, data, block_mode());
  ASSERT_TRUE(r.ok()) << r.abort;
  EXPECT_TRUE(r.fell_back);
  EXPECT_EQ(r.protocol, SdoProtocol::Segmented);
  ASSERT_GE(trace.size(), 3u);
  EXPECT_EQ(trace[0], "605#C600200064000000");
  EXPECT_EQ(trace[1], "585#8000200001000405");
  EXPECT_EQ(trace[2], "605#2100200064000000");
  auto up = run_upload(0x2000, 0, block_mode());
  ASSERT_TRUE(up.ok());
  EXPECT_TRUE(up.fell_back);
  EXPECT_EQ(up.data, data);
}

TEST_F(SdoTransferTest, ClientTimesOutOnASlowServerAndSendsAbort) {
  server.node.engine().set_delay(1500ms);
  SdoTransferOptions o;
  o.timeout = 1000ms;
  auto r = run_download(0x1017, 0, {0xE8, 0x03}, o);
  EXPECT_EQ(r.abort, SdoAbort::Timeout);
  EXPECT_FALSE(r.aborted_by_server);
  // Request at 0, abort when 1 s passed without a response; the late response still comes.
  ASSERT_EQ(trace.size(), 3u);
  EXPECT_EQ(trace[0], "605#2B171000E8030000");
  EXPECT_EQ(trace[1], "605#8017100000000405");
  EXPECT_EQ(trace[2], "585#6017100000000000");
  EXPECT_EQ(r.finished - r.started, 1000ms);
}

TEST_F(SdoTransferTest, SlowServerWithinTheTimeoutSucceeds) {
  server.node.engine().set_delay(20ms);
  auto r = run_upload(0x1008, 0);
  ASSERT_TRUE(r.ok()) << r.abort;
  // Four request/response exchanges of 20 ms each.
  EXPECT_GE(r.finished - r.started, 80ms);
  EXPECT_LT(r.finished - r.started, 81ms);
}

// --- repeated expedited requests (SdoTransferOptions::repeat_after), the server's view -------

SdoTransferOptions repeating_after(Duration after) {
  SdoTransferOptions o;
  o.timeout = 500ms;
  o.repeat_after = after;
  return o;
}

TEST_F(SdoTransferTest, ALostAnswerCostsTheRepeatNotTheTimeout) {
  bool dropped = false;
  bus.set_filter([&dropped](const CanFrame& f, TimePoint) {
    if (f.id != 0x585 || dropped) return FrameFate::deliver();
    dropped = true;
    return FrameFate::drop();
  });
  auto r = run_upload(0x1000, 0, repeating_after(20ms));
  ASSERT_TRUE(r.ok()) << r.abort;
  EXPECT_EQ(r.repeats, 1u);
  EXPECT_GE(r.finished - r.started, 20ms);
  EXPECT_LT(r.finished - r.started, 21ms);
  EXPECT_EQ(count("605#40001000"), 2);
}

// A server slower than repeat_after gets the expedited write twice: it writes the same value
// twice (CiA 301 §7.2.4.3.3: each expedited download is complete in itself) and answers both;
// the second answer comes while the next transfer runs and is not taken for its answer.
TEST_F(SdoTransferTest, ARepeatedExpeditedWriteToASlowServerLeavesTheValueAndTheNextTransfer) {
  server.node.engine().set_delay(30ms);
  results.clear();
  client.apply([&](SdoClientMux& m, TimePoint now, SdoClientMux::Output& out) {
    auto& c = m.client(*cfg::NodeId::from(5));
    test_support::started(c.download(0x2003, 0, {0xF4, 0x01, 0x00, 0x00}, now, out,
                                     repeating_after(20ms)));  // 500
    test_support::started(c.upload(0x2003, 0, now, out, repeating_after(20ms)));
  });
  ASSERT_TRUE(bus.run_until_idle(bus.now() + 60s));
  ASSERT_EQ(results.size(), 2u);
  EXPECT_TRUE(results[0].ok()) << results[0].abort;
  EXPECT_EQ(results[0].repeats, 1u);
  ASSERT_TRUE(results[1].ok()) << results[1].abort;
  EXPECT_EQ(results[1].data, (Bytes{0xF4, 0x01, 0x00, 0x00}));
  EXPECT_EQ(server.dict.get_unsigned(0x2003, 0), 500u);
  EXPECT_EQ(count("605#23032000F4010000"), 2);  // the write, twice
  EXPECT_EQ(count("585#60032000"), 2);          // answered twice
}

// The limit of repeating an upload: a value of more than 4 bytes is answered segmented, and this
// server (like many) refuses a second initiate while its segmented upload runs (abort 0504 0001,
// then the segment request finds no transfer): the client reports the server's abort, no wrong
// value. Hence the master repeats only its boot's uploads, all of 32-bit objects (1000h, 1018h,
// 1020h, 1F56h/1F57h, PDO COB-IDs) that a server answers expedited (sdo_client.hpp, top).
TEST_F(SdoTransferTest, ARepeatedUploadOfALongValueFromASlowServerEndsWithTheServersAbort) {
  server.node.engine().set_delay(30ms);
  auto r = run_upload(0x1008, 0, repeating_after(20ms));
  EXPECT_EQ(r.abort, SdoAbort::InvalidCommandSpecifier);
  EXPECT_TRUE(r.aborted_by_server);
  EXPECT_EQ(r.repeats, 1u);
  EXPECT_TRUE(r.data.empty());
  EXPECT_FALSE(server.sdo().busy());
}

TEST_F(SdoTransferTest, TimeoutWhenTheLastSegmentOfABlockIsLost) {
  // The segment with c=1 never arrives: the server cannot acknowledge, the client times out.
  bus.set_filter([](const CanFrame& f, TimePoint) {
    return f.id == 0x605 && (f.data[0] & 0x80) != 0 && (f.data[0] & 0x7F) != 0
               ? FrameFate::drop()
               : FrameFate::deliver();
  });
  SdoTransferOptions o = block_mode();
  o.timeout = 300ms;
  auto r = run_download(0x2000, 0, pattern(50), o);
  EXPECT_EQ(r.abort, SdoAbort::Timeout);
  EXPECT_FALSE(server.sdo().busy());  // the client's abort reset the server
}

TEST_F(SdoTransferTest, ManyConcurrentTransfersToTenNodesComplete) {
  std::vector<std::unique_ptr<ServerNode>> servers;
  for (std::uint8_t id = 10; id < 20; ++id) {
    servers.push_back(std::make_unique<ServerNode>(id));
    bus.attach(servers.back()->node);
  }
  client.apply([&](SdoClientMux& m, TimePoint now, SdoClientMux::Output& out) {
    for (std::uint8_t id = 10; id < 20; ++id) {
      auto& c = m.client(*cfg::NodeId::from(id));
      test_support::started(c.download(0x2000, 0, pattern(700, id), now, out, block_mode()));
      test_support::started(c.download(0x2005, 0, pattern(30, id), now, out));
      test_support::started(c.download(0x1017, 0, {id, 0}, now, out));
      test_support::started(c.upload(0x2000, 0, now, out, block_mode()));
      test_support::started(c.upload(0x1018, 1, now, out));
    }
  });
  ASSERT_TRUE(bus.run_until_idle(bus.now() + 60s));
  ASSERT_EQ(results.size(), 50u);
  TimePoint last{};
  Duration sum{0};
  for (const auto& r : results) {
    ASSERT_TRUE(r.node_id.has_value());
    EXPECT_TRUE(r.ok()) << "node " << int{r.node_id->value()} << " " << r.abort;
    if (r.upload && r.address.index == 0x2000) {
      EXPECT_EQ(r.data, pattern(700, r.node_id->value()));
    }
    last = std::max(last, r.finished);
    sum += r.finished - r.started;
  }
  for (std::uint8_t id = 10; id < 20; ++id) {
    EXPECT_EQ(servers[id - 10]->dict.get_unsigned(0x1017, 0), id);
  }
  // The transfers overlapped: all were done in less time than they took one after another.
  EXPECT_LT(last.time_since_epoch().count() * 3, sum.count());
}

TEST_F(SdoTransferTest, EveryTransferEndsOnALossyBus) {
  bus.set_loss_rate(0.05, 7);
  SdoTransferOptions o = block_mode();
  o.timeout = 100ms;
  client.apply([&](SdoClientMux& m, TimePoint now, SdoClientMux::Output& out) {
    for (int i = 0; i < 40; ++i) {
      if (i % 2 == 0) {
        test_support::started(
            m.client(*cfg::NodeId::from(5))
                .download(0x2000, 0, pattern(300, static_cast<unsigned>(i)), now, out, o));
      } else {
        test_support::started(m.client(*cfg::NodeId::from(5)).upload(0x2000, 0, now, out, o));
      }
    }
  });
  ASSERT_TRUE(bus.run_until_idle(bus.now() + 600s));
  ASSERT_EQ(results.size(), 40u);
  // Seed 7 is deterministic: these outcomes were recorded on the code before the engine
  // refactoring and must not change. Every failure is the client's own timeout
  // (0504 0000, no server abort); two downloads fell back to segmented after a 0504 0001.
  std::vector<std::uint32_t> timed_out;
  std::vector<std::uint32_t> fell_back;
  int succeeded = 0;
  for (const auto& r : results) {
    succeeded += r.ok() ? 1 : 0;
    if (!r.ok()) {
      EXPECT_EQ(r.abort, SdoAbort::Timeout) << r.id;
      EXPECT_FALSE(r.aborted_by_server) << r.id;
      timed_out.push_back(r.id);
    }
    if (r.fell_back) fell_back.push_back(r.id);
  }
  EXPECT_EQ(succeeded, 25);
  EXPECT_EQ(timed_out,
            (std::vector<std::uint32_t>{1, 3, 9, 15, 16, 17, 19, 26, 28, 29, 31, 34, 36, 37, 39}));
  EXPECT_EQ(fell_back, (std::vector<std::uint32_t>{29, 39}));
  EXPECT_EQ(results.back().id, 40u);
  EXPECT_EQ(results.back().finished, TimePoint{Duration{1'880'773}});
  EXPECT_FALSE(server.sdo().busy());
}

// The fuzz_sdo_client finding (seeds/sdo_client/lost_abort_block_livelock) in words.
// Two CiA 301 facts meet: an SDO abort is not confirmed (a lost one leaves the server in its
// transfer), SDO frames carry no transaction number (a late answer naming the same object is
// taken for the running transfer's), and inside a sub-block every frame is a segment (byte 0:
// c, seqno). Client timeout 100 ms, server timeout 2 s; frames are handed over one by one.
// (Until stop 27 this ended only by the client's timeout, 99 rounds later.)
TEST(SdoLostAbort, BlockUploadMeetingAServerStillInABlockDownloadEndsAfterFourEmptyRounds) {
  auto dict =
      LocalDictionary::from_device(test_support::sdo_test_device(), *cfg::NodeId::from(5)).value();
  SdoServer server{dict, SdoServerConfig::for_node(*cfg::NodeId::from(5))};
  SdoClient client{SdoClientConfig::for_node(*cfg::NodeId::from(5))};
  std::vector<SdoResult> results;
  TimePoint now{};
  auto text = [](const std::vector<CanFrame>& frames) {
    std::vector<std::string> s;
    for (const auto& f : frames) s.push_back(to_candump(f));
    return s;
  };
  auto to_server = [&](const std::string& frame) {
    SdoServer::Output out;
    server.on_frame(*from_candump(frame), now, out);
    return text(out.frames);
  };
  auto take = [&](SdoClient::Output& out) {
    for (auto& r : out.events) results.push_back(r);
    auto frames = text(out.frames);
    out.clear();
    return frames;
  };
  auto to_client = [&](const std::string& frame) {
    SdoClient::Output out;
    client.on_frame(*from_candump(frame), now, out);
    return take(out);
  };
  using Frames = std::vector<std::string>;
  SdoTransferOptions o = block_mode();
  o.timeout = 100ms;

  // t = 0: block upload A of 1017h. The server answers C6h (2 bytes), but the answer is slow;
  // the application cancels A first, and the server takes the abort.
  SdoClient::Output out;
  const auto a = test_support::started(client.upload(0x1017, 0, now, out, o));
  EXPECT_EQ(take(out), Frames{"605#A41710007F000000"});
  const Frames late_a = to_server("605#A41710007F000000");
  EXPECT_EQ(late_a, Frames{"585#C617100002000000"});
  client.cancel(a, now, out);
  EXPECT_EQ(take(out), Frames{"605#8017100000000008"});  // 0800 0000
  EXPECT_EQ(to_server("605#8017100000000008"), Frames{});
  // Block download B of 979 bytes to 2005h: the server enters the block download and answers
  // A4h (block size 127), slow too. B is cancelled; its abort is lost on the bus.
  const auto b = test_support::started(client.download(0x2005, 0, Bytes(979, 0x55), now, out, o));
  EXPECT_EQ(take(out), Frames{"605#C6052000D3030000"});
  const Frames late_b = to_server("605#C6052000D3030000");
  EXPECT_EQ(late_b, Frames{"585#A40520007F000000"});
  client.cancel(b, now, out);
  EXPECT_EQ(take(out), Frames{"605#8005200000000008"});  // lost
  ASSERT_TRUE(server.busy());
  // Block upload C of 1017h: the server, still in B's sub-block, reads its initiate as segment
  // 36 with c=1, out of order, and acknowledges no segment.
  const auto c = test_support::started(client.upload(0x1017, 0, now, out, o));
  EXPECT_EQ(take(out), Frames{"605#A41710007F000000"});
  EXPECT_EQ(to_server("605#A41710007F000000"), Frames{"585#A2007F0000000000"});
  // t = 1 ms: A's late C6h names 1017h: the client takes it for C's and starts the upload (A3h),
  // which the server reads as segment 35 with c=1.
  now = TimePoint{Duration{1'000}};
  EXPECT_EQ(to_client(late_a[0]), Frames{"605#A300000000000000"});
  EXPECT_EQ(to_server("605#A300000000000000"), Frames{"585#A2007F0000000000"});
  // From 2 ms on, every millisecond: B's late A4h, then each acknowledgement, reads as segment
  // 36 or 34 with c=1 on the other side, which acknowledges no segment at once. The server's
  // 4th such round in a row (sdo::kMaxEmptyBlockRounds, our choice) is an abort, 0504 0003 for
  // B's object, which the client takes as the end of C: no traffic at full bus load until a
  // timeout.
  const Frames ack = to_client(late_b[0]);
  ASSERT_EQ(ack, Frames{"605#A2007F0000000000"});
  EXPECT_EQ(to_server(ack[0]), Frames{"585#A2007F0000000000"});  // round 3
  now = TimePoint{Duration{2'000}};
  const Frames ack2 = to_client("585#A2007F0000000000");
  ASSERT_EQ(ack2, Frames{"605#A2007F0000000000"});
  const Frames abort = to_server(ack2[0]);  // round 4
  EXPECT_EQ(abort, Frames{"585#8005200003000405"});
  EXPECT_FALSE(server.busy());
  now = TimePoint{Duration{3'000}};
  EXPECT_EQ(to_client(abort[0]), Frames{});
  ASSERT_EQ(results.size(), 3U);
  EXPECT_EQ(results[2].id, c);
  EXPECT_EQ(results[2].abort, SdoAbort::InvalidSequenceNumber);
  EXPECT_TRUE(results[2].aborted_by_server);
  EXPECT_EQ(results[2].finished, TimePoint{Duration{3'000}});
  EXPECT_FALSE(client.busy());
}

}  // namespace
}  // namespace nmt
