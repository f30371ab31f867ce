// UDP multicast bus against python-can 4.1's udp_multicast interface (Debian python3-can), the
// independent implementation of the wire format.
//
// UdpUrl.* and UdpDatagram.* use no network. UdpBus.* send multicast, so they run only inside
// the private network namespace the ctest test `io_udp_bus_netns` creates (its only interface
// is lo, with the multicast route on lo): nothing can leave the machine. Elsewhere they skip.
#include "nmt/io/udp_bus.hpp"

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <msgpack.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <thread>
#include <vector>

#include "multicast_netns.hpp"
#include "nmt/io/bus.hpp"
#include "prerequisite.hpp"
#include "python_peer.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using test_support::PythonPeer;
using test_support::run_python_peer;

CanFrame frame(std::string_view candump) {
  auto f = from_candump(candump);
  EXPECT_TRUE(f.has_value()) << candump;
  return f.value_or(CanFrame{});
}

std::vector<std::uint8_t> from_hex(std::string_view hex) {
  std::vector<std::uint8_t> out;
  for (std::size_t i = 0; i + 1 < hex.size(); i += 2) {
    out.push_back(static_cast<std::uint8_t>(std::stoi(std::string(hex.substr(i, 2)), nullptr, 16)));
  }
  return out;
}

std::string to_hex(std::span<const std::uint8_t> bytes) {
  std::string out;
  char buf[3];
  for (auto b : bytes) {
    std::snprintf(buf, sizeof buf, "%02x", b);
    out += buf;
  }
  return out;
}

// ---- URLs -----------------------------------------------------------------------------------

TEST(UdpUrl, DefaultsToPythonCanGroupAndPort) {
  // python-can udp_multicast/bus.py: DEFAULT_GROUP_IPv4 = "239.74.163.2", port=43113.
  auto options = parse_udp_url("udp://");
  ASSERT_TRUE(options.ok()) << options.error().message;
  EXPECT_EQ(options->group, "239.74.163.2");
  EXPECT_EQ(options->port, 43113);
  EXPECT_EQ(options->interface_address, "127.0.0.1");
  EXPECT_EQ(options->ttl, 1);
  EXPECT_EQ(to_udp_url(*options), "udp://239.74.163.2:43113");
}

TEST(UdpUrl, ParsesGroupPortInterfaceAndTtl) {
  auto options = parse_udp_url("udp://239.1.2.3:5000?iface=192.168.1.10&ttl=4");
  ASSERT_TRUE(options.ok()) << options.error().message;
  EXPECT_EQ(options->group, "239.1.2.3");
  EXPECT_EQ(options->port, 5000);
  EXPECT_EQ(options->interface_address, "192.168.1.10");
  EXPECT_EQ(options->ttl, 4);
  EXPECT_EQ(to_udp_url(*options), "udp://239.1.2.3:5000?iface=192.168.1.10&ttl=4");
}

TEST(UdpUrl, GroupAloneKeepsDefaultPort) {
  auto options = parse_udp_url("udp://224.0.0.200");
  ASSERT_TRUE(options.ok()) << options.error().message;
  EXPECT_EQ(options->group, "224.0.0.200");
  EXPECT_EQ(options->port, 43113);
}

TEST(UdpUrl, RejectsBadUrlsNamingTheUrlAndTheForm) {
  for (const char* url :
       {"udp://192.168.1.1:43113",  // not multicast (RFC 5771: 224/4)
        "udp://240.0.0.1:43113", "udp://239.1.2.3:0", "udp://239.1.2.3:65536",
        "udp://239.1.2.3:port", "udp://[ff15::1]:43113", "udp://group:1", "udp://239.1.2.3:1?ttl=0",
        "udp://239.1.2.3:1?ttl=256", "udp://239.1.2.3:1?iface=eth0", "udp://239.1.2.3:1?loop=1",
        "tcp://239.1.2.3:1"}) {
    auto options = parse_udp_url(url);
    ASSERT_FALSE(options.ok()) << url;
    EXPECT_NE(options.error().message.find(url), std::string::npos) << options.error().message;
    EXPECT_NE(options.error().message.find("udp://GROUP:PORT"), std::string::npos)
        << options.error().message;
  }
}

// ---- datagrams ------------------------------------------------------------------------------

// Builds a MessagePack map with msgpack-c, for datagrams python-can's packer never produces.
class MapBuilder {
 public:
  explicit MapBuilder(std::size_t entries) {
    msgpack_packer_init(&pk_, &bytes_, [](void* data, const char* buf, std::size_t len) {
      auto* out = static_cast<std::vector<std::uint8_t>*>(data);
      out->insert(out->end(), buf, buf + len);
      return 0;
    });
    msgpack_pack_map(&pk_, entries);
  }
  MapBuilder& key(std::string_view k) {
    msgpack_pack_str(&pk_, k.size());
    msgpack_pack_str_body(&pk_, k.data(), k.size());
    return *this;
  }
  MapBuilder& uint(std::uint64_t v) {
    msgpack_pack_uint64(&pk_, v);
    return *this;
  }
  MapBuilder& boolean(bool v) {
    if (v) {
      msgpack_pack_true(&pk_);
    } else {
      msgpack_pack_false(&pk_);
    }
    return *this;
  }
  MapBuilder& bin(std::vector<std::uint8_t> v) {
    msgpack_pack_bin(&pk_, v.size());
    msgpack_pack_bin_body(&pk_, v.data(), v.size());
    return *this;
  }
  MapBuilder& str(std::string_view v) {
    msgpack_pack_str(&pk_, v.size());
    msgpack_pack_str_body(&pk_, v.data(), v.size());
    return *this;
  }
  const std::vector<std::uint8_t>& bytes() const { return bytes_; }

 private:
  std::vector<std::uint8_t> bytes_;
  msgpack_packer pk_{};
};

TEST(UdpDatagram, PythonCanUnpacksOurDatagramsWithExactlyItsKeys) {
  if (auto why = test_support::python_can_missing()) PREREQUISITE_MISSING(*why);
  CanFrame error_frame = frame("20000080#0000000000000000");
  std::vector<std::string> args = {"unpack"};
  for (const CanFrame& f : {frame("123#DEADBEEF"), frame("1FFFFFFF#CAFE"), frame("705#R3"),
                            frame("12345678#R"), frame("000#"), error_frame}) {
    auto datagram = encode_udp_datagram(f, 1700000000.5);
    ASSERT_TRUE(datagram.ok()) << datagram.error().message;
    args.push_back(to_hex(*datagram));
  }
  auto run = run_python_peer(args);
  ASSERT_EQ(run.exit_code, 0);
  // python-can utils.py pack_message(): these 11 keys in this order; unpack_message(check=True)
  // builds the Message. Lines: id ext rtr err dlc data.
  const std::string keys =
      "timestamp,arbitration_id,is_extended_id,is_remote_frame,is_error_frame,channel,dlc,data,"
      "is_fd,bitrate_switch,error_state_indicator";
  EXPECT_EQ(run.lines, (std::vector<std::string>{keys, "123 0 0 0 4 DEADBEEF",   //
                                                 keys, "1FFFFFFF 1 0 0 2 CAFE",  //
                                                 keys, "705 0 1 0 3 -",          //
                                                 keys, "12345678 1 1 0 0 -",     //
                                                 keys, "0 0 0 0 0 -",            //
                                                 keys, "80 1 0 1 8 0000000000000000"}));
}

TEST(UdpDatagram, DecodesPythonCanDatagrams) {
  if (auto why = test_support::python_can_missing()) PREREQUISITE_MISSING(*why);
  auto run = run_python_peer({"pack", "123#DEADBEEF", "1FFFFFFF#0102030405060708", "705#R",
                              "12345678#R8", "7FF#", "E80#0000000000000000"});
  ASSERT_EQ(run.exit_code, 0);
  ASSERT_EQ(run.lines.size(), 6u);
  std::vector<std::string> decoded;
  for (const auto& hex : run.lines) {
    auto f = decode_udp_datagram(from_hex(hex));
    ASSERT_TRUE(f.ok()) << f.error().message;
    decoded.push_back(to_candump(*f));
  }
  // Error frames come back extended, as SocketCanBus reports them.
  EXPECT_EQ(decoded,
            (std::vector<std::string>{"123#DEADBEEF", "1FFFFFFF#0102030405060708", "705#R",
                                      "12345678#R8", "7FF#", "20000080#0000000000000000"}));
}

TEST(UdpDatagram, MissingKeysTakeCanMessageDefaultsAndUnknownKeysAreIgnored) {
  // can.Message.__init__: is_extended_id defaults to True, dlc to len(data).
  auto bytes =
      MapBuilder(3).key("arbitration_id").uint(0x100).key("data").bin({1, 2}).key("x").uint(1);
  auto f = decode_udp_datagram(bytes.bytes());
  ASSERT_TRUE(f.ok()) << f.error().message;
  EXPECT_EQ(to_candump(*f), "00000100#0102");
}

TEST(UdpDatagram, RejectsWhatPythonCanRejectsAndCanFd) {
  struct Case {
    const char* why;
    std::vector<std::uint8_t> bytes;
  };
  const std::vector<Case> cases = {
      {"dlc does not match data (Message._check)",
       MapBuilder(3).key("arbitration_id").uint(1).key("dlc").uint(3).key("data").bin({1}).bytes()},
      {"dlc > 8",
       MapBuilder(2).key("dlc").uint(9).key("data").bin({1, 2, 3, 4, 5, 6, 7, 8, 9}).bytes()},
      {"standard id >= 0x800", MapBuilder(2)
                                   .key("arbitration_id")
                                   .uint(0x800)
                                   .key("is_extended_id")
                                   .boolean(false)
                                   .bytes()},
      {"extended id >= 2^29", MapBuilder(1).key("arbitration_id").uint(0x20000000).bytes()},
      {"remote and error", MapBuilder(2)
                               .key("is_remote_frame")
                               .boolean(true)
                               .key("is_error_frame")
                               .boolean(true)
                               .bytes()},
      {"CAN FD", MapBuilder(2).key("is_fd").boolean(true).key("data").bin({1}).bytes()},
      {"bitrate switch on a classic frame",
       MapBuilder(1).key("bitrate_switch").boolean(true).bytes()},
      {"flag of the wrong type", MapBuilder(1).key("is_remote_frame").str("yes").bytes()},
      {"id of the wrong type", MapBuilder(1).key("arbitration_id").str("0x123").bytes()},
      {"key not a string", {0x81, 0x01, 0x02}},
      {"not a map", {0x05}},
      {"empty", {}},
      {"never-used byte 0xc1", {0xc1}},
      {"array32 announcing 2^32-1 elements", {0xdd, 0xff, 0xff, 0xff, 0xff}},
      {"map32 announcing 2^31 entries", {0xdf, 0x80, 0x00, 0x00, 0x00, 0xc0}},
      {"bin32 longer than the datagram", {0xc6, 0x7f, 0xff, 0xff, 0xff, 0x00}},
      {"map cut short", {0x82, 0xa3, 'd', 'l', 'c', 0x01}},
      {"text", {'h', 'e', 'l', 'l', 'o'}},
  };
  for (const auto& c : cases) {
    auto f = decode_udp_datagram(c.bytes);
    EXPECT_FALSE(f.ok()) << c.why << " decoded as " << to_candump(f.ok() ? *f : CanFrame{});
  }
  // A valid datagram followed by one more byte.
  auto good = encode_udp_datagram(frame("123#01"), 0);
  ASSERT_TRUE(good.ok());
  auto padded = *good;
  padded.push_back(0xc0);
  EXPECT_FALSE(decode_udp_datagram(padded).ok());
  // Every truncation of a valid datagram.
  for (std::size_t n = 0; n < good->size(); ++n) {
    EXPECT_FALSE(decode_udp_datagram({good->data(), n}).ok()) << n;
  }
}

TEST(UdpDatagram, RefusesToEncodeFramesPythonCanWouldReject) {
  CanFrame big_standard = frame("7FF#");
  big_standard.id = 0x800;
  EXPECT_FALSE(encode_udp_datagram(big_standard, 0).ok());
  CanFrame long_frame = frame("123#0102030405060708");
  long_frame.dlc = 9;
  EXPECT_FALSE(encode_udp_datagram(long_frame, 0).ok());
  CanFrame remote_error = frame("705#R");
  remote_error.error = true;
  EXPECT_FALSE(encode_udp_datagram(remote_error, 0).ok());
}

// ---- the bus, in the private network namespace -------------------------------------------

// Every test has its own port (python-can binds to the port on all addresses).
std::unique_ptr<UdpBus> open_udp(std::uint16_t port, const std::string& group = "239.74.163.2") {
  UdpBusOptions options;
  options.group = group;
  options.port = port;
  auto bus = UdpBus::open(options);
  EXPECT_TRUE(bus.ok()) << bus.error().message;
  return bus.ok() ? std::move(*bus) : nullptr;
}

std::optional<CanFrame> receive_one(Bus& bus, Duration timeout = 2s) {
  auto r = bus.receive(timeout);
  EXPECT_TRUE(r.ok()) << r.error().message;
  if (!r.ok() || !r->has_value()) return std::nullopt;
  return (*r)->frame;
}

TEST(UdpBus, TwoMembersExchangeFramesAndDropTheirOwn) {
  REQUIRE_ISOLATED_MULTICAST();
  auto a = open_udp(47001);
  auto b = open_udp(47001);
  ASSERT_TRUE(a && b);
  ASSERT_TRUE(a->send(frame("605#2B171000E8030000")).ok());
  auto got = receive_one(*b);
  ASSERT_TRUE(got);
  EXPECT_EQ(to_candump(*got), "605#2B171000E8030000");
  // a hears its own datagram (IP_MULTICAST_LOOP) and drops it.
  auto own = a->receive(100ms);
  ASSERT_TRUE(own.ok());
  EXPECT_FALSE(own->has_value());
  EXPECT_EQ(a->counters().own_datagrams, 1u);
  ASSERT_TRUE(b->send(frame("585#60171000")).ok());
  got = receive_one(*a);
  ASSERT_TRUE(got);
  EXPECT_EQ(to_candump(*got), "585#60171000");
}

TEST(UdpBus, ReceiveTimesOutWithoutFrames) {
  REQUIRE_ISOLATED_MULTICAST();
  auto bus = open_udp(47002);
  ASSERT_TRUE(bus);
  const auto start = std::chrono::steady_clock::now();
  auto r = bus->receive(50ms);
  const auto waited = std::chrono::steady_clock::now() - start;
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->has_value());
  EXPECT_GE(waited, 50ms);
  EXPECT_LT(waited, 1s);
}

TEST(UdpBus, GroupsOnOnePortStayApart) {
  REQUIRE_ISOLATED_MULTICAST();
  auto a = open_udp(47004, "239.74.163.2");
  auto other = open_udp(47004, "239.74.163.3");
  auto b = open_udp(47004, "239.74.163.2");
  ASSERT_TRUE(a && other && b);
  ASSERT_TRUE(a->send(frame("181#01")).ok());
  auto got = receive_one(*b);
  ASSERT_TRUE(got);
  EXPECT_EQ(to_candump(*got), "181#01");
  auto r = other->receive(100ms);
  ASSERT_TRUE(r.ok());
  EXPECT_FALSE(r->has_value()) << to_candump((*r)->frame);
}

TEST(UdpBus, SendRefusesInvalidFrameAndSendsNothing) {
  REQUIRE_ISOLATED_MULTICAST();
  auto a = open_udp(47005);
  auto b = open_udp(47005);
  ASSERT_TRUE(a && b);
  CanFrame bad = frame("7FF#");
  bad.id = 0x800;  // python-can: "Normal arbitration IDs must be less than 2^11"
  auto st = a->send(bad);
  ASSERT_FALSE(st.ok());
  EXPECT_NE(st.error().message.find("udp://239.74.163.2:47005"), std::string::npos)
      << st.error().message;
  ASSERT_TRUE(a->send(frame("123#")).ok());
  auto got = receive_one(*b);
  ASSERT_TRUE(got);
  EXPECT_EQ(to_candump(*got), "123#");
}

TEST(UdpBus, OpenFailsOnAnAddressThatIsNotLocal) {
  REQUIRE_ISOLATED_MULTICAST();
  UdpBusOptions options;
  options.port = 47006;
  options.interface_address = "192.0.2.1";  // RFC 5737 TEST-NET-1, never local here
  auto bus = UdpBus::open(options);
  ASSERT_FALSE(bus.ok());
  EXPECT_NE(bus.error().message.find("192.0.2.1"), std::string::npos) << bus.error().message;
}

// socket(7), SO_TIMESTAMPNS: the kernel stamps a datagram as it reaches the socket, so a datagram
// read late keeps the time it arrived (engines judge by when frames arrived).
TEST(UdpBus, TimestampIsWhenTheDatagramArrivedNotWhenItWasRead) {
  REQUIRE_ISOLATED_MULTICAST();
  auto a = open_udp(47003);
  auto b = open_udp(47003);
  ASSERT_TRUE(a && b);
  const TimePoint before = wall_clock_now();
  ASSERT_TRUE(a->send(frame("705#05")).ok());
  const TimePoint sent = wall_clock_now();
  std::this_thread::sleep_for(300ms);  // the datagram waits in b's socket
  auto r = b->receive(2s);
  ASSERT_TRUE(r.ok() && r->has_value());
  EXPECT_EQ((*r)->clock, StampClock::Realtime);
  EXPECT_GE((*r)->timestamp, before);
  EXPECT_LE((*r)->timestamp, sent + 100ms);  // on loopback it arrives as it is sent
}

TEST(UdpBus, OpensThroughOpenBus) {
  REQUIRE_ISOLATED_MULTICAST();
  auto bus = open_bus("udp://239.74.163.2:47007");
  ASSERT_TRUE(bus.ok()) << bus.error().message;
  EXPECT_EQ((*bus)->url(), "udp://239.74.163.2:47007");
  auto defaults = open_bus("udp://");
  ASSERT_TRUE(defaults.ok()) << defaults.error().message;
  EXPECT_EQ((*defaults)->url(), "udp://239.74.163.2:43113");
}

// The frames both directions exchange with python-can, and how python-can prints them
// (can_peer.py: id ext rtr err dlc data).
struct Exchange {
  const char* ours;    // candump text on our side
  const char* python;  // can_peer.py frame text
  const char* shown;   // python-can's view
};
const std::vector<Exchange> kExchanges = {
    {"000#", "000#", "0 0 0 0 0 -"},
    {"181#11", "181#11", "181 0 0 0 1 11"},
    {"182#1122", "182#1122", "182 0 0 0 2 1122"},
    {"183#112233", "183#112233", "183 0 0 0 3 112233"},
    {"184#11223344", "184#11223344", "184 0 0 0 4 11223344"},
    {"185#1122334455", "185#1122334455", "185 0 0 0 5 1122334455"},
    {"186#112233445566", "186#112233445566", "186 0 0 0 6 112233445566"},
    {"187#11223344556677", "187#11223344556677", "187 0 0 0 7 11223344556677"},
    {"7FF#1122334455667788", "7FF#1122334455667788", "7FF 0 0 0 8 1122334455667788"},
    {"00000001#", "00000001#", "1 1 0 0 0 -"},
    {"1FFFFFFF#CAFE", "1FFFFFFF#CAFE", "1FFFFFFF 1 0 0 2 CAFE"},
    {"705#R", "705#R", "705 0 1 0 0 -"},
    {"705#R1", "705#R1", "705 0 1 0 1 -"},
    {"12345678#R8", "12345678#R8", "12345678 1 1 0 8 -"},
    // Error frame, class CAN_ERR_BUSERROR (linux/can/error.h), as SocketCanBus reports it.
    {"20000080#0000000000000000", "E80#0000000000000000", "80 1 0 1 8 0000000000000000"},
};

TEST(UdpBus, PythonCanReceivesOurFrames) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  auto bus = open_udp(47010);
  ASSERT_TRUE(bus);
  PythonPeer peer({"recv", "239.74.163.2", "47010", std::to_string(kExchanges.size()), "5"});
  ASSERT_EQ(peer.read_line(), "READY");
  std::vector<std::string> expected;
  for (const auto& e : kExchanges) {
    ASSERT_TRUE(bus->send(frame(e.ours)).ok()) << e.ours;
    expected.push_back(e.shown);
  }
  EXPECT_EQ(peer.read_all(), expected);
  EXPECT_EQ(peer.finish(), 0);
}

TEST(UdpBus, WeReceivePythonCanFrames) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  auto bus = open_udp(47011);
  ASSERT_TRUE(bus);
  std::vector<std::string> args = {"send", "239.74.163.2", "47011"};
  std::vector<std::string> expected;
  for (const auto& e : kExchanges) {
    args.push_back(e.python);
    expected.push_back(e.ours);
  }
  auto run = run_python_peer(args);
  ASSERT_EQ(run.exit_code, 0);
  std::vector<std::string> got;
  while (got.size() < expected.size()) {
    auto f = receive_one(*bus);
    if (!f) break;
    got.push_back(to_candump(*f));
  }
  EXPECT_EQ(got, expected);
  EXPECT_EQ(bus->counters().rejected, 0u) << bus->last_rejection();
}

// 127 frames back to back: the largest SDO block (CiA 301 §7.2.4.3.9, blksize 1..127).
std::string burst_frame(int i) {
  char text[32];
  std::snprintf(text, sizeof text, "5C5#%02X000000000000%02X", i, 127 - i);
  return text;
}

TEST(UdpBus, BurstArrivesInOrderAtPythonCan) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  auto bus = open_udp(47012);
  ASSERT_TRUE(bus);
  PythonPeer peer({"recv", "239.74.163.2", "47012", "127", "10"});
  ASSERT_EQ(peer.read_line(), "READY");
  std::vector<std::string> expected;
  for (int i = 0; i < 127; ++i) {
    ASSERT_TRUE(bus->send(frame(burst_frame(i))).ok());
    char shown[64];
    std::snprintf(shown, sizeof shown, "5C5 0 0 0 8 %02X000000000000%02X", i, 127 - i);
    expected.push_back(shown);
  }
  EXPECT_EQ(peer.read_all(), expected);
  EXPECT_EQ(peer.finish(), 0);
}

TEST(UdpBus, BurstFromPythonCanArrivesInOrder) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  auto bus = open_udp(47013);
  ASSERT_TRUE(bus);
  std::vector<std::string> args = {"send", "239.74.163.2", "47013"};
  std::vector<std::string> expected;
  for (int i = 0; i < 127; ++i) {
    args.push_back(burst_frame(i));
    expected.push_back(burst_frame(i));
  }
  ASSERT_EQ(run_python_peer(args).exit_code, 0);
  std::vector<std::string> got;
  while (got.size() < expected.size()) {
    auto f = receive_one(*bus);
    if (!f) break;
    got.push_back(to_candump(*f));
  }
  EXPECT_EQ(got, expected);
}

// Sends raw bytes to the group from a plain UDP socket on lo.
void send_raw(std::uint16_t port, std::span<const std::uint8_t> bytes) {
  const int fd = ::socket(AF_INET, SOCK_DGRAM, 0);
  ASSERT_GE(fd, 0);
  in_addr lo{};
  lo.s_addr = htonl(INADDR_LOOPBACK);
  ASSERT_EQ(setsockopt(fd, IPPROTO_IP, IP_MULTICAST_IF, &lo, sizeof lo), 0);
  sockaddr_in to{};
  to.sin_family = AF_INET;
  to.sin_port = htons(port);
  inet_pton(AF_INET, "239.74.163.2", &to.sin_addr);
  EXPECT_EQ(
      ::sendto(fd, bytes.data(), bytes.size(), 0, reinterpret_cast<sockaddr*>(&to), sizeof to),
      static_cast<ssize_t>(bytes.size()));
  ::close(fd);
}

TEST(UdpBus, MalformedDatagramsAreCountedAndSkipped) {
  REQUIRE_ISOLATED_MULTICAST();
  REQUIRE_PYTHON_CAN();
  auto bus = open_udp(47014);
  ASSERT_TRUE(bus);
  const std::vector<std::vector<std::uint8_t>> junk = {
      {},
      {'h', 'e', 'l', 'l', 'o'},
      {0xdd, 0xff, 0xff, 0xff, 0xff},
      {0x81, 0xa5, 'i', 's', '_', 'f', 'd', 0xc3},  // {"is_fd": true}
      std::vector<std::uint8_t>(5000, 0x90),        // longer than python-can's 4096-byte buffer
  };
  for (const auto& j : junk) send_raw(47014, j);
  ASSERT_EQ(run_python_peer({"send", "239.74.163.2", "47014", "123#C0FFEE"}).exit_code, 0);
  auto got = receive_one(*bus);
  ASSERT_TRUE(got);
  EXPECT_EQ(to_candump(*got), "123#C0FFEE");
  EXPECT_EQ(bus->counters().rejected, junk.size());
  EXPECT_FALSE(bus->last_rejection().empty());
}

}  // namespace
}  // namespace nmt
