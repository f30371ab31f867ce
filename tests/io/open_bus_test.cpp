// nmt::open_bus: URL dispatch and its messages. Opening a UDP bus sends nothing but joins a
// group, so that case runs with the other multicast tests (UdpBus.OpensThroughOpenBus).
#include <gtest/gtest.h>

#include <cerrno>

#include <string>

#include "nmt/io/bus.hpp"

namespace nmt {
namespace {

void expect_names_url_and_forms(const std::string& url) {
  auto bus = open_bus(url);
  ASSERT_FALSE(bus.ok()) << url;
  const std::string& message = bus.error().message;
  EXPECT_NE(message.find("'" + url + "'"), std::string::npos) << message;
  EXPECT_NE(message.find("socketcan:IFNAME"), std::string::npos) << message;
  EXPECT_NE(message.find("udp://GROUP:PORT"), std::string::npos) << message;
}

// A full transmit queue is back-pressure (ENOBUFS from the qdisc, net/can/af_can.c
// can_send; EAGAIN from a full socket buffer), a vanished or downed interface ends the loop,
// anything else is retried.
TEST(SendStatusOfErrno, TellsBackPressureAVanishedInterfaceAndOtherFailuresApart) {
  using S = SendResult::Status;
  EXPECT_EQ(send_status_of_errno(ENOBUFS), S::QueueFull);
  EXPECT_EQ(send_status_of_errno(EAGAIN), S::QueueFull);
  EXPECT_EQ(send_status_of_errno(EWOULDBLOCK), S::QueueFull);
  EXPECT_EQ(send_status_of_errno(ENODEV), S::InterfaceGone);
  EXPECT_EQ(send_status_of_errno(ENXIO), S::InterfaceGone);
  EXPECT_EQ(send_status_of_errno(ENETDOWN), S::InterfaceGone);
  EXPECT_EQ(send_status_of_errno(EIO), S::Failed);
  EXPECT_EQ(send_status_of_errno(EMSGSIZE), S::Failed);
}

TEST(OpenBus, RejectsUnknownSchemesNamingTheAcceptedForms) {
  for (const char* url : {"", "can0", "tcp://239.74.163.2:43113", "UDP://239.74.163.2:43113",
                          "socketcan", "virtual:0"}) {
    expect_names_url_and_forms(url);
  }
}

TEST(OpenBus, RejectsSocketcanWithoutAValidInterfaceName) {
  for (const char* url :
       {"socketcan:", "socketcan:a/b", "socketcan:can 0", "socketcan:sixteen_chars_xx"}) {
    expect_names_url_and_forms(url);
  }
}

TEST(OpenBus, RejectsBadUdpUrls) {
  for (const char* url : {"udp://10.0.0.1:43113", "udp://239.74.163.2:99999", "udp://[ff15::1]"}) {
    auto bus = open_bus(url);
    ASSERT_FALSE(bus.ok()) << url;
    EXPECT_NE(bus.error().message.find(url), std::string::npos) << bus.error().message;
    EXPECT_NE(bus.error().message.find("udp://GROUP:PORT"), std::string::npos);
  }
}

// Syntax alone, nothing opened: a tool tells a mistyped URL (usage) from an absent bus (I/O).
// Linux interface names are 1..15 bytes (IFNAMSIZ 16 with the NUL), without '/' or whitespace.
TEST(OpenBus, CheckBusUrlJudgesSyntaxWithoutOpening) {
  EXPECT_TRUE(check_bus_url("socketcan:nosuchcan9").ok());  // exists or not: not asked
  EXPECT_TRUE(check_bus_url("udp://239.74.163.2:43113").ok());
  EXPECT_FALSE(check_bus_url("socketcan:").ok());
  EXPECT_FALSE(check_bus_url("socketcan:0123456789abcdef").ok());  // 16 bytes
  EXPECT_FALSE(check_bus_url("socketcan:a/b").ok());
  EXPECT_FALSE(check_bus_url("udp://239.74.163.2:notaport").ok());
  EXPECT_FALSE(check_bus_url("carrier-pigeon:1").ok());
}

TEST(OpenBus, SocketcanInterfaceThatDoesNotExistFailsNamingTheUrl) {
  // Fails either for lack of CAN support or because there is no such interface; no frame is
  // sent in either case.
  auto bus = open_bus("socketcan:nmtnosuch0");
  ASSERT_FALSE(bus.ok());
  EXPECT_NE(bus.error().message.find("socketcan:nmtnosuch0"), std::string::npos)
      << bus.error().message;
}

}  // namespace
}  // namespace nmt
