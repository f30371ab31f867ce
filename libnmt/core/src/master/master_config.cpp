// MasterConfig (nmt/master/master_config.hpp): the master's objects of CiA 302-2 §6 as types, read
// from and written to the master's dictionary, and checked in words before the master is built.
#include "nmt/master/master_config.hpp"

#include <algorithm>
#include <array>
#include <map>
#include <set>
#include <string>

#include "cfg/config_manager.hpp"
#include "cfg/network.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "nmt/master/network_source.hpp"
#include "nmt/protocol/error_control.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

using std::chrono::milliseconds;

std::uint64_t whole_ms(Duration d) {
  return static_cast<std::uint64_t>(std::chrono::duration_cast<milliseconds>(d).count());
}

std::string ms_text(Duration d) {
  if (d % milliseconds(1) == Duration::zero()) return std::to_string(whole_ms(d)) + " ms";
  return std::to_string(d.count()) + " us";
}

/// A time in whole ms within 1..`most` ms (`zero_ok`: 0 too); the problem in words, or nullopt.
std::optional<std::string> ms_problem(Duration d, std::uint64_t most, bool zero_ok) {
  if (d < Duration::zero() || d % milliseconds(1) != Duration::zero()) {
    return ms_text(d) + " is not a whole number of milliseconds";
  }
  if (!zero_ok && d == Duration::zero()) return "0 ms is below 1 ms";
  if (whole_ms(d) > most) return ms_text(d) + " is above " + std::to_string(most) + " ms";
  return std::nullopt;
}

std::uint32_t u32(const LocalDictionary& dict, std::uint16_t index, std::uint8_t sub) {
  return static_cast<std::uint32_t>(dict.get_unsigned(index, sub).value_or(0));
}

constexpr std::array<std::uint16_t, 5> kIdentityObjects{
    obj::kDeviceTypeIdentification, obj::kVendorIdentification, obj::kProductCode,
    obj::kRevisionNumber, obj::kSerialNumber};

std::array<std::optional<std::uint32_t>*, 5> identity_fields(ExpectedIdentity& id) {
  return {&id.device_type, &id.vendor_id, &id.product_code, &id.revision, &id.serial_number};
}
std::array<const std::optional<std::uint32_t>*, 5> identity_fields(const ExpectedIdentity& id) {
  return {&id.device_type, &id.vendor_id, &id.product_code, &id.revision, &id.serial_number};
}

/// Writes the typed values into a master's dictionary (nothing has run on it yet).
class DictionaryWriter {
 public:
  explicit DictionaryWriter(LocalDictionary& dict) : dict_(dict) {}
  void put(std::uint16_t index, std::uint8_t sub, std::uint64_t value) {
    if (!problem_.empty() || dict_.set_unsigned(index, sub, value)) return;
    // A DCF may list fewer sub-indices (1F81h with SubNumber=3): an absent entry reads as 0 to
    // the master (value_of), so 0 needs no entry; any other value does.
    if (value == 0 && !dict_.get_unsigned(index, sub)) return;
    problem_ = "the master DCF has no " + cfg::to_string(cfg::ObjectAddress{index, sub}) +
               " for the value " + std::to_string(value) +
               "; list that sub-index in the master DCF (raise the object's SubNumber) or leave "
               "the value 0";
  }
  void fail(std::string problem) {
    if (problem_.empty()) problem_ = std::move(problem);
  }
  cfg::Status status() const {
    if (problem_.empty()) return {};
    return cfg::Error{problem_};
  }

 private:
  LocalDictionary& dict_;
  std::string problem_;
};

/// 1016h: each configured heartbeat in the entry that already names its node (so a DCF's layout
/// stays), else in a free one; the entries of other nodes are cleared.
void write_heartbeats(const MasterConfig& config, LocalDictionary& dict, DictionaryWriter& out) {
  std::map<std::uint8_t, std::uint16_t> wanted;
  for (const auto& s : config.slaves) {
    if (s.heartbeat) wanted[s.node.value()] = static_cast<std::uint16_t>(whole_ms(*s.heartbeat));
  }
  const auto count = static_cast<std::uint8_t>(
      std::min<std::uint64_t>(dict.get_unsigned(obj::kConsumerHeartbeatTime, 0).value_or(0), 0xFF));
  std::set<std::uint8_t> placed;
  std::vector<std::uint8_t> free;
  for (unsigned sub = 1; sub <= count; ++sub) {
    const auto s = static_cast<std::uint8_t>(sub);
    const auto entry = HeartbeatConsumerEntry::decode(u32(dict, obj::kConsumerHeartbeatTime, s));
    auto it = wanted.find(entry.node_id);
    if (it != wanted.end() && placed.insert(entry.node_id).second) {
      out.put(obj::kConsumerHeartbeatTime, s,
              HeartbeatConsumerEntry{entry.node_id, it->second}.encode());
    } else {
      out.put(obj::kConsumerHeartbeatTime, s, 0);
      free.push_back(s);
    }
  }
  std::size_t next = 0;
  for (const auto& [node, ms] : wanted) {
    if (placed.count(node) != 0) continue;
    if (next == free.size()) {
      out.fail("1016h has " + std::to_string(count) +
               " entries: no room for the heartbeat of node " + std::to_string(node) + " (" +
               std::to_string(wanted.size()) +
               " wanted); give 1016h more entries in the master DCF (SubNumber or "
               "CompactSubObj) or consume fewer heartbeats");
      return;
    }
    out.put(obj::kConsumerHeartbeatTime, free[next++], HeartbeatConsumerEntry{node, ms}.encode());
  }
}

}  // namespace

cfg::NmtStartup StartupFlags::value() const {
  using S = cfg::NmtStartup;
  std::uint32_t v = 0;
  if (master) v |= S::kMaster;
  if (start_all_nodes) v |= S::kStartAllNodes;
  if (no_auto_operational) v |= S::kNoAutoOperational;
  if (no_start_slaves) v |= S::kNoStartSlaves;
  if (reset_all_nodes) v |= S::kResetAllNodes;
  if (flying_master) v |= S::kFlyingMaster;
  if (stop_all_nodes) v |= S::kStopAllNodes;
  return {v};
}

StartupFlags StartupFlags::from(cfg::NmtStartup value) {
  return {value.is_master(),       value.start_all_nodes(), value.no_auto_operational(),
          value.no_start_slaves(), value.reset_all_nodes(), value.flying_master(),
          value.stop_all_nodes()};
}

cfg::SlaveAssignment SlaveConfig::assignment() const {
  using A = cfg::SlaveAssignment;
  std::uint32_t flags = 0;
  if (slave) flags |= A::kSlave;
  if (boot) flags |= A::kBootSlave;
  if (mandatory) flags |= A::kMandatory;
  if (keep_alive) flags |= A::kKeepAlive;
  if (verify_software) flags |= A::kVerifySoftware;
  if (update_software) flags |= A::kUpdateSoftware;
  if (restore) flags |= A::kRestore;
  const auto guard_ms =
      guarding ? static_cast<std::uint16_t>(whole_ms(guarding->guard_time)) : std::uint16_t{0};
  const std::uint8_t retries = guarding ? guarding->retry_factor : 0;
  return A::make(static_cast<std::uint8_t>(flags), retries, guard_ms);
}

SlaveConfig& MasterConfig::add_slave(cfg::NodeId node) {
  for (auto& s : slaves) {
    if (s.node == node) return s;
  }
  return slaves.emplace_back(SlaveConfig(node));
}

const SlaveConfig* MasterConfig::slave(cfg::NodeId node) const {
  for (const auto& s : slaves) {
    if (s.node == node) return &s;
  }
  return nullptr;
}

cfg::Status MasterConfig::validate() const {
  auto error = [](std::string text) { return cfg::Status{cfg::Error{std::move(text)}}; };
  std::set<std::uint8_t> seen;
  for (const auto& s : slaves) {
    const std::string who = "slave " + std::to_string(s.node.value()) + ": ";
    // §6.3: "The sub-index corresponding to its own node-ID shall be ignored."
    if (s.node == node_id) {
      return error(who + "is the master's own node-ID; remove it or give the master another");
    }
    if (!seen.insert(s.node.value()).second) {
      return error(who + "listed twice; keep one entry per node (add_slave gives the one there)");
    }
    if (s.guarding) {
      // §6.3: a guard time or retry factor of 0 disables guarding.
      if (auto p = ms_problem(s.guarding->guard_time, 0xFFFF, false)) {
        return error(who + "guard time " + *p +
                     " (1F81h bytes 2-3: 1..65535 ms); give whole ms in that range, or leave "
                     "guarding unset");
      }
      if (s.guarding->retry_factor == 0) {
        return error(who +
                     "retry factor 0 disables guarding (1F81h byte 1: 1..255); leave "
                     "guarding unset instead");
      }
    }
    if (s.heartbeat) {
      if (auto p = ms_problem(*s.heartbeat, 0xFFFF, false)) {
        return error(who + "heartbeat time " + *p +
                     " (1016h: 1..65535 ms); give whole ms in that range, or leave it unset");
      }
    }
    static constexpr std::array<const char*, 5> kNames{"device type", "vendor-ID", "product code",
                                                       "revision number", "serial number"};
    const auto fields = identity_fields(s.identity);
    for (std::size_t i = 0; i < fields.size(); ++i) {
      // §6.6-§6.10: 0 means "not checked"; an expected 0 cannot be said.
      if (*fields[i] == std::optional<std::uint32_t>{0}) {
        return error(who + "expected " + kNames[i] + " 0 means 'not checked' in " +
                     cfg::to_string(cfg::ObjectAddress{kIdentityObjects[i], s.node.value()}) +
                     "; leave it unset");
      }
    }
  }
  for (const auto& s : slaves) {
    // DSP 302 §9 / CiA 302-2 Table 1 G: 1F53h and 1F54h both 0 mean "not configured".
    if (s.program_version == cfg::ProgramVersion{}) {
      return error("slave " + std::to_string(s.node.value()) +
                   ": program version 0, 0 means 'not configured' in 1F53h/1F54h; leave it "
                   "unset");
    }
  }
  if (auto p = ms_problem(boot_time, 0xFFFFFFFF, true)) {
    return error("boot time (1F89h) " + *p +
                 "; give whole ms up to 4294967295 (0: retried without end)");
  }
  if (auto p = ms_problem(heartbeat_producer, 0xFFFF, true)) {
    return error("producer heartbeat time (1017h) " + *p +
                 "; give whole ms up to 65535 (0: no heartbeat)");
  }
  // §6.1: 102Ah in multiples of 100 us, UNSIGNED16.
  if (nmt_inhibit_time < Duration::zero() ||
      nmt_inhibit_time % std::chrono::microseconds(100) != Duration::zero() ||
      nmt_inhibit_time.count() / 100 > 0xFFFF) {
    return error("NMT inhibit time (102Ah) " + std::to_string(nmt_inhibit_time.count()) +
                 " us is not a multiple of 100 us up to 6553500 us; round it to one");
  }
  const auto& f = flying_master;
  const std::array<std::pair<const char*, Duration>, 5> times{{
      {"timeout (sub 1)", f.timeout},
      {"negotiation time delay (sub 2)", f.negotiation_delay},
      {"priority time slot (sub 4)", f.priority_time_slot},
      {"device time slot (sub 5)", f.device_time_slot},
      {"detect cycle (sub 6)", f.detect_cycle.value_or(Duration::zero())},
  }};
  for (const auto& [name, time] : times) {
    if (auto p = ms_problem(time, 0xFFFF, true)) {
      return error(std::string("flying master ") + name + " " + *p +
                   " (1F90h: UNSIGNED16 ms); give whole ms up to 65535");
    }
  }
  // §6.13, Table 48: 0 high, 1 medium, 2 low.
  if (static_cast<unsigned>(f.priority) > 2) {
    return error("flying master priority " + std::to_string(static_cast<unsigned>(f.priority)) +
                 " is reserved (1F90h sub 3: 0 high, 1 medium, 2 low); use High, Medium or Low");
  }
  // §6.13: "Priority time slot > 127 x CANopen device time slot".
  if (whole_ms(f.priority_time_slot) <= 127 * whole_ms(f.device_time_slot)) {
    return error("flying master priority time slot " + ms_text(f.priority_time_slot) +
                 " must exceed 127 x the device time slot " + ms_text(f.device_time_slot) +
                 " (CiA 302-2 §6.13); lengthen the one or shorten the other");
  }
  return {};
}

cfg::Result<NmtMaster> MasterConfig::build() const {
  if (auto valid = validate(); !valid) return valid.error();
  auto created = NmtMaster::create(dcf, node_id, options);
  if (!created) return created.error();
  NmtMaster master = std::move(created).value();
  LocalDictionary& dict = master.dictionary();
  DictionaryWriter out(dict);
  out.put(obj::kNmtStartup, 0, startup.value().value);
  for (unsigned n = cfg::kMinNodeId; n <= cfg::kMaxNodeId; ++n) {
    const auto node = cfg::NodeId::from(n).value();
    const SlaveConfig* s = slave(node);
    out.put(obj::kSlaveAssignment, node, s ? s->assignment().value : 0);
    const ExpectedIdentity none;
    const auto fields = identity_fields(s ? s->identity : none);
    for (std::size_t i = 0; i < fields.size(); ++i) {
      out.put(kIdentityObjects[i], node, fields[i]->value_or(0));
    }
    if (s) out.put(obj::kRestoreConfiguration, node, s->restore_subindex);
    const cfg::ConfigurationStamp stamp = s ? s->expected_configuration : cfg::ConfigurationStamp{};
    out.put(obj::kExpectedConfigurationDate, node, stamp.days);
    out.put(obj::kExpectedConfigurationTime, node, stamp.ms);
    const auto version =
        s ? s->program_version.value_or(cfg::ProgramVersion{}) : cfg::ProgramVersion{};
    out.put(obj::kExpectedApplicationSwDate, node, version.date_days);
    out.put(obj::kExpectedApplicationSwTime, node, version.time_ms);
  }
  out.put(obj::kProducerHeartbeatTime, 0, whole_ms(heartbeat_producer));
  write_heartbeats(*this, dict, out);
  out.put(obj::kBootTime, 0, whole_ms(boot_time));
  out.put(obj::kNmtInhibitTime, 0, static_cast<std::uint64_t>(nmt_inhibit_time.count() / 100));
  const auto& f = flying_master;
  out.put(obj::kFlyingMasterParameters, 1, whole_ms(f.timeout));
  out.put(obj::kFlyingMasterParameters, 2, whole_ms(f.negotiation_delay));
  out.put(obj::kFlyingMasterParameters, 3, static_cast<std::uint64_t>(f.priority));
  out.put(obj::kFlyingMasterParameters, 4, whole_ms(f.priority_time_slot));
  out.put(obj::kFlyingMasterParameters, 5, whole_ms(f.device_time_slot));
  out.put(obj::kFlyingMasterParameters, 6,
          f.detect_cycle ? whole_ms(*f.detect_cycle) : 4000 + 10 * std::uint64_t{node_id.value()});
  if (auto s = out.status(); !s) return s.error();
  return master;
}

MasterConfig MasterConfig::from_dictionary(const LocalDictionary& dict, cfg::NodeId node_id) {
  MasterConfig config(node_id);
  config.startup = StartupFlags::from({u32(dict, obj::kNmtStartup, 0)});
  std::map<std::uint8_t, Duration> heartbeats;
  const auto count = dict.get_unsigned(obj::kConsumerHeartbeatTime, 0).value_or(0);
  for (std::uint64_t sub = 1; sub <= count && sub <= 0xFF; ++sub) {
    const auto entry = HeartbeatConsumerEntry::decode(
        u32(dict, obj::kConsumerHeartbeatTime, static_cast<std::uint8_t>(sub)));
    if (entry.active()) heartbeats.emplace(entry.node_id, milliseconds(entry.time_ms));
  }
  for (unsigned n = cfg::kMinNodeId; n <= cfg::kMaxNodeId; ++n) {
    const auto node = cfg::NodeId::from(n).value();
    if (node == node_id) continue;  // §6.3: its own sub-index is ignored
    const cfg::SlaveAssignment a{u32(dict, obj::kSlaveAssignment, node)};
    ExpectedIdentity identity;
    const auto fields = identity_fields(identity);
    bool any = a.value != 0;
    for (std::size_t i = 0; i < fields.size(); ++i) {
      if (const auto v = u32(dict, kIdentityObjects[i], node); v != 0) {
        *fields[i] = v;
        any = true;
      }
    }
    const cfg::ConfigurationStamp stamp{u32(dict, obj::kExpectedConfigurationDate, node),
                                        u32(dict, obj::kExpectedConfigurationTime, node)};
    any = any || !stamp.is_zero();
    const cfg::ProgramVersion version{u32(dict, obj::kExpectedApplicationSwDate, node),
                                      u32(dict, obj::kExpectedApplicationSwTime, node)};
    any = any || version != cfg::ProgramVersion{};
    const auto heartbeat = heartbeats.find(node.value());
    if (!any && heartbeat == heartbeats.end()) continue;
    SlaveConfig& s = config.add_slave(node);
    s.slave = a.is_slave();
    s.boot = a.boot_slave();
    s.mandatory = a.mandatory();
    s.keep_alive = a.keep_alive();
    s.verify_software = a.verify_software();
    s.update_software = a.update_software();
    s.restore = a.restore();
    // §6.3: a guard time or a retry factor of 0 disables guarding.
    if (a.guard_time_ms() != 0 && a.retry_factor() != 0) {
      s.guarding = GuardingConfig{milliseconds(a.guard_time_ms()), a.retry_factor()};
    }
    s.identity = identity;
    if (version != cfg::ProgramVersion{}) s.program_version = version;
    if (heartbeat != heartbeats.end()) s.heartbeat = heartbeat->second;
    s.restore_subindex =
        static_cast<std::uint8_t>(dict.get_unsigned(obj::kRestoreConfiguration, node).value_or(1));
    s.expected_configuration = stamp;
  }
  config.heartbeat_producer = milliseconds(u32(dict, obj::kProducerHeartbeatTime, 0));
  config.boot_time = milliseconds(u32(dict, obj::kBootTime, 0));
  config.nmt_inhibit_time = std::chrono::microseconds(100) * u32(dict, obj::kNmtInhibitTime, 0);
  auto flying = [&](std::uint8_t sub) {
    return milliseconds(u32(dict, obj::kFlyingMasterParameters, sub));
  };
  auto& f = config.flying_master;
  f.timeout = flying(1);
  f.negotiation_delay = flying(2);
  f.priority =
      static_cast<FlyingMasterConfig::Priority>(u32(dict, obj::kFlyingMasterParameters, 3));
  f.priority_time_slot = flying(4);
  f.device_time_slot = flying(5);
  f.detect_cycle = flying(6);
  return config;
}

cfg::Result<MasterConfig> MasterConfig::from_dcf(const cfg::DeviceDescription& dcf,
                                                 cfg::NodeId node_id, MasterOptions options) {
  // The defaults and the checks of the objects the DCF lacks are NmtMaster::create's own (a
  // master only read, so without the options: nothing of theirs touches these objects).
  auto master = NmtMaster::create(dcf, node_id);
  if (!master) return master.error();
  MasterConfig config = from_dictionary(master.value().dictionary(), node_id);
  config.options = std::move(options);
  config.dcf = dcf;
  return config;
}

cfg::Result<MasterConfig> MasterConfig::from_network(std::shared_ptr<const cfg::Network> network,
                                                     cfg::NodeId node_id, MasterOptions options) {
  if (const cfg::NetworkNode* clash = network->find(node_id)) {
    return cfg::Error{"the master's node-ID " + std::to_string(node_id.value()) +
                      " is also the node-ID of " + clash->file};
  }
  const cfg::DeviceDescription& dcf = network->master;
  if (options.emcy.sources.empty()) options.emcy.sources = emcy_sources(*network);
  options.configurations = std::make_shared<NetworkSource>(std::move(network));
  if (!options.manager) options.manager = std::make_shared<cfg::ConfigManager>();
  return from_dcf(dcf, node_id, std::move(options));
}

cfg::NodeId MasterConfig::default_node_id(const cfg::Network& network) {
  constexpr std::uint8_t kHighest = 0x7F;
  return network.master_node_id ? *network.master_node_id : *cfg::NodeId::from(kHighest);
}

}  // namespace nmt
