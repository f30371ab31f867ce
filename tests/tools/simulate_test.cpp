// cfgmgr simulate end to end. Argument and file errors need no network. The run over a UDP
// multicast bus happens in a private network namespace whose only interface is lo
// (tests/support/run_in_netns.sh, as the UDP bus tests do): Simulate.EndToEndOverUdp re-runs this
// executable there with --gtest_filter=SimulateInNetns.*; those tests skip anywhere else.
// The master side of the conversation is libnmt's SdoClient on a UdpBus, driven by the same
// BusEventLoop; the expected values come from tests/data/sim_device.eds and spec/002 (frames).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <net/if.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <deque>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/sdo/sdo.hpp"
#include "started.hpp"
#include "tool_test_support.hpp"

extern char** environ;

namespace {

using namespace std::chrono_literals;
using tool_test::data_path;
using tool_test::run;
using tool_test::ScratchDir;

const std::string kDevice = data_path("sim_device.eds");

// ------------------------------------------------------------------- no network -------------

TEST(Simulate, HelpDocumentsUsageExamplesAndExitCodes) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"simulate", "--help"}, dir.path().string());
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_NE(r.out.find("DEVICE.eds[@NODE-ID]"), std::string::npos);
  EXPECT_NE(r.out.find("--bus"), std::string::npos);
  EXPECT_NE(r.out.find("Examples:"), std::string::npos);
  EXPECT_NE(r.out.find("Exit codes:"), std::string::npos);
  EXPECT_NE(r.out.find("--state DIR"), std::string::npos);
  EXPECT_NE(r.out.find("cfgmgr simulate --state /tmp/devices drive.eds@255"), std::string::npos);
}

TEST(Simulate, DamagedStateFileIsAnInputErrorBeforeTheBusIsOpened) {
  // A state file without end= was cut short (nmt/sim/device_state.hpp): never taken.
  ScratchDir dir;
  const std::filesystem::path state = dir.path() / "state";
  std::filesystem::create_directories(state);
  {
    std::ofstream out(state / "node-05.saved");
    out << "node=5\n1017sub00=E803\n";
  }
  auto r =
      run("cfgmgr",
          {"simulate", "--bus", "socketcan:no-such-if0", "--state", state.string(), kDevice + "@5"},
          dir.path().string());
  EXPECT_EQ(r.exit_code, 1) << r.err;
  EXPECT_NE(r.err.find("node-05.saved:2: error: no end= line: the file is cut short"),
            std::string::npos)
      << r.err;
}

TEST(Simulate, RejectsNodeIdOutOfRange) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"simulate", "--for", "0.1", kDevice + "@128"}, dir.path().string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("out of range 1..127"), std::string::npos) << r.err;
}

TEST(Simulate, RejectsTheSameNodeIdTwice) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"simulate", "--for", "0.1", kDevice + "@5", kDevice + "@0x05"},
               dir.path().string());
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("node-ID 5 given twice"), std::string::npos) << r.err;
}

TEST(Simulate, EdsWithoutNodeIdIsAnInputError) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"simulate", "--for", "0.1", kDevice}, dir.path().string());
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("no node-ID"), std::string::npos) << r.err;
}

TEST(Simulate, MissingDeviceFileIsAnIoError) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"simulate", "--for", "0.1", dir / "missing.eds@3"}, dir.path().string());
  EXPECT_EQ(r.exit_code, 3);
  EXPECT_NE(r.err.find("missing.eds"), std::string::npos) << r.err;
}

TEST(Simulate, BusUrlThatDoesNotParseIsAUsageError) {
  ScratchDir dir;
  // An unknown scheme, a udp:// group outside 224.0.0.0/4 (RFC 5771), a port that is not a
  // number, and socketcan: without an interface name: none names a bus, so none is opened.
  for (const std::string url :
       {"carrier-pigeon:1", "udp://10.0.0.1:43113", "udp://239.74.163.2:port", "socketcan:"}) {
    auto r = run("cfgmgr", {"simulate", "--bus", url, "--for", "0.1", kDevice + "@3"},
                 dir.path().string());
    EXPECT_EQ(r.exit_code, 2) << url << "\n" << r.err;
    EXPECT_NE(r.err.find("--bus"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(url), std::string::npos) << r.err;
  }
}

TEST(Simulate, BusThatCannotBeOpenedIsAnIoError) {
  ScratchDir dir;
  // Well-formed, but no such interface (or no CAN support in the kernel): opening fails.
  auto r =
      run("cfgmgr", {"simulate", "--bus", "socketcan:nosuchcan9", "--for", "0.1", kDevice + "@3"},
          dir.path().string());
  EXPECT_EQ(r.exit_code, 3) << r.err;
  EXPECT_NE(r.err.find("socketcan:nosuchcan9"), std::string::npos) << r.err;
}

TEST(Simulate, BadLossRateIsAUsageError) {
  ScratchDir dir;
  auto r = run("cfgmgr", {"simulate", "--loss", "1.5", "--for", "0.1", kDevice + "@3"},
               dir.path().string());
  EXPECT_EQ(r.exit_code, 2);
}

// --------------------------------------------------------- over UDP, in a namespace ----------

TEST(Simulate, EndToEndOverUdp) {
  tool_test::run_in_private_netns("SimulateInNetns.*");
}

// cfgmgr simulate in the background, so that the test can signal it.
class Simulator : public tool_test::SpawnedTool {
 public:
  Simulator(const std::vector<std::string>& args, const std::string& out, const std::string& err)
      : SpawnedTool("cfgmgr", with_command(args), out, err) {}

 private:
  static std::vector<std::string> with_command(const std::vector<std::string>& args) {
    std::vector<std::string> out{"simulate"};
    out.insert(out.end(), args.begin(), args.end());
    return out;
  }
};

// Sends scripted frames from the test's side of the bus and records what it hears.
class Script {
 public:
  using Event = nmt::NoEvent;
  using Output = nmt::Outbox<nmt::NoEvent>;
  void queue(std::string candump) { out_.push_back(*nmt::from_candump(candump)); }
  bool on_frame(const nmt::CanFrame& f, nmt::TimePoint now, Output&) {
    heard.push_back({now, nmt::to_candump(f)});
    return false;
  }
  void on_timer(nmt::TimePoint, Output& out) {
    for (auto& f : out_) out.send(f);
    out_.clear();
  }
  std::optional<nmt::TimePoint> next_deadline() const {
    return out_.empty() ? std::nullopt : std::optional<nmt::TimePoint>(nmt::TimePoint{});
  }
  std::size_t count(const std::string& frame) const {
    std::size_t n = 0;
    for (const auto& [t, f] : heard) n += f == frame ? 1 : 0;
    return n;
  }
  std::vector<std::pair<nmt::TimePoint, std::string>> heard;

 private:
  std::deque<nmt::CanFrame> out_;
};

TEST(SimulateInNetns, DevicesBootAnswerSdoAndFollowNmtOverUdp) {
  REQUIRE_ISOLATED_MULTICAST();
  ScratchDir dir;
  const std::string url = test_support::udp_test_url("43171");
  auto opened = nmt::open_bus(url);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  auto bus = std::move(opened).value();

  Simulator sim({"--bus", url, kDevice + "@5", kDevice + "@6", "-v", "--candump", dir / "run.log",
                 "--trace", dir / "run.pcap"},
                dir / "out.txt", dir / "err.txt");
  ASSERT_TRUE(sim.started());

  nmt::BusEventLoop loop(*bus);
  Script script;
  nmt::SdoClient client(nmt::SdoClientConfig::for_node(*cfg::NodeId::from(5)));
  std::map<nmt::SdoClient::TransferId, nmt::SdoResult> results;
  const auto result = [&](nmt::SdoClient::TransferId id) -> const nmt::SdoResult* {
    auto it = results.find(id);
    return it == results.end() ? nullptr : &it->second;
  };
  nmt::EngineRef script_ref(script);
  nmt::EngineRef client_ref(client,
                            [&](const nmt::SdoResult& r, nmt::TimePoint) { results[r.id] = r; });
  const auto upload = [&](std::uint16_t index, std::uint8_t sub) {
    return test_support::started(
        client_ref.apply([&](nmt::SdoClient& c, nmt::TimePoint now, nmt::SdoClient::Output& out) {
          return c.upload(index, sub, now, out);
        }));
  };
  const auto download = [&](std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data) {
    return test_support::started(
        client_ref.apply([&](nmt::SdoClient& c, nmt::TimePoint now, nmt::SdoClient::Output& out) {
          return c.download(index, sub, std::move(data), now, out);
        }));
  };
  loop.add(script_ref);
  loop.add(client_ref);
  auto run_until = [&](const std::function<bool()>& done, nmt::Duration limit) {
    const auto end = loop.now() + limit;
    while (!done() && loop.now() < end) ASSERT_TRUE(loop.run_for(10ms).ok());
  };

  // Boot-up of both nodes (spec/002: `7xx#00`).
  run_until([&] { return script.count("705#00") == 1 && script.count("706#00") == 1; }, 5s);
  ASSERT_EQ(script.count("705#00"), 1u) << tool_test::slurp(dir / "err.txt");
  ASSERT_EQ(script.count("706#00"), 1u);

  // SDO: 1018h sub 1 is VendorNumber 0x7E57C0DE in sim_device.eds.
  auto vendor = upload(0x1018, 1);
  run_until([&] { return result(vendor) != nullptr; }, 3s);
  ASSERT_NE(result(vendor), nullptr);
  ASSERT_TRUE(result(vendor)->ok()) << result(vendor)->abort;
  EXPECT_EQ(result(vendor)->data, (std::vector<std::uint8_t>{0xDE, 0xC0, 0x57, 0x7E}));

  // A segmented download and upload of a string (2001h VISIBLE_STRING).
  const std::string name = "simulated over UDP multicast";
  auto write = download(0x2001, 0, std::vector<std::uint8_t>(name.begin(), name.end()));
  run_until([&] { return result(write) != nullptr; }, 3s);
  ASSERT_NE(result(write), nullptr);
  EXPECT_TRUE(result(write)->ok()) << result(write)->abort;
  auto read = upload(0x2001, 0);
  run_until([&] { return result(read) != nullptr; }, 3s);
  ASSERT_NE(result(read), nullptr);
  EXPECT_EQ(std::string(result(read)->data.begin(), result(read)->data.end()), name);

  // Heartbeat 100 ms, then start node 5: heartbeats say operational (05).
  auto hb = download(0x1017, 0, {100, 0});
  run_until([&] { return result(hb) != nullptr; }, 3s);
  ASSERT_TRUE(result(hb) && result(hb)->ok());
  script.queue("000#0105");
  run_until([&] { return script.count("705#05") >= 3; }, 2s);
  EXPECT_GE(script.count("705#05"), 3u);
  EXPECT_EQ(script.count("706#05"), 0u);  // node 6 was not started and has no heartbeat

  // Node guarding on node 6 (1017h = 0): toggle bit starts at 0 (spec/002).
  script.queue("706#R1");
  run_until([&] { return script.count("706#7F") == 1; }, 2s);
  EXPECT_EQ(script.count("706#7F"), 1u);

  // SIGINT ends it with exit code 0.
  EXPECT_EQ(sim.stop(SIGINT, 3000ms), 0);

  const std::string out = tool_test::slurp(dir / "out.txt");
  EXPECT_NE(out.find("rx  000#0105"), std::string::npos) << out;
  EXPECT_NE(out.find("tx  705#00"), std::string::npos);
  EXPECT_NE(out.find("node 5  nmt: start"), std::string::npos);
  const std::string log = tool_test::slurp(dir / "run.log");
  EXPECT_NE(log.find(" can0 705#00\n"), std::string::npos) << log;
  EXPECT_NE(log.find(" can0 000#0105\n"), std::string::npos);
  // pcap: the classic file header (magic a1b2c3d4 little-endian) with link type 227
  // (LINKTYPE_CAN_SOCKETCAN), then records.
  const std::string pcap = tool_test::slurp(dir / "run.pcap");
  ASSERT_GT(pcap.size(), 24u);
  EXPECT_EQ(pcap.substr(0, 4), std::string("\xD4\xC3\xB2\xA1", 4));
  EXPECT_EQ(static_cast<unsigned char>(pcap[20]), 227);
}

TEST(SimulateInNetns, AnswersTheIdentityOfItsFileWhere1018hHasNoValue) {
  // tests/data/network/nodes/drive_node3.dcf has 1018h sub 1 only; its [DeviceInfo] says
  // ProductNumber 0x00000402 and RevisionNumber 0x00020004. The device answers those in 1018h
  // sub 2/3, as a `sim:` device of the same file and the real device do, so a master derived
  // from the file accepts it (without them it ends the boot with status M/N).
  REQUIRE_ISOLATED_MULTICAST();
  ScratchDir dir;
  const std::string url = test_support::udp_test_url("43173");
  auto opened = nmt::open_bus(url);
  ASSERT_TRUE(opened.ok()) << opened.error().message;
  auto bus = std::move(opened).value();
  Simulator sim({"--bus", url, tool_test::test_network("nodes/drive_node3.dcf") + "@3"},
                dir / "out.txt", dir / "err.txt");
  ASSERT_TRUE(sim.started());

  nmt::BusEventLoop loop(*bus);
  Script script;
  nmt::SdoClient client(nmt::SdoClientConfig::for_node(*cfg::NodeId::from(3)));
  std::map<nmt::SdoClient::TransferId, nmt::SdoResult> results;
  nmt::EngineRef script_ref(script);
  nmt::EngineRef client_ref(client,
                            [&](const nmt::SdoResult& r, nmt::TimePoint) { results[r.id] = r; });
  loop.add(script_ref);
  loop.add(client_ref);
  const auto run_until = [&](const std::function<bool()>& done, nmt::Duration limit) {
    const auto end = loop.now() + limit;
    while (!done() && loop.now() < end) ASSERT_TRUE(loop.run_for(10ms).ok());
  };
  run_until([&] { return script.count("703#00") == 1; }, 5s);
  ASSERT_EQ(script.count("703#00"), 1u) << tool_test::slurp(dir / "err.txt");
  const auto read_u32 = [&](std::uint8_t sub) -> std::optional<std::vector<std::uint8_t>> {
    const auto id = test_support::started(
        client_ref.apply([&](nmt::SdoClient& c, nmt::TimePoint now, nmt::SdoClient::Output& out) {
          return c.upload(0x1018, sub, now, out);
        }));
    run_until([&] { return results.contains(id); }, 3s);
    if (!results.contains(id) || !results[id].ok()) return std::nullopt;
    return results[id].data;
  };
  EXPECT_EQ(read_u32(1), (std::vector<std::uint8_t>{0xBC, 0x0A, 0x00, 0x00}));  // 1018h sub 1
  EXPECT_EQ(read_u32(2), (std::vector<std::uint8_t>{0x02, 0x04, 0x00, 0x00}));  // ProductNumber
  EXPECT_EQ(read_u32(3), (std::vector<std::uint8_t>{0x04, 0x00, 0x02, 0x00}));  // RevisionNumber
  EXPECT_EQ(sim.stop(SIGINT, 3000ms), 0);
}

TEST(SimulateInNetns, ForEndsTheRunByItself) {
  REQUIRE_ISOLATED_MULTICAST();
  ScratchDir dir;
  auto r = run(
      "cfgmgr",
      {"simulate", "--bus", test_support::udp_test_url("43172"), "--for", "0.3", kDevice + "@7"},
      dir.path().string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("node 7: "), std::string::npos);
  EXPECT_NE(r.out.find("frames: 0 received, 1 sent"), std::string::npos) << r.out;
}

}  // namespace
