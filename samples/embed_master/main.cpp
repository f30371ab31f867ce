// Embedding the CiA 302-2 NMT master: two simulated devices on a simulated 500 kbit/s bus and a
// master (node 1), configured through nmt::MasterConfig, that checks their vendor-ID, downloads a
// configuration from the application's own ConfigurationSource, waits for the application's
// configuration step and starts them; the device at node 3 reports a wrong vendor-ID and fails with
// boot error D. Every event is printed with its simulated time. Exit status 0 when node 2 ended
// stopped (by a request NMT) and node 3 with error D.
#include <cstdint>
#include <iostream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cfg/hex.hpp"
#include "nmt/master/master_config.hpp"
#include "nmt/master/master_event_text.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sim/sim_bus.hpp"
#include "nmt/sim/simulated_device.hpp"

using namespace std::chrono_literals;
using namespace cfg::literals;

namespace {

constexpr std::uint32_t kVendor = 0x7E57C0DE;
constexpr std::uint8_t kSlaves[] = {2, 3};

// The device file, in code: 1000h, 1010h, 1017h (heartbeat 100 ms), 1018h, 1020h, 2000h.
cfg::DeviceDescription device_file() {
  cfg::DeviceDescription d;
  auto add = [&d](std::uint16_t index, std::uint8_t sub, cfg::DataType type, cfg::AccessType access,
                  std::string value) {
    cfg::Object& o = d.objects[index];
    o.index = index;
    if (sub != 0) o.object_type = cfg::ObjectType::Record;
    cfg::SubObject& s = o.subs[sub];
    s.sub_index = sub;
    s.data_type = static_cast<std::uint16_t>(type);
    s.access = access;
    s.default_value = std::move(value);
  };
  using T = cfg::DataType;
  using A = cfg::AccessType;
  add(0x1000, 0, T::Unsigned32, A::Ro, "0x000F0191");
  add(0x1010, 1, T::Unsigned32, A::Rw, "1");
  add(0x1017, 0, T::Unsigned16, A::Rw, "100");
  add(0x1018, 1, T::Unsigned32, A::Ro, cfg::hex(kVendor));
  add(0x1020, 1, T::Unsigned32, A::Rw, "0");
  add(0x1020, 2, T::Unsigned32, A::Rw, "0");
  add(0x2000, 0, T::Unsigned16, A::Rw, "0");
  for (auto& [index, o] : d.objects) {  // sub 0 of a RECORD: the highest sub-index
    if (o.is_var()) continue;
    const auto highest = o.subs.rbegin()->first;
    add(index, 0, T::Unsigned8, A::Ro, std::to_string(highest));
  }
  return d;
}

// Where the application keeps each node's configuration (here: one value per node).
class MyConfigurations final : public nmt::ConfigurationSource {
 public:
  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override {
    return std::vector<cfg::ObjectWrite>{{0x2000, 0, {0xE8, node.value()}}};
  }
};

}  // namespace

int main() {
  nmt::SimBus bus(500'000);
  std::vector<std::unique_ptr<nmt::SimEngineNode<nmt::SimulatedDevice>>> devices;
  for (const std::uint8_t id : kSlaves) {
    nmt::DeviceFaults faults;
    if (id == 3) faults.vendor_id = 0x00000BAD;  // not the 1F85h value: status D
    auto device = nmt::SimulatedDevice::create(device_file(), id, faults);
    if (!device.ok()) return std::cerr << device.error().message << "\n", 1;
    devices.push_back(
        std::make_unique<nmt::SimEngineNode<nmt::SimulatedDevice>>(std::move(device).value()));
    bus.attach(*devices.back());
    devices.back()->apply([](auto& d, nmt::TimePoint now, auto& out) { d.start(now, out); });
  }

  // The master's configuration (CiA 302-2 §6) as types: no object indices, no bytes.
  nmt::MasterConfig config(1_node);
  config.startup.master = true;  // 1F80h: the NMT master, which starts each slave once booted
  for (const std::uint8_t id : kSlaves) {
    nmt::SlaveConfig& slave =
        config.add_slave(*cfg::NodeId::from(id));  // 1F81h: boot and start it, optional
    slave.identity.vendor_id = kVendor;            // 1F85h: checked against 1018h sub 1
    slave.heartbeat = 300ms;                       // 1016h: the master consumes it
  }
  config.options.configurations = std::make_shared<MyConfigurations>();
  config.options.boot.application_step =
      true;  // MasterEvent::ApplicationStep, then configuration_done()
  auto created = config.build();
  if (!created.ok()) return std::cerr << created.error().message << "\n", 1;
  nmt::SimEngineNode<nmt::NmtMaster> master(std::move(created).value());
  bus.attach(master);

  master.set_event_handler([&](const nmt::MasterEvent& e, nmt::TimePoint now) {
    std::cout << now.time_since_epoch().count() / 1000 << " ms  " << nmt::to_string(e.kind) << ": "
              << nmt::describe(e) << "\n";
    if (e.kind == nmt::MasterEvent::Kind::ApplicationStep) {  // the application's own step
      master.apply([&](nmt::NmtMaster& m, nmt::TimePoint t, auto& out) {
        m.configuration_done(*e.node_id, true, t, out);  // ApplicationStep: always a node
      });
    }
  });
  master.apply([](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) { m.start(now, out); });
  bus.run_for(3s);
  // Request NMT (1F82h, CiA 302-2 Table 28): stop node 2.
  master.apply([](nmt::NmtMaster& m, nmt::TimePoint now, auto& out) {
    m.request_nmt(2_node, nmt::NmtRequest::Stop, now, out);
  });
  bus.run_for(500ms);

  const nmt::NmtMaster& m = master.engine();
  const auto error3 = m.last_error(3_node);
  std::cout << "start-up " << nmt::to_string(m.startup_state()) << "; node 2 state "
            << cfg::hex(m.known_state(2_node).to_byte(), 2) << "; node 3 boot error "
            << (error3 ? nmt::letter(*error3) : '-') << "\n";
  return m.known_state(2_node).nmt_state() == nmt::NmtState::Stopped && error3 == nmt::BootError::D
             ? 0
             : 1;
}
