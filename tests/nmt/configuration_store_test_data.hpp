// What the tests of the configuration manager's objects (DSP 302 v3.2.1 §6) share: the master
// engine alone (configuration_store_objects_test.cpp) and composed in the NMT master
// (nmt_master_store_test.cpp). Streams are written out byte by byte from the §6.2 table
// (UNSIGNED32 count, then per entry UNSIGNED16 index, UNSIGNED8 sub-index, UNSIGNED32 size, data;
// little-endian as CiA 301 §7.1).
#pragma once

#include <gtest/gtest.h>

#include <unistd.h>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "nmt/master/master_options.hpp"
#include "scratch_dir.hpp"

namespace nmt::store_test {

using test_support::ScratchDir;

constexpr std::uint8_t kNode = 5;
// DSP 302 §6.4: "the signature 'conf' (this equals the UNSIGNED32 number 666E 6F63h)".
constexpr std::uint32_t kConf = 0x666E6F63;

// Node 5's configuration as a §6.2 stream: 3 entries, 2000h sub 0 = 1234h (UNSIGNED16),
// 1017h sub 0 = 200 ms (UNSIGNED16), 2001h sub 0 = "spindle" (VISIBLE_STRING, 7 bytes).
inline const std::vector<std::uint8_t> kStream = {
    0x03, 0x00, 0x00, 0x00,                                // number of entries
    0x00, 0x20, 0x00, 0x02, 0x00, 0x00, 0x00, 0x34, 0x12,  // 2000h sub 0, 2 bytes
    0x17, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0xC8, 0x00,  // 1017h sub 0, 2 bytes
    0x01, 0x20, 0x00, 0x07, 0x00, 0x00, 0x00,              // 2001h sub 0, 7 bytes
    's',  'p',  'i',  'n',  'd',  'l',  'e'};

// Node 5's configuration as the network gives it (nmt::NetworkSource): 2 entries, 2000h
// sub 0 = 5678h (UNSIGNED16), 1017h sub 0 = 300 ms (UNSIGNED16); 4 + 9 + 9 = 22 bytes.
inline const std::vector<std::uint8_t> kNetworkStream = {
    0x02, 0x00, 0x00, 0x00,                                 // number of entries
    0x00, 0x20, 0x00, 0x02, 0x00, 0x00, 0x00, 0x78, 0x56,   // 2000h sub 0, 2 bytes
    0x17, 0x10, 0x00, 0x02, 0x00, 0x00, 0x00, 0x2C, 0x01};  // 1017h sub 0, 2 bytes
inline const std::string kNetworkDcf =
    "[DeviceInfo]\r\nProductName=node 5 as the network has it\r\n";

/// A source that has node 5's configuration, its concise DCF and its DCF (as nmt::NetworkSource
/// has a network node's), and for node 6 a DCF it cannot read.
class NetworkLikeSource final : public ConfigurationSource {
 public:
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override {
    if (node.value() != kNode) return std::nullopt;
    return cfg::decode_concise_dcf(kNetworkStream).value();
  }
  std::optional<std::vector<std::uint8_t>> concise_dcf(cfg::NodeId node) const override {
    if (node.value() != kNode) return std::nullopt;
    return kNetworkStream;
  }
  cfg::Result<std::optional<std::string>> dcf(cfg::NodeId node) const override {
    if (node.value() == 6)
      return cfg::Error{"node6.dcf: cannot open the file", cfg::ErrorCategory::Io};
    if (node.value() != kNode) return std::optional<std::string>{};
    return std::optional<std::string>{kNetworkDcf};
  }
};

}  // namespace nmt::store_test
