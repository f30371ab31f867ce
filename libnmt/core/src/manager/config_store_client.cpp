// The store operations of a configuration manager's client (nmt/manager/config_store_client.hpp).
#include "nmt/manager/config_store_client.hpp"

#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/network.hpp"
#include "cfg/object_index.hpp"

namespace nmt {
namespace {

namespace obj = cfg::object;

cfg::ObjectAddress at(std::uint16_t index, cfg::NodeId node) {
  return {index, node.value()};
}

}  // namespace

std::uint16_t store_index(StoreFile file) {
  switch (file) {
    case StoreFile::Dcf:
      return obj::kStoreDcf;
    case StoreFile::Eds:
      return obj::kStoreEds;
    case StoreFile::Concise:
      break;
  }
  return obj::kConciseDcf;
}

cfg::Result<StoreAccess> StoreDirectoryObjects::read(cfg::ObjectAddress address) {
  auto r = manager_.read(address.index, address.sub_index);
  return StoreAccess{r.abort, std::move(r.data), std::move(r.message)};
}

cfg::Result<StoreAccess> StoreDirectoryObjects::write(cfg::ObjectAddress address,
                                                      std::vector<std::uint8_t> data) {
  auto r = manager_.write(address.index, address.sub_index, data);
  // cfg/config_manager.hpp: 0800 0020h is a directory that could not be written (1F25h,
  // whose wrong signature gives it too, is never written to a store directory).
  const bool io = r.abort == SdoAbort::CannotStoreOrTransfer;
  return StoreAccess{r.abort, {}, std::move(r.message), io};
}

cfg::Error store_access_error(cfg::ObjectAddress address, const StoreAccess& access) {
  std::string text = cfg::to_string(address) + ": ";
  const std::string code = to_string(access.abort);
  if (access.message.empty()) {
    text += code;
  } else {
    text += access.message;
    if (access.message.find(code) == std::string::npos) text += " (SDO abort " + code + ")";
  }
  return {std::move(text), access.io ? cfg::ErrorCategory::Io : cfg::ErrorCategory::Input};
}

cfg::Result<StoreAccess> ConfigStoreClient::must(cfg::ObjectAddress address,
                                                 cfg::Result<StoreAccess> access) {
  if (access && !access->ok()) return store_access_error(address, *access);
  return access;
}

cfg::Status ConfigStoreClient::write(cfg::ObjectAddress address, std::vector<std::uint8_t> data) {
  auto done = must(address, objects_.write(address, std::move(data)));
  if (!done) return done.error();
  return {};
}

cfg::Result<std::uint32_t> ConfigStoreClient::read_u32(cfg::ObjectAddress address) {
  auto a = must(address, objects_.read(address));
  if (!a) return a.error();
  return cfg::low_le32(a->data);
}

cfg::Result<std::optional<cfg::ConfigurationStamp>> ConfigStoreClient::put(
    cfg::NodeId node, StoreFile file, std::vector<std::uint8_t> data) {
  const std::uint16_t index = store_index(file);
  std::optional<cfg::ConfigurationStamp> stamp;
  if (file != StoreFile::Eds) {
    // Checked as the manager checks it, in memory: the stamp is of the writes it stands for.
    cfg::ConfigManager check;
    const auto put = check.write(index, node.value(), data);
    if (!put.ok()) return cfg::Error{put.message};
    const auto writes = check.configuration_or_error(node);
    if (!writes) return writes.error();
    stamp = cfg::configuration_stamp(cfg::encode_concise_dcf(writes.value()));
  }
  if (auto s = write(at(index, node), std::move(data)); !s) return s.error();
  if (stamp) {
    if (auto s = write(at(obj::kExpectedConfigurationDate, node), cfg::le32_bytes(stamp->days));
        !s) {
      return s.error();
    }
    if (auto s = write(at(obj::kExpectedConfigurationTime, node), cfg::le32_bytes(stamp->ms)); !s) {
      return s.error();
    }
  }
  return stamp;
}

cfg::Result<std::vector<std::uint8_t>> ConfigStoreClient::get(cfg::NodeId node, StoreFile file) {
  auto a = must(at(store_index(file), node), objects_.read(at(store_index(file), node)));
  if (!a) return a.error();
  return std::move(a->data);
}

cfg::Result<StoreNodeSummary> ConfigStoreClient::summary(cfg::NodeId node) {
  StoreNodeSummary s;
  s.node = node;
  // DSP 302 §6.1/§6.5: nothing stored reads as 0800 0024h.
  auto size_or_empty = [&](std::uint16_t index) -> cfg::Result<std::optional<std::size_t>> {
    auto a = objects_.read(at(index, node));
    if (a && a->abort == SdoAbort::NoDataAvailable) return std::optional<std::size_t>{};
    a = must(at(index, node), std::move(a));
    if (!a) return a.error();
    return std::optional<std::size_t>{a->data.size()};
  };
  auto dcf = size_or_empty(obj::kStoreDcf);
  if (!dcf) return dcf.error();
  s.dcf_bytes = *dcf;
  auto eds = size_or_empty(obj::kStoreEds);
  if (!eds) return eds.error();
  s.eds_bytes = *eds;
  auto concise = must(at(obj::kConciseDcf, node), objects_.read(at(obj::kConciseDcf, node)));
  if (!concise) return concise.error();
  // §6.2: the stream starts with the number of entries (UNSIGNED32).
  if (concise->data.size() >= 4) s.concise_entries = cfg::load_le32(concise->data);
  if (s.concise_entries != 0) s.concise_bytes = concise->data.size();
  auto days = read_u32(at(obj::kExpectedConfigurationDate, node));
  if (!days) return days.error();
  auto ms = read_u32(at(obj::kExpectedConfigurationTime, node));
  if (!ms) return ms.error();
  s.stamp = {*days, *ms};
  return s;
}

cfg::Result<std::vector<StoreNodeSummary>> ConfigStoreClient::list() {
  std::vector<StoreNodeSummary> nodes;
  for (unsigned id = cfg::kMinNodeId; id <= cfg::kMaxNodeId; ++id) {
    auto s = summary(*cfg::NodeId::from(static_cast<std::uint8_t>(id)));
    if (!s) return s.error();
    if (!s->empty()) nodes.push_back(*s);
  }
  return nodes;
}

cfg::Status ConfigStoreClient::remove(cfg::NodeId node) {
  for (auto [index, value] : {std::pair{obj::kConciseDcf, cfg::le32_bytes(0)},
                              std::pair{obj::kStoreDcf, std::vector<std::uint8_t>{}},
                              std::pair{obj::kStoreEds, std::vector<std::uint8_t>{}},
                              std::pair{obj::kExpectedConfigurationDate, cfg::le32_bytes(0)},
                              std::pair{obj::kExpectedConfigurationTime, cfg::le32_bytes(0)}}) {
    if (auto s = write(at(index, node), std::move(value)); !s) return s;
  }
  return {};
}

cfg::Status ConfigStoreClient::configure(std::optional<cfg::NodeId> node) {
  if (!objects_.remote()) {
    return cfg::Error{"configure asks a running master (1F25h); a store directory cannot act"};
  }
  const std::uint8_t sub = node ? node->value() : cfg::kConfigureAllNodes;
  return write({obj::kConfigureSlave, sub}, cfg::le32_bytes(cfg::kConfigureSignature));
}

}  // namespace nmt
