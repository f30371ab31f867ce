// The words of DSP 302 §7.2.3 and the scene of the SDO manager's spec suites, shared by the
// whole-master suite (sdo_manager_spec_test.cpp) and the engine's
// (sdo_manager_engine_spec_test.cpp): node-IDs, object indices and the bit layouts of 1F10h,
// 1F00h/1F01h, 1F03h and 1F02h, written from the spec (../shared/spec/001_846495643a25878e.txt).
#pragma once

#include <cstdint>

namespace nmt::master_spec {

constexpr std::uint8_t kSrd = 127;         // §7.2.4 guideline 2: SRDs take the highest node-IDs
constexpr std::uint8_t kSrd2 = 126;        // a second SRD
constexpr std::uint8_t kSrd3 = 124;        // a third SRD
constexpr std::uint8_t kWithChannels = 2;  // slave_channels.eds: 1201h, 1202h
constexpr std::uint8_t kDefaultOnly = 3;   // slave.eds: 1200h only

// §7.2.1: "the Dynamic SDO Request ... is a data frame without data bytes. The COB-ID is 1760d."
constexpr std::uint32_t kDynamicSdoRequest = 1760;
static_assert(kDynamicSdoRequest == 0x6E0);
constexpr const char* kDynamicSdoRequestFrame = "6E0#";

// Object indices of §7.2.3 and CiA 301 (SDO parameters).
constexpr std::uint16_t kRequestSdo = 0x1F00;
constexpr std::uint16_t kReleaseSdo = 0x1F01;
constexpr std::uint16_t kPool = 0x1F02;
constexpr std::uint16_t kConnections = 0x1F03;
constexpr std::uint16_t kConnectionState = 0x1F10;
constexpr std::uint16_t kSlaveFailed = 0x1F11;
constexpr std::uint16_t kServerSdo = 0x1200;
constexpr std::uint16_t kClientSdo = 0x1280;

// 1F10h (§7.2.3): bits 31-16 index, 15-8 error code, bit 3 Req EC, bits 2-1 Cnxn state, bit 0 Rq
// indication, bits 7-4 reserved (0).
constexpr std::uint32_t kRq = 1U << 0U;
constexpr std::uint32_t kReqEc = 1U << 3U;
constexpr std::uint32_t cnxn(unsigned state) {
  return (state & 3U) << 1U;
}
constexpr std::uint32_t state_word(std::uint16_t index, std::uint8_t error, std::uint32_t bits) {
  return std::uint32_t{index} << 16U | std::uint32_t{error} << 8U | bits;
}
constexpr unsigned cnxn_of(std::uint32_t word) {
  return (word >> 1U) & 3U;
}
constexpr std::uint8_t error_of(std::uint32_t word) {
  return static_cast<std::uint8_t>(word >> 8U);
}
constexpr std::uint16_t index_of(std::uint32_t word) {
  return static_cast<std::uint16_t>(word >> 16U);
}
// §7.2.3 examples: xxxx0001h a request, xxxx0009h a request with Req EC, 00000003h all default
// SDOs.
static_assert(state_word(0x1280, 0, kRq) == 0x12800001);
static_assert(state_word(0x1280, 0, kRq | kReqEc) == 0x12800009);
static_assert(state_word(0, 0, kRq | cnxn(1)) == 0x00000003);

// 1F00h / 1F01h (§7.2.3): bits 31-16 the SRD's client SDO index, 15-8 SRD node-ID, 7-0 slave.
constexpr std::uint32_t request_word(std::uint16_t index, std::uint8_t srd, std::uint8_t slave) {
  return std::uint32_t{index} << 16U | std::uint32_t{srd} << 8U | slave;
}
// 1F03h row (§7.2.3): client offset (from 1280h), client node-ID, server offset (from 1200h),
// server node-ID.
constexpr std::uint32_t row_word(std::uint8_t client_offset, std::uint8_t client,
                                 std::uint8_t server_offset, std::uint8_t server) {
  return std::uint32_t{client_offset} << 24U | std::uint32_t{client} << 16U |
         std::uint32_t{server_offset} << 8U | server;
}

// 1F02h entries (§7.2.3): bit 31 not valid, bit 30 in use, bit 29 29-bit identifier.
constexpr std::uint32_t kNotValid = 0x80000000U;
constexpr std::uint32_t kInUse = 0x40000000U;
constexpr std::uint32_t kIdBits = 0x1FFFFFFFU;
constexpr std::uint32_t k29Bit = 0x20000000U;    // bit 29: a 29-bit identifier
constexpr std::uint8_t kPoolEntries = 9;         // manager.dcf 1F02h sub 0
constexpr std::uint32_t kInvalidPoolId = 0x689;  // sub 9, bit 31 set in the file

/// The COB-IDs and node-ID of an SRD's client entry (CiA 301 1280h.. sub 1..3).
struct ClientEntry {
  std::uint32_t request;   // sub 1, client -> server
  std::uint32_t response;  // sub 2, server -> client
  std::uint8_t server;     // sub 3
  bool valid() const { return (request & kNotValid) == 0 && (response & kNotValid) == 0; }
};

}  // namespace nmt::master_spec
