// A simulated device (nmt::SlaveNode) answers an SDO download with the abort code libcfg's write
// rules give for that write (cfg/write_acceptance.hpp): one implementation, so `cfgmgr check`
// predicts what the device refuses. Device: tests/data/write_refusal/accepted.dcf (node 5; README
// there). The codes are those of the CiA 301 abort code table (§7.2.4.3.17), the PDO rules
// CiA 301 §7.5.2.35-38.
#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/write_acceptance.hpp"
#include "nmt/slave/slave_node.hpp"
#include "test_paths.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;

struct Write {
  const char* what;
  std::uint16_t index;
  std::uint8_t sub;
  std::vector<std::uint8_t> data;
  SdoAbort code;  // CiA 301
};

TEST(WriteAcceptanceParity, SlaveNodeAnswersTheCodeOfTheSharedRules) {
  auto read =
      cfg::read_device_file(std::string(CANOPEN_TEST_DATA_DIR) + "/write_refusal/accepted.dcf");
  ASSERT_TRUE(read.device) << read.diagnostics.format();
  const cfg::DeviceDescription& dcf = *read.device;
  auto node = SlaveNode::create(dcf, *cfg::NodeId::from(5));
  ASSERT_TRUE(node) << node.error().message;
  auto entries = cfg::device_entries(dcf, 5);
  ASSERT_TRUE(entries) << entries.error().message;

  const std::vector<Write> writes = {
      {"1000h is ro", 0x1000, 0, {0x91, 0x01, 0x03, 0x00}, SdoAbort::WriteOfReadOnly},
      {"no 2100h", 0x2100, 0, {1, 0}, SdoAbort::ObjectDoesNotExist},
      {"no 1018h sub 9", 0x1018, 9, {1, 0, 0, 0}, SdoAbort::SubIndexDoesNotExist},
      {"4 bytes to an UNSIGNED16", 0x2000, 0, {1, 2, 3, 4}, SdoAbort::LengthTooHigh},
      {"1 byte to an UNSIGNED16", 0x2000, 0, {1}, SdoAbort::LengthTooLow},
      {"2002h above HighLimit=100", 0x2002, 0, {101, 0}, SdoAbort::ValueTooHigh},
      {"2002h below LowLimit=1", 0x2002, 0, {0, 0}, SdoAbort::ValueTooLow},
      {"valid RPDO COB-ID to another", 0x1400, 1, {0x06, 0x02, 0, 0}, SdoAbort::ValueRangeExceeded},
      {"RPDO mapping while valid", 0x1600, 0, {0}, SdoAbort::DeviceState},
      {"1016h sub 1 = node 3, which sub 2 consumes",
       0x1016,
       1,
       {0x90, 0x01, 0x03, 0x00},
       SdoAbort::ParameterIncompatibility},
      {"1200h sub 1 other than 605h", 0x1200, 1, {0x06, 0x06, 0, 0}, SdoAbort::WriteOfReadOnly},
      {"2000h within its type", 0x2000, 0, {7, 0}, SdoAbort::None},
  };
  for (const Write& w : writes) {
    SCOPED_TRACE(w.what);
    const auto shared =
        cfg::check_device_write(*entries, {&dcf.dummy_usage}, w.index, w.sub, w.data);
    const SdoAbort device = (*node)->dictionary().write(w.index, w.sub, w.data, TimePoint{1s});
    EXPECT_EQ(device, w.code);
    EXPECT_EQ(shared.code, device) << shared.reason;
  }
}

}  // namespace
}  // namespace nmt
