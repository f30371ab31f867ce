// Bus traces, checked with independent readers: can-utils' log2asc and python-can's LogReader for
// candump logs; libpcap and tshark (Wireshark's CANopen dissector) for pcap files.
#include "nmt/io/trace.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <pcap/pcap.h>
#include <unistd.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "nmt/sim/sim_bus.hpp"
#include "pcap_library.hpp"
#include "prerequisite.hpp"
#include "python_peer.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;

CanFrame frame(std::string_view candump) {
  auto f = from_candump(candump);
  EXPECT_TRUE(f.has_value()) << candump;
  return f.value_or(CanFrame{});
}

// 2023-11-14 22:13:20 UTC plus microseconds.
constexpr TimePoint at(std::int64_t us_after) {
  return TimePoint{Duration{1'700'000'000'000'000 + us_after}};
}

// One frame of each kind, with the time each is written at.
struct Timed {
  const char* candump;
  TimePoint time;
};
const std::vector<Timed> kFrames = {
    {"123#DEADBEEF", at(123'456)},
    {"12345678#R", at(200'000)},
    {"705#R3", at(300'000)},
    // Error frame with class CAN_ERR_BUSERROR (linux/can/error.h: 0x00000080).
    {"20000080#0000000000000000", at(400'000)},
    {"000#", at(500'000)},
    {"1FFFFFFF#CAFE", at(600'000)},
};

std::vector<std::string> read_lines(const fs::path& path) {
  std::ifstream in(path);
  std::vector<std::string> lines;
  for (std::string line; std::getline(in, line);) lines.push_back(line);
  return lines;
}

// Runs a shell command; its exit code and stdout lines.
std::pair<int, std::vector<std::string>> run(const std::string& command) {
  std::FILE* pipe = ::popen(command.c_str(), "r");
  std::vector<std::string> lines;
  if (pipe == nullptr) return {-1, lines};
  std::string line;
  char buf[1024];
  while (std::fgets(buf, sizeof buf, pipe) != nullptr) {
    line += buf;
    if (line.back() == '\n') {
      line.pop_back();
      lines.push_back(line);
      line.clear();
    }
  }
  if (!line.empty()) lines.push_back(line);
  const int status = ::pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, lines};
}

bool have_program(const std::string& name) {
  return std::system(("command -v " + name + " >/dev/null 2>&1").c_str()) == 0;
}

class Trace : public ::testing::Test {
 protected:
  void SetUp() override {
    std::string pattern = (fs::temp_directory_path() / "nmt_trace_test_XXXXXX").string();
    ASSERT_NE(::mkdtemp(pattern.data()), nullptr);
    dir_ = pattern;
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  fs::path write_all(const fs::path& name) {
    auto writer = open_trace(dir_ / name);
    EXPECT_TRUE(writer.ok()) << writer.error().message;
    if (!writer.ok()) return {};
    for (const auto& f : kFrames) EXPECT_TRUE((*writer)->write(frame(f.candump), f.time).ok());
    EXPECT_TRUE((*writer)->flush().ok());
    return dir_ / name;
  }
  fs::path dir_;
};

// ---- candump log ----------------------------------------------------------------------------

TEST_F(Trace, CandumpLogHasCandumpLines) {
  // can-utils candump -l: "(%010lu.%06lu) %s %s" with lib.c's compact frame text.
  auto path = write_all("bus.log");
  EXPECT_EQ(read_lines(path), (std::vector<std::string>{
                                  "(1700000000.123456) can0 123#DEADBEEF",
                                  "(1700000000.200000) can0 12345678#R",
                                  "(1700000000.300000) can0 705#R3",
                                  "(1700000000.400000) can0 20000080#0000000000000000",
                                  "(1700000000.500000) can0 000#",
                                  "(1700000000.600000) can0 1FFFFFFF#CAFE",
                              }));
}

TEST_F(Trace, CandumpLogOfSimulatedTimeCountsFromZero) {
  auto writer = open_candump_log(dir_ / "sim.log", "vcan0");
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  ASSERT_TRUE((*writer)->write(frame("080#"), TimePoint{Duration{1500}}).ok());
  ASSERT_TRUE((*writer)->write(frame("701#05"), TimePoint{Duration{2'000'000}}).ok());
  writer->reset();
  EXPECT_EQ(read_lines(dir_ / "sim.log"),
            (std::vector<std::string>{"(0000000000.001500) vcan0 080#",
                                      "(0000000002.000000) vcan0 701#05"}));
}

TEST_F(Trace, Log2ascFromCanUtilsReadsCandumpLog) {
  if (!have_program("log2asc")) PREREQUISITE_MISSING("log2asc missing: apt-get install can-utils");
  auto path = write_all("bus.log");
  auto [code, lines] = run("log2asc -I '" + path.string() + "' can0");
  ASSERT_EQ(code, 0);
  // The frame lines of log2asc's output (can-utils 2020.11), times relative to the first frame.
  std::vector<std::string> frames(lines.begin() + std::min<std::ptrdiff_t>(3, lines.size()),
                                  lines.end());
  EXPECT_EQ(frames, (std::vector<std::string>{
                        "   0.000000 1  123             Rx   d 4 DE AD BE EF",
                        "   0.076544 1  12345678x       Rx   r 0",
                        "   0.176544 1  705             Rx   r 3",
                        "   0.276544 1  ErrorFrame",
                        "   0.376544 1  0               Rx   d 0",
                        "   0.476544 1  1FFFFFFFx       Rx   d 2 CA FE",
                    }));
}

TEST_F(Trace, PythonCanLogReaderReadsCandumpLog) {
  if (auto why = test_support::python_can_missing()) PREREQUISITE_MISSING(*why);
  auto path = write_all("bus.log");
  auto result = test_support::run_python_peer({"readlog", path.string()});
  ASSERT_EQ(result.exit_code, 0);
  // can.io.CanutilsLogReader; fields: timestamp id ext rtr err dlc data. It recognises error
  // frames by CAN_ERR_BUSERROR and then builds Message(is_error_frame=True) with default fields.
  EXPECT_EQ(result.lines, (std::vector<std::string>{
                              "1700000000.123456 123 0 0 0 4 DEADBEEF",
                              "1700000000.200000 12345678 1 1 0 0 -",
                              "1700000000.300000 705 0 1 0 3 -",
                              "1700000000.400000 0 1 0 1 0 -",
                              "1700000000.500000 0 0 0 0 0 -",
                              "1700000000.600000 1FFFFFFF 1 0 0 2 CAFE",
                          }));
}

// ---- pcap -------------------------------------------------------------------------------------

TEST_F(Trace, PcapRecordsAreSocketCanFrames) {
  auto path = write_all("bus.pcap");
  char errbuf[PCAP_ERRBUF_SIZE];
  pcap_t* p = pcap_open_offline(path.c_str(), errbuf);
  ASSERT_NE(p, nullptr) << errbuf;
  EXPECT_EQ(pcap_datalink(p), 227);  // LINKTYPE_CAN_SOCKETCAN (tcpdump.org link-layer types)
  // struct can_frame: can_id (network byte order; EFF 0x80000000, RTR 0x40000000, ERR
  // 0x20000000), len, __pad, __res0, len8_dlc, data[8].
  using Bytes = std::array<std::uint8_t, 16>;
  const std::vector<Bytes> expected = {
      {0x00, 0x00, 0x01, 0x23, 4, 0, 0, 0, 0xDE, 0xAD, 0xBE, 0xEF, 0, 0, 0, 0},
      {0xD2, 0x34, 0x56, 0x78, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
      {0x40, 0x00, 0x07, 0x05, 3, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
      {0x20, 0x00, 0x00, 0x80, 8, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
      {0x00, 0x00, 0x00, 0x00, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},
      {0x9F, 0xFF, 0xFF, 0xFF, 2, 0, 0, 0, 0xCA, 0xFE, 0, 0, 0, 0, 0, 0},
  };
  pcap_pkthdr* header = nullptr;
  const u_char* data = nullptr;
  std::size_t i = 0;
  while (pcap_next_ex(p, &header, &data) == 1) {
    ASSERT_LT(i, expected.size());
    EXPECT_EQ(header->caplen, 16u);
    EXPECT_EQ(header->len, 16u);
    EXPECT_EQ(header->ts.tv_sec, 1'700'000'000);
    EXPECT_EQ(header->ts.tv_usec, kFrames[i].time.time_since_epoch().count() % 1'000'000);
    Bytes got{};
    std::copy_n(data, std::min<std::size_t>(header->caplen, 16), got.begin());
    EXPECT_EQ(got, expected[i]) << kFrames[i].candump;
    ++i;
  }
  EXPECT_EQ(i, expected.size());
  pcap_close(p);
}

TEST_F(Trace, PcapFileIsTheClassicFormatByteForByte) {
  // pcap-savefile(5) (tcpdump.org): the global header in the writer's byte order (little-endian
  // here): magic a1b2c3d4, version 2.4, thiszone 0, sigfigs 0, snaplen 65535, link type 227;
  // then each record: ts_sec, ts_usec, caplen, len, and the 16-byte struct can_frame.
  const auto path = write_all("exact.pcap");
  const std::vector<std::uint8_t> header = {0xD4, 0xC3, 0xB2, 0xA1, 0x02, 0x00, 0x04, 0x00,
                                            0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
                                            0xFF, 0xFF, 0x00, 0x00, 0xE3, 0x00, 0x00, 0x00};
  // 1700000000 s = 0x6553F100, 123456 us = 0x0001E240; 123#DEADBEEF as in
  // PcapRecordsAreSocketCanFrames.
  const std::vector<std::uint8_t> first_record = {0x00, 0xF1, 0x53, 0x65, 0x40, 0xE2, 0x01, 0x00,
                                                  0x10, 0x00, 0x00, 0x00, 0x10, 0x00, 0x00, 0x00,
                                                  0x00, 0x00, 0x01, 0x23, 0x04, 0x00, 0x00, 0x00,
                                                  0xDE, 0xAD, 0xBE, 0xEF, 0x00, 0x00, 0x00, 0x00};
  std::ifstream in(path, std::ios::binary);
  const std::vector<std::uint8_t> file{std::istreambuf_iterator<char>(in),
                                       std::istreambuf_iterator<char>()};
  ASSERT_EQ(file.size(), header.size() + kFrames.size() * first_record.size());
  EXPECT_EQ(std::vector<std::uint8_t>(file.begin(), file.begin() + 24), header);
  EXPECT_EQ(std::vector<std::uint8_t>(file.begin() + 24, file.begin() + 56), first_record);
}

TEST_F(Trace, TsharkDecodesCanopenFromPcap) {
  if (!have_program("tshark")) PREREQUISITE_MISSING("tshark missing: apt-get install tshark");
  auto writer = open_pcap(dir_ / "canopen.pcap");
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  // CiA 301: NMT "start remote node" (cs 0x01) for node 5; SDO upload of 1018h sub 1 from
  // node 5 (client request 605h, ccs 2) and its expedited answer (585h); node 5's heartbeat.
  for (const char* f : {"000#0105", "605#4018100100000000", "585#4318100178563412", "705#05"}) {
    ASSERT_TRUE((*writer)->write(frame(f), at(0)).ok());
  }
  writer->reset();
  const std::string file = (dir_ / "canopen.pcap").string();
  auto [code, lines] = run("tshark -r '" + file +
                           "' -d can.subdissector,canopen -T fields -E separator=, -e can.id "
                           "-e canopen.nmt_ctrl.cd -e canopen.nmt_ctrl.node_id "
                           "-e canopen.sdo.main_idx -e canopen.sdo.sub_idx 2>/dev/null");
  ASSERT_EQ(code, 0);
  EXPECT_EQ(lines, (std::vector<std::string>{"0,0x01,0x05,,", "1541,,,0x1018,0x01",
                                             "1413,,,0x1018,0x01", "1797,,,,"}));
  auto [vcode, verbose] =
      run("tshark -r '" + file + "' -d can.subdissector,canopen -V 2>/dev/null");
  ASSERT_EQ(vcode, 0);
  std::string all;
  for (const auto& l : verbose) all += l + "\n";
  EXPECT_NE(all.find("Start remote node"), std::string::npos);
  EXPECT_NE(all.find("Initiate upload request"), std::string::npos);
  EXPECT_NE(all.find("Initiate upload response"), std::string::npos);
}

// ---- writer behaviour -------------------------------------------------------------------------

TEST_F(Trace, OpenTraceChoosesFormatByExtension) {
  auto log = write_all("a.log");
  auto pcap = write_all("a.pcap");
  EXPECT_EQ(read_lines(log).front(), "(1700000000.123456) can0 123#DEADBEEF");
  std::ifstream in(pcap, std::ios::binary);
  std::array<unsigned char, 4> magic{};
  in.read(reinterpret_cast<char*>(magic.data()), 4);
  // pcap magic 0xa1b2c3d4 in the writer's (little-endian here) byte order.
  EXPECT_EQ(magic, (std::array<unsigned char, 4>{0xd4, 0xc3, 0xb2, 0xa1}));

  auto other = open_trace(dir_ / "a.txt");
  ASSERT_FALSE(other.ok());
  EXPECT_NE(other.error().message.find(".log"), std::string::npos);
  EXPECT_NE(other.error().message.find(".pcap"), std::string::npos);
}

TEST_F(Trace, OpenFailsNamingThePath) {
  for (const char* name : {"no/such/dir/a.log", "no/such/dir/a.pcap"}) {
    auto writer = open_trace(dir_ / name);
    ASSERT_FALSE(writer.ok()) << name;
    EXPECT_NE(writer.error().message.find(name), std::string::npos) << writer.error().message;
  }
  EXPECT_FALSE(open_candump_log(dir_ / "x.log", "can 0").ok());
  EXPECT_FALSE(open_candump_log(dir_ / "x.log", "").ok());
}

TEST_F(Trace, FailuresAreSticky) {
  auto writer = open_candump_log(dir_ / "bad.log");
  ASSERT_TRUE(writer.ok());
  CanFrame too_long = frame("123#0102030405060708");
  too_long.dlc = 9;
  EXPECT_FALSE((*writer)->write(too_long, at(0)).ok());
  EXPECT_FALSE((*writer)->write(frame("123#"), at(0)).ok());
  EXPECT_FALSE((*writer)->status().ok());
  writer->reset();
  EXPECT_TRUE(read_lines(dir_ / "bad.log").empty());

  auto negative = open_pcap(dir_ / "neg.pcap");
  ASSERT_TRUE(negative.ok());
  EXPECT_FALSE((*negative)->write(frame("123#"), TimePoint{Duration{-1}}).ok());
}

TEST_F(Trace, WriteErrorOnFullDeviceIsReported) {
  if (!fs::exists("/dev/full")) PREREQUISITE_MISSING("no /dev/full");
  auto writer = open_candump_log("/dev/full");
  ASSERT_TRUE(writer.ok()) << writer.error().message;
  (void)(*writer)->write(frame("123#"), at(0));
  auto flushed = (*writer)->flush();
  ASSERT_FALSE(flushed.ok());
  EXPECT_NE(flushed.error().message.find("/dev/full"), std::string::npos);
  EXPECT_FALSE((*writer)->write(frame("123#"), at(1)).ok());
}

// ---- libpcap, loaded when the first pcap trace is opened ---------------------------------------

TEST(PcapLibrary, LoadsOnceForAllThreads) {
  // Threads opening their first pcap trace at once share one loaded library.
  std::vector<const detail::PcapLibrary*> seen(4, nullptr);
  std::vector<std::thread> threads;
  for (auto& s : seen) {
    threads.emplace_back([&s] {
      auto library = detail::pcap_library();
      s = library.ok() ? *library : nullptr;
    });
  }
  for (auto& t : threads) t.join();
  ASSERT_NE(seen[0], nullptr) << detail::pcap_library().error().message;
  for (const auto* s : seen) EXPECT_EQ(s, seen[0]);
  EXPECT_NE(seen[0]->dump, nullptr);
  EXPECT_NE(seen[0]->dump_close, nullptr);
}

TEST(PcapLibrary, MissingLibraryIsAnIoErrorNamingThePackageAndTheLoadersReason) {
  auto loaded = detail::load_pcap_library("libcanopen-test-no-such-library.so.0");
  ASSERT_FALSE(loaded.ok());
  EXPECT_EQ(loaded.error().category, cfg::ErrorCategory::Io);
  EXPECT_THAT(
      loaded.error().message,
      testing::StartsWith("writing a pcap trace needs libpcap (Debian package libpcap0.8): "
                          "libcanopen-test-no-such-library.so.0: cannot open shared object file"));
}

TEST(PcapLibrary, LibraryWithoutThePcapFunctionsIsRefusedNamingTheFirstMissing) {
  // zlib: loaded into every test program (libcfg links it), and it has no pcap_* function.
  auto loaded = detail::load_pcap_library("libz.so.1");
  ASSERT_FALSE(loaded.ok());
  EXPECT_THAT(loaded.error().message,
              testing::AllOf(testing::StartsWith("writing a pcap trace needs libpcap"),
                             testing::HasSubstr("undefined symbol: pcap_open_dead")));
}

// ---- any bus can be traced --------------------------------------------------------------------

// A scripted bus: records what is sent, hands out queued frames. No clock, unlike the event
// loop tests' FakeClockBus (tests/support): TracingBus passes the driver's stamps through.
class ScriptedBus : public Bus {
 public:
  cfg::Status send(const CanFrame& f) override {
    if (fail_sends) return cfg::Error{"scripted failure"};
    sent.push_back(f);
    return {};
  }
  cfg::Result<std::optional<ReceivedFrame>> receive(Duration) override {
    if (incoming.empty()) return std::optional<ReceivedFrame>{};
    auto r = incoming.front();
    incoming.pop_front();
    return std::optional<ReceivedFrame>(r);
  }
  std::string url() const override { return "scripted:0"; }

  std::vector<CanFrame> sent;
  std::deque<ReceivedFrame> incoming;
  bool fail_sends = false;
};

TEST_F(Trace, TracingBusRecordsSentAndReceivedFrames) {
  auto inner = std::make_unique<ScriptedBus>();
  ScriptedBus& scripted = *inner;
  scripted.incoming.push_back({frame("581#4B00100091010000"), TimePoint{Duration{42}}});
  auto writer = open_candump_log(dir_ / "traced.log");
  ASSERT_TRUE(writer.ok());
  TimePoint clock{Duration{1'000'000}};
  TracingBus bus(std::move(inner), std::move(*writer), [&clock] {
    clock += 1000us;
    return clock;
  });
  EXPECT_EQ(bus.url(), "scripted:0");

  ASSERT_TRUE(bus.send(frame("601#4000100000000000")).ok());
  auto r = bus.receive(10ms);
  ASSERT_TRUE(r.ok() && r->has_value());
  EXPECT_EQ(to_candump((*r)->frame), "581#4B00100091010000");
  EXPECT_EQ((*r)->timestamp, TimePoint{Duration{42}});  // the driver's timestamp, unchanged
  auto none = bus.receive(10ms);                        // nothing received: nothing traced
  ASSERT_TRUE(none.ok());
  EXPECT_FALSE(none->has_value());
  scripted.fail_sends = true;
  EXPECT_FALSE(bus.send(frame("000#8100")).ok());  // not sent: not traced
  ASSERT_EQ(scripted.sent.size(), 1u);
  ASSERT_TRUE(bus.trace().flush().ok());

  EXPECT_EQ(read_lines(dir_ / "traced.log"),
            (std::vector<std::string>{"(0000000001.001000) can0 601#4000100000000000",
                                      "(0000000001.002000) can0 581#4B00100091010000"}));
}

// The event loop sends with try_send: a frame the inner bus took is traced, one it did
// not take (retried later by the loop) is not.
TEST_F(Trace, TracingBusTracesWhatTrySendHandedOver) {
  auto inner = std::make_unique<ScriptedBus>();
  ScriptedBus& scripted = *inner;
  auto writer = open_candump_log(dir_ / "try_send.log");
  ASSERT_TRUE(writer.ok());
  TracingBus bus(std::move(inner), std::move(*writer),
                 [] { return TimePoint{Duration{2'000'000}}; });
  scripted.fail_sends = true;
  EXPECT_EQ(bus.try_send(frame("000#8100")).status, SendResult::Status::Failed);
  scripted.fail_sends = false;
  EXPECT_EQ(bus.try_send(frame("000#0100")).status, SendResult::Status::Sent);
  ASSERT_TRUE(bus.trace().flush().ok());
  EXPECT_EQ(read_lines(dir_ / "try_send.log"),
            std::vector<std::string>{"(0000000002.000000) can0 000#0100"});
}

TEST_F(Trace, SimulatedBusTraceHasDeliveryTimes) {
  SimBus sim(500'000);
  auto writer = open_candump_log(dir_ / "sim.log");
  ASSERT_TRUE(writer.ok());
  sim.add_observer(trace_observer(**writer));
  std::vector<TimePoint> seen;  // when the receiving node saw each frame
  FunctionNode a;
  FunctionNode b([&seen](FunctionNode&, const CanFrame&, TimePoint now) { seen.push_back(now); });
  sim.attach(a);
  sim.attach(b);
  sim.schedule_at(TimePoint{}, [&a](TimePoint) {
    a.send(frame("000#0105"));
    a.send(frame("705#05"));
  });
  sim.run_until_idle(TimePoint{Duration{1'000'000}});
  ASSERT_EQ(seen.size(), 2u);
  ASSERT_TRUE((*writer)->flush().ok());
  char line1[64], line2[64];
  std::snprintf(line1, sizeof line1, "(0000000000.%06lld) can0 000#0105",
                static_cast<long long>(seen[0].time_since_epoch().count()));
  std::snprintf(line2, sizeof line2, "(0000000000.%06lld) can0 705#05",
                static_cast<long long>(seen[1].time_since_epoch().count()));
  EXPECT_EQ(read_lines(dir_ / "sim.log"), (std::vector<std::string>{line1, line2}));
}

}  // namespace
}  // namespace nmt
