// The configuration manager's objects on the NMT master's SDO server (DSP 302 §6; see
// configuration_store_objects.hpp): 1F20h-1F25h are served from MasterOptions::manager, and
// 1F26h/1F27h have one owner (docs/master.md). The dictionary keeps only the entries'
// attributes: a read fills the value from the manager, a write hands it over and the
// dictionary's copy of a file is dropped at once.
#include "manager/configuration_store_objects.hpp"

#include <string>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/object_index.hpp"
#include "master/master_support.hpp"
#include "nmt/manager/configuration_manager_source.hpp"
#include "nmt/sdo/sdo_server.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

bool is_store_index(std::uint16_t index) {
  return index >= obj::kStoreDcf && index <= obj::kExpectedConfigurationTime;
}

/// The DOMAIN objects, whose values are files or streams.
bool holds_files(std::uint16_t index) {
  return index == obj::kStoreDcf || index == obj::kConciseDcf || index == obj::kStoreEds;
}

bool is_stamp(std::uint16_t index) {
  return index == obj::kExpectedConfigurationDate || index == obj::kExpectedConfigurationTime;
}

/// An ARRAY of 127 node entries (128 with 1F25h's sub 80h, DSP 302 §6.4), replacing what the
/// master DCF has: sub 0 is the ro number of entries (§6.1-§6.5).
void add_store_array(LocalDictionary& dict, std::uint16_t index, const char* name,
                     cfg::DataType type, cfg::AccessType access, std::uint8_t last,
                     std::size_t max_size) {
  dict.insert(make_entry(index, 0, "Highest sub-index supported", cfg::DataType::Unsigned8,
                         cfg::AccessType::Const, last));
  for (unsigned sub = 1; sub <= last; ++sub) {
    const auto s = static_cast<std::uint8_t>(sub);
    dict.insert(
        make_entry(index, s, std::string(name) + " node " + std::to_string(sub), type, access, 0));
    if (max_size != 0) dict.set_max_size(index, s, max_size);
  }
}

}  // namespace

void ConfigurationStoreObjects::install() {
  if (!manager_) return;
  using T = cfg::DataType;
  using A = cfg::AccessType;
  // The file's own streams stay the fallback of a node the manager holds nothing for.
  for (unsigned sub = cfg::kMinNodeId; sub <= cfg::kMaxNodeId; ++sub) {
    const auto s = static_cast<std::uint8_t>(sub);
    if (auto bytes = dict_.get_bytes(obj::kConciseDcf, s); bytes && !bytes->empty()) {
      file_concise_[s].assign(bytes->begin(), bytes->end());
    }
  }
  if (configurations_) {
    for (unsigned sub = cfg::kMinNodeId; sub <= cfg::kMaxNodeId; ++sub) {
      const auto node = *cfg::NodeId::from(sub);
      auto text = configurations_->dcf(node);
      if (!text) {
        source_dcfs_.emplace(node, text.error());
      } else if (*text) {
        source_dcfs_.emplace(node, std::move(**text));
      }
    }
  }
  // A DCF text may be large; the SDO server's own limit is the bound.
  const std::size_t file_limit = SdoServerConfig{}.max_download_size;
  constexpr auto nodes = static_cast<std::uint8_t>(cfg::kMaxNodeId);
  add_store_array(dict_, obj::kStoreDcf, "Store DCF", T::Domain, A::Rw, nodes, file_limit);
  add_store_array(dict_, obj::kStorageFormat, "Storage format", T::Unsigned8, A::Rw, nodes, 0);
  add_store_array(dict_, obj::kConciseDcf, "Concise DCF", T::Domain, A::Rw, nodes, file_limit);
  add_store_array(dict_, obj::kStoreEds, "Store slave EDS", T::Domain, A::Rw, nodes, file_limit);
  add_store_array(dict_, obj::kStorageFormatEds, "Slave EDS storage format", T::Unsigned8, A::Rw,
                  nodes, 0);
  add_store_array(dict_, obj::kConfigureSlave, "Configure slave", T::Unsigned32, A::Wo,
                  cfg::kConfigureAllNodes, 0);

  dict_.add_read_hook([this](std::uint16_t index, std::uint8_t sub, TimePoint /*now*/) {
    return read(index, sub);
  });
  dict_.add_write_hook([this](std::uint16_t index, std::uint8_t sub,
                              std::span<const std::uint8_t> data, TimePoint now, HookOutput out) {
    return write(index, sub, data, now, out.as<MasterEvent>());
  });
  // A peer's files are bounded before they are buffered (cfg::ConfigManagerLimits): the SDO
  // server asks with the indicated size, else with the size received so far.
  dict_.add_size_hook([this](std::uint16_t index, std::uint8_t sub, std::size_t size) {
    if (!holds_files(index)) return SdoAbort::None;
    return manager_->admits(index, sub, size);
  });
  // The manager has the value now; the dictionary need not keep a second copy of a file.
  dict_.add_write_observer(
      [this](std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t>, TimePoint) {
        if (holds_files(index)) dict_.set_bytes(index, sub, {});
      });
}

std::optional<cfg::ConfigurationStamp> ConfigurationStoreObjects::stored_stamp(
    cfg::NodeId node) const {
  if (!manager_) return std::nullopt;
  const auto stamp = manager_->expected_stamp(node);
  if (stamp.is_zero() && !manager_->has_configuration(node)) return std::nullopt;
  return stamp;
}

cfg::ConfigurationStamp ConfigurationStoreObjects::expected_configuration(cfg::NodeId node) const {
  // One owner (docs/master.md): the configuration manager for a node it holds anything for.
  if (auto stamp = stored_stamp(node)) return *stamp;
  auto value = [this](std::uint16_t index, cfg::NodeId n) {
    return static_cast<std::uint32_t>(dict_.get_unsigned(index, n.value()).value_or(0));
  };
  return {value(obj::kExpectedConfigurationDate, node),
          value(obj::kExpectedConfigurationTime, node)};
}

std::optional<std::vector<cfg::ObjectWrite>> ConfigurationStoreObjects::configuration(
    cfg::NodeId node) const {
  // The configuration manager first (MasterOptions::manager), then the source, then 1F22h.
  if (manager_ && manager_->has_configuration(node)) {
    return manager_->configuration(node);
  }
  if (configurations_) return configurations_->configuration(node);
  // §3.5 d: "The DCF may be read from ... object 1F22h on the configuration manager."
  const auto stream = own_concise_dcf(node);
  if (stream.empty()) return std::nullopt;
  auto decoded = cfg::decode_concise_dcf(stream);
  if (!decoded) return std::nullopt;
  return std::move(decoded.value());
}

std::span<const std::uint8_t> ConfigurationStoreObjects::own_concise_dcf(cfg::NodeId node) const {
  if (manager_) {
    const auto it = file_concise_.find(node);
    if (it == file_concise_.end()) return {};
    return it->second;
  }
  return dict_.get_bytes(obj::kConciseDcf, node).value_or(std::span<const std::uint8_t>{});
}

SdoAbort ConfigurationStoreObjects::read(std::uint16_t index, std::uint8_t sub) {
  if (!manager_ || !is_store_index(index) || sub == 0) return SdoAbort::None;
  if (read_entry_) {
    dict_.set_bytes(read_entry_->first, read_entry_->second, {});
    read_entry_.reset();
  }
  std::vector<std::uint8_t> value;
  const auto node = cfg::NodeId::from(sub);
  if (is_stamp(index) && node) {
    // The one owner's value (expected_configuration), also for a node the manager lacks.
    const auto stamp = expected_configuration(*node);
    value = cfg::le32_bytes(index == obj::kExpectedConfigurationDate ? stamp.days : stamp.ms);
  } else if (auto unstored = node ? unstored_read(index, *node) : std::nullopt) {
    if (unstored->abort != SdoAbort::None) return unstored->abort;
    value = std::move(unstored->data);
  } else {
    auto read = manager_->read(index, sub);
    if (!read.ok()) return read.abort;
    value = std::move(read.data);
  }
  dict_.set_bytes(index, sub, value);
  if (holds_files(index)) read_entry_ = {index, sub};
  return SdoAbort::None;
}

std::optional<ConfigurationStoreObjects::StoreValue> ConfigurationStoreObjects::unstored_read(
    std::uint16_t index, cfg::NodeId node) const {
  // "Stored, else the network" (docs/master.md): a stored configuration takes the place of the
  // source's, as in configuration().
  if (manager_->has_configuration(node)) return std::nullopt;
  const ConfigurationSource* source = configurations_.get();
  if (index == obj::kConciseDcf) {
    if (source != nullptr) {
      if (auto stream = source->concise_dcf(node)) {
        return StoreValue{SdoAbort::None, std::move(*stream)};
      }
    }
    const auto own = own_concise_dcf(node);
    if (own.empty()) return std::nullopt;  // DSP 302 §6.2 hint 2: the count-0 stream
    return StoreValue{SdoAbort::None, {own.begin(), own.end()}};
  }
  if ((index != obj::kStoreDcf && index != obj::kStorageFormat) || source == nullptr) {
    return std::nullopt;
  }
  const auto text = source_dcfs_.find(node);
  if (text == source_dcfs_.end()) return std::nullopt;  // 0800 0024h, as the manager answers
  if (!text->second) return StoreValue{SdoAbort::CannotStoreOrTransfer, {}};
  if (index == obj::kStorageFormat) return StoreValue{SdoAbort::None, {cfg::kStorageFormatAscii}};
  return StoreValue{SdoAbort::None, {text->second->begin(), text->second->end()}};
}

WriteVerdict ConfigurationStoreObjects::write(std::uint16_t index, std::uint8_t sub,
                                              std::span<const std::uint8_t> data, TimePoint now,
                                              Output* out) {
  if (!manager_ || !is_store_index(index)) return SdoAbort::None;
  const auto& manager = *manager_;
  const auto node = cfg::NodeId::from(sub);
  if (is_stamp(index) && node && !stored_stamp(*node) && data.size() == 4) {
    // The manager takes the node over with the half that is not written.
    auto stamp = expected_configuration(*node);
    (index == obj::kExpectedConfigurationDate ? stamp.days : stamp.ms) = cfg::low_le32(data);
    auto staged = manager.stage_expected_stamp(*node, stamp);
    if (!staged) return SdoAbort::ValueRangeExceeded;  // 1F27h: no time of day
    return persist_entry(std::move(staged).value(), now, out);
  }
  std::optional<cfg::StoreUpdate> update;
  auto written = manager.stage(index, sub, data, update);
  if (index == obj::kConfigureSlave) add_unstored_configurations(sub, written);
  if (!written.ok()) return written.abort;
  if (index == obj::kConfigureSlave) return configure_slaves(sub, written.configure, now, out);
  if (update) return persist_entry(std::move(*update), now, out);
  return SdoAbort::None;
}

WriteVerdict ConfigurationStoreObjects::persist_entry(cfg::StoreUpdate update, TimePoint now,
                                                      Output* out) {
  if (!manager_->persistent()) {
    manager_->commit(std::move(update));
    return SdoAbort::None;
  }
  if (out == nullptr) return SdoAbort::DeviceState;  // no output to ask the driver in
  // No disk I/O in the engine (docs/master.md): the driver writes the entry and answers with
  // entry_persisted(); until then the SDO confirmation waits and the manager keeps its value.
  const std::uint64_t ticket = ++last_persist_ticket_;
  const auto node = update.node;
  auto shared = std::make_shared<cfg::StoreUpdate>(std::move(update));
  persists_.emplace(ticket, shared);
  auto event = master_event(MasterEvent::Kind::PersistEntry, now, node);
  event.persist = MasterEvent::Persist{ticket, std::move(shared)};
  out->report(std::move(event));
  return WriteVerdict::hold(ticket);
}

void ConfigurationStoreObjects::entry_persisted(std::uint64_t ticket, const cfg::Status& result,
                                                TimePoint /*now*/, Output& out) {
  const auto it = persists_.find(ticket);
  if (it == persists_.end()) return;
  const auto update = std::move(it->second);
  persists_.erase(it);
  // CiA 301 §7.2.4.3.17: 0800 0020h "data cannot be transferred or stored to the application",
  // as cfg::ConfigManager answers a store directory it cannot write.
  SdoAbort code = SdoAbort::CannotStoreOrTransfer;
  if (result) {
    manager_->commit(std::move(*update));
    code = SdoAbort::None;
  }
  port_.complete_download(ticket, code, out);
}

void ConfigurationStoreObjects::add_unstored_configurations(std::uint8_t sub,
                                                            cfg::ConfigWrite& written) const {
  // DSP 302 §6.4: 'conf' configures a node "with the stored configuration"; a node the manager
  // stores nothing for has the source's (or the master DCF's) configuration, which the master
  // downloads just the same (docs/master.md), so 1F25h takes those nodes too.
  const auto has_configuration = [this](cfg::NodeId node) {
    return configuration(node).has_value();
  };
  const auto node = cfg::NodeId::from(sub);
  if (sub == cfg::kConfigureAllNodes && written.ok()) {
    std::vector<cfg::NodeId> nodes;
    for (const auto id : all_node_ids()) {
      if (port_.is_slave(id) && has_configuration(id)) nodes.push_back(id);
    }
    written.configure = std::move(nodes);
  } else if (written.abort == cfg::SdoAbort::NoDataAvailable && node && has_configuration(*node)) {
    written = cfg::ConfigWrite{cfg::SdoAbort::None, {}, {*node}};
  }
}

SdoAbort ConfigurationStoreObjects::configure_slaves(std::uint8_t sub,
                                                     const std::vector<cfg::NodeId>& nodes,
                                                     TimePoint now, Output* out) {
  // As request NMT: only the active master boots slaves (0800 0022 on a standby master).
  if (!port_.boots_slaves()) return SdoAbort::DeviceState;
  // A node the master does not boot cannot be configured by it (§3.4 a would end with A).
  const auto named = cfg::NodeId::from(sub);
  if (sub != cfg::kConfigureAllNodes && !(named && port_.is_slave(*named))) {
    return SdoAbort::General;
  }
  if (out == nullptr) return SdoAbort::DeviceState;  // booting needs the call's output
  for (const auto node : nodes) {
    // As boot_slave(): the application (here a tool) asks for it.
    if (port_.is_slave(node)) port_.configure(node, now, *out);
  }
  return SdoAbort::None;
}

}  // namespace nmt
