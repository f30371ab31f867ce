// The configuration manager's objects on the NMT master's SDO server (DSP 302 §6): 1F20h-1F25h
// are served from MasterOptions::manager, and 1F26h/1F27h have one owner (nmt_master.hpp). The
// dictionary keeps only the entries' attributes: a read fills the value from the manager, a
// write hands it over and the dictionary's copy of a file is dropped at once.
#include <string>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/object_index.hpp"
#include "nmt/configuration_manager_source.hpp"
#include "nmt_master_impl.hpp"

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

void NmtMaster::Impl::install_store_objects() {
  if (!options.manager) return;
  using T = cfg::DataType;
  using A = cfg::AccessType;
  // The file's own streams stay the fallback of a node the manager holds nothing for.
  for (unsigned sub = cfg::kMinNodeId; sub <= cfg::kMaxNodeId; ++sub) {
    const auto s = static_cast<std::uint8_t>(sub);
    if (auto bytes = dict.get_bytes(obj::kConciseDcf, s); bytes && !bytes->empty()) {
      file_concise[s].assign(bytes->begin(), bytes->end());
    }
  }
  // A DCF text may be large; the SDO server's own limit is the bound.
  const std::size_t file_limit = SdoServerConfig{}.max_download_size;
  constexpr auto nodes = static_cast<std::uint8_t>(cfg::kMaxNodeId);
  add_store_array(dict, obj::kStoreDcf, "Store DCF", T::Domain, A::Rw, nodes, file_limit);
  add_store_array(dict, obj::kStorageFormat, "Storage format", T::Unsigned8, A::Rw, nodes, 0);
  add_store_array(dict, obj::kConciseDcf, "Concise DCF", T::Domain, A::Rw, nodes, file_limit);
  add_store_array(dict, obj::kStoreEds, "Store slave EDS", T::Domain, A::Rw, nodes, file_limit);
  add_store_array(dict, obj::kStorageFormatEds, "Slave EDS storage format", T::Unsigned8, A::Rw,
                  nodes, 0);
  add_store_array(dict, obj::kConfigureSlave, "Configure slave", T::Unsigned32, A::Wo,
                  cfg::kConfigureAllNodes, 0);

  dict.add_read_hook([this](std::uint16_t index, std::uint8_t sub, TimePoint /*now*/) {
    return store_read(index, sub);
  });
  dict.add_write_hook([this](std::uint16_t index, std::uint8_t sub,
                             std::span<const std::uint8_t> data,
                             TimePoint now) { return store_write(index, sub, data, now); });
  // The manager has the value now; the dictionary need not keep a second copy of a file.
  dict.add_write_observer(
      [this](std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t>, TimePoint) {
        if (holds_files(index)) dict.set_bytes(index, sub, {});
      });
}

std::optional<cfg::ConfigurationStamp> NmtMaster::Impl::stored_stamp(std::uint8_t node) const {
  if (!options.manager) return std::nullopt;
  const auto id = cfg::NodeId::from(node);
  if (!id) return std::nullopt;
  const auto stamp = options.manager->expected_stamp(*id);
  if (stamp.is_zero() && !options.manager->has_configuration(*id)) return std::nullopt;
  return stamp;
}

std::span<const std::uint8_t> NmtMaster::Impl::own_concise_dcf(std::uint8_t node) const {
  if (options.manager) {
    const auto it = file_concise.find(node);
    if (it == file_concise.end()) return {};
    return it->second;
  }
  return dict.get_bytes(obj::kConciseDcf, node).value_or(std::span<const std::uint8_t>{});
}

SdoAbort NmtMaster::Impl::store_read(std::uint16_t index, std::uint8_t sub) {
  if (!options.manager || !is_store_index(index) || sub == 0) return SdoAbort::None;
  if (store_read_entry) {
    dict.set_bytes(store_read_entry->first, store_read_entry->second, {});
    store_read_entry.reset();
  }
  std::vector<std::uint8_t> value;
  const auto node = cfg::NodeId::from(sub);
  if (is_stamp(index) && node) {
    // The one owner's value (expected_configuration), also for a node the manager lacks.
    const auto stamp = expected_configuration(sub);
    value = u32_bytes(index == obj::kExpectedConfigurationDate ? stamp.days : stamp.ms);
  } else if (index == obj::kConciseDcf && node && !options.manager->concise(*node) &&
             !own_concise_dcf(sub).empty()) {
    const auto own = own_concise_dcf(sub);
    value.assign(own.begin(), own.end());
  } else {
    auto read = options.manager->read(index, sub);
    if (!read.ok()) return to_sdo_abort(read.abort);
    value = std::move(read.data);
  }
  dict.set_bytes(index, sub, value);
  if (holds_files(index)) store_read_entry = {index, sub};
  return SdoAbort::None;
}

SdoAbort NmtMaster::Impl::store_write(std::uint16_t index, std::uint8_t sub,
                                      std::span<const std::uint8_t> data, TimePoint now) {
  if (!options.manager || !is_store_index(index)) return SdoAbort::None;
  auto& manager = *options.manager;
  if (is_stamp(index) && cfg::is_node_id(sub) && !stored_stamp(sub)) {
    // The manager takes the node over with the half that is not written.
    if (!manager.set_expected_stamp(*cfg::NodeId::from(sub), expected_configuration(sub))) {
      return SdoAbort::CannotStoreOrTransfer;
    }
  }
  const auto written = manager.write(index, sub, data);
  if (!written.ok()) return to_sdo_abort(written.abort);
  if (index == obj::kConfigureSlave) return configure_slaves(sub, written.configure, now);
  return SdoAbort::None;
}

SdoAbort NmtMaster::Impl::configure_slaves(std::uint8_t sub, const std::vector<cfg::NodeId>& nodes,
                                           TimePoint now) {
  // As request NMT: only the active master boots slaves (0800 0022 on a standby master).
  if (!startup_config().is_master() || !acts_as_master()) return SdoAbort::DeviceState;
  // A node the master does not boot cannot be configured by it (§3.4 a would end with A).
  if (sub != cfg::kConfigureAllNodes && !is_slave(sub)) return SdoAbort::General;
  Output& out = sink();
  for (const auto node : nodes) {
    const std::uint8_t n = node.value();
    if (!is_slave(n)) continue;
    // As boot_slave(): the application (here a tool) asks for it.
    slaves[n].held = false;
    stop_error_control(n);
    start_boot(n, false, now, out, /*asked_by_application=*/true);
    slaves[n].reconfigure = true;
  }
  return SdoAbort::None;
}

}  // namespace nmt
