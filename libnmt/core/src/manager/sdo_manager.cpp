// The SDO manager of NmtMaster (DSP 302 §7): registration of SDO requesting devices (SRDs) after
// the Dynamic SDO Request, the connections an SRD asks for with 1F00h and gives back with 1F01h,
// the error control of SRDs (and of slaves for SRDs that asked), and its objects 1F00h-1F06h.
// The choices where §7 leaves room are listed at the top of nmt/nmt_master.hpp.
//
// The work runs as jobs, one at a time (SdoManager::jobs; a scan lets the others go first between
// its reads), each a sequence of SDO accesses over the master's default SDO clients; a
// 1F00h/1F01h write only queues one (§7.2.3: a successful response means the manager started).
#include <algorithm>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "cfg/sdo_manager_objects.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

namespace sm = cfg::sdo_manager;
using sm::ConnectionState;
using sm::DynamicSdoError;
using sm::DynamicSdoState;
using sm::ManagerCobId;

// The pool a master DCF without 1F02h gets: identifiers the pre-defined connection set of
// CiA 301 neither uses nor restricts.
constexpr std::uint32_t kPoolFirst = 0x680;
constexpr std::uint32_t kPoolLast = 0x6DF;

constexpr std::uint16_t kDefaultServer = obj::kSdoServerFirst;  // 1200h
constexpr std::uint8_t kGuardLifeTimeFactor = 3;
// §7.2.3: 1F03h-1F06h, 254 rows each; rows are numbered from 1.
constexpr unsigned kRows = sm::kConnectionsPerPart * sm::kConnectionParts;

sm::ConnectionSlot slot_of(std::uint16_t row) {
  return sm::connection_slot(row - 1U);
}
void set_row(LocalDictionary& dict, std::uint16_t row, std::uint32_t word) {
  const auto slot = slot_of(row);
  dict.set_unsigned(slot.index, slot.sub_index, word);
}
/// The COB-ID of 1F02h sub `sub` without the manager's bits.
cfg::CobId pool_cob_id(const LocalDictionary& dict, std::uint8_t sub) {
  return ManagerCobId::decode(
             static_cast<std::uint32_t>(dict.get_unsigned(obj::kSdoManagerCobIds, sub).value_or(0)))
      .cob_id();
}
std::uint32_t row_word(const ManagedSdoConnection& c) {
  return sm::SdoConnection::of(c.client_index, c.srd, c.server_index, c.server).encode();
}

std::string cob_text(cfg::CobId id) {
  return cfg::hex(id.can_id().id, 3);
}

std::string connection_text(const ManagedSdoConnection& c) {
  return node_text(c.srd) + " " + cfg::object_name(c.client_index) + " -> " + node_text(c.server) +
         " " + cfg::object_name(c.server_index) + " (COB-IDs " + cob_text(c.request) + "/" +
         cob_text(c.response) + ")";
}

SdoManager::Step write_step(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                            std::uint32_t value, std::size_t size, bool must_succeed = true,
                            bool retry = true) {
  SdoManager::Step s;
  s.node = node;
  s.index = index;
  s.sub = sub;
  s.value = value;
  s.size = size;
  s.must_succeed = must_succeed;
  s.retry = retry;
  return s;
}

SdoManager::Step read_step(std::uint8_t node, std::uint16_t index, std::uint8_t sub,
                           bool retry = true) {
  // must_succeed false: the phase looks at the result.
  auto s = write_step(node, index, sub, 0, 0, false, retry);
  s.upload = true;
  return s;
}

}  // namespace

// --- objects ---

void NmtMaster::Impl::install_sdo_manager() {
  sdo_manager.enabled = options.sdo_manager || dict.has_object(obj::kSdoRequest);
  if (!sdo_manager.enabled) return;
  using T = cfg::DataType;
  using A = cfg::AccessType;
  // §7.2.3: 1F00h and 1F01h are write-only requests, whatever the file says.
  for (const auto& [index, name] :
       {std::pair{obj::kSdoRequest, "Request SDO"}, std::pair{obj::kSdoRelease, "Release SDO"}}) {
    auto entry = dict.entry(index, 0) != nullptr
                     ? *dict.entry(index, 0)
                     : make_entry(index, 0, name, T::Unsigned32, A::Wo, 0);
    entry.access = A::Wo;
    dict.insert(std::move(entry));
  }
  if (!dict.has_object(obj::kSdoManagerCobIds)) {
    const auto count = kPoolLast - kPoolFirst + 1;
    dict.insert(make_entry(obj::kSdoManagerCobIds, 0, "Highest sub-index supported", T::Unsigned8,
                           A::Const, count));
    for (std::uint32_t i = 0; i < count; ++i) {
      dict.insert(make_entry(obj::kSdoManagerCobIds, static_cast<std::uint8_t>(i + 1),
                             "SDO manager COB-ID " + std::to_string(i + 1), T::Unsigned32, A::Rw,
                             kPoolFirst + i));
    }
  }
  for (unsigned part = 0; part < sm::kConnectionParts; ++part) {
    const auto index = static_cast<std::uint16_t>(obj::kSdoConnectionsFirst + part);
    if (dict.has_object(index)) continue;
    dict.insert(make_entry(index, 0, "Highest sub-index supported", T::Unsigned8, A::Const,
                           sm::kConnectionsPerPart));
    for (unsigned sub = 1; sub <= sm::kConnectionsPerPart; ++sub) {
      dict.insert(
          make_entry(index, static_cast<std::uint8_t>(sub),
                     "SDO connection " + std::to_string(part * sm::kConnectionsPerPart + sub),
                     T::Unsigned32, A::Ro, 0));
    }
  }
  // The server channels SRDs get (CiA 301 1201h..), invalid until one registers.
  const unsigned channels = std::clamp<unsigned>(options.sdo_manager_channels, 1, 127);
  for (unsigned i = 1; i <= channels; ++i) {
    const auto index = static_cast<std::uint16_t>(obj::kSdoServerFirst + i);
    if (dict.has_object(index)) continue;
    dict.insert(make_entry(index, 0, "Highest sub-index supported", T::Unsigned8, A::Const, 3));
    dict.insert(make_entry(index, 1, "COB-ID client -> server", T::Unsigned32, A::Rw,
                           cfg::kCobIdInvalidBit));
    dict.insert(make_entry(index, 2, "COB-ID server -> client", T::Unsigned32, A::Rw,
                           cfg::kCobIdInvalidBit));
    dict.insert(make_entry(index, 3, "Node-ID of the SDO client", T::Unsigned8, A::Rw, 0));
  }
  dict.add_write_hook([this](std::uint16_t index, std::uint8_t sub,
                             std::span<const std::uint8_t> data,
                             TimePoint /*now*/) { return manager_write(index, sub, data); });
}

bool NmtMaster::Impl::manager_active() const {
  // §7: "The SDO Manager is active only if the NMT Master residing on the same device is active."
  if (!sdo_manager.enabled || !startup_config().is_master() || !acts_as_master()) return false;
  return startup == StartupState::BootingSlaves || startup == StartupState::Halted ||
         startup == StartupState::AwaitApplication || startup == StartupState::Operational;
}

SdoAbort NmtMaster::Impl::manager_write(std::uint16_t index, std::uint8_t sub,
                                        std::span<const std::uint8_t> data) {
  // Every write comes here, DOMAINs of any length too (1F22h, 1F50h); the objects below have had
  // their size checked by the dictionary (0607 0010).
  const auto value = low_u32(data);
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
    // The manager's own server channels for SRDs (choice, nmt/nmt_master.hpp): it opens and
    // closes them; §7.2.3 lets tools change connections only through 1F00h/1F01h.
    return SdoAbort::LocalControl;
  }
  if (index != obj::kSdoRequest && index != obj::kSdoRelease) return SdoAbort::None;
  if (!manager_active()) return SdoAbort::DeviceState;
  const auto request = sm::SdoRequest::decode(value);
  const auto slave = request.slave_node_id;
  const auto srd = request.srd_node_id;
  const auto client_index = request.client_index;
  // §7.2.3: refused with 060A 0023 ("Resource not available: SDO connection").
  const auto it = sdo_manager.srds.find(srd);
  if (it == sdo_manager.srds.end()) return SdoAbort::ResourceNotAvailable;
  if (sdo_manager.writer != 0 && sdo_manager.writer != srd) return SdoAbort::ResourceNotAvailable;
  if (index == obj::kSdoRequest) {
    if (!cfg::is_node_id(slave) || slave == srd || slave == node_id.value()) {
      return SdoAbort::ResourceNotAvailable;
    }
    if (!obj::is_sdo_client_parameter(client_index)) return SdoAbort::ValueRangeExceeded;
    const bool taken = it->second.info.client_index == client_index ||
                       std::any_of(sdo_manager.connections.begin(), sdo_manager.connections.end(),
                                   [&](const SdoManager::Connection& c) {
                                     return c.row.srd == srd && c.row.client_index == client_index;
                                   }) ||
                       std::any_of(sdo_manager.jobs.begin(), sdo_manager.jobs.end(),
                                   [&](const SdoManager::Job& j) {
                                     return j.kind == SdoManager::Job::Kind::Connect &&
                                            j.node == srd && j.client_index == client_index;
                                   });
    if (taken) return SdoAbort::ResourceNotAvailable;
    // A bounded queue (MasterOptions::sdo_manager_max_queued_requests): 0504 0005, the request
    // is valid but there is no room to keep it.
    const auto queued = std::count_if(
        sdo_manager.jobs.begin(), sdo_manager.jobs.end(),
        [](const SdoManager::Job& j) { return j.kind == SdoManager::Job::Kind::Connect; });
    if (static_cast<std::size_t>(queued) >= options.sdo_manager_max_queued_requests) {
      return SdoAbort::OutOfMemory;
    }
    SdoManager::Job job;
    job.kind = SdoManager::Job::Kind::Connect;
    job.node = srd;
    job.slave = slave;
    job.client_index = client_index;
    sdo_manager.jobs.push_back(std::move(job));
    return SdoAbort::None;
  }
  // 1F01h: slave 0 releases everything and de-registers; index 0 every connection to the slave.
  if (slave != 0 && !cfg::is_node_id(slave)) return SdoAbort::ResourceNotAvailable;
  auto rows = manager_take_connections([&](const ManagedSdoConnection& c) {
    return c.srd == srd && (slave == 0 || (!c.to_manager && c.server == slave &&
                                           (client_index == 0 || c.client_index == client_index)));
  });
  if (slave == 0) {
    manager_release_job(srd, std::move(rows), true, false,
                        "1F01h: " + node_text(srd) + " de-registers");
    sdo_manager.srds.erase(srd);
  } else if (!rows.empty()) {
    manager_release_job(srd, std::move(rows), false, false,
                        "1F01h: " + node_text(srd) + " releases");
  }
  return SdoAbort::None;
}

// --- frames and time ---

bool NmtMaster::Impl::manager_frame(const CanFrame& frame, TimePoint /*now*/) {
  if (frame.id != sm::kDynamicSdoRequestCanId || frame.extended || frame.rtr || frame.dlc != 0) {
    return false;
  }
  if (!manager_active()) return false;  // a standby master ignores it
  using Kind = SdoManager::Job::Kind;
  const auto scan = std::find_if(sdo_manager.jobs.begin(), sdo_manager.jobs.end(),
                                 [](const SdoManager::Job& j) { return j.kind == Kind::Scan; });
  if (scan == sdo_manager.jobs.end()) {
    SdoManager::Job job;
    job.kind = Kind::Scan;
    sdo_manager.jobs.push_back(std::move(job));
  } else if (scan->phase != SdoManager::Job::Phase::Start) {
    sdo_manager.rescan = true;  // the running scan may have passed the new SRD
  }
  return true;
}

bool NmtMaster::Impl::manager_servers_frame(const CanFrame& frame, TimePoint now, Output& out) {
  Outbox<NoEvent> server_out;
  // 1F00h/1F01h learn the writer from the channel: the SRD it was opened for.
  const auto taken = sdo_manager.channels.on_frame(
      frame, now, server_out,
      [this](std::uint16_t index) { sdo_manager.writer = sdo_manager.channel_clients[index]; });
  sdo_manager.writer = 0;
  for (const auto& f : server_out.frames) out.send(f);
  return taken.has_value();
}

void NmtMaster::Impl::manager_servers_timer(TimePoint now, Output& out) {
  Outbox<NoEvent> server_out;
  sdo_manager.channels.on_timer(now, server_out);
  for (const auto& f : server_out.frames) out.send(f);
}

std::optional<TimePoint> NmtMaster::Impl::manager_deadline() const {
  std::optional<TimePoint> due = sdo_manager.channels.next_deadline();
  // Queued work starts from the next call.
  if (!sdo_manager.in_flight && !sdo_manager.jobs.empty() && manager_active()) due = TimePoint{0};
  return due;
}

void NmtMaster::Impl::manager_clear() {
  for (auto& c : sdo_manager.connections) set_row(dict, c.row.row, 0);
  sdo_manager.connections.clear();
  for (const auto& [node, srd] : sdo_manager.srds) {
    if (!is_slave(node)) stop_error_control(node);
  }
  for (auto node : sdo_manager.watched) {
    if (!is_slave(node)) stop_error_control(node);
  }
  sdo_manager.srds.clear();
  sdo_manager.watched.clear();
  sdo_manager.jobs.clear();
  sdo_manager.in_flight = false;
  ++sdo_manager.serial;  // results of transfers still running are stale
  sdo_manager.rescan = false;
  for (const auto index : sdo_manager.channels.indices()) manager_close_channel(index);
  const auto count = value_of(obj::kSdoManagerCobIds, 0);
  for (std::uint32_t sub = 1; sub <= count && sub <= 0xFF; ++sub) {
    manager_mark_pool(static_cast<std::uint8_t>(sub), false);
  }
}

// --- tables ---

std::vector<std::uint8_t> NmtMaster::Impl::manager_free_pool() const {
  std::vector<std::uint8_t> free;
  const auto count = value_of(obj::kSdoManagerCobIds, 0);
  for (std::uint32_t sub = 1; sub <= count && sub <= 0xFF; ++sub) {
    const auto word = value_of(obj::kSdoManagerCobIds, static_cast<std::uint8_t>(sub));
    if (ManagerCobId::decode(word).free()) free.push_back(static_cast<std::uint8_t>(sub));
  }
  return free;
}

void NmtMaster::Impl::manager_mark_pool(std::uint8_t sub, bool in_use) {
  if (sub == 0 || !dict.entry(obj::kSdoManagerCobIds, sub)) return;
  const auto entry = ManagerCobId::decode(value_of(obj::kSdoManagerCobIds, sub));
  dict.set_unsigned(obj::kSdoManagerCobIds, sub, entry.with_in_use(in_use).encode());
}

void NmtMaster::Impl::manager_open_channel(std::uint16_t index, const SdoManager::Connection& c) {
  dict.set_unsigned(index, 3, c.row.srd);
  dict.set_unsigned(index, 1, c.row.request.word());
  dict.set_unsigned(index, 2, c.row.response.word());
  // Served as the dictionary now says (CiA 301 §7.5.2.33), with the default channel's settings.
  SdoServerConfig config = SdoServerConfig::from_dictionary(dict, index);
  config.timeout = server.config().timeout;
  config.block_transfer = server.config().block_transfer;
  sdo_manager.channels.open(index, config);
  sdo_manager.channel_clients[index] = c.row.srd;
}

void NmtMaster::Impl::manager_close_channel(std::uint16_t index) {
  dict.set_unsigned(index, 1, value_of(index, 1) | cfg::kCobIdInvalidBit);
  dict.set_unsigned(index, 2, value_of(index, 2) | cfg::kCobIdInvalidBit);
  dict.set_unsigned(index, 3, 0);
  sdo_manager.channels.close(index);
  sdo_manager.channel_clients.erase(index);
}

std::uint16_t NmtMaster::Impl::manager_free_row() const {
  for (std::uint16_t row = 1; row <= kRows; ++row) {
    if (!dict.entry(slot_of(row).index, slot_of(row).sub_index)) break;
    const bool used =
        std::any_of(sdo_manager.connections.begin(), sdo_manager.connections.end(),
                    [&](const SdoManager::Connection& c) { return c.row.row == row; });
    if (!used) return row;
  }
  return 0;
}

bool NmtMaster::Impl::default_sdo_taken(std::uint8_t node) const {
  return std::any_of(sdo_manager.connections.begin(), sdo_manager.connections.end(),
                     [&](const SdoManager::Connection& c) {
                       return c.row.server == node && c.row.server_index == kDefaultServer;
                     });
}

bool NmtMaster::Impl::default_sdo_given_out(std::uint8_t node) const {
  if (!sdo_manager.enabled) return false;
  return default_sdo_taken(node) ||
         std::any_of(sdo_manager.srds.begin(), sdo_manager.srds.end(),
                     [](const auto& s) { return s.second.info.all_default_sdos; });
}

void NmtMaster::Impl::manager_watch(std::uint8_t node, std::optional<Duration> heartbeat,
                                    TimePoint now) {
  if (!heartbeat) heartbeat = heartbeat_time(node);
  if (heartbeat && heartbeat->count() > 0) {
    const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(*heartbeat).count();
    heartbeats.monitor({node, static_cast<std::uint16_t>(std::min<std::int64_t>(ms, 0xFFFF))}, now);
    return;
  }
  const auto a = assignment(node);
  auto id = *cfg::NodeId::from(node);
  if (a.guard_time_ms() != 0 && a.retry_factor() != 0) {
    guarding.start(id, a.guard_time_ms(), a.retry_factor(), now);
    return;
  }
  const auto guard_ms =
      std::chrono::duration_cast<std::chrono::milliseconds>(options.srd_guard_time).count();
  guarding.start(id, static_cast<std::uint16_t>(std::clamp<std::int64_t>(guard_ms, 1, 0xFFFF)),
                 kGuardLifeTimeFactor, now);
}

// --- losses ---

void NmtMaster::Impl::manager_node_lost(std::uint8_t node, bool boot_up, TimePoint now,
                                        Output& out) {
  if (!sdo_manager.enabled) return;
  if (auto it = sdo_manager.srds.find(node); it != sdo_manager.srds.end()) {
    // §7.2.1: "the Manager forces all SDOs requested by that SRD to be released".
    auto rows =
        manager_take_connections([node](const ManagedSdoConnection& c) { return c.srd == node; });
    sdo_manager.srds.erase(it);
    if (!is_slave(node)) stop_error_control(node);
    const std::string why = node_text(node) + (boot_up ? ": SRD booted up" : ": SRD lost");
    report(out,
           master_event(MasterEvent::Kind::SrdLost, now, node,
                        why + ", releasing " + std::to_string(rows.size()) + " SDO connection(s)"));
    manager_release_job(node, std::move(rows), true, true, why);
    return;
  }
  if (boot_up) {
    manager_slave_booted(node);
    return;
  }
  if (sdo_manager.watched.count(node) == 0) return;
  // §7.2.2 "Error Control of Slave Devices": 1F11h on each SRD with Req EC, then its client
  // entry cleared.
  sdo_manager.watched.erase(node);
  if (!is_slave(node)) stop_error_control(node);
  auto rows = manager_take_connections([&](const ManagedSdoConnection& c) {
    const auto srd = sdo_manager.srds.find(c.srd);
    return c.server == node && !c.to_manager && srd != sdo_manager.srds.end() &&
           srd->second.info.slave_error_control;
  });
  manager_release_per_srd(std::move(rows), node, node_text(node) + " failed (error control)");
}

void NmtMaster::Impl::manager_slave_booted(std::uint8_t node) {
  // CiA 301: the server entries 1201h.. a slave had written into it are not kept over a reset
  // (a boot-up follows every reset, the master's own too): those connections are gone on S, so
  // their rows go and each SRD's client entry is invalidated. S's default SDO survives (its
  // COB-IDs are fixed): a connection on it stays.
  auto rows = manager_take_connections([node](const ManagedSdoConnection& c) {
    return c.server == node && !c.to_manager && c.server_index != kDefaultServer;
  });
  manager_release_per_srd(std::move(rows), 0,
                          node_text(node) + " booted up: its server entry is gone");
}

std::vector<SdoManager::Connection> NmtMaster::Impl::manager_take_connections(
    const std::function<bool(const ManagedSdoConnection&)>& match) {
  std::vector<SdoManager::Connection> taken;
  for (auto c = sdo_manager.connections.begin(); c != sdo_manager.connections.end();) {
    if (!match(c->row)) {
      ++c;
      continue;
    }
    taken.push_back(*c);
    set_row(dict, c->row.row, 0);
    c = sdo_manager.connections.erase(c);
  }
  return taken;
}

void NmtMaster::Impl::manager_release_per_srd(std::vector<SdoManager::Connection> rows,
                                              std::uint8_t failed, const std::string& why) {
  // S's side is gone (it failed, or its reset dropped the entry): only the SRDs are written.
  std::map<std::uint8_t, std::vector<SdoManager::Connection>> by_srd;
  for (const auto& c : rows) by_srd[c.row.srd].push_back(c);
  for (auto& [srd, its_rows] : by_srd) {
    SdoManager::Job job;
    job.kind = SdoManager::Job::Kind::Release;
    job.node = srd;
    job.failed = failed;  // 1F11h first when not 0
    job.server_gone = true;
    job.why = why;
    job.releases = std::move(its_rows);
    sdo_manager.jobs.push_back(std::move(job));
  }
}

void NmtMaster::Impl::manager_release_job(std::uint8_t srd,
                                          std::vector<SdoManager::Connection> rows, bool deregister,
                                          bool lost, std::string why) {
  // The SRD's channel to the manager goes last: the SRD keeps its line until the end.
  std::stable_partition(rows.begin(), rows.end(),
                        [](const SdoManager::Connection& c) { return !c.row.to_manager; });
  SdoManager::Job job;
  job.kind = SdoManager::Job::Kind::Release;
  job.node = srd;
  job.releases = std::move(rows);
  job.deregister = deregister;
  job.srd_lost = lost;
  job.why = std::move(why);
  sdo_manager.jobs.push_back(std::move(job));
}

// --- jobs ---

void NmtMaster::Impl::manager_pump(TimePoint now, Output& out) {
  if (!sdo_manager.enabled) return;
  while (!sdo_manager.in_flight && !sdo_manager.jobs.empty()) {
    if (!manager_active()) return;  // resumes when the master is active again
    if (sdo_manager.jobs.front().kind == SdoManager::Job::Kind::Scan) {
      // Between two reads of a scan (126 silent node-IDs take 126 x the scan timeout), the
      // requests and releases that came meanwhile go first: a scan step costs them one read.
      const auto other = std::find_if(
          sdo_manager.jobs.begin(), sdo_manager.jobs.end(),
          [](const SdoManager::Job& j) { return j.kind != SdoManager::Job::Kind::Scan; });
      if (other != sdo_manager.jobs.end()) {
        std::rotate(sdo_manager.jobs.begin(), other, std::next(other));
        continue;
      }
    }
    auto& job = sdo_manager.jobs.front();
    if (job.steps.empty()) {
      manager_advance(now, out);
      continue;
    }
    const auto& step = job.steps.front();
    MasterTransfer t;
    t.for_manager = true;
    t.try_id = ++sdo_manager.serial;
    t.index = step.index;
    t.sub = step.sub;
    t.upload = step.upload;
    if (!step.upload) cfg::append_le(t.data, step.value, step.size);
    t.options.timeout = job.kind == SdoManager::Job::Kind::Scan ? options.sdo_manager_scan_timeout
                                                                : options.sdo_timeout;
    t.retries_left = step.retry ? options.sdo_retries : 0;
    sdo_manager.in_flight = true;
    launch_transfer(step.node, std::move(t), now);
  }
}

void NmtMaster::Impl::manager_result(const SdoResult& result, TimePoint now, Output& out) {
  using Phase = SdoManager::Job::Phase;
  sdo_manager.in_flight = false;
  if (sdo_manager.jobs.empty() || sdo_manager.jobs.front().steps.empty()) return;
  auto& job = sdo_manager.jobs.front();
  const auto step = job.steps.front();
  job.steps.pop_front();
  if (!result.ok() && step.must_succeed) {
    manager_job_failed(result, now, out);
    return;
  }
  const bool answered = result.ok() || result.aborted_by_server;
  switch (job.phase) {
    case Phase::Scanning:
      // §7.2.1: an open request has Rq indication set.
      if (result.ok() && DynamicSdoState::decode(uploaded_u32(result)).request_indication) {
        manager_start_register(uploaded_u32(result));
      } else if (job.node > cfg::kMinNodeId) {
        --job.node;
      } else {
        job.node = 0;
      }
      return;
    case Phase::ReadHeartbeat: {
      // Consumer time 2 x the SRD's producer time + 100 ms (its 1017h; 0: guarding).
      const auto ms = result.ok() ? (uploaded_u32(result) & 0xFFFF) : 0;
      if (ms != 0)
        job.heartbeat = 2 * std::chrono::milliseconds(ms) + std::chrono::milliseconds(100);
      // Confirmed last (§7.2.3: reset 1F10h): the SRD may use its channel as soon as it sees it.
      job.phase = Phase::Writing;
      job.steps.push_back(
          write_step(job.node, obj::kDynamicSdoConnectionState, 0, job.confirmation, 4));
      return;
    }
    case Phase::ProbeSlave:
      if (!answered) {
        manager_refuse(DynamicSdoError::kSlaveNotAvailable,
                       node_text(job.slave) + " does not answer");
      } else {
        manager_connect_with(kDefaultServer);
      }
      return;
    case Phase::SearchChannel: {
      if (!answered) {
        manager_refuse(DynamicSdoError::kSlaveNotAvailable,
                       node_text(job.slave) + " does not answer");
        return;
      }
      const bool free =
          result.ok() && (uploaded_u32(result) & cfg::kCobIdInvalidBit) != 0 &&
          std::none_of(sdo_manager.connections.begin(), sdo_manager.connections.end(),
                       [&](const SdoManager::Connection& c) {
                         return c.row.server == job.slave && c.row.server_index == job.probe;
                       });
      if (free) {
        manager_connect_with(job.probe);
      } else if (!result.ok() || job.probe >= obj::kSdoServerLast) {
        manager_refuse(DynamicSdoError::kNoFreeServerOnSlave,
                       node_text(job.slave) + " has no free server SDO entry");
      } else {
        ++job.probe;
        job.steps.push_back(read_step(job.slave, job.probe, 1));
      }
      return;
    }
    default:
      return;
  }
}

void NmtMaster::Impl::manager_job_failed(const SdoResult& result, TimePoint now, Output& out) {
  using Kind = SdoManager::Job::Kind;
  auto& job = sdo_manager.jobs.front();
  const std::string why = node_text(result.node_id) + ": " + transfer_failure(result);
  job.steps.clear();
  auto& c = job.connection;
  if (job.kind == Kind::Register) {
    // The SRD did not take the channel: give it back.
    if (c.row.server_index != 0) manager_close_channel(c.row.server_index);
    manager_mark_pool(c.pool_request, false);
    manager_mark_pool(c.pool_response, false);
    auto e = master_event(MasterEvent::Kind::SrdRegistrationFailed, now, job.node,
                          node_text(job.node) + ": registration failed: " + why);
    e.connection = c.row;
    report(out, std::move(e));
    manager_finish_job();
    return;
  }
  if (job.kind == Kind::Connect) {
    if (result.node_id == job.slave) {
      manager_mark_pool(c.pool_request, false);
      manager_mark_pool(c.pool_response, false);
      const bool timed_out = !result.aborted_by_server && result.abort == SdoAbort::Timeout;
      manager_refuse(timed_out ? DynamicSdoError::kSlaveNotAvailable : DynamicSdoError::kNoDetails,
                     why);
      return;
    }
    // The SRD did not take its entry: undo S's side (best effort), no confirmation possible.
    if (c.row.server_index != kDefaultServer) {
      job.steps.push_back(write_step(job.slave, c.row.server_index, 1,
                                     c.row.request.with_valid(false).word(), 4, false));
      job.steps.push_back(write_step(job.slave, c.row.server_index, 2,
                                     c.row.response.with_valid(false).word(), 4, false));
    }
    manager_mark_pool(c.pool_request, false);
    manager_mark_pool(c.pool_response, false);
    job.phase = SdoManager::Job::Phase::Refusing;
    job.error = DynamicSdoError::kNoDetails;
    job.why = why;
    return;
  }
  manager_finish_job();
}

void NmtMaster::Impl::manager_refuse(DynamicSdoError error, const std::string& why) {
  auto& job = sdo_manager.jobs.front();
  job.steps.clear();
  job.phase = SdoManager::Job::Phase::Refusing;
  job.error = error;
  job.why = why;
  // §7.2.3: Cnxn state 0 and the reason in the error code.
  const auto srd = sdo_manager.srds.find(job.node);
  const bool ec = job.kind == SdoManager::Job::Kind::Register
                      ? DynamicSdoState::decode(job.request).request_error_control
                      : srd != sdo_manager.srds.end() && srd->second.info.slave_error_control;
  const std::uint16_t index = job.kind == SdoManager::Job::Kind::Register
                                  ? DynamicSdoState::decode(job.request).client_index
                                  : job.client_index;
  auto state = DynamicSdoState::failure(index, error);
  state.request_error_control = ec;
  job.steps.push_back(
      write_step(job.node, obj::kDynamicSdoConnectionState, 0, state.encode(), 4, false));
}

void NmtMaster::Impl::manager_start_register(std::uint32_t request) {
  auto& job = sdo_manager.jobs.front();
  const auto srd = job.node;
  job.kind = SdoManager::Job::Kind::Register;
  job.request = request;
  job.connection = {};
  job.connection.row.srd = srd;
  if (sdo_manager.rescan) {
    // Another 6E0h came during the scan: scan again after this registration.
    sdo_manager.rescan = false;
    SdoManager::Job scan;
    scan.kind = SdoManager::Job::Kind::Scan;
    sdo_manager.jobs.push_back(std::move(scan));
  }
  const auto state = DynamicSdoState::decode(request);
  if (state.is_all_default_sdos_request()) {
    // §7.2.2: all default SDOs, when none is in use (Cnxn 2; no channel to the manager).
    const bool taken =
        std::any_of(sdo_manager.connections.begin(), sdo_manager.connections.end(),
                    [](const SdoManager::Connection& c) {
                      return !c.row.to_manager && c.row.server_index == kDefaultServer;
                    }) ||
        std::any_of(sdo_manager.srds.begin(), sdo_manager.srds.end(),
                    [](const auto& s) { return s.second.info.all_default_sdos; });
    if (taken) {
      manager_refuse(DynamicSdoError::kNoDetails, "a default SDO is in use");
      return;
    }
    job.phase = SdoManager::Job::Phase::Confirming;
    job.confirmation =
        DynamicSdoState::confirmation(0, ConnectionState::kAllDefaultSdosOwned).encode();
    return;
  }
  const auto index = state.client_index;
  if (!obj::is_sdo_client_parameter(index)) {
    manager_refuse(DynamicSdoError::kNoDetails,
                   "1F10h names " + cfg::object_name(index) + ", no client SDO entry");
    return;
  }
  std::uint16_t channel = 0;
  for (unsigned i = obj::kSdoServerFirst + 1; i <= obj::kSdoServerLast; ++i) {
    const auto candidate = static_cast<std::uint16_t>(i);
    if (!dict.entry(candidate, 1) || sdo_manager.channels.is_open(candidate)) continue;
    if ((value_of(candidate, 1) & cfg::kCobIdInvalidBit) == 0) continue;
    channel = candidate;
    break;
  }
  const auto pool = manager_free_pool();
  const auto row = manager_free_row();
  if (channel == 0 || pool.size() < 2 || row == 0) {
    manager_refuse(
        DynamicSdoError::kNoChannelToManager,
        channel == 0 ? "no free server channel on the manager" : "no free COB-IDs in 1F02h");
    return;
  }
  auto& c = job.connection;
  c.pool_request = pool[0];
  c.pool_response = pool[1];
  manager_mark_pool(c.pool_request, true);
  manager_mark_pool(c.pool_response, true);
  c.row.client_index = index;
  c.row.server = node_id.value();
  c.row.server_index = channel;
  c.row.request = pool_cob_id(dict, pool[0]);
  c.row.response = pool_cob_id(dict, pool[1]);
  c.row.to_manager = true;
  manager_open_channel(channel, c);
  job.phase = SdoManager::Job::Phase::Confirming;
  // §7.2.1: enable the SRD's client entry named in 1F10h, then reset 1F10h (Cnxn 1).
  job.steps.push_back(write_step(srd, index, 3, node_id.value(), 1));
  job.steps.push_back(write_step(srd, index, 1, c.row.request.word(), 4));
  job.steps.push_back(write_step(srd, index, 2, c.row.response.word(), 4));
  job.confirmation = DynamicSdoState::confirmation(index, ConnectionState::kManagerConnected,
                                                   state.request_error_control)
                         .encode();
}

void NmtMaster::Impl::manager_start_connect() {
  auto& job = sdo_manager.jobs.front();
  if (sdo_manager.srds.count(job.node) == 0) {  // lost or gone meanwhile
    manager_finish_job();
    return;
  }
  job.connection = {};
  job.connection.row.srd = job.node;
  job.connection.row.client_index = job.client_index;
  job.connection.row.server = job.slave;
  const bool all_default =
      std::any_of(sdo_manager.srds.begin(), sdo_manager.srds.end(),
                  [](const auto& s) { return s.second.info.all_default_sdos; });
  if (!default_sdo_taken(job.slave) && !all_default) {
    // Is S there? Its default SDO needs no write (§7.1).
    job.phase = SdoManager::Job::Phase::ProbeSlave;
    job.steps.push_back(read_step(job.slave, obj::kDeviceType, 0));
    return;
  }
  if (manager_free_pool().size() < 2) {
    manager_refuse(DynamicSdoError::kNoFreeChannelInNetwork, "no two free COB-IDs in 1F02h");
    return;
  }
  job.phase = SdoManager::Job::Phase::SearchChannel;
  job.probe = obj::kSdoServerFirst + 1;
  job.steps.push_back(read_step(job.slave, job.probe, 1));
}

void NmtMaster::Impl::manager_connect_with(std::uint16_t server_index) {
  auto& job = sdo_manager.jobs.front();
  auto& c = job.connection;
  c.row.server_index = server_index;
  if (server_index == kDefaultServer) {
    const auto cob_ids = sdo::default_cob_ids(job.slave);
    c.row.request = cob_ids.request;
    c.row.response = cob_ids.response;
  } else {
    const auto pool = manager_free_pool();
    if (pool.size() < 2) {
      manager_refuse(DynamicSdoError::kNoFreeChannelInNetwork, "no two free COB-IDs in 1F02h");
      return;
    }
    c.pool_request = pool[0];
    c.pool_response = pool[1];
    manager_mark_pool(c.pool_request, true);
    manager_mark_pool(c.pool_response, true);
    c.row.request = pool_cob_id(dict, pool[0]);
    c.row.response = pool_cob_id(dict, pool[1]);
    // §7.1: the free server entry of S, for the SRD.
    job.steps.push_back(write_step(job.slave, server_index, 3, job.node, 1));
    job.steps.push_back(write_step(job.slave, server_index, 1, c.row.request.word(), 4));
    job.steps.push_back(write_step(job.slave, server_index, 2, c.row.response.word(), 4));
  }
  const bool ec = sdo_manager.srds.at(job.node).info.slave_error_control;
  job.steps.push_back(write_step(job.node, job.client_index, 3, job.slave, 1));
  job.steps.push_back(write_step(job.node, job.client_index, 1, c.row.request.word(), 4));
  job.steps.push_back(write_step(job.node, job.client_index, 2, c.row.response.word(), 4));
  job.steps.push_back(write_step(
      job.node, obj::kDynamicSdoConnectionState, 0,
      DynamicSdoState::confirmation(job.client_index, ConnectionState::kSlaveConnected, ec)
          .encode(),
      4));
  job.phase = SdoManager::Job::Phase::Writing;
}

void NmtMaster::Impl::manager_advance(TimePoint now, Output& out) {
  using Kind = SdoManager::Job::Kind;
  auto& job = sdo_manager.jobs.front();
  if (job.phase == SdoManager::Job::Phase::Refusing) {
    manager_report_refusal(now, out);
    return;
  }
  switch (job.kind) {
    case Kind::Scan:
      manager_advance_scan();
      return;
    case Kind::Register:
      manager_advance_register(now, out);
      return;
    case Kind::Connect:
      manager_advance_connect(now, out);
      return;
    case Kind::Release:
      manager_advance_release(now, out);
      return;
  }
}

void NmtMaster::Impl::manager_report_refusal(TimePoint now, Output& out) {
  using Kind = SdoManager::Job::Kind;
  auto& job = sdo_manager.jobs.front();
  const bool registering = job.kind == Kind::Register;
  auto e =
      master_event(registering ? MasterEvent::Kind::SrdRegistrationFailed
                               : MasterEvent::Kind::SdoConnectionRefused,
                   now, job.node,
                   node_text(job.node) +
                       (registering ? ": registration refused"
                                    : ": SDO connection to " + node_text(job.slave) + " refused") +
                       ", error " + cfg::hex(static_cast<std::uint8_t>(job.error), 2) + " (" +
                       std::string(sm::describe(job.error)) + "): " + job.why);
  e.connection = job.connection.row;
  e.connection_error = static_cast<std::uint8_t>(job.error);
  report(out, std::move(e));
  manager_finish_job();
}

void NmtMaster::Impl::manager_advance_scan() {
  using Kind = SdoManager::Job::Kind;
  using Phase = SdoManager::Job::Phase;
  auto& job = sdo_manager.jobs.front();
  if (job.phase == Phase::Start) {
    job.phase = Phase::Scanning;
    job.node = cfg::kMaxNodeId;
  }
  // §7.2.1 / §7.2.4 guideline 2: from 127 down, node-IDs not registered, whose default SDO
  // no connection holds.
  while (job.node >= cfg::kMinNodeId &&
         (job.node == node_id.value() || sdo_manager.srds.count(job.node) != 0 ||
          default_sdo_taken(job.node))) {
    --job.node;
  }
  if (job.node < cfg::kMinNodeId) {
    manager_finish_job();
    if (sdo_manager.rescan) {
      sdo_manager.rescan = false;
      SdoManager::Job scan;
      scan.kind = Kind::Scan;
      sdo_manager.jobs.push_back(std::move(scan));
    }
    return;
  }
  job.steps.push_back(read_step(job.node, obj::kDynamicSdoConnectionState, 0, false));
}

void NmtMaster::Impl::manager_advance_register(TimePoint now, Output& out) {
  using Phase = SdoManager::Job::Phase;
  auto& job = sdo_manager.jobs.front();
  if (job.phase == Phase::Confirming) {
    // §7.2.1 "Error Control of SRD": the master's 1016h entry, else the SRD's 1017h; known
    // before the confirmation, so the SRD is registered once it has taken it.
    job.heartbeat = heartbeat_time(job.node);
    if (job.heartbeat) {
      job.phase = Phase::Writing;
      job.steps.push_back(
          write_step(job.node, obj::kDynamicSdoConnectionState, 0, job.confirmation, 4));
    } else {
      job.phase = Phase::ReadHeartbeat;
      job.steps.push_back(read_step(job.node, obj::kProducerHeartbeatTime, 0));
    }
    return;
  }
  manager_watch(job.node, job.heartbeat, now);
  SdoManager::Srd srd;
  srd.info.node = job.node;
  const auto request = DynamicSdoState::decode(job.request);
  srd.info.all_default_sdos = request.is_all_default_sdos_request();
  srd.info.slave_error_control = request.request_error_control;
  auto e = master_event(MasterEvent::Kind::SrdRegistered, now, job.node,
                        node_text(job.node) + ": SRD registered");
  if (!srd.info.all_default_sdos) {
    auto c = job.connection;
    c.row.row = manager_free_row();
    srd.info.client_index = c.row.client_index;
    srd.own_channel = c.row.server_index;
    set_row(dict, c.row.row, row_word(c.row));
    sdo_manager.connections.push_back(c);
    e.connection = c.row;
    e.text += ", " + connection_text(c.row);
  } else {
    e.text += " with all default SDOs";
  }
  if (srd.info.slave_error_control) e.text += ", error control of its slaves";
  sdo_manager.srds[job.node] = srd;
  report(out, std::move(e));
  manager_finish_job();
}

void NmtMaster::Impl::manager_advance_connect(TimePoint now, Output& out) {
  using Phase = SdoManager::Job::Phase;
  auto& job = sdo_manager.jobs.front();
  if (job.phase == Phase::Start) {
    manager_start_connect();
    return;
  }
  // Phase::Writing done: established (§7.2.2).
  auto c = job.connection;
  c.row.row = manager_free_row();
  if (c.row.row != 0) set_row(dict, c.row.row, row_word(c.row));
  sdo_manager.connections.push_back(c);
  const auto srd = sdo_manager.srds.find(job.node);
  if (srd != sdo_manager.srds.end() && srd->second.info.slave_error_control &&
      sdo_manager.watched.count(job.slave) == 0 && !heartbeats.monitors(job.slave) &&
      !guarding.guards(job.slave)) {
    // §7.2.5 step 4.4: error control of S for the SRD.
    manager_watch(job.slave, std::nullopt, now);
    sdo_manager.watched.insert(job.slave);
  } else if (srd != sdo_manager.srds.end() && srd->second.info.slave_error_control) {
    sdo_manager.watched.insert(job.slave);
  }
  auto e = master_event(MasterEvent::Kind::SdoConnectionEstablished, now, job.node,
                        "SDO connection established: " + connection_text(c.row));
  e.connection = c.row;
  report(out, std::move(e));
  manager_finish_job();
}

void NmtMaster::Impl::manager_advance_release(TimePoint now, Output& out) {
  using Phase = SdoManager::Job::Phase;
  auto& job = sdo_manager.jobs.front();
  if (job.phase == Phase::Start) {
    job.phase = Phase::Releasing;
    if (job.failed != 0) {
      // §7.2.3 1F11h: reason 00h, the failed slave's node-ID.
      job.steps.push_back(write_step(
          job.node, obj::kSlaveFailed, 0,
          sm::SlaveFailed{static_cast<std::uint8_t>(sm::SlaveFailedReason::kErrorControl),
                          job.failed}
              .encode(),
          2, false, !job.srd_lost));
    }
    for (const auto& c : job.releases) {
      // §7.2.1: invalidate the SRD's client entry, then S's server entry (not its default).
      job.steps.push_back(write_step(job.node, c.row.client_index, 1,
                                     c.row.request.with_valid(false).word(), 4, false,
                                     !job.srd_lost));
      job.steps.push_back(write_step(job.node, c.row.client_index, 2,
                                     c.row.response.with_valid(false).word(), 4, false,
                                     !job.srd_lost));
      if (!c.row.to_manager && c.row.server_index != kDefaultServer && !job.server_gone) {
        job.steps.push_back(write_step(c.row.server, c.row.server_index, 1,
                                       c.row.request.with_valid(false).word(), 4, false));
        job.steps.push_back(write_step(c.row.server, c.row.server_index, 2,
                                       c.row.response.with_valid(false).word(), 4, false));
      }
    }
    if (!job.steps.empty()) return;
  }
  if (job.failed != 0) {
    ManagedSdoConnection failed;
    failed.srd = job.node;
    failed.server = job.failed;
    auto e =
        master_event(MasterEvent::Kind::SlaveFailedReported, now, job.node,
                     node_text(job.node) + ": 1F11h reports " + node_text(job.failed) + " failed");
    e.connection = failed;
    report(out, std::move(e));
  }
  for (const auto& c : job.releases) {
    manager_mark_pool(c.pool_request, false);
    manager_mark_pool(c.pool_response, false);
    if (c.row.to_manager) manager_close_channel(c.row.server_index);
    auto e = master_event(MasterEvent::Kind::SdoConnectionReleased, now, job.node,
                          "SDO connection released (" + job.why + "): " + connection_text(c.row));
    e.connection = c.row;
    report(out, std::move(e));
  }
  if (job.deregister && !job.srd_lost) {
    if (!is_slave(job.node)) stop_error_control(job.node);
    report(out, master_event(MasterEvent::Kind::SrdDeregistered, now, job.node,
                             node_text(job.node) + ": SRD de-registered"));
  }
  manager_finish_job();
}

void NmtMaster::Impl::manager_finish_job() {
  if (!sdo_manager.jobs.empty()) sdo_manager.jobs.pop_front();
}

// --- the public accessors ---

std::vector<ManagedSdoConnection> NmtMaster::sdo_connections() const {
  std::vector<ManagedSdoConnection> rows;
  for (const auto& c : impl_->sdo_manager.connections) rows.push_back(c.row);
  std::sort(rows.begin(), rows.end(), [](const auto& a, const auto& b) { return a.row < b.row; });
  return rows;
}

std::vector<RegisteredSrd> NmtMaster::registered_srds() const {
  std::vector<RegisteredSrd> srds;
  for (const auto& [node, srd] : impl_->sdo_manager.srds) srds.push_back(srd.info);
  return srds;
}

}  // namespace nmt
