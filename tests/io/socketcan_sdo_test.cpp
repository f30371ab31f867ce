// Our SDO client over the SocketCAN driver against simulated devices that run in another process
// (`cfgmgr simulate --bus socketcan:vcan0 DEVICE.eds@NODE...`), through the kernel's CAN stack.
// The VM tier's hook tests/vm/guest.d/simulate_sdo.sh starts the simulator and runs these tests
// with CANOPEN_VM_SIMULATED_DEVICES set to the same "DEVICE.eds@NODE" list, blank-separated;
// without it (or without SocketCAN) every test skips.
//
// Expected values come from the device files, read with the project's reader and parse_value,
// never from what the simulator happens to answer. Protocols and abort codes: CiA 301 §7.2.4
// (public knowledge of CiA 301; not in spec/).
#include <gtest/gtest.h>
#include <linux/can.h>
#include <net/if.h>
#include <sys/socket.h>
#include <unistd.h>

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cstdlib>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/value.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/io/socketcan_bus.hpp"
#include "nmt/sdo/sdo.hpp"
#include "prerequisite.hpp"
#include "started.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

constexpr const char* kDevicesVariable = "CANOPEN_VM_SIMULATED_DEVICES";

std::string env_or(const char* name, const char* fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? v : fallback;
}

std::string can_if() {
  return env_or("CANOPEN_TEST_CAN_IF", "vcan0");
}

// Why these tests cannot run here, or an empty string when they can.
std::string unavailable(const std::string& ifname, const std::string& devices) {
  if (devices.empty()) {
    return std::string(kDevicesVariable) + " is not set: these tests need simulated devices on " +
           ifname + " (cfgmgr simulate --bus socketcan:" + ifname +
           " DEVICE.eds@NODE...); the VM tier (ctest -L vm) runs them from "
           "tests/vm/guest.d/simulate_sdo.sh";
  }
  const int fd = ::socket(PF_CAN, SOCK_RAW, CAN_RAW);
  if (fd < 0) return "no SocketCAN in this kernel (socket(PF_CAN, SOCK_RAW, CAN_RAW) failed)";
  ::close(fd);
  if (if_nametoindex(ifname.c_str()) == 0) return "interface " + ifname + " does not exist";
  return {};
}

// One device the simulator runs: its node-ID and the model of its device file.
struct SimulatedNode {
  std::uint8_t node_id = 0;
  std::string path;
  cfg::DeviceDescription device;
};

// Parses the "DEVICE.eds@NODE" list (the syntax of cfgmgr simulate; here the node-ID is
// required) and reads each device file. Failures are test failures, with the reason.
std::vector<SimulatedNode> read_simulated_nodes(const std::string& list) {
  std::vector<SimulatedNode> nodes;
  std::istringstream words(list);
  std::string word;
  while (words >> word) {
    const auto at = word.rfind('@');
    unsigned node = 0;
    const char* first = word.data() + (at == std::string::npos ? word.size() : at + 1);
    const char* last = word.data() + word.size();
    const auto [end, ec] = std::from_chars(first, last, node);
    if (at == std::string::npos || ec != std::errc{} || end != last || node < 1 || node > 127) {
      ADD_FAILURE() << kDevicesVariable << ": \"" << word << "\" is not DEVICE.eds@NODE";
      continue;
    }
    SimulatedNode n;
    n.node_id = static_cast<std::uint8_t>(node);
    n.path = word.substr(0, at);
    auto read = cfg::read_device_file(n.path);
    if (!read.ok()) {
      ADD_FAILURE() << n.path << ": " << read.diagnostics.format();
      continue;
    }
    n.device = std::move(*read.device);
    nodes.push_back(std::move(n));
  }
  return nodes;
}

// The bytes SDO carries for an entry's configured value in the device file (CiA 306 value text
// through parse_value, CiA 301 little-endian encoding), with $NODEID as the node's.
Bytes file_value(const SimulatedNode& node, std::uint16_t index, std::uint8_t sub) {
  const cfg::SubObject* entry = node.device.sub(index, sub);
  if (entry == nullptr || !entry->basic_type() || !entry->configured_value()) {
    ADD_FAILURE() << node.path << " has no value for " << std::hex << index << "h sub " << int{sub};
    return {};
  }
  auto value = cfg::parse_value(*entry->basic_type(), *entry->configured_value(), node.node_id);
  if (!value.ok()) {
    ADD_FAILURE() << node.path << ": " << value.error().message;
    return {};
  }
  return cfg::encode(*value);
}

// The first DOMAIN entry of the file that SDO may both write and read (nullptr: none).
const cfg::SubObject* writable_domain(const cfg::DeviceDescription& device, std::uint16_t& index) {
  for (const auto& [i, object] : device.objects) {
    for (const auto& [s, sub] : object.subs) {
      if (sub.basic_type() == cfg::DataType::Domain && cfg::is_writable(sub.access) &&
          cfg::is_readable(sub.access)) {
        index = i;
        return &sub;
      }
    }
  }
  return nullptr;
}

class SocketCanSdo : public ::testing::Test {
 protected:
  void SetUp() override {
    const std::string devices = env_or(kDevicesVariable, "");
    // Without simulated devices the test is not missing anything: it runs from the VM tier's
    // hook simulate_sdo.sh (which fails on any skip), so it skips plainly. Without SocketCAN or
    // the interface, with devices named, a prerequisite is missing.
    if (devices.empty()) GTEST_SKIP() << unavailable(can_if(), devices);
    if (auto why = unavailable(can_if(), devices); !why.empty()) PREREQUISITE_MISSING(why);
    nodes_ = read_simulated_nodes(devices);
    ASSERT_FALSE(nodes_.empty()) << kDevicesVariable << " names no device";
    auto bus = SocketCanBus::open(can_if());
    ASSERT_TRUE(bus.ok()) << bus.error().message;
    bus_ = std::move(bus).value();
    loop_ = std::make_unique<BusEventLoop>(*bus_);
    loop_->add(mux_ref_);
  }

  // Each SDO response may take this long. Generous: under TCG one emulated CPU runs the
  // simulator, this test and the paced vcan0 (tbf, about 1000 frames/s).
  static SdoTransferOptions options(SdoMode mode = SdoMode::Auto) {
    SdoTransferOptions o;
    o.timeout = 3s;
    o.mode = mode;
    return o;
  }

  // Runs the loop until no transfer is queued or running (at most 30 s of wall time).
  void run_until_idle() {
    const TimePoint give_up = loop_->now() + 30s;
    while (mux_.busy() && loop_->now() < give_up) {
      auto status = loop_->run_for(5ms);
      ASSERT_TRUE(status.ok()) << status.error().message;
    }
    ASSERT_FALSE(mux_.busy()) << "transfers still running after 30 s";
    // The clients' last frames (the end of a block upload) out of the loop's transmit queue,
    // which a full vcan0 queue (tbf) can hold back.
    auto sent = loop_->run_until_sent(1s);
    ASSERT_TRUE(sent.ok()) << sent.error().message;
  }

  // The result the mux reported for transfer `id` of `node_id`'s client.
  SdoResult take(std::uint8_t node_id, SdoClient::TransferId id) {
    auto it = results_.find({node_id, id});
    EXPECT_TRUE(it != results_.end())
        << "transfer " << id << " to node " << int{node_id} << " has no result";
    if (it == results_.end()) return SdoResult{};
    auto r = it->second;
    results_.erase(it);
    return r;
  }

  SdoClient::TransferId start_upload(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub,
                                     SdoTransferOptions o = options()) {
    return test_support::started(
        mux_ref_.apply([&](SdoClientMux& m, TimePoint now, SdoClientMux::Output& out) {
          return m.client(*cfg::NodeId::from(node_id)).upload(index, sub, now, out, o);
        }));
  }

  SdoResult upload(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub,
                   SdoTransferOptions o = options()) {
    const auto id = start_upload(node_id, index, sub, o);
    run_until_idle();
    return take(node_id, id);
  }

  SdoResult download(std::uint8_t node_id, std::uint16_t index, std::uint8_t sub, Bytes data,
                     SdoTransferOptions o = options()) {
    const auto id = test_support::started(
        mux_ref_.apply([&](SdoClientMux& m, TimePoint now, SdoClientMux::Output& out) {
          return m.client(*cfg::NodeId::from(node_id))
              .download(index, sub, std::move(data), now, out, o);
        }));
    run_until_idle();
    return take(node_id, id);
  }

  std::vector<SimulatedNode> nodes_;
  std::unique_ptr<SocketCanBus> bus_;
  SdoClientMux mux_;
  std::map<std::pair<std::uint8_t, SdoClient::TransferId>, SdoResult> results_;
  EngineRef<SdoClientMux> mux_ref_{mux_, [this](const SdoResult& r, TimePoint) {
                                     results_[{r.node_id ? r.node_id->value() : 0, r.id}] = r;
                                   }};
  std::unique_ptr<BusEventLoop> loop_;
};

TEST_F(SocketCanSdo, ExpeditedUploadOfDeviceTypeEqualsDeviceFile) {
  for (const auto& node : nodes_) {
    SCOPED_TRACE(node.path);
    const SdoResult r = upload(node.node_id, 0x1000, 0);
    ASSERT_TRUE(r.ok()) << r.abort;
    EXPECT_EQ(r.protocol, SdoProtocol::Expedited);  // 4 bytes fit one frame
    EXPECT_EQ(r.data, file_value(node, 0x1000, 0));
  }
}

TEST_F(SocketCanSdo, ExpeditedUploadOfVendorIdEqualsDeviceFile) {
  for (const auto& node : nodes_) {
    SCOPED_TRACE(node.path);
    const SdoResult r = upload(node.node_id, 0x1018, 1);
    ASSERT_TRUE(r.ok()) << r.abort;
    EXPECT_EQ(r.protocol, SdoProtocol::Expedited);
    EXPECT_EQ(r.data, file_value(node, 0x1018, 1));
  }
}

TEST_F(SocketCanSdo, ExpeditedDownloadOfHeartbeatTimeIsReadBack) {
  for (const auto& node : nodes_) {
    SCOPED_TRACE(node.path);
    // The hook may have set the heartbeat already: put back what was there.
    const SdoResult before = upload(node.node_id, 0x1017, 0);
    ASSERT_TRUE(before.ok()) << before.abort;
    ASSERT_EQ(before.data.size(), 2u);  // UNSIGNED16 (CiA 301 1017h)
    const Bytes written = before.data == Bytes{0xD2, 0x04} ? Bytes{0xD3, 0x04} : Bytes{0xD2, 0x04};

    const SdoResult w = download(node.node_id, 0x1017, 0, written);
    ASSERT_TRUE(w.ok()) << w.abort;
    EXPECT_EQ(w.protocol, SdoProtocol::Expedited);
    const SdoResult r = upload(node.node_id, 0x1017, 0);
    ASSERT_TRUE(r.ok()) << r.abort;
    EXPECT_EQ(r.data, written);

    const SdoResult restored = download(node.node_id, 0x1017, 0, before.data);
    EXPECT_TRUE(restored.ok()) << restored.abort;
  }
}

TEST_F(SocketCanSdo, SegmentedUploadOfDeviceNameEqualsDeviceFile) {
  bool any = false;
  for (const auto& node : nodes_) {
    if (node.device.sub(0x1008, 0) == nullptr) continue;
    SCOPED_TRACE(node.path);
    any = true;
    const Bytes expected = file_value(node, 0x1008, 0);
    const SdoResult r = upload(node.node_id, 0x1008, 0);
    ASSERT_TRUE(r.ok()) << r.abort;
    EXPECT_EQ(r.data, expected);
    // More than 4 bytes do not fit an expedited response.
    if (expected.size() > 4) {
      EXPECT_EQ(r.protocol, SdoProtocol::Segmented);
    }
  }
  if (!any) PREREQUISITE_MISSING("no simulated device has 1008h (manufacturer device name)");
}

TEST_F(SocketCanSdo, BlockDownloadOfDomainIsReadBackByBlockUpload) {
  bool any = false;
  for (const auto& node : nodes_) {
    std::uint16_t index = 0;
    const cfg::SubObject* domain = writable_domain(node.device, index);
    if (domain == nullptr) continue;
    SCOPED_TRACE(node.path);
    any = true;
    // 1000 bytes are 143 segments of 7: a full sub-block of 127 and a second one.
    Bytes data(1000);
    for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<std::uint8_t>(i * 7 + 3);

    const SdoResult w =
        download(node.node_id, index, domain->sub_index, data, options(SdoMode::Block));
    ASSERT_TRUE(w.ok()) << w.abort;
    EXPECT_EQ(w.protocol, SdoProtocol::Block);
    EXPECT_FALSE(w.fell_back);

    const SdoResult r = upload(node.node_id, index, domain->sub_index, options(SdoMode::Block));
    ASSERT_TRUE(r.ok()) << r.abort;
    EXPECT_EQ(r.protocol, SdoProtocol::Block);
    EXPECT_FALSE(r.fell_back);
    EXPECT_EQ(r.data, data);
  }
  if (!any) PREREQUISITE_MISSING("no simulated device has a writable DOMAIN");
}

TEST_F(SocketCanSdo, AccessToMissingObjectIsAbortedByServerWithObjectDoesNotExist) {
  for (const auto& node : nodes_) {
    SCOPED_TRACE(node.path);
    // The first manufacturer-specific index the device file does not define.
    std::uint16_t missing = 0x2000;
    while (node.device.object(missing) != nullptr) ++missing;

    const SdoResult r = upload(node.node_id, missing, 0);
    EXPECT_EQ(r.abort, SdoAbort::ObjectDoesNotExist);
    EXPECT_TRUE(r.aborted_by_server);
    // CiA 301 abort code table: 0602 0000 "object does not exist in the object dictionary".
    EXPECT_EQ(to_string(r.abort), "0x06020000 (object does not exist in the object dictionary)");

    const SdoResult w = download(node.node_id, missing, 0, Bytes{1, 2, 3, 4});
    EXPECT_EQ(w.abort, SdoAbort::ObjectDoesNotExist);
    EXPECT_TRUE(w.aborted_by_server);
  }
}

TEST_F(SocketCanSdo, TransfersToSeveralNodesRunAtTheSameTime) {
  if (nodes_.size() < 2) PREREQUISITE_MISSING("needs two simulated devices");
  // Every node's responses, in the order they came off the bus.
  std::vector<std::uint8_t> responders;
  loop_->set_observer([&](const CanFrame& f, TimePoint, BusEventLoop::Direction d) {
    if (d == BusEventLoop::Direction::Received && f.id > 0x580 && f.id < 0x600) {
      responders.push_back(static_cast<std::uint8_t>(f.id - 0x580));
    }
  });
  // Segmented uploads (several request/response rounds each) started together, then an
  // expedited one queued behind each.
  struct Started {
    const SimulatedNode* node;
    std::uint16_t index;
    SdoClient::TransferId id;
  };
  std::vector<Started> started;
  for (const auto& node : nodes_) {
    const std::uint16_t name_index = node.device.sub(0x1008, 0) != nullptr ? 0x1008 : 0x1000;
    started.push_back({&node, name_index, start_upload(node.node_id, name_index, 0)});
    started.push_back({&node, 0x1000, start_upload(node.node_id, 0x1000, 0)});
  }
  run_until_idle();
  loop_->set_observer({});

  for (const auto& s : started) {
    SCOPED_TRACE(s.node->path);
    const SdoResult r = take(s.node->node_id, s.id);
    ASSERT_TRUE(r.ok()) << r.abort;
    EXPECT_EQ(r.data, file_value(*s.node, s.index, 0));
  }
  // In flight at once: each node answered before another node's last answer, i.e. the
  // responses of different nodes interleave on the bus.
  for (const auto& a : nodes_) {
    for (const auto& b : nodes_) {
      if (a.node_id == b.node_id) continue;
      const auto first_a = std::find(responders.begin(), responders.end(), a.node_id);
      const auto last_b = std::find(responders.rbegin(), responders.rend(), b.node_id);
      ASSERT_NE(first_a, responders.end()) << "node " << int{a.node_id} << " never answered";
      ASSERT_NE(last_b, responders.rend()) << "node " << int{b.node_id} << " never answered";
      EXPECT_LT(first_a - responders.begin(), responders.rend() - last_b - 1)
          << "node " << int{a.node_id} << " answered only after node " << int{b.node_id}
          << " had finished";
    }
  }
}

}  // namespace
}  // namespace nmt
