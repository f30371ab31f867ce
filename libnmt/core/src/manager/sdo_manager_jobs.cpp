// The SDO manager's jobs (DSP 302 §7.2.1, §7.2.2): the scan of 1F10h after a Dynamic SDO
// Request, the registration of an SRD, the connections 1F00h asks for and the releases of 1F01h
// and of lost nodes, each a sequence of SDO accesses over the master's default SDO clients
// (SdoManagerPort::start_transfer), one job at a time (a scan lets the others go first between
// its reads). A 1F00h/1F01h write only queues one (§7.2.3: a successful response means the
// manager started). The engine and its port: sdo_manager_process.hpp.
#include <algorithm>
#include <type_traits>
#include <utility>
#include <variant>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_index.hpp"
#include "manager/sdo_manager_process.hpp"
#include "master/master_support.hpp"

namespace nmt {

namespace obj = cfg::object;

namespace {

namespace sm = cfg::sdo_manager;
using sm::ConnectionState;
using sm::DynamicSdoError;
using sm::DynamicSdoState;

constexpr std::uint16_t kDefaultServer = obj::kSdoServerFirst;  // 1200h

}  // namespace

SdoManagerProcess::Step SdoManagerProcess::write_step(cfg::NodeId node, cfg::ObjectAddress address,
                                                      std::uint32_t value, std::size_t size,
                                                      bool must_succeed, bool retry) {
  return Step{.node = node,
              .address = address,
              .value = value,
              .size = size,
              .must_succeed = must_succeed,
              .retry = retry};
}

SdoManagerProcess::Step SdoManagerProcess::read_step(cfg::NodeId node, cfg::ObjectAddress address,
                                                     bool retry) {
  // must_succeed false: the phase looks at the result.
  auto s = write_step(node, address, 0, 0, false, retry);
  s.upload = true;
  return s;
}

SdoManagerProcess::Job SdoManagerProcess::scan_job() {
  return Job{.work = ScanJob{.node = *cfg::NodeId::from(cfg::kMaxNodeId)}};
}

void SdoManagerProcess::scan_next(ScanJob& scan) {
  if (const auto below = cfg::NodeId::from(scan.node.value() - 1U)) {
    scan.node = *below;
  } else {
    scan.scanned_all = true;
  }
}

// --- jobs ---

void SdoManagerProcess::pump(TimePoint now, Output& out) {
  if (!enabled_) return;
  while (!in_flight_ && !jobs_.empty()) {
    if (!active()) return;  // resumes when the master is active again
    const auto is_scan = [](const Job& j) { return std::holds_alternative<ScanJob>(j.work); };
    if (is_scan(jobs_.front())) {
      // Between two reads of a scan (126 silent node-IDs take 126 x the scan timeout), the
      // requests and releases that came meanwhile go first: a scan step costs them one read.
      const auto other = std::find_if_not(jobs_.begin(), jobs_.end(), is_scan);
      if (other != jobs_.end()) {
        std::rotate(jobs_.begin(), other, std::next(other));
        continue;
      }
    }
    auto& job = jobs_.front();
    if (job.steps.empty()) {
      advance(now, out);
      continue;
    }
    const auto& step = job.steps.front();
    SdoManagerTransfer t{
        .tag = ++serial_, .node = step.node, .address = step.address, .upload = step.upload};
    if (!step.upload) cfg::append_le(t.data, step.value, step.size);
    t.timeout = is_scan(job) ? settings_.scan_timeout : settings_.sdo_timeout;
    t.retries = step.retry ? settings_.sdo_retries : 0;
    in_flight_ = true;
    port_.start_transfer(std::move(t), now);
  }
}

void SdoManagerProcess::on_transfer_result(std::uint64_t tag, const SdoResult& result,
                                           TimePoint now, Output& out) {
  if (!in_flight_ || tag != serial_) return;  // of a job the tables' clearing dropped
  in_flight_ = false;
  if (jobs_.empty() || jobs_.front().steps.empty()) return;
  auto& job = jobs_.front();
  const auto step = job.steps.front();
  job.steps.pop_front();
  if (!result.ok() && step.must_succeed) {
    job_failed(result, now, out);
    return;
  }
  const bool answered = result.ok() || result.aborted_by_server;
  // The reads whose result a job looks at; the other steps (writes that may fail, a refusal's
  // best-effort writes) move it on from the next pump() when its steps are done.
  if (auto* scan = std::get_if<ScanJob>(&job.work)) {
    // §7.2.1: an open request has Rq indication set.
    if (result.ok() && DynamicSdoState::decode(uploaded_u32(result)).request_indication) {
      start_register(job, scan->node, uploaded_u32(result));
    } else {
      scan_next(*scan);
    }
    return;
  }
  if (auto* reg = std::get_if<RegisterJob>(&job.work)) {
    if (reg->refusal || reg->phase != RegisterJob::Phase::ReadHeartbeat) return;
    // Consumer time 2 x the SRD's producer time + 100 ms (its 1017h; 0: guarding).
    const auto ms = result.ok() ? (uploaded_u32(result) & 0xFFFF) : 0;
    if (ms != 0)
      reg->heartbeat = 2 * std::chrono::milliseconds(ms) + std::chrono::milliseconds(100);
    // Confirmed last (§7.2.3: reset 1F10h): the SRD may use its channel as soon as it sees it.
    reg->phase = RegisterJob::Phase::Writing;
    job.steps.push_back(
        write_step(reg->srd, {obj::kDynamicSdoConnectionState, 0}, reg->confirmation, 4));
    return;
  }
  auto* connect = std::get_if<ConnectJob>(&job.work);
  if (connect == nullptr || connect->refusal) return;
  switch (connect->phase) {
    case ConnectJob::Phase::ProbeSlave:
      if (!answered) {
        refuse(job, DynamicSdoError::kSlaveNotAvailable,
               {.kind = SdoManagerReason::Kind::SlaveDoesNotAnswer, .node = connect->slave});
      } else {
        connect_with(job, *connect, kDefaultServer);
      }
      return;
    case ConnectJob::Phase::SearchChannel: {
      if (!answered) {
        refuse(job, DynamicSdoError::kSlaveNotAvailable,
               {.kind = SdoManagerReason::Kind::SlaveDoesNotAnswer, .node = connect->slave});
        return;
      }
      const bool free =
          result.ok() && (uploaded_u32(result) & cfg::kCobIdInvalidBit) != 0 &&
          std::none_of(connections_.begin(), connections_.end(), [&](const Connection& c) {
            return c.row.server == connect->slave && c.row.server_index == connect->probe;
          });
      if (free) {
        connect_with(job, *connect, connect->probe);
      } else if (!result.ok() || connect->probe >= obj::kSdoServerLast) {
        refuse(job, DynamicSdoError::kNoFreeServerOnSlave,
               {.kind = SdoManagerReason::Kind::NoFreeServerEntry, .node = connect->slave});
      } else {
        ++connect->probe;
        job.steps.push_back(read_step(connect->slave, {connect->probe, 1}));
      }
      return;
    }
    case ConnectJob::Phase::Start:
    case ConnectJob::Phase::Writing:
      return;
  }
}

void SdoManagerProcess::job_failed(const SdoResult& result, TimePoint now, Output& out) {
  auto& job = jobs_.front();
  const SdoManagerReason why{
      .kind = SdoManagerReason::Kind::TransferFailed, .node = result.node_id, .transfer = result};
  job.steps.clear();
  if (auto* reg = std::get_if<RegisterJob>(&job.work)) {
    // The SRD did not take the channel: give it back.
    const auto& c = reg->connection;
    if (c.row.server_index != 0) close_channel(c.row.server_index);
    mark_pool(c.pool_request, false);
    mark_pool(c.pool_response, false);
    auto e = master_event(MasterEvent::Kind::SrdRegistrationFailed, now, reg->srd);
    e.connection = c.row;
    e.manager_reason = why;
    out.report(std::move(e));
    finish_job();
    return;
  }
  if (auto* connect = std::get_if<ConnectJob>(&job.work)) {
    const auto& c = connect->connection;
    if (result.node_id == connect->slave) {
      mark_pool(c.pool_request, false);
      mark_pool(c.pool_response, false);
      const bool timed_out = !result.aborted_by_server && result.abort == SdoAbort::Timeout;
      refuse(job, timed_out ? DynamicSdoError::kSlaveNotAvailable : DynamicSdoError::kNoDetails,
             why);
      return;
    }
    // The SRD did not take its entry: undo S's side (best effort), no confirmation possible.
    if (c.row.server_index != kDefaultServer) {
      job.steps.push_back(write_step(connect->slave, {c.row.server_index, 1},
                                     c.row.request.with_valid(false).word(), 4, false));
      job.steps.push_back(write_step(connect->slave, {c.row.server_index, 2},
                                     c.row.response.with_valid(false).word(), 4, false));
    }
    mark_pool(c.pool_request, false);
    mark_pool(c.pool_response, false);
    connect->refusal = Refusal{.error = DynamicSdoError::kNoDetails, .why = why};
    return;
  }
  finish_job();
}

void SdoManagerProcess::refuse(Job& job, DynamicSdoError error, SdoManagerReason why) {
  job.steps.clear();
  // §7.2.3: Cnxn state 0 and the reason in the error code, Req EC as the SRD has it.
  const auto failure = [&](auto& work, std::uint16_t client_index, bool error_control) {
    work.refusal = Refusal{.error = error, .why = why};
    auto state = DynamicSdoState::failure(client_index, error);
    state.request_error_control = error_control;
    job.steps.push_back(
        write_step(work.srd, {obj::kDynamicSdoConnectionState, 0}, state.encode(), 4, false));
  };
  if (auto* reg = std::get_if<RegisterJob>(&job.work)) {
    const auto request = DynamicSdoState::decode(reg->request);
    failure(*reg, request.client_index, request.request_error_control);
    return;
  }
  auto& connect = std::get<ConnectJob>(job.work);
  const auto srd = srds_.find(connect.srd);
  failure(connect, connect.client_index,
          srd != srds_.end() && srd->second.info.slave_error_control);
}

void SdoManagerProcess::start_register(Job& job, cfg::NodeId srd, std::uint32_t request) {
  job.work = RegisterJob{.srd = srd, .request = request};
  auto& reg = std::get<RegisterJob>(job.work);
  reg.connection.row.srd = srd;
  if (rescan_) {
    // Another 6E0h came during the scan: scan again after this registration.
    rescan_ = false;
    jobs_.push_back(scan_job());
  }
  const auto state = DynamicSdoState::decode(request);
  if (state.is_all_default_sdos_request()) {
    // §7.2.2: all default SDOs, when none is in use (Cnxn 2; no channel to the manager).
    const bool taken =
        std::any_of(connections_.begin(), connections_.end(),
                    [](const Connection& c) {
                      return !c.row.to_manager && c.row.server_index == kDefaultServer;
                    }) ||
        all_default_sdos_owned();
    if (taken) {
      refuse(job, DynamicSdoError::kNoDetails, {.kind = SdoManagerReason::Kind::DefaultSdoInUse});
      return;
    }
    reg.confirmation =
        DynamicSdoState::confirmation(0, ConnectionState::kAllDefaultSdosOwned).encode();
    return;
  }
  const auto index = state.client_index;
  if (!obj::is_sdo_client_parameter(index)) {
    refuse(job, DynamicSdoError::kNoDetails,
           {.kind = SdoManagerReason::Kind::NotAClientEntry, .index = index});
    return;
  }
  const auto channel = free_own_channel();
  const auto pool = free_pool();
  const auto row = free_row();
  if (channel == 0 || pool.size() < 2 || row == 0) {
    refuse(job, DynamicSdoError::kNoChannelToManager,
           SdoManagerReason{.kind = channel == 0 ? SdoManagerReason::Kind::NoFreeServerChannel
                                                 : SdoManagerReason::Kind::NoFreeCobIds});
    return;
  }
  auto& c = reg.connection;
  c.pool_request = pool[0];
  c.pool_response = pool[1];
  mark_pool(c.pool_request, true);
  mark_pool(c.pool_response, true);
  c.row.client_index = index;
  c.row.server = node_id_;
  c.row.server_index = channel;
  c.row.request = pool_cob_id(pool[0]);
  c.row.response = pool_cob_id(pool[1]);
  c.row.to_manager = true;
  open_channel(channel, c);
  // §7.2.1: enable the SRD's client entry named in 1F10h, then reset 1F10h (Cnxn 1).
  job.steps.push_back(write_step(srd, {index, 3}, node_id_.value(), 1));
  job.steps.push_back(write_step(srd, {index, 1}, c.row.request.word(), 4));
  job.steps.push_back(write_step(srd, {index, 2}, c.row.response.word(), 4));
  reg.confirmation = DynamicSdoState::confirmation(index, ConnectionState::kManagerConnected,
                                                   state.request_error_control)
                         .encode();
}

void SdoManagerProcess::start_connect(Job& job, ConnectJob& connect) {
  if (srds_.count(connect.srd) == 0) {  // lost or gone meanwhile
    finish_job();
    return;
  }
  connect.connection = {};
  connect.connection.row.srd = connect.srd;
  connect.connection.row.client_index = connect.client_index;
  const auto slave = connect.slave;
  connect.connection.row.server = slave;
  if (!default_sdo_taken(slave) && !all_default_sdos_owned()) {
    // Is S there? Its default SDO needs no write (§7.1).
    connect.phase = ConnectJob::Phase::ProbeSlave;
    job.steps.push_back(read_step(slave, {obj::kDeviceType, 0}));
    return;
  }
  if (free_pool().size() < 2) {
    refuse(job, DynamicSdoError::kNoFreeChannelInNetwork,
           {.kind = SdoManagerReason::Kind::NoTwoFreeCobIds});
    return;
  }
  connect.phase = ConnectJob::Phase::SearchChannel;
  connect.probe = obj::kSdoServerFirst + 1;
  job.steps.push_back(read_step(slave, {connect.probe, 1}));
}

void SdoManagerProcess::connect_with(Job& job, ConnectJob& connect, std::uint16_t server_index) {
  auto& c = connect.connection;
  const auto slave = connect.slave;
  const auto srd = connect.srd;
  c.row.server_index = server_index;
  if (server_index == kDefaultServer) {
    const auto cob_ids = sdo::default_cob_ids(slave);
    c.row.request = cob_ids.request;
    c.row.response = cob_ids.response;
  } else {
    const auto pool = free_pool();
    if (pool.size() < 2) {
      refuse(job, DynamicSdoError::kNoFreeChannelInNetwork,
             {.kind = SdoManagerReason::Kind::NoTwoFreeCobIds});
      return;
    }
    c.pool_request = pool[0];
    c.pool_response = pool[1];
    mark_pool(c.pool_request, true);
    mark_pool(c.pool_response, true);
    c.row.request = pool_cob_id(pool[0]);
    c.row.response = pool_cob_id(pool[1]);
    // §7.1: the free server entry of S, for the SRD.
    job.steps.push_back(write_step(slave, {server_index, 3}, srd.value(), 1));
    job.steps.push_back(write_step(slave, {server_index, 1}, c.row.request.word(), 4));
    job.steps.push_back(write_step(slave, {server_index, 2}, c.row.response.word(), 4));
  }
  const bool ec = srds_.at(srd).info.slave_error_control;
  job.steps.push_back(write_step(srd, {connect.client_index, 3}, slave.value(), 1));
  job.steps.push_back(write_step(srd, {connect.client_index, 1}, c.row.request.word(), 4));
  job.steps.push_back(write_step(srd, {connect.client_index, 2}, c.row.response.word(), 4));
  job.steps.push_back(write_step(
      srd, {obj::kDynamicSdoConnectionState, 0},
      DynamicSdoState::confirmation(connect.client_index, ConnectionState::kSlaveConnected, ec)
          .encode(),
      4));
  connect.phase = ConnectJob::Phase::Writing;
}

void SdoManagerProcess::advance(TimePoint now, Output& out) {
  auto& job = jobs_.front();
  // The front job's steps are done: its next phase, or its end.
  std::visit(
      [&](auto& work) {
        using Work = std::decay_t<decltype(work)>;
        if constexpr (std::is_same_v<Work, ScanJob>) {
          advance_scan(job, work);
        } else if constexpr (std::is_same_v<Work, ReleaseJob>) {
          advance_release(job, work, now, out);
        } else if (work.refusal) {
          report_refusal(job, now, out);
        } else if constexpr (std::is_same_v<Work, RegisterJob>) {
          advance_register(job, work, now, out);
        } else {
          advance_connect(job, work, now, out);
        }
      },
      job.work);
}

void SdoManagerProcess::report_refusal(const Job& job, TimePoint now, Output& out) {
  const auto* reg = std::get_if<RegisterJob>(&job.work);
  const auto* connect = std::get_if<ConnectJob>(&job.work);
  const auto srd = reg ? reg->srd : connect->srd;
  const auto& refusal = reg ? *reg->refusal : *connect->refusal;
  auto e = master_event(
      reg ? MasterEvent::Kind::SrdRegistrationFailed : MasterEvent::Kind::SdoConnectionRefused, now,
      srd);
  e.connection = reg ? reg->connection.row : connect->connection.row;
  e.connection_error = refusal.error;
  e.manager_reason = refusal.why;
  out.report(std::move(e));
  finish_job();
}

void SdoManagerProcess::advance_scan(Job& job, ScanJob& scan) {
  scan.started = true;  // from 127 (scan_job)
  // §7.2.1 / §7.2.4 guideline 2: from 127 down, node-IDs not registered, whose default SDO
  // no connection holds.
  while (!scan.scanned_all &&
         (scan.node == node_id_ || srds_.count(scan.node) != 0 || default_sdo_taken(scan.node))) {
    scan_next(scan);
  }
  if (scan.scanned_all) {
    finish_job();
    if (rescan_) {
      rescan_ = false;
      jobs_.push_back(scan_job());
    }
    return;
  }
  job.steps.push_back(read_step(scan.node, {obj::kDynamicSdoConnectionState, 0}, false));
}

void SdoManagerProcess::advance_register(Job& job, RegisterJob& reg, TimePoint now, Output& out) {
  if (reg.phase == RegisterJob::Phase::Confirming) {
    // §7.2.1 "Error Control of SRD": the master's 1016h entry, else the SRD's 1017h; known
    // before the confirmation, so the SRD is registered once it has taken it.
    reg.heartbeat = port_.consumer_time(reg.srd);
    if (reg.heartbeat) {
      reg.phase = RegisterJob::Phase::Writing;
      job.steps.push_back(
          write_step(reg.srd, {obj::kDynamicSdoConnectionState, 0}, reg.confirmation, 4));
    } else {
      reg.phase = RegisterJob::Phase::ReadHeartbeat;
      job.steps.push_back(read_step(reg.srd, {obj::kProducerHeartbeatTime, 0}));
    }
    return;
  }
  port_.watch(reg.srd, reg.heartbeat, now);
  Srd srd;
  srd.info.node = reg.srd;
  const auto request = DynamicSdoState::decode(reg.request);
  srd.info.all_default_sdos = request.is_all_default_sdos_request();
  srd.info.slave_error_control = request.request_error_control;
  auto e = master_event(MasterEvent::Kind::SrdRegistered, now, reg.srd);
  if (!srd.info.all_default_sdos) {
    auto c = reg.connection;
    c.row.row = free_row();
    srd.info.client_index = c.row.client_index;
    srd.own_channel = c.row.server_index;
    e.connection = c.row;
    add_row(c);
  }
  e.srd = srd.info;
  srds_[reg.srd] = srd;
  out.report(std::move(e));
  finish_job();
}

void SdoManagerProcess::advance_connect(Job& job, ConnectJob& connect, TimePoint now, Output& out) {
  if (connect.phase == ConnectJob::Phase::Start) {
    start_connect(job, connect);
    return;
  }
  // Phase::Writing done: established (§7.2.2).
  auto c = connect.connection;
  c.row.row = free_row();
  add_row(c);
  const auto srd = srds_.find(connect.srd);
  if (srd != srds_.end() && srd->second.info.slave_error_control) {
    const auto slave = connect.slave;
    if (watched_.count(slave) == 0) {
      // §7.2.5 step 4.4: error control of S for the SRD.
      port_.watch(slave, std::nullopt, now);
    }
    watched_.insert(slave);
  }
  auto e = master_event(MasterEvent::Kind::SdoConnectionEstablished, now, connect.srd);
  e.connection = c.row;
  out.report(std::move(e));
  finish_job();
}

void SdoManagerProcess::advance_release(Job& job, ReleaseJob& release, TimePoint now, Output& out) {
  if (!release.started) {
    release.started = true;
    if (release.failed) {
      // §7.2.3 1F11h: reason 00h, the failed slave's node-ID.
      job.steps.push_back(write_step(
          release.srd, {obj::kSlaveFailed, 0},
          sm::SlaveFailed{static_cast<std::uint8_t>(sm::SlaveFailedReason::kErrorControl),
                          release.failed->value()}
              .encode(),
          2, false, !release.srd_lost));
    }
    for (const auto& c : release.releases) {
      // §7.2.1: invalidate the SRD's client entry, then S's server entry (not its default).
      job.steps.push_back(write_step(release.srd, {c.row.client_index, 1},
                                     c.row.request.with_valid(false).word(), 4, false,
                                     !release.srd_lost));
      job.steps.push_back(write_step(release.srd, {c.row.client_index, 2},
                                     c.row.response.with_valid(false).word(), 4, false,
                                     !release.srd_lost));
      if (!c.row.to_manager && c.row.server_index != kDefaultServer && !release.server_gone) {
        job.steps.push_back(write_step(c.server(), {c.row.server_index, 1},
                                       c.row.request.with_valid(false).word(), 4, false));
        job.steps.push_back(write_step(c.server(), {c.row.server_index, 2},
                                       c.row.response.with_valid(false).word(), 4, false));
      }
    }
    if (!job.steps.empty()) return;
  }
  if (release.failed) {
    ManagedSdoConnection failed;
    failed.srd = release.srd;
    failed.server = *release.failed;
    auto e = master_event(MasterEvent::Kind::SlaveFailedReported, now, release.srd);
    e.connection = failed;
    out.report(std::move(e));
  }
  for (const auto& c : release.releases) {
    mark_pool(c.pool_request, false);
    mark_pool(c.pool_response, false);
    if (c.row.to_manager) close_channel(c.row.server_index);
    auto e = master_event(MasterEvent::Kind::SdoConnectionReleased, now, release.srd);
    e.connection = c.row;
    e.manager_reason = release.why;
    out.report(std::move(e));
  }
  if (release.deregister && !release.srd_lost) {
    port_.unwatch(release.srd);
    out.report(master_event(MasterEvent::Kind::SrdDeregistered, now, release.srd));
  }
  finish_job();
}

void SdoManagerProcess::finish_job() {
  if (!jobs_.empty()) jobs_.pop_front();
}

}  // namespace nmt
