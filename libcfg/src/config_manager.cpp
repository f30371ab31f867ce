// The configuration manager (DSP 302 v3.2.1 §6): SDO access to 1F20h-1F27h, the stored values
// and the download plan (CiA 302-2 §3.5).
#include "cfg/config_manager.hpp"

#include <unistd.h>

#include <algorithm>
#include <array>
#include <filesystem>
#include <stdexcept>
#include <system_error>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/device_file.hpp"
#include "cfg/download_order.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "config_manager_store.hpp"

namespace cfg {
namespace {

using detail::EntryEncoding;

// DSP 302 §6: sub-index 0 of 1F20h-1F24h, 1F26h, 1F27h is 127 (the highest node-ID); 1F25h
// has 128 (80h: all nodes).
constexpr std::uint8_t kNodeEntries = kMaxNodeId;
constexpr std::uint8_t kConfigureSlaveEntries = kConfigureAllNodes;

/// A DCF or EDS text as it is held: zlib-compressed (DSP 302 §6.1: "The device may always store
/// the file compressed internally").
struct PackedText {
  std::vector<std::uint8_t> deflated;
  std::uint32_t size = 0;
};

struct NodeSlot {
  std::vector<std::uint8_t> concise;  // empty: none (an empty data set is never stored)
  std::optional<PackedText> dcf;
  std::optional<PackedText> eds;
  ConfigurationStamp stamp;
};

std::span<const std::uint8_t> as_bytes(std::string_view text) {
  return {reinterpret_cast<const std::uint8_t*>(text.data()), text.size()};
}

/// The node's 1F20h, 1F22h and 1F23h values as written (ConfigManager::value_bytes()).
std::size_t value_bytes_of(const NodeSlot& s) {
  return s.concise.size() + (s.dcf ? s.dcf->size : 0) + (s.eds ? s.eds->size : 0);
}

/// The size of the node's value of a file object as written.
std::size_t file_size_of(const NodeSlot& s, std::uint16_t index) {
  if (index == object::kConciseDcf) return s.concise.size();
  const auto& text = index == object::kStoreDcf ? s.dcf : s.eds;
  return text ? text->size : 0;
}

std::string as_text(const std::vector<std::uint8_t>& bytes) {
  return {bytes.begin(), bytes.end()};
}

std::vector<std::uint8_t> unpack_bytes(const PackedText& packed) {
  auto bytes = detail::inflate_bytes(packed.deflated, packed.size);
  // Held bytes were deflated here or checked when loaded: failing to inflate them is a bug.
  if (!bytes) throw std::logic_error("configuration manager: " + bytes.error().message);
  return std::move(*bytes);
}

std::string unpack(const PackedText& packed) {
  return as_text(unpack_bytes(packed));
}

/// The name a node's DCF goes by in messages: "1F20h sub 05h".
std::string dcf_name(NodeId node) {
  return to_string(ObjectAddress{object::kStoreDcf, node.value()});
}

/// The writes a DCF text configures for `node`, or why it has none.
Result<std::vector<ObjectWrite>> writes_of_dcf(std::string_view text, NodeId node) {
  ReadOptions read_options;
  read_options.file_name = dcf_name(node);
  ReadResult read = parse_device_description(text, read_options);
  if (!read.ok()) {
    return Error{"the DCF does not read: " + read.diagnostics.format()};
  }
  ConciseOptions options;
  options.node_id = node.value();
  options.file_name = read_options.file_name;
  Diagnostics diagnostics;
  auto writes = concise_writes_from_dcf(*read.device, options, diagnostics);
  if (!writes) return Error{"the DCF's values do not encode: " + diagnostics.format()};
  return std::move(*writes);
}

SdoAbort abort_for(const Error& error) {
  return error.category == ErrorCategory::Io ? SdoAbort::CannotStoreOrTransfer
                                             : SdoAbort::ValueRangeExceeded;
}

ConfigWrite write_answer(const Status& status) {
  if (status) return {};
  return {abort_for(status.error()), status.error().message, {}};
}

ConfigRead read_abort(SdoAbort abort, std::string message) {
  return {abort, {}, std::move(message)};
}

}  // namespace

struct ConfigManager::State {
  std::string directory;  // empty: in memory only
  StoreWriteHooks hooks;
  Diagnostics problems;
  std::array<NodeSlot, kMaxNodeId + 1> nodes{};  // by node-ID; [0] unused
  ConfigManagerLimits limits;

  NodeSlot& slot(NodeId node) { return nodes[node.value()]; }
  const NodeSlot& slot(NodeId node) const { return nodes[node.value()]; }

  /// A DCF or EDS text (1F20h/1F23h) as an update; empty text removes the entry.
  static Result<StoreUpdate> stage_text(std::uint16_t index, NodeId node, std::string_view text) {
    StoreUpdate update{index, node, text.empty(), true, {}, 0};
    if (text.empty()) return update;
    if (text.size() > UINT32_MAX) return Error{"the file is 4 GiB or larger"};
    update.stored = detail::deflate_bytes(as_bytes(text));
    update.value_size = static_cast<std::uint32_t>(text.size());
    return update;
  }

  static Result<StoreUpdate> stage_concise(NodeId node, std::span<const std::uint8_t> stream) {
    auto decoded = decode_concise_dcf(stream);
    if (!decoded) return Error{"not a valid concise DCF: " + decoded.error().message};
    // DSP 302 §6.2 application hint 1: the stream with count 0 is the empty data set.
    StoreUpdate update{object::kConciseDcf, node, decoded->empty(), false, {}, 0};
    if (!update.remove) {
      update.stored.assign(stream.begin(), stream.end());
      update.value_size = static_cast<std::uint32_t>(stream.size());
    }
    return update;
  }

  static Result<StoreUpdate> stage_stamp(NodeId node, ConfigurationStamp stamp) {
    if (stamp.ms >= kMsPerDay) {
      return Error{"1F27h " + std::to_string(stamp.ms) +
                   " ms is not a time of day (milliseconds after midnight, below 86 400 000)"};
    }
    StoreUpdate update{object::kExpectedConfigurationDate, node, stamp.is_zero(), false, {}, 8};
    append_le(update.stored, stamp.days, 4);
    append_le(update.stored, stamp.ms, 4);
    return update;
  }

  Status persist(const StoreUpdate& update) const {
    if (directory.empty()) return {};
    const std::string name = store_entry_file_name(update.index, update.node);
    if (update.remove) return detail::remove_file_durably(directory, name);
    const auto encoding = update.zlib ? EntryEncoding::Zlib : EntryEncoding::Raw;
    return detail::write_file_atomically(
        directory, name,
        detail::encode_entry_file(update.index, update.node, encoding, update.stored,
                                  update.value_size),
        hooks);
  }

  void commit(StoreUpdate update) {
    NodeSlot& s = slot(update.node);
    switch (update.index) {
      case object::kConciseDcf:
        s.concise = update.remove ? std::vector<std::uint8_t>{} : std::move(update.stored);
        s.concise.shrink_to_fit();
        break;
      case object::kStoreDcf:
      case object::kStoreEds: {
        auto& text = update.index == object::kStoreDcf ? s.dcf : s.eds;
        if (update.remove) {
          text.reset();
        } else {
          text = PackedText{std::move(update.stored), update.value_size};
        }
        break;
      }
      default:  // 1F26h with 1F27h
        s.stamp = update.remove
                      ? ConfigurationStamp{}
                      : ConfigurationStamp{load_le32(update.stored),
                                           load_le32(std::span(update.stored).subspan(4))};
        break;
    }
  }

  /// The C++ API's write: the entry file first, so that memory never holds a value the
  /// directory does not.
  Status apply(Result<StoreUpdate> update) {
    if (!update) return update.error();
    if (auto done = persist(*update); !done) return done;
    commit(std::move(update).value());
    return {};
  }

  void load(const detail::DecodedEntry& entry, const std::string& path) {
    NodeSlot& s = slot(entry.node);
    switch (entry.index) {
      case object::kConciseDcf: {
        // The CRC says the file is as written; the stream is checked too, as anything may have
        // written the file.
        auto decoded = decode_concise_dcf(entry.value);
        if (!decoded) {
          problems.add(path, 0, Severity::Error,
                       "not a valid concise DCF: " + decoded.error().message);
          return;
        }
        if (!decoded->empty()) s.concise = entry.value;  // count 0: the empty data set
        break;
      }
      case object::kStoreDcf:
      case object::kStoreEds: {
        if (entry.index == object::kStoreDcf) {
          const std::string_view text(reinterpret_cast<const char*>(entry.value.data()),
                                      entry.value.size());
          if (auto writes = writes_of_dcf(text, entry.node); !writes) {
            problems.add(path, 0, Severity::Error, writes.error().message);
            return;
          }
        }
        PackedText packed{entry.stored, entry.value_size};
        if (entry.encoding == EntryEncoding::Raw)
          packed.deflated = detail::deflate_bytes(entry.value);
        (entry.index == object::kStoreDcf ? s.dcf : s.eds) = std::move(packed);
        break;
      }
      default: {  // 1F26h with 1F27h
        const ConfigurationStamp stamp{load_le32(entry.value),
                                       load_le32(std::span(entry.value).subspan(4))};
        if (stamp.ms >= kMsPerDay) {
          problems.add(path, 0, Severity::Error,
                       "1F27h " + std::to_string(stamp.ms) + " ms is not a time of day");
          return;
        }
        s.stamp = stamp;
        break;
      }
    }
  }
};

ConfigManager::ConfigManager() : state_(std::make_unique<State>()) {}
ConfigManager::ConfigManager(ConfigManager&&) noexcept = default;
ConfigManager& ConfigManager::operator=(ConfigManager&&) noexcept = default;
ConfigManager::~ConfigManager() = default;

Result<ConfigManager> ConfigManager::open(const std::string& directory, StoreWriteHooks hooks) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(directory, ec);
  if (ec) {
    return Error{"cannot create the store directory '" + directory + "': " + ec.message(),
                 ErrorCategory::Io};
  }
  if (!fs::is_directory(directory, ec)) {
    return Error{"the store '" + directory + "' is not a directory", ErrorCategory::Io};
  }
  if (::access(directory.c_str(), R_OK | W_OK | X_OK) != 0) {
    return Error{"the store directory '" + directory + "' cannot be read and written",
                 ErrorCategory::Io};
  }
  ConfigManager manager;
  manager.state_->directory = directory;
  manager.state_->hooks = std::move(hooks);
  std::vector<fs::path> files;
  for (fs::directory_iterator it(directory, ec), end; !ec && it != end; it.increment(ec)) {
    files.push_back(it->path());
  }
  if (ec) {
    return Error{"cannot list the store directory '" + directory + "': " + ec.message(),
                 ErrorCategory::Io};
  }
  std::sort(files.begin(), files.end());  // problems in a stable order
  for (const fs::path& path : files) {
    const std::string name = path.filename().string();
    if (name.starts_with('.') && name.ends_with(".tmp")) {
      // A write that was interrupted before its rename: the entry still has its old file.
      fs::remove(path, ec);
      continue;
    }
    std::uint16_t index = 0;
    NodeId node = *NodeId::from(1);
    if (!detail::parse_entry_file_name(name, index, node)) continue;  // not ours
    auto text = read_file(path.string());
    if (!text) {
      manager.state_->problems.add(path.string(), 0, Severity::Error, text.error().message);
      continue;
    }
    auto entry = detail::decode_entry_file(as_bytes(text->view()), name);
    if (!entry) {
      manager.state_->problems.add(path.string(), 0, Severity::Error, entry.error().message);
      continue;
    }
    manager.state_->load(*entry, path.string());
  }
  return manager;
}

const Diagnostics& ConfigManager::problems() const {
  return state_->problems;
}

const std::string& ConfigManager::directory() const {
  return state_->directory;
}

Status ConfigManager::put_dcf(NodeId node, std::string_view text) {
  if (!text.empty()) {
    auto writes = writes_of_dcf(text, node);
    if (!writes) return writes.error();
  }
  return state_->apply(State::stage_text(object::kStoreDcf, node, text));
}

Status ConfigManager::put_eds(NodeId node, std::string_view text) {
  return state_->apply(State::stage_text(object::kStoreEds, node, text));
}

Status ConfigManager::put_concise(NodeId node, std::span<const std::uint8_t> stream) {
  return state_->apply(State::stage_concise(node, stream));
}

Status ConfigManager::set_expected_stamp(NodeId node, ConfigurationStamp stamp) {
  return state_->apply(State::stage_stamp(node, stamp));
}

Result<StoreUpdate> ConfigManager::stage_expected_stamp(NodeId node,
                                                        ConfigurationStamp stamp) const {
  return State::stage_stamp(node, stamp);
}

Status ConfigManager::persist(const StoreUpdate& update) const {
  return state_->persist(update);
}

void ConfigManager::commit(StoreUpdate update) {
  state_->commit(std::move(update));
}

std::optional<std::string> ConfigManager::dcf(NodeId node) const {
  const auto& packed = state_->slot(node).dcf;
  if (!packed) return std::nullopt;
  return unpack(*packed);
}

std::optional<std::vector<std::uint8_t>> ConfigManager::concise(NodeId node) const {
  const auto& bytes = state_->slot(node).concise;
  if (bytes.empty()) return std::nullopt;
  return bytes;
}

std::optional<std::string> ConfigManager::eds(NodeId node) const {
  const auto& packed = state_->slot(node).eds;
  if (!packed) return std::nullopt;
  return unpack(*packed);
}

ConfigurationStamp ConfigManager::expected_stamp(NodeId node) const {
  return state_->slot(node).stamp;
}

bool ConfigManager::has_configuration(NodeId node) const {
  const NodeSlot& s = state_->slot(node);
  return !s.concise.empty() || s.dcf.has_value();
}

std::vector<NodeId> ConfigManager::configured_nodes() const {
  std::vector<NodeId> nodes;
  for (unsigned id = kMinNodeId; id <= kMaxNodeId; ++id) {
    const NodeId node = *NodeId::from(id);
    if (has_configuration(node)) nodes.push_back(node);
  }
  return nodes;
}

Result<std::vector<ObjectWrite>> ConfigManager::configuration_or_error(NodeId node) const {
  const NodeSlot& s = state_->slot(node);
  std::vector<ObjectWrite> writes;
  if (!s.concise.empty()) {
    auto decoded = decode_concise_dcf(s.concise);
    if (!decoded) return decoded.error();  // checked when stored: not expected
    writes = std::move(*decoded);
  } else if (s.dcf) {
    auto from_dcf = writes_of_dcf(unpack(*s.dcf), node);
    if (!from_dcf) return Error{dcf_name(node) + ": " + from_dcf.error().message};
    writes = std::move(*from_dcf);
  } else {
    return Error{"node " + std::to_string(node.value()) +
                 " has no configuration (neither 1F22h nor 1F20h stored)"};
  }
  // CiA 302-2 §3.5: 1020h and 1010h are the master's, written after the download.
  std::erase_if(writes, [](const ObjectWrite& w) {
    return w.index == object::kVerifyConfiguration || w.index == object::kStoreParameters;
  });
  return writes;
}

std::optional<std::vector<ObjectWrite>> ConfigManager::configuration(NodeId node) const {
  auto writes = configuration_or_error(node);
  if (!writes) return std::nullopt;
  return std::move(*writes);
}

Result<DownloadPlan> ConfigManager::download_plan(NodeId node, const PlanOptions& options) const {
  auto writes = configuration_or_error(node);
  if (!writes) return writes.error();
  DownloadOrder order = plan_download(*writes, {expected_stamp(node), options.save});
  DownloadPlan plan;
  plan.writes = std::move(order.writes);
  plan.unknown_cob_id = std::move(order.unknown_cob_id);
  plan.unknown_mapping_count = std::move(order.unknown_mapping_count);
  plan.source = state_->slot(node).concise.empty() ? DownloadPlan::Source::Dcf
                                                   : DownloadPlan::Source::ConciseDcf;
  return plan;
}

std::size_t ConfigManager::value_bytes() const {
  std::size_t total = 0;
  for (const NodeSlot& s : state_->nodes) total += value_bytes_of(s);
  return total;
}

std::size_t ConfigManager::stored_bytes() const {
  std::size_t total = 0;
  for (const NodeSlot& s : state_->nodes) {
    total += s.concise.capacity();
    if (s.dcf) total += s.dcf->deflated.capacity();
    if (s.eds) total += s.eds->deflated.capacity();
  }
  return total;
}

// --- SDO access ---------------------------------------------------------------------------------

namespace {

bool is_manager_index(std::uint16_t index) {
  return index >= object::kStoreDcf && index <= object::kExpectedConfigurationTime;
}

std::uint8_t entries_of(std::uint16_t index) {
  return index == object::kConfigureSlave ? kConfigureSlaveEntries : kNodeEntries;
}

std::string address(std::uint16_t index, std::uint8_t sub_index) {
  return to_string(ObjectAddress{index, sub_index});
}

}  // namespace

const ConfigManagerLimits& ConfigManager::limits() const {
  return state_->limits;
}

void ConfigManager::set_limits(ConfigManagerLimits limits) {
  state_->limits = limits;
}

SdoAbort ConfigManager::admits(std::uint16_t index, std::uint8_t sub_index,
                               std::size_t size) const {
  const bool file =
      index == object::kStoreDcf || index == object::kConciseDcf || index == object::kStoreEds;
  const auto node = NodeId::from(sub_index);
  if (!file || !node) return SdoAbort::None;
  const auto& limits = state_->limits;
  if (size > limits.max_entry_bytes) return SdoAbort::OutOfMemory;
  // The written value takes the place of the node's value of that object.
  const std::size_t others = value_bytes() - file_size_of(state_->slot(*node), index);
  return others + size > limits.max_total_bytes ? SdoAbort::OutOfMemory : SdoAbort::None;
}

ConfigRead ConfigManager::read(std::uint16_t index, std::uint8_t sub_index) const {
  if (!is_manager_index(index)) {
    return read_abort(SdoAbort::ObjectDoesNotExist,
                      object_name(index) + " is not an object of the configuration manager");
  }
  if (sub_index == 0) return {SdoAbort::None, {entries_of(index)}, {}};
  if (sub_index > entries_of(index)) {
    return read_abort(SdoAbort::SubIndexDoesNotExist,
                      address(index, sub_index) + " does not exist");
  }
  if (index == object::kConfigureSlave) {
    return read_abort(SdoAbort::ReadOfWriteOnly,
                      "1F25h is write only: 'conf' written to it starts a configuration");
  }
  const NodeId node = *NodeId::from(sub_index);
  const NodeSlot& s = state_->slot(node);
  auto empty = [&] {
    return read_abort(SdoAbort::NoDataAvailable,
                      address(index, sub_index) + ": data set empty (nothing stored)");
  };
  switch (index) {
    case object::kStoreDcf:
      if (!s.dcf) return empty();
      return {SdoAbort::None, unpack_bytes(*s.dcf), {}};
    case object::kStorageFormat:
      if (!s.dcf) return empty();
      return {SdoAbort::None, {kStorageFormatAscii}, {}};
    case object::kConciseDcf:
      // DSP 302 §6.2 application hint 2: nothing stored reads as the stream with count 0.
      if (s.concise.empty()) return {SdoAbort::None, le32_bytes(0), {}};
      return {SdoAbort::None, s.concise, {}};
    case object::kStoreEds:
      if (!s.eds) return empty();
      return {SdoAbort::None, unpack_bytes(*s.eds), {}};
    case object::kStorageFormatEds:
      if (!s.eds) return empty();
      return {SdoAbort::None, {kStorageFormatAscii}, {}};
    case object::kExpectedConfigurationDate:
      return {SdoAbort::None, le32_bytes(s.stamp.days), {}};
    default:  // 1F27h
      return {SdoAbort::None, le32_bytes(s.stamp.ms), {}};
  }
}

ConfigWrite ConfigManager::write(std::uint16_t index, std::uint8_t sub_index,
                                 std::span<const std::uint8_t> data) {
  std::optional<StoreUpdate> update;
  ConfigWrite answer = stage(index, sub_index, data, update);
  if (!answer.ok() || !update) return answer;
  if (auto done = state_->persist(*update); !done) {
    return {SdoAbort::CannotStoreOrTransfer, done.error().message, {}};
  }
  state_->commit(std::move(*update));
  return answer;
}

ConfigWrite ConfigManager::stage(std::uint16_t index, std::uint8_t sub_index,
                                 std::span<const std::uint8_t> data,
                                 std::optional<StoreUpdate>& update) const {
  update.reset();
  // A staged change, or the abort its failure answers (0609 0030h: the value is refused).
  auto staged = [&update](Result<StoreUpdate> result) -> ConfigWrite {
    if (!result) return write_answer(result.error());
    update = std::move(result).value();
    return {};
  };
  if (!is_manager_index(index)) {
    return {SdoAbort::ObjectDoesNotExist,
            object_name(index) + " is not an object of the configuration manager",
            {}};
  }
  if (sub_index == 0) {
    return {SdoAbort::WriteOfReadOnly, address(index, 0) + " (number of entries) is read only", {}};
  }
  if (sub_index > entries_of(index)) {
    return {SdoAbort::SubIndexDoesNotExist, address(index, sub_index) + " does not exist", {}};
  }
  auto wrong_length = [&](std::size_t expected) {
    return ConfigWrite{SdoAbort::LengthMismatch,
                       address(index, sub_index) + " takes " + std::to_string(expected) +
                           " bytes, not " + std::to_string(data.size()),
                       {}};
  };
  if (index == object::kConfigureSlave) {
    if (data.size() != 4) return wrong_length(4);
    if (load_le32(data) != kConfigureSignature) {
      // DSP 302 §6.4: only the signature starts it ("to avoid accidental access"); refused as
      // CiA 301 refuses a wrong 'save' (§7.5.2.13).
      return {SdoAbort::CannotStoreOrTransfer,
              "1F25h takes the signature 'conf' (" + hex(kConfigureSignature, 8) + "), not " +
                  hex(load_le32(data), 8),
              {}};
    }
    if (sub_index == kConfigureAllNodes) return {SdoAbort::None, {}, configured_nodes()};
    const NodeId node = *NodeId::from(sub_index);
    if (!has_configuration(node)) {
      return {SdoAbort::NoDataAvailable,
              "node " + std::to_string(sub_index) + ": data set empty (neither 1F22h nor 1F20h)",
              {}};
    }
    return {SdoAbort::None, {}, {node}};
  }
  if (const auto abort = admits(index, sub_index, data.size()); abort != SdoAbort::None) {
    const auto& limits = state_->limits;
    return {abort,
            address(index, sub_index) + ": out of memory: " + std::to_string(data.size()) +
                " bytes; the manager takes at most " + std::to_string(limits.max_entry_bytes) +
                " bytes per entry and " + std::to_string(limits.max_total_bytes) +
                " bytes for all nodes (" + std::to_string(value_bytes()) + " stored)",
            {}};
  }
  const NodeId node = *NodeId::from(sub_index);
  switch (index) {
    case object::kStoreDcf: {
      const std::string_view text(reinterpret_cast<const char*>(data.data()), data.size());
      if (!text.empty()) {
        if (auto writes = writes_of_dcf(text, node); !writes) return write_answer(writes.error());
      }
      return staged(State::stage_text(index, node, text));
    }
    case object::kStorageFormat:
    case object::kStorageFormatEds:
      if (data.size() != 1) return wrong_length(1);
      if (data[0] != kStorageFormatAscii) {
        return {SdoAbort::ValueRangeExceeded,
                address(index, sub_index) + ": storage format " + hex(data[0], 2) +
                    " is reserved (00h: ASCII, not compressed)",
                {}};
      }
      return {};
    case object::kConciseDcf:
      return staged(State::stage_concise(node, data));
    case object::kStoreEds: {
      const std::string_view text(reinterpret_cast<const char*>(data.data()), data.size());
      return staged(State::stage_text(index, node, text));
    }
    case object::kExpectedConfigurationDate:
    case object::kExpectedConfigurationTime: {
      if (data.size() != 4) return wrong_length(4);
      ConfigurationStamp stamp = expected_stamp(node);
      (index == object::kExpectedConfigurationDate ? stamp.days : stamp.ms) = load_le32(data);
      return staged(State::stage_stamp(node, stamp));
    }
    default:
      return {SdoAbort::ObjectDoesNotExist, object_name(index) + " is not served", {}};
  }
}

}  // namespace cfg
