// The SDO manager's dictionary side (DSP 302 §7.2.3): its objects 1F00h-1F06h and their value
// checks, the 1F02h pool, the 1F03h-1F06h rows, its own server channels 1201h.. for SRDs, the
// frames and time they take, and what a lost or booted node takes out of the tables. The jobs a
// write of 1F00h/1F01h, a 6E0h or a loss queues run in sdo_manager_jobs.cpp; the engine and its
// port are described in sdo_manager_process.hpp.
#include <algorithm>
#include <utility>
#include <variant>

#include "cfg/bytes.hpp"
#include "cfg/object_index.hpp"
#include "manager/sdo_manager_process.hpp"
#include "master/master_support.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

namespace sm = cfg::sdo_manager;
using sm::ManagerCobId;

// The pool a master DCF without 1F02h gets: identifiers the pre-defined connection set of
// CiA 301 neither uses nor restricts.
constexpr std::uint32_t kPoolFirst = 0x680;
constexpr std::uint32_t kPoolLast = 0x6DF;

constexpr std::uint16_t kDefaultServer = obj::kSdoServerFirst;  // 1200h
// §7.2.3: 1F03h-1F06h, 254 rows each; rows are numbered from 1.
constexpr unsigned kRows = sm::kConnectionsPerPart * sm::kConnectionParts;

sm::ConnectionSlot slot_of(std::uint16_t row) {
  return sm::connection_slot(row - 1U);
}

}  // namespace

SdoManagerProcess::SdoManagerProcess(LocalDictionary& dict, SdoManagerPort& port, cfg::NodeId node,
                                     SdoManagerSettings settings)
    : dict_(dict), port_(port), node_id_(node), settings_(settings), channels_(dict) {}

// --- objects ---

void SdoManagerProcess::install() {
  enabled_ = settings_.enabled || dict_.has_object(obj::kSdoRequest);
  if (!enabled_) return;
  using T = cfg::DataType;
  using A = cfg::AccessType;
  // §7.2.3: 1F00h and 1F01h are write-only requests, whatever the file says.
  for (const auto& [index, name] :
       {std::pair{obj::kSdoRequest, "Request SDO"}, std::pair{obj::kSdoRelease, "Release SDO"}}) {
    auto entry = dict_.entry(index, 0) != nullptr
                     ? *dict_.entry(index, 0)
                     : make_entry(index, 0, name, T::Unsigned32, A::Wo, 0);
    entry.access = A::Wo;
    dict_.insert(std::move(entry));
  }
  if (!dict_.has_object(obj::kSdoManagerCobIds)) {
    const auto count = kPoolLast - kPoolFirst + 1;
    dict_.insert(make_entry(obj::kSdoManagerCobIds, 0, "Highest sub-index supported", T::Unsigned8,
                            A::Const, count));
    for (std::uint32_t i = 0; i < count; ++i) {
      dict_.insert(make_entry(obj::kSdoManagerCobIds, static_cast<std::uint8_t>(i + 1),
                              "SDO manager COB-ID " + std::to_string(i + 1), T::Unsigned32, A::Rw,
                              kPoolFirst + i));
    }
  }
  for (unsigned part = 0; part < sm::kConnectionParts; ++part) {
    const auto index = static_cast<std::uint16_t>(obj::kSdoConnectionsFirst + part);
    if (dict_.has_object(index)) continue;
    dict_.insert(make_entry(index, 0, "Highest sub-index supported", T::Unsigned8, A::Const,
                            sm::kConnectionsPerPart));
    for (unsigned sub = 1; sub <= sm::kConnectionsPerPart; ++sub) {
      dict_.insert(
          make_entry(index, static_cast<std::uint8_t>(sub),
                     "SDO connection " + std::to_string(part * sm::kConnectionsPerPart + sub),
                     T::Unsigned32, A::Ro, 0));
    }
  }
  // The server channels SRDs get (CiA 301 1201h..), invalid until one registers.
  const unsigned channels = std::clamp<unsigned>(settings_.channels, 1, 127);
  for (unsigned i = 1; i <= channels; ++i) {
    const auto index = static_cast<std::uint16_t>(obj::kSdoServerFirst + i);
    if (dict_.has_object(index)) continue;
    dict_.insert(make_entry(index, 0, "Highest sub-index supported", T::Unsigned8, A::Const, 3));
    dict_.insert(make_entry(index, 1, "COB-ID client -> server", T::Unsigned32, A::Rw,
                            cfg::kCobIdInvalidBit));
    dict_.insert(make_entry(index, 2, "COB-ID server -> client", T::Unsigned32, A::Rw,
                            cfg::kCobIdInvalidBit));
    dict_.insert(make_entry(index, 3, "Node-ID of the SDO client", T::Unsigned8, A::Rw, 0));
  }
  dict_.add_write_hook([this](std::uint16_t index, std::uint8_t sub,
                              std::span<const std::uint8_t> data,
                              TimePoint /*now*/) { return check_write(index, sub, data); });
}

bool SdoManagerProcess::active() const {
  return enabled_ && port_.master_active();
}

std::uint32_t SdoManagerProcess::value_of(std::uint16_t index, std::uint8_t sub) const {
  return static_cast<std::uint32_t>(dict_.get_unsigned(index, sub).value_or(0));
}

SdoAbort SdoManagerProcess::check_write(std::uint16_t index, std::uint8_t sub,
                                        std::span<const std::uint8_t> data) {
  // Every write comes here, DOMAINs of any length too (1F22h, 1F50h); the objects below have had
  // their size checked by the dictionary (0607 0010).
  const auto value = cfg::low_le32(data);
  if (index == obj::kSdoManagerCobIds) {
    if (sub == 0) return SdoAbort::None;
    for (std::uint8_t s = 1; s <= value_of(obj::kSdoManagerCobIds, 0) && s != 0; ++s) {
      if (ManagerCobId::decode(value_of(obj::kSdoManagerCobIds, s)).in_use()) {
        return SdoAbort::DeviceState;
      }
    }
    // Bit 30 is the manager's; an 11-bit entry has bits 28-11 clear (§7.2.3).
    const auto entry = ManagerCobId::decode(value);
    if (entry.in_use() || !entry.cob_id().well_formed()) return SdoAbort::ValueRangeExceeded;
    return SdoAbort::None;
  }
  if (obj::is_sdo_server_parameter(index) && index != kDefaultServer) {
    // The manager's own server channels for SRDs (choice, docs/master.md): it opens and
    // closes them; §7.2.3 lets tools change connections only through 1F00h/1F01h.
    return SdoAbort::LocalControl;
  }
  if (index != obj::kSdoRequest && index != obj::kSdoRelease) return SdoAbort::None;
  if (!active()) return SdoAbort::DeviceState;
  // The node-IDs of 1F00h/1F01h are checked here, once. §7.2.3: a refused request is aborted
  // with 060A 0023h ("Resource not available: SDO connection"): an SRD node-ID that is no
  // registered SRD (0 and 80h-FFh never are), or one not of the channel written on.
  const auto request = sm::SdoRequest::decode(value);
  const auto srd = cfg::NodeId::from(request.srd_node_id);
  if (!srd || srds_.count(*srd) == 0) return SdoAbort::ResourceNotAvailable;
  if (writer_ && *writer_ != *srd) return SdoAbort::ResourceNotAvailable;
  // 1F01h slave node-ID 0: release everything and de-register.
  if (index == obj::kSdoRelease && request.deregister()) return deregister(*srd);
  // 1F00h: "The requested Node-ID must not be 0"; 80h-FFh name no node either.
  const auto slave = cfg::NodeId::from(request.slave_node_id);
  if (!slave) return SdoAbort::ResourceNotAvailable;
  return index == obj::kSdoRequest ? request_connection(*srd, *slave, request.client_index)
                                   : release_connections(*srd, *slave, request.client_index);
}

SdoAbort SdoManagerProcess::request_connection(cfg::NodeId srd, cfg::NodeId slave,
                                               std::uint16_t client_index) {
  if (slave == srd || slave == node_id_) return SdoAbort::ResourceNotAvailable;
  if (!obj::is_sdo_client_parameter(client_index)) return SdoAbort::ValueRangeExceeded;
  const bool taken =
      srds_.at(srd).info.client_index == client_index ||
      std::any_of(connections_.begin(), connections_.end(),
                  [&](const Connection& c) {
                    return c.row.srd == srd && c.row.client_index == client_index;
                  }) ||
      std::any_of(jobs_.begin(), jobs_.end(), [&](const Job& j) {
        const auto* connect = std::get_if<ConnectJob>(&j.work);
        return connect != nullptr && connect->srd == srd && connect->client_index == client_index;
      });
  if (taken) return SdoAbort::ResourceNotAvailable;
  // A bounded queue (MasterOptions::sdo_manager.max_queued_requests): 0504 0005, the request
  // is valid but there is no room to keep it.
  const auto queued = std::count_if(jobs_.begin(), jobs_.end(), [](const Job& j) {
    return std::holds_alternative<ConnectJob>(j.work);
  });
  if (static_cast<std::size_t>(queued) >= settings_.max_queued_requests) {
    return SdoAbort::OutOfMemory;
  }
  jobs_.push_back(
      Job{.work = ConnectJob{.srd = srd, .slave = slave, .client_index = client_index}});
  return SdoAbort::None;
}

SdoAbort SdoManagerProcess::release_connections(cfg::NodeId srd, cfg::NodeId slave,
                                                std::uint16_t client_index) {
  auto rows = take_connections([&](const ManagedSdoConnection& c) {
    return c.srd == srd && !c.to_manager && c.server == slave &&
           (client_index == 0 || c.client_index == client_index);
  });
  if (!rows.empty()) {
    release_job(srd, std::move(rows), false, false,
                {.kind = SdoManagerReason::Kind::Releases, .node = srd});
  }
  return SdoAbort::None;
}

SdoAbort SdoManagerProcess::deregister(cfg::NodeId srd) {
  auto rows = take_connections([&](const ManagedSdoConnection& c) { return c.srd == srd; });
  release_job(srd, std::move(rows), true, false,
              {.kind = SdoManagerReason::Kind::Deregisters, .node = srd});
  srds_.erase(srd);
  return SdoAbort::None;
}

// --- frames and time ---

bool SdoManagerProcess::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  bool taken = false;
  if (port_.serves_sdo()) {
    Outbox<NoEvent> server_out;
    // 1F00h/1F01h learn the writer from the channel: the SRD it was opened for.
    taken = channels_
                .on_frame(frame, now, server_out, HookOutput(out),
                          [this](std::uint16_t index) {
                            const auto client = channel_clients_.find(index);
                            if (client != channel_clients_.end()) writer_ = client->second;
                          })
                .has_value();
    writer_.reset();
    for (const auto& f : server_out.frames) out.send(f);
  }
  if (frame.id != sm::kDynamicSdoRequestCanId || frame.extended || frame.rtr || frame.dlc != 0) {
    return taken;
  }
  if (!active()) return taken;  // a standby master ignores it
  queue_scan();
  return true;
}

void SdoManagerProcess::on_timer(TimePoint now, Output& out) {
  if (port_.serves_sdo()) {
    Outbox<NoEvent> server_out;
    channels_.on_timer(now, server_out);
    for (const auto& f : server_out.frames) out.send(f);
  }
  pump(now, out);
}

std::optional<TimePoint> SdoManagerProcess::next_deadline() const {
  std::optional<TimePoint> due = channels_.next_deadline();
  // Queued work starts from the next call.
  if (!in_flight_ && !jobs_.empty() && active()) due = TimePoint{};
  return due;
}

void SdoManagerProcess::clear() {
  for (auto& c : connections_) set_row(c.row.row, 0);
  connections_.clear();
  for (const auto& [node, srd] : srds_) port_.unwatch(node);
  for (const auto node : watched_) port_.unwatch(node);
  srds_.clear();
  watched_.clear();
  jobs_.clear();
  in_flight_ = false;
  ++serial_;  // results of transfers still running are stale
  rescan_ = false;
  for (const auto index : channels_.indices()) close_channel(index);
  const auto count = value_of(obj::kSdoManagerCobIds, 0);
  for (std::uint32_t sub = 1; sub <= count && sub <= 0xFF; ++sub) {
    mark_pool(static_cast<std::uint8_t>(sub), false);
  }
}

void SdoManagerProcess::queue_scan() {
  const auto scan = std::find_if(jobs_.begin(), jobs_.end(), [](const Job& j) {
    return std::holds_alternative<ScanJob>(j.work);
  });
  if (scan == jobs_.end()) {
    jobs_.push_back(scan_job());
  } else if (std::get<ScanJob>(scan->work).started) {
    rescan_ = true;  // the running scan may have passed the new SRD
  }
}

// --- losses: rows taken from the tables, release jobs queued (they run in sdo_manager_jobs.cpp)
// ---

void SdoManagerProcess::node_lost(cfg::NodeId node, TimePoint now, Output& out) {
  if (!enabled_) return;
  if (srds_.count(node) != 0) {
    srd_gone(node, false, now, out);
    return;
  }
  if (watched_.count(node) == 0) return;
  // §7.2.2 "Error Control of Slave Devices": 1F11h on each SRD with Req EC, then its client
  // entry cleared.
  watched_.erase(node);
  port_.unwatch(node);
  auto rows = take_connections([&](const ManagedSdoConnection& c) {
    const auto srd = srds_.find(c.srd);
    return c.server == node && !c.to_manager && srd != srds_.end() &&
           srd->second.info.slave_error_control;
  });
  release_per_srd(rows, node, {.kind = SdoManagerReason::Kind::SlaveFailed, .node = node});
}

void SdoManagerProcess::node_booted(cfg::NodeId node, TimePoint now, Output& out) {
  if (!enabled_) return;
  if (srds_.count(node) != 0) {
    srd_gone(node, true, now, out);  // an SRD that booted forgot its entries
    return;
  }
  slave_booted(node);
}

void SdoManagerProcess::srd_gone(cfg::NodeId node, bool boot_up, TimePoint now, Output& out) {
  // §7.2.1: "the Manager forces all SDOs requested by that SRD to be released".
  auto rows = take_connections([node](const ManagedSdoConnection& c) { return c.srd == node; });
  srds_.erase(node);
  port_.unwatch(node);
  const SdoManagerReason why{
      .kind = boot_up ? SdoManagerReason::Kind::SrdBootedUp : SdoManagerReason::Kind::SrdLost,
      .node = node};
  auto e = master_event(MasterEvent::Kind::SrdLost, now, node);
  e.manager_reason = why;
  e.released = rows.size();
  out.report(std::move(e));
  release_job(node, std::move(rows), true, true, why);
}

void SdoManagerProcess::slave_booted(cfg::NodeId node) {
  // CiA 301: the server entries 1201h.. a slave had written into it are not kept over a reset
  // (a boot-up follows every reset, the master's own too): those connections are gone on S, so
  // their rows go and each SRD's client entry is invalidated. S's default SDO survives (its
  // COB-IDs are fixed): a connection on it stays.
  auto rows = take_connections([node](const ManagedSdoConnection& c) {
    return c.server == node && !c.to_manager && c.server_index != kDefaultServer;
  });
  release_per_srd(rows, std::nullopt,
                  {.kind = SdoManagerReason::Kind::SlaveBootedUp, .node = node});
}

void SdoManagerProcess::release_per_srd(const std::vector<Connection>& rows,
                                        std::optional<cfg::NodeId> failed,
                                        const SdoManagerReason& why) {
  // S's side is gone (it failed, or its reset dropped the entry): only the SRDs are written.
  std::map<cfg::NodeId, std::vector<Connection>> by_srd;
  for (const auto& c : rows) by_srd[c.srd()].push_back(c);
  for (auto& [srd, its_rows] : by_srd) {
    jobs_.push_back(Job{.work = ReleaseJob{.srd = srd,
                                           .releases = std::move(its_rows),
                                           .why = why,
                                           .failed = failed,  // 1F11h first
                                           .server_gone = true}});
  }
}

void SdoManagerProcess::release_job(cfg::NodeId srd, std::vector<Connection> rows, bool deregister,
                                    bool lost, SdoManagerReason why) {
  // The SRD's channel to the manager goes last: the SRD keeps its line until the end.
  std::stable_partition(rows.begin(), rows.end(),
                        [](const Connection& c) { return !c.row.to_manager; });
  jobs_.push_back(Job{.work = ReleaseJob{.srd = srd,
                                         .releases = std::move(rows),
                                         .why = std::move(why),
                                         .deregister = deregister,
                                         .srd_lost = lost}});
}

// --- tables ---

std::vector<std::uint8_t> SdoManagerProcess::free_pool() const {
  std::vector<std::uint8_t> free;
  const auto count = value_of(obj::kSdoManagerCobIds, 0);
  for (std::uint32_t sub = 1; sub <= count && sub <= 0xFF; ++sub) {
    const auto word = value_of(obj::kSdoManagerCobIds, static_cast<std::uint8_t>(sub));
    if (ManagerCobId::decode(word).free()) free.push_back(static_cast<std::uint8_t>(sub));
  }
  return free;
}

cfg::CobId SdoManagerProcess::pool_cob_id(std::uint8_t sub) const {
  // Without the manager's bits.
  return ManagerCobId::decode(value_of(obj::kSdoManagerCobIds, sub)).cob_id();
}

void SdoManagerProcess::mark_pool(std::uint8_t sub, bool in_use) {
  if (sub == 0 || !dict_.entry(obj::kSdoManagerCobIds, sub)) return;
  const auto entry = ManagerCobId::decode(value_of(obj::kSdoManagerCobIds, sub));
  dict_.set_unsigned(obj::kSdoManagerCobIds, sub, entry.with_in_use(in_use).encode());
}

std::uint16_t SdoManagerProcess::free_own_channel() const {
  for (unsigned i = obj::kSdoServerFirst + 1; i <= obj::kSdoServerLast; ++i) {
    const auto candidate = static_cast<std::uint16_t>(i);
    if (!dict_.entry(candidate, 1) || channels_.is_open(candidate)) continue;
    if ((value_of(candidate, 1) & cfg::kCobIdInvalidBit) == 0) continue;
    return candidate;
  }
  return 0;
}

void SdoManagerProcess::open_channel(std::uint16_t index, const Connection& c) {
  dict_.set_unsigned(index, 3, c.row.srd);
  dict_.set_unsigned(index, 1, c.row.request.word());
  dict_.set_unsigned(index, 2, c.row.response.word());
  // Served as the dictionary now says (CiA 301 §7.5.2.33), with the default channel's settings.
  SdoServerConfig config = SdoServerConfig::from_dictionary(dict_, index);
  config.timeout = settings_.server_timeout;
  config.block_transfer = settings_.server_block_transfer;
  channels_.open(index, config);
  channel_clients_.insert_or_assign(index, c.srd());
}

void SdoManagerProcess::close_channel(std::uint16_t index) {
  dict_.set_unsigned(index, 1, value_of(index, 1) | cfg::kCobIdInvalidBit);
  dict_.set_unsigned(index, 2, value_of(index, 2) | cfg::kCobIdInvalidBit);
  dict_.set_unsigned(index, 3, 0);
  channels_.close(index);
  channel_clients_.erase(index);
}

std::uint16_t SdoManagerProcess::free_row() const {
  for (std::uint16_t row = 1; row <= kRows; ++row) {
    if (!dict_.entry(slot_of(row).index, slot_of(row).sub_index)) break;
    const bool used = std::any_of(connections_.begin(), connections_.end(),
                                  [&](const Connection& c) { return c.row.row == row; });
    if (!used) return row;
  }
  return 0;
}

void SdoManagerProcess::set_row(std::uint16_t row, std::uint32_t word) {
  const auto slot = slot_of(row);
  dict_.set_unsigned(slot.index, slot.sub_index, word);
}

void SdoManagerProcess::add_row(const Connection& c) {
  if (c.row.row != 0) {
    set_row(c.row.row,
            sm::SdoConnection::of(c.row.client_index, c.row.srd, c.row.server_index, c.row.server)
                .encode());
  }
  connections_.push_back(c);
}

std::vector<SdoManagerProcess::Connection> SdoManagerProcess::take_connections(
    const std::function<bool(const ManagedSdoConnection&)>& match) {
  std::vector<Connection> taken;
  for (auto c = connections_.begin(); c != connections_.end();) {
    if (!match(c->row)) {
      ++c;
      continue;
    }
    taken.push_back(*c);
    set_row(c->row.row, 0);
    c = connections_.erase(c);
  }
  return taken;
}

bool SdoManagerProcess::default_sdo_taken(cfg::NodeId node) const {
  return std::any_of(connections_.begin(), connections_.end(), [&](const Connection& c) {
    return c.row.server == node && c.row.server_index == kDefaultServer;
  });
}

bool SdoManagerProcess::all_default_sdos_owned() const {
  return std::any_of(srds_.begin(), srds_.end(),
                     [](const auto& s) { return s.second.info.all_default_sdos; });
}

bool SdoManagerProcess::default_sdo_given_out(cfg::NodeId node) const {
  if (!enabled_) return false;
  return default_sdo_taken(node) || all_default_sdos_owned();
}

std::vector<ManagedSdoConnection> SdoManagerProcess::connections() const {
  std::vector<ManagedSdoConnection> rows;
  for (const auto& c : connections_) rows.push_back(c.row);
  std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.row < b.row; });
  return rows;
}

std::vector<RegisteredSrd> SdoManagerProcess::srds() const {
  std::vector<RegisteredSrd> out;
  for (const auto& [node, srd] : srds_) out.push_back(srd.info);
  return out;
}

}  // namespace nmt
