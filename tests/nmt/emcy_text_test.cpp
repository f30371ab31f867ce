// The words of emergencies (nmt/protocol/emcy_text.hpp) and of the master's emergency events
// (describe, nmt/master/master_event_text.hpp). The code words are CiA 301 Table 21's
// (emergency error codes), as CANopenNode's CO_Emergency.h and openCANopen's
// cia302-error-codes.h list them; the register bits CiA 301 §7.5.2.2's; the CiA 402 codes
// IEC 61800-7-201's (openCANopen's cia402-error-codes.h), the CiA 401 codes CANopenNode's
// CO_EMC401_*.
#include <gtest/gtest.h>

#include <chrono>
#include <string>

#include "nmt/master/master_event_text.hpp"
#include "nmt/protocol/emcy_text.hpp"

namespace nmt {
namespace {

using Kind = MasterEvent::Kind;

constexpr cfg::NodeId node(std::uint8_t id) {
  return *cfg::NodeId::from(id);
}

TEST(EmcyText, Cia301CodesHaveTheirOwnWords) {
  EXPECT_EQ(emcy_code_words(0x0000), "error reset or no error");
  EXPECT_EQ(emcy_code_words(0x1000), "generic error");
  EXPECT_EQ(emcy_code_words(0x8110), "CAN overrun (objects lost)");
  EXPECT_EQ(emcy_code_words(0x8120), "CAN in error passive mode");
  EXPECT_EQ(emcy_code_words(0x8130), "life guard error or heartbeat error");
  EXPECT_EQ(emcy_code_words(0x8140), "recovered from bus off");
  EXPECT_EQ(emcy_code_words(0x8150), "CAN-ID collision");
  EXPECT_EQ(emcy_code_words(0x8210), "PDO not processed due to length error");
  EXPECT_EQ(emcy_code_words(0x8220), "PDO length exceeded");
  EXPECT_EQ(emcy_code_words(0x8230), "DAM MPDO not processed, destination object not available");
  EXPECT_EQ(emcy_code_words(0x8240), "unexpected SYNC data length");
  EXPECT_EQ(emcy_code_words(0x8250), "RPDO timeout");
}

TEST(EmcyText, OtherCodesHaveTheirClassWords) {
  EXPECT_EQ(emcy_code_words(0x2001), "current");
  EXPECT_EQ(emcy_code_words(0x2310), "current, device output side");
  EXPECT_EQ(emcy_code_words(0x3210), "voltage inside the device");
  EXPECT_EQ(emcy_code_words(0x4310), "temperature");
  EXPECT_EQ(emcy_code_words(0x5000), "device hardware");
  EXPECT_EQ(emcy_code_words(0x6010), "device software");
  EXPECT_EQ(emcy_code_words(0x7121), "additional modules");
  EXPECT_EQ(emcy_code_words(0x8611), "monitoring");
  EXPECT_EQ(emcy_code_words(0x9000), "external error");
  EXPECT_EQ(emcy_code_words(0xF001), "additional functions");
  EXPECT_EQ(emcy_code_words(0xFF42), "device specific");
}

TEST(EmcyText, Cia402DriveCodesAreReadInTheProfile) {
  constexpr std::uint32_t kDrive = 0x00020192;  // 1000h of a CiA 402 servo drive
  EXPECT_EQ(emcy_profile_words(0x2310, kDrive), "continuous over-current (device output side)");
  EXPECT_EQ(emcy_profile_words(0x3210, kDrive), "DC link over-voltage");
  EXPECT_EQ(emcy_profile_words(0x3220, kDrive), "DC link under-voltage");
  EXPECT_EQ(emcy_profile_words(0x4310, kDrive), "excess temperature drive");
  EXPECT_EQ(emcy_profile_words(0x7121, kDrive), "motor blocked");
  EXPECT_EQ(emcy_profile_words(0x8611, kDrive), "following error");
  EXPECT_EQ(emcy_profile_words(0xFF00, kDrive), std::nullopt);
  EXPECT_EQ(describe_emcy_code(0x8611, kDrive), "8611h following error (CiA 402); monitoring");
  EXPECT_EQ(describe_emcy_code(0x8611, std::nullopt), "8611h monitoring");
}

TEST(EmcyText, Cia401IoCodesAreReadInTheProfile) {
  constexpr std::uint32_t kIo = 0x000F0191;  // 1000h of a CiA 401 module (inputs and outputs)
  EXPECT_EQ(emcy_profile_words(0x2310, kIo), "current at outputs too high (overload)");
  EXPECT_EQ(emcy_profile_words(0x3120, kIo), "input voltage too low");
  EXPECT_EQ(emcy_profile_words(0x2310, 0x00000000), std::nullopt);
}

TEST(EmcyText, ErrorRegisterBitsInWords) {
  EXPECT_EQ(describe_error_register(0x00), "none");
  EXPECT_EQ(describe_error_register(0x11), "generic, communication");
  EXPECT_EQ(describe_error_register(0xFF),
            "generic, current, voltage, temperature, communication, device profile specific, "
            "reserved, manufacturer specific");
}

MasterEvent emergency(std::uint16_t code, std::uint8_t reg) {
  MasterEvent e{Kind::Emergency};
  e.node_id = node(3);
  e.emergency = MasterEvent::EmergencyReport{.emcy = {code, reg, {0x01, 0x02, 0x03, 0x04, 0xFF}}};
  return e;
}

TEST(EmcyText, DescribeEmergencySaysNodeCodeRegisterAndBytes) {
  EXPECT_EQ(describe(emergency(0x8130, 0x11)),
            "node 3: emergency 8130h life guard error or heartbeat error; error register 11h "
            "(generic, communication); manufacturer bytes 01 02 03 04 FF");
}

TEST(EmcyText, DescribeErrorResetSaysItEnds) {
  auto e = emergency(0x0000, 0x00);
  e.emergency->ends_error = true;
  EXPECT_EQ(describe(e),
            "node 3: emergency ended: 0000h error reset or no error; error register 00h (none); "
            "manufacturer bytes 01 02 03 04 FF");
}

TEST(EmcyText, DescribeFloodSaysTheCountAndTheBound) {
  MasterEvent e{Kind::EmergencyFlood};
  e.node_id = node(3);
  e.emergency = MasterEvent::EmergencyReport{.emcy = {0x8130, 0x11, {}},
                                             .suppressed = 9995,
                                             .window = std::chrono::seconds(1),
                                             .max_per_window = 5};
  EXPECT_EQ(describe(e),
            "node 3: 9995 more emergencies 8130h life guard error or heartbeat error not "
            "reported (at most 5 per 1000 ms per node and code)");
}

TEST(EmcyText, BootErrorSaysTheEmergencySentDuringTheBoot) {
  MasterEvent e{Kind::BootError};
  e.node_id = node(3);
  e.error = BootError::K;
  e.failure = BootFailure{.reason = BootFailure::Reason::NoFirstHeartbeat, .consumer_time_ms = 300};
  e.boot_emergency = MasterEvent::EmergencyReport{.emcy = {0x8130, 0x11, {}}};
  EXPECT_EQ(describe_boot_error(e),
            std::string(describe(BootError::K)) +
                " (no heartbeat within the consumer time of 300 ms (1016h)); the node sent "
                "emergency 8130h life guard error or heartbeat error during its boot");
}

}  // namespace
}  // namespace nmt
