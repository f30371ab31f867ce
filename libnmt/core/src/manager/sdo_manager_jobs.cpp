// The SDO manager's jobs (DSP 302 §7.2.1, §7.2.2): the scan of 1F10h after a Dynamic SDO
// Request, the registration of an SRD, the connections 1F00h asks for and the releases of 1F01h
// and of lost nodes, each a sequence of SDO accesses over the master's default SDO clients
// (SdoManagerPort::start_transfer), one job at a time (a scan lets the others go first between
// its reads). A 1F00h/1F01h write only queues one (§7.2.3: a successful response means the
// manager started). The engine and its port: sdo_manager_process.hpp.
#include <algorithm>
#include <utility>

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
  return Job{.kind = Job::Kind::Scan, .node = *cfg::NodeId::from(cfg::kMaxNodeId)};
}

void SdoManagerProcess::scan_next(Job& job) {
  if (const auto below = cfg::NodeId::from(job.node.value() - 1U)) {
    job.node = *below;
  } else {
    job.scanned_all = true;
  }
}

// --- jobs ---

void SdoManagerProcess::pump(TimePoint now, Output& out) {
  if (!enabled_) return;
  while (!in_flight_ && !jobs_.empty()) {
    if (!active()) return;  // resumes when the master is active again
    if (jobs_.front().kind == Job::Kind::Scan) {
      // Between two reads of a scan (126 silent node-IDs take 126 x the scan timeout), the
      // requests and releases that came meanwhile go first: a scan step costs them one read.
      const auto other = std::find_if(jobs_.begin(), jobs_.end(),
                                      [](const Job& j) { return j.kind != Job::Kind::Scan; });
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
    t.timeout = job.kind == Job::Kind::Scan ? settings_.scan_timeout : settings_.sdo_timeout;
    t.retries = step.retry ? settings_.sdo_retries : 0;
    in_flight_ = true;
    port_.start_transfer(std::move(t), now);
  }
}

void SdoManagerProcess::on_transfer_result(std::uint64_t tag, const SdoResult& result,
                                           TimePoint now, Output& out) {
  using Phase = Job::Phase;
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
  switch (job.phase) {
    case Phase::Scanning:
      // §7.2.1: an open request has Rq indication set.
      if (result.ok() && DynamicSdoState::decode(uploaded_u32(result)).request_indication) {
        start_register(uploaded_u32(result));
      } else {
        scan_next(job);
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
          write_step(job.node, {obj::kDynamicSdoConnectionState, 0}, job.confirmation, 4));
      return;
    }
    case Phase::ProbeSlave:
      if (!answered) {
        refuse(DynamicSdoError::kSlaveNotAvailable,
               {.kind = SdoManagerReason::Kind::SlaveDoesNotAnswer, .node = job.slave});
      } else {
        connect_with(kDefaultServer);
      }
      return;
    case Phase::SearchChannel: {
      if (!answered) {
        refuse(DynamicSdoError::kSlaveNotAvailable,
               {.kind = SdoManagerReason::Kind::SlaveDoesNotAnswer, .node = job.slave});
        return;
      }
      const bool free =
          result.ok() && (uploaded_u32(result) & cfg::kCobIdInvalidBit) != 0 &&
          std::none_of(connections_.begin(), connections_.end(), [&](const Connection& c) {
            return c.row.server == *job.slave && c.row.server_index == job.probe;
          });
      if (free) {
        connect_with(job.probe);
      } else if (!result.ok() || job.probe >= obj::kSdoServerLast) {
        refuse(DynamicSdoError::kNoFreeServerOnSlave,
               {.kind = SdoManagerReason::Kind::NoFreeServerEntry, .node = job.slave});
      } else {
        ++job.probe;
        job.steps.push_back(read_step(*job.slave, {job.probe, 1}));
      }
      return;
    }
    default:
      return;
  }
}

void SdoManagerProcess::job_failed(const SdoResult& result, TimePoint now, Output& out) {
  auto& job = jobs_.front();
  const SdoManagerReason why{
      .kind = SdoManagerReason::Kind::TransferFailed, .node = result.node_id, .transfer = result};
  job.steps.clear();
  auto& c = job.connection;
  if (job.kind == Job::Kind::Register) {
    // The SRD did not take the channel: give it back.
    if (c.row.server_index != 0) close_channel(c.row.server_index);
    mark_pool(c.pool_request, false);
    mark_pool(c.pool_response, false);
    auto e = master_event(MasterEvent::Kind::SrdRegistrationFailed, now, job.node);
    e.connection = c.row;
    e.manager_reason = why;
    out.report(std::move(e));
    finish_job();
    return;
  }
  if (job.kind == Job::Kind::Connect) {
    if (result.node_id == job.slave) {
      mark_pool(c.pool_request, false);
      mark_pool(c.pool_response, false);
      const bool timed_out = !result.aborted_by_server && result.abort == SdoAbort::Timeout;
      refuse(timed_out ? DynamicSdoError::kSlaveNotAvailable : DynamicSdoError::kNoDetails, why);
      return;
    }
    // The SRD did not take its entry: undo S's side (best effort), no confirmation possible.
    if (c.row.server_index != kDefaultServer) {
      job.steps.push_back(write_step(*job.slave, {c.row.server_index, 1},
                                     c.row.request.with_valid(false).word(), 4, false));
      job.steps.push_back(write_step(*job.slave, {c.row.server_index, 2},
                                     c.row.response.with_valid(false).word(), 4, false));
    }
    mark_pool(c.pool_request, false);
    mark_pool(c.pool_response, false);
    job.phase = Job::Phase::Refusing;
    job.error = DynamicSdoError::kNoDetails;
    job.why = why;
    return;
  }
  finish_job();
}

void SdoManagerProcess::refuse(DynamicSdoError error, SdoManagerReason why) {
  auto& job = jobs_.front();
  job.steps.clear();
  job.phase = Job::Phase::Refusing;
  job.error = error;
  job.why = std::move(why);
  // §7.2.3: Cnxn state 0 and the reason in the error code.
  const auto srd = srds_.find(job.node);
  const bool registering = job.kind == Job::Kind::Register;
  const bool ec = registering ? DynamicSdoState::decode(job.request).request_error_control
                              : srd != srds_.end() && srd->second.info.slave_error_control;
  const std::uint16_t index =
      registering ? DynamicSdoState::decode(job.request).client_index : job.client_index;
  auto state = DynamicSdoState::failure(index, error);
  state.request_error_control = ec;
  job.steps.push_back(
      write_step(job.node, {obj::kDynamicSdoConnectionState, 0}, state.encode(), 4, false));
}

void SdoManagerProcess::start_register(std::uint32_t request) {
  auto& job = jobs_.front();
  const auto srd = job.node;
  job.kind = Job::Kind::Register;
  job.request = request;
  job.connection = {};
  job.connection.row.srd = srd;
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
      refuse(DynamicSdoError::kNoDetails, {.kind = SdoManagerReason::Kind::DefaultSdoInUse});
      return;
    }
    job.phase = Job::Phase::Confirming;
    job.confirmation =
        DynamicSdoState::confirmation(0, ConnectionState::kAllDefaultSdosOwned).encode();
    return;
  }
  const auto index = state.client_index;
  if (!obj::is_sdo_client_parameter(index)) {
    refuse(DynamicSdoError::kNoDetails,
           {.kind = SdoManagerReason::Kind::NotAClientEntry, .index = index});
    return;
  }
  const auto channel = free_own_channel();
  const auto pool = free_pool();
  const auto row = free_row();
  if (channel == 0 || pool.size() < 2 || row == 0) {
    refuse(DynamicSdoError::kNoChannelToManager,
           SdoManagerReason{.kind = channel == 0 ? SdoManagerReason::Kind::NoFreeServerChannel
                                                 : SdoManagerReason::Kind::NoFreeCobIds});
    return;
  }
  auto& c = job.connection;
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
  job.phase = Job::Phase::Confirming;
  // §7.2.1: enable the SRD's client entry named in 1F10h, then reset 1F10h (Cnxn 1).
  job.steps.push_back(write_step(srd, {index, 3}, node_id_.value(), 1));
  job.steps.push_back(write_step(srd, {index, 1}, c.row.request.word(), 4));
  job.steps.push_back(write_step(srd, {index, 2}, c.row.response.word(), 4));
  job.confirmation = DynamicSdoState::confirmation(index, ConnectionState::kManagerConnected,
                                                   state.request_error_control)
                         .encode();
}

void SdoManagerProcess::start_connect() {
  auto& job = jobs_.front();
  if (srds_.count(job.node) == 0) {  // lost or gone meanwhile
    finish_job();
    return;
  }
  job.connection = {};
  job.connection.row.srd = job.node;
  job.connection.row.client_index = job.client_index;
  const auto slave = *job.slave;
  job.connection.row.server = slave;
  if (!default_sdo_taken(slave) && !all_default_sdos_owned()) {
    // Is S there? Its default SDO needs no write (§7.1).
    job.phase = Job::Phase::ProbeSlave;
    job.steps.push_back(read_step(slave, {obj::kDeviceType, 0}));
    return;
  }
  if (free_pool().size() < 2) {
    refuse(DynamicSdoError::kNoFreeChannelInNetwork,
           {.kind = SdoManagerReason::Kind::NoTwoFreeCobIds});
    return;
  }
  job.phase = Job::Phase::SearchChannel;
  job.probe = obj::kSdoServerFirst + 1;
  job.steps.push_back(read_step(slave, {job.probe, 1}));
}

void SdoManagerProcess::connect_with(std::uint16_t server_index) {
  auto& job = jobs_.front();
  auto& c = job.connection;
  const auto slave = *job.slave;
  c.row.server_index = server_index;
  if (server_index == kDefaultServer) {
    const auto cob_ids = sdo::default_cob_ids(slave);
    c.row.request = cob_ids.request;
    c.row.response = cob_ids.response;
  } else {
    const auto pool = free_pool();
    if (pool.size() < 2) {
      refuse(DynamicSdoError::kNoFreeChannelInNetwork,
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
    job.steps.push_back(write_step(slave, {server_index, 3}, job.node.value(), 1));
    job.steps.push_back(write_step(slave, {server_index, 1}, c.row.request.word(), 4));
    job.steps.push_back(write_step(slave, {server_index, 2}, c.row.response.word(), 4));
  }
  const bool ec = srds_.at(job.node).info.slave_error_control;
  job.steps.push_back(write_step(job.node, {job.client_index, 3}, slave.value(), 1));
  job.steps.push_back(write_step(job.node, {job.client_index, 1}, c.row.request.word(), 4));
  job.steps.push_back(write_step(job.node, {job.client_index, 2}, c.row.response.word(), 4));
  job.steps.push_back(write_step(
      job.node, {obj::kDynamicSdoConnectionState, 0},
      DynamicSdoState::confirmation(job.client_index, ConnectionState::kSlaveConnected, ec)
          .encode(),
      4));
  job.phase = Job::Phase::Writing;
}

void SdoManagerProcess::advance(TimePoint now, Output& out) {
  auto& job = jobs_.front();
  if (job.phase == Job::Phase::Refusing) {
    report_refusal(now, out);
    return;
  }
  switch (job.kind) {
    case Job::Kind::Scan:
      advance_scan();
      return;
    case Job::Kind::Register:
      advance_register(now, out);
      return;
    case Job::Kind::Connect:
      advance_connect(now, out);
      return;
    case Job::Kind::Release:
      advance_release(now, out);
      return;
  }
}

void SdoManagerProcess::report_refusal(TimePoint now, Output& out) {
  auto& job = jobs_.front();
  const bool registering = job.kind == Job::Kind::Register;
  auto e = master_event(registering ? MasterEvent::Kind::SrdRegistrationFailed
                                    : MasterEvent::Kind::SdoConnectionRefused,
                        now, job.node);
  e.connection = job.connection.row;
  e.connection_error = job.error;
  e.manager_reason = job.why;
  out.report(std::move(e));
  finish_job();
}

void SdoManagerProcess::advance_scan() {
  auto& job = jobs_.front();
  job.phase = Job::Phase::Scanning;  // from 127 (scan_job)
  // §7.2.1 / §7.2.4 guideline 2: from 127 down, node-IDs not registered, whose default SDO
  // no connection holds.
  while (!job.scanned_all &&
         (job.node == node_id_ || srds_.count(job.node) != 0 || default_sdo_taken(job.node))) {
    scan_next(job);
  }
  if (job.scanned_all) {
    finish_job();
    if (rescan_) {
      rescan_ = false;
      jobs_.push_back(scan_job());
    }
    return;
  }
  job.steps.push_back(read_step(job.node, {obj::kDynamicSdoConnectionState, 0}, false));
}

void SdoManagerProcess::advance_register(TimePoint now, Output& out) {
  auto& job = jobs_.front();
  if (job.phase == Job::Phase::Confirming) {
    // §7.2.1 "Error Control of SRD": the master's 1016h entry, else the SRD's 1017h; known
    // before the confirmation, so the SRD is registered once it has taken it.
    job.heartbeat = port_.consumer_time(job.node);
    if (job.heartbeat) {
      job.phase = Job::Phase::Writing;
      job.steps.push_back(
          write_step(job.node, {obj::kDynamicSdoConnectionState, 0}, job.confirmation, 4));
    } else {
      job.phase = Job::Phase::ReadHeartbeat;
      job.steps.push_back(read_step(job.node, {obj::kProducerHeartbeatTime, 0}));
    }
    return;
  }
  port_.watch(job.node, job.heartbeat, now);
  Srd srd;
  srd.info.node = job.node;
  const auto request = DynamicSdoState::decode(job.request);
  srd.info.all_default_sdos = request.is_all_default_sdos_request();
  srd.info.slave_error_control = request.request_error_control;
  auto e = master_event(MasterEvent::Kind::SrdRegistered, now, job.node);
  if (!srd.info.all_default_sdos) {
    auto c = job.connection;
    c.row.row = free_row();
    srd.info.client_index = c.row.client_index;
    srd.own_channel = c.row.server_index;
    e.connection = c.row;
    add_row(c);
  }
  e.srd = srd.info;
  srds_[job.node] = srd;
  out.report(std::move(e));
  finish_job();
}

void SdoManagerProcess::advance_connect(TimePoint now, Output& out) {
  auto& job = jobs_.front();
  if (job.phase == Job::Phase::Start) {
    start_connect();
    return;
  }
  // Phase::Writing done: established (§7.2.2).
  auto c = job.connection;
  c.row.row = free_row();
  add_row(c);
  const auto srd = srds_.find(job.node);
  if (srd != srds_.end() && srd->second.info.slave_error_control) {
    const auto slave = *job.slave;
    if (watched_.count(slave) == 0) {
      // §7.2.5 step 4.4: error control of S for the SRD.
      port_.watch(slave, std::nullopt, now);
    }
    watched_.insert(slave);
  }
  auto e = master_event(MasterEvent::Kind::SdoConnectionEstablished, now, job.node);
  e.connection = c.row;
  out.report(std::move(e));
  finish_job();
}

void SdoManagerProcess::advance_release(TimePoint now, Output& out) {
  auto& job = jobs_.front();
  if (job.phase == Job::Phase::Start) {
    job.phase = Job::Phase::Releasing;
    if (job.failed) {
      // §7.2.3 1F11h: reason 00h, the failed slave's node-ID.
      job.steps.push_back(write_step(
          job.node, {obj::kSlaveFailed, 0},
          sm::SlaveFailed{static_cast<std::uint8_t>(sm::SlaveFailedReason::kErrorControl),
                          job.failed->value()}
              .encode(),
          2, false, !job.srd_lost));
    }
    for (const auto& c : job.releases) {
      // §7.2.1: invalidate the SRD's client entry, then S's server entry (not its default).
      job.steps.push_back(write_step(job.node, {c.row.client_index, 1},
                                     c.row.request.with_valid(false).word(), 4, false,
                                     !job.srd_lost));
      job.steps.push_back(write_step(job.node, {c.row.client_index, 2},
                                     c.row.response.with_valid(false).word(), 4, false,
                                     !job.srd_lost));
      if (!c.row.to_manager && c.row.server_index != kDefaultServer && !job.server_gone) {
        job.steps.push_back(write_step(c.server(), {c.row.server_index, 1},
                                       c.row.request.with_valid(false).word(), 4, false));
        job.steps.push_back(write_step(c.server(), {c.row.server_index, 2},
                                       c.row.response.with_valid(false).word(), 4, false));
      }
    }
    if (!job.steps.empty()) return;
  }
  if (job.failed) {
    ManagedSdoConnection failed;
    failed.srd = job.node;
    failed.server = *job.failed;
    auto e = master_event(MasterEvent::Kind::SlaveFailedReported, now, job.node);
    e.connection = failed;
    out.report(std::move(e));
  }
  for (const auto& c : job.releases) {
    mark_pool(c.pool_request, false);
    mark_pool(c.pool_response, false);
    if (c.row.to_manager) close_channel(c.row.server_index);
    auto e = master_event(MasterEvent::Kind::SdoConnectionReleased, now, job.node);
    e.connection = c.row;
    e.manager_reason = job.why;
    out.report(std::move(e));
  }
  if (job.deregister && !job.srd_lost) {
    port_.unwatch(job.node);
    out.report(master_event(MasterEvent::Kind::SrdDeregistered, now, job.node));
  }
  finish_job();
}

void SdoManagerProcess::finish_job() {
  if (!jobs_.empty()) jobs_.pop_front();
}

}  // namespace nmt
