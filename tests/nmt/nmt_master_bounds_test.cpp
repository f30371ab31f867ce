// Memory a peer on the bus can make the NMT master use is bounded (the choice "Memory a
// peer can make the master use" at the top of nmt/master/nmt_master.hpp). Beyond a bound the
// request is refused with 0504 0005h, CiA 301 §7.2.4.3.17 "Out of memory": the configuration
// manager's files (1F20h, 1F22h, 1F23h: DSP 302 §6) by cfg::ConfigManagerLimits, at the initiate
// request when the download indicates its size, else as soon as the data received passes the limit;
// the NMT commands 1F82h queues behind the inhibit time 102Ah (CiA 302-2 §6.1, §6.4) by
// MasterOptions::max_queued_nmt_requests. The SDO manager's bounds are in sdo_manager_test.cpp.
//
// The rig (nmt_master_spec_test_rig.hpp): the master at node 1 with slaves 2 and 3, the tool as
// the master's SDO client (601h/581h); raw SDO frames are written out from CiA 301 §7.2.4.3.
#include <gtest/gtest.h>

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "cfg/config_manager.hpp"
#include "nmt_master_spec_test_rig.hpp"

namespace nmt::master_spec {
namespace {

using Kind = MasterEvent::Kind;

// CiA 301 §7.2.4.3.17: "Out of memory".
constexpr std::uint32_t kOutOfMemory = 0x05040005;
constexpr std::uint32_t kToolRequestId = 0x601;
constexpr std::uint32_t kMasterResponseId = 0x581;
// The master's abort of a 1F22h sub 05h download with 0504 0005h (cs 80h, index, sub, code).
constexpr const char* kOutOfMemoryAbort = "581#80221F0505000405";

/// A concise DCF stream (DSP 302 §6.2) of `total` bytes: count 1, then 2002h sub 0 (a DOMAIN of
/// slave.eds) with 4 + 7 bytes of framing before its data.
std::vector<std::uint8_t> stream_of_size(std::size_t total, std::uint8_t fill = 0x5A) {
  std::vector<std::uint8_t> stream = le(1, 4);
  for (auto b : le(0x2002, 2)) stream.push_back(b);
  stream.push_back(0);
  for (auto b : le(total - 11, 4)) stream.push_back(b);
  stream.resize(total, fill);
  return stream;
}

SdoTransferOptions by(SdoMode mode) {
  SdoTransferOptions o;
  o.mode = mode;
  return o;
}

/// The master with a configuration manager of the given limits, start-up complete.
struct BoundsRig {
  explicit BoundsRig(cfg::ConfigManagerLimits limits) {
    manager->set_limits(limits);
    rig.options.manager = manager;
    rig.add_slave(2);
    rig.add_slave(3);
    rig.power_on_network();
    EXPECT_TRUE(rig.run_until_kind(Kind::StartupComplete, 10s));
  }
  /// The frames of `id` from `from` on, as candump text.
  std::vector<std::string> frames(std::uint32_t id, TimePoint from) const {
    std::vector<std::string> out;
    for (const auto& s : rig.on_id(id, from)) out.push_back(s.text());
    return out;
  }
  /// Sends a raw request to the master's default SDO and lets it answer.
  void request(const std::string& candump) {
    rig.send_foreign(candump);
    rig.run_for(1ms);
  }
  bool aborted_since(TimePoint from) const {
    for (const auto& s : rig.on_id(kMasterResponseId, from)) {
      if (s.frame.data[0] == 0x80) return true;
    }
    return false;
  }

  std::shared_ptr<cfg::ConfigManager> manager = std::make_shared<cfg::ConfigManager>();
  MasterRig rig;
};

TEST(MasterBounds, StreamOf1F22hWritesForEveryNodeStaysWithinTheTotalAndTheNextAbortsOutOfMemory) {
  BoundsRig s({.max_entry_bytes = 1024, .max_total_bytes = std::size_t{8} * 1024});
  // A tool writes the largest stream the manager takes for every node-ID, by block download
  // (size indicated), and then the first node again.
  std::vector<std::uint8_t> accepted;
  for (unsigned n = 1; n <= 127; ++n) {
    const auto node = static_cast<std::uint8_t>(n);
    const auto written =
        s.rig.tool_write(0x1F22, node, stream_of_size(1024, node), by(SdoMode::Block));
    if (written.ok()) {
      accepted.push_back(node);
    } else {
      EXPECT_EQ(static_cast<std::uint32_t>(written.abort), kOutOfMemory) << "node " << n;
      EXPECT_TRUE(written.aborted_by_server);
    }
    EXPECT_LE(s.manager->value_bytes(), 8U * 1024) << "node " << n;
  }
  EXPECT_EQ(accepted, (std::vector<std::uint8_t>{1, 2, 3, 4, 5, 6, 7, 8}));
  // A node's entry is replaced in place: within the total.
  ASSERT_TRUE(s.rig.tool_write(0x1F22, 1, stream_of_size(1024, 0xEE), by(SdoMode::Block)).ok());
  EXPECT_EQ(s.manager->value_bytes(), 8U * 1024);
  // After the refusals normal writes work: a smaller stream for node 2 (by segmented download)
  // makes room, and node 9 then fits.
  const auto small = stream_of_size(100);
  ASSERT_TRUE(s.rig.tool_write(0x1F22, 2, small, by(SdoMode::Segmented)).ok());
  EXPECT_EQ(s.rig.tool_read(0x1F22, 2).data, small);
  ASSERT_TRUE(s.rig.tool_write(0x1F22, 9, stream_of_size(900), by(SdoMode::Block)).ok());
  EXPECT_EQ(s.rig.tool_read(0x1F22, 9).data, stream_of_size(900));
}

// CiA 301 §7.2.4.3.3/§7.2.4.3.9: the initiate request of a segmented (s = 1) or block download
// indicates the size; one above max_entry_bytes is refused in the answer to that request,
// before any data is sent.
TEST(MasterBounds, TooLargeWriteIsRefusedAtTheInitiateWhenTheSizeIsIndicated) {
  BoundsRig s({.max_entry_bytes = 1024, .max_total_bytes = 1 << 20});
  for (auto mode : {SdoMode::Segmented, SdoMode::Block}) {
    s.rig.run_for(1ms);  // the frames of the last transfer are before `from`
    const TimePoint from = s.rig.bus.now();
    const auto written = s.rig.tool_write(0x1F22, 5, stream_of_size(1025), by(mode));
    EXPECT_EQ(static_cast<std::uint32_t>(written.abort), kOutOfMemory);
    EXPECT_TRUE(written.aborted_by_server);
    EXPECT_EQ(s.frames(kToolRequestId, from).size(), 1U) << "only the initiate request";
    EXPECT_EQ(s.frames(kMasterResponseId, from), std::vector<std::string>{kOutOfMemoryAbort});
  }
  EXPECT_FALSE(s.manager->has_configuration(*cfg::NodeId::from(5)));
  // The limit itself is fine.
  EXPECT_TRUE(s.rig.tool_write(0x1F22, 5, stream_of_size(1024), by(SdoMode::Segmented)).ok());
}

// A segmented download without indicated size (initiate 20h: ccs 1, e = 0, s = 0): each full
// segment carries 7 bytes; 146 segments are 1022 bytes, the 147th would make 1029 > 1024 and is
// answered with the abort instead of a segment response.
TEST(MasterBounds, SegmentedWriteWithoutSizeIsRefusedWhenItsDataPassesTheLimit) {
  BoundsRig s({.max_entry_bytes = 1024, .max_total_bytes = 1 << 20});
  const TimePoint from = s.rig.bus.now();
  s.request("601#20221F0500000000");
  ASSERT_EQ(s.frames(kMasterResponseId, from), std::vector<std::string>{"581#60221F0500000000"});
  unsigned segments = 0;
  bool toggle = false;
  while (!s.aborted_since(from) && segments < 400) {
    // Download segment: t in bit 4, n = 0 (7 bytes), c = 0.
    s.request(std::string("601#") + (toggle ? "10" : "00") + "5A5A5A5A5A5A5A");
    toggle = !toggle;
    ++segments;
  }
  EXPECT_EQ(segments, 147U);
  const auto answers = s.frames(kMasterResponseId, from);
  ASSERT_EQ(answers.size(), 1U + 147U);
  EXPECT_EQ(answers.back(), kOutOfMemoryAbort);
  EXPECT_FALSE(s.manager->has_configuration(*cfg::NodeId::from(5)));
  // The channel is free again: a normal write works.
  EXPECT_TRUE(s.rig.tool_write(0x1F22, 5, stream_of_size(1024), by(SdoMode::Segmented)).ok());
  EXPECT_EQ(s.manager->concise(*cfg::NodeId::from(5)), stream_of_size(1024));
}

// The same by block download without indicated size (initiate C0h: ccs 6, s = 0). The last
// segment may carry up to 6 bytes of padding, so a segment counts as at least 1 byte: after 147
// segments (1029 bytes, of which 1024 may be data) the 148th passes the limit.
TEST(MasterBounds, BlockWriteWithoutSizeIsRefusedWhenItsDataPassesTheLimit) {
  BoundsRig s({.max_entry_bytes = 1024, .max_total_bytes = 1 << 20});
  const TimePoint from = s.rig.bus.now();
  s.request("601#C0221F0500000000");
  const auto initiate = s.frames(kMasterResponseId, from);
  ASSERT_EQ(initiate.size(), 1U);
  // scs 5, sc = 1 (CRC), the index and sub, blksize.
  ASSERT_EQ(initiate[0].substr(0, 12), "581#A4221F05");
  const unsigned block_size = s.rig.on_id(kMasterResponseId, from)[0].frame.data[4];
  ASSERT_GE(block_size, 1U);
  unsigned segments = 0;
  unsigned seq = 0;
  while (!s.aborted_since(from) && segments < 400) {
    seq = seq % block_size + 1;
    char head[9];  // seq is 1..127: two digits; room for any unsigned so -Wformat-truncation stays
                   // quiet
    std::snprintf(head, sizeof head, "%02X", seq);
    s.request(std::string("601#") + head + "5A5A5A5A5A5A5A");
    ++segments;
  }
  EXPECT_EQ(segments, 148U);
  EXPECT_EQ(s.frames(kMasterResponseId, from).back(), kOutOfMemoryAbort);
  EXPECT_FALSE(s.manager->has_configuration(*cfg::NodeId::from(5)));
  EXPECT_TRUE(s.rig.tool_write(0x1F22, 5, stream_of_size(1024), by(SdoMode::Block)).ok());
}

// CiA 302-2 §6.1: NMT services go out at least 102Ah apart; §6.4: 1F82h writes queue them. A
// peer may set 102Ah to its largest value (6.5535 s) and write 1F82h as fast as the bus allows:
// beyond MasterOptions::nmt.max_queued_requests the write is refused with 0504 0005, and once
// the queue drained, requests are taken again.
TEST(MasterBounds, RequestNmtBeyondTheQueueBoundIsRefusedOutOfMemory) {
  MasterRig rig;
  rig.options.nmt.max_queued_requests = 3;
  rig.two_slaves();
  ASSERT_TRUE(rig.run_until_kind(Kind::StartupComplete, 10s));
  ASSERT_EQ(rig.tool_write_u(0x102A, 0, 65535, 2), SdoAbort::None);
  const TimePoint from = rig.bus.now();
  // Table 28: 04h stop, 05h start (NMT command specifiers 02h and 01h, CiA 301 §7.2.8.3.1).
  // The start-up's last NMT command went out less than 102Ah ago, so every
  // request waits in the queue.
  EXPECT_EQ(rig.tool_write_u(0x1F82, 2, 0x04, 1), SdoAbort::None);
  EXPECT_EQ(rig.tool_write_u(0x1F82, 3, 0x04, 1), SdoAbort::None);
  EXPECT_EQ(rig.tool_write_u(0x1F82, 2, 0x05, 1), SdoAbort::None);
  EXPECT_EQ(static_cast<std::uint32_t>(rig.tool_write_u(0x1F82, 3, 0x05, 1)), kOutOfMemory);
  EXPECT_EQ(static_cast<std::uint32_t>(rig.tool_write_u(0x1F82, 0x80, 0x04, 1)), kOutOfMemory);
  // One command leaves per 6.5535 s; then there is room for one more.
  rig.run_for(7s);
  EXPECT_EQ(rig.nmt(from).size(), 1U);
  EXPECT_EQ(rig.tool_write_u(0x1F82, 3, 0x05, 1), SdoAbort::None);
  rig.run_for(20s);
  EXPECT_EQ(rig.nmt(from),
            (std::vector<std::string>{"000#0202", "000#0203", "000#0102", "000#0103"}));
}

}  // namespace
}  // namespace nmt::master_spec
