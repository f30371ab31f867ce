// The process boot NMT slave (CiA 302-2 §3.4) with its error status (§3.8, Table 1), check NMT
// state (§3.6), start error control (§4.1) and the retries of start process boot NMT slave
// (§3.3): BootSlaveProcess (boot_slave_process.hpp). The software version check and update
// (§3.4 part 2, DSP 302 §9) are in boot_software.cpp, check configuration (§3.5) in
// check_configuration.cpp; start remote node (§3.4 part 3) is the master's answer to the report
// (BootSlavePort::boot_con).
#include <string>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "master/boot_slave_process.hpp"
#include "master/master_support.hpp"

namespace nmt {

namespace obj = cfg::object;
using Phase = BootSlaveProcess::Phase;

std::uint32_t uploaded_u32(const SdoResult& result) {
  return cfg::low_le32(result.data);
}

BootFailure transfer_failed(const SdoResult& result, BootFailure::Reason reason) {
  return {.reason = reason, .transfer = result};
}

BootSlaveProcess::Options BootSlaveProcess::Options::from(const MasterOptions& options) {
  return {.reboot_timeout = options.boot.reboot_timeout,
          .guarding_reply_timeout = options.boot.guarding_reply_timeout,
          .retry_interval = options.boot.retry_interval,
          .force_download = options.boot.force_download,
          .save_configuration = options.boot.save_configuration,
          .application_step = options.boot.application_step,
          .program_control_timeout = options.program.control_timeout,
          .program_clear_timeout = options.program.clear_timeout,
          .program_data_timeout = options.program.data_timeout,
          .sdo_timeout = options.sdo.timeout,
          .sdo_retries = options.sdo.retries};
}

BootSlaveProcess::BootSlaveProcess(cfg::NodeId node, BootSlavePort& port, BootUpGate& gate,
                                   Options options)
    : node_(node), port_(&port), gate_(&gate), options_(options) {}

void BootSlaveProcess::set_deadline(std::optional<TimePoint> deadline) {
  deadline_ = deadline;
}

void BootSlaveProcess::set_step(BootStep step, TimePoint now, Output& out) {
  if (step_ == step) return;
  step_ = step;
  auto e = master_event(MasterEvent::Kind::BootStepChanged, now, node_);
  e.step = step;
  e.boot_try = tries_;
  e.total = plan_.size();
  e.written = next_;
  out.report(std::move(e));
}

void BootSlaveProcess::cancel(TimePoint now) {
  ++try_id_;
  running_ = false;
  phase_ = Phase::Idle;
  set_deadline(std::nullopt);
  // The transfers of the ended try: forgotten, and stopped on the bus.
  port_->cancel_transfers(node_, now);
}

void BootSlaveProcess::reset(TimePoint now) {
  cancel(now);
  // try_id_ goes on counting: a transfer of an old try still queued in the master never matches.
  BootSlaveProcess fresh(node_, *port_, *gate_, options_);
  fresh.try_id_ = try_id_;  // tries_ starts again: a new start-up
  *this = std::move(fresh);
}

void BootSlaveProcess::start(AskedBy asker, TimePoint now, Output& out) {
  begin(std::nullopt, asker == AskedBy::Application, now, out);
}

void BootSlaveProcess::start_after_reset(TimePoint wait_until, TimePoint now, Output& out) {
  begin(wait_until, false, now, out);
}

void BootSlaveProcess::begin(std::optional<TimePoint> boot_up_until, bool asked_by_application,
                             TimePoint now, Output& out) {
  // A start without a wait for the boot-up while the try still waited for one (a boot-up that
  // came after the one it took, a power-on boot-up before the reset's) goes on with that try:
  // it had not asked the slave anything yet.
  if (!(phase_ == Phase::AwaitBootUp && running_ && !boot_up_until)) ++tries_;
  cancel(now);
  // A new try: its data goes, what outlives a try stays (a 1F25h request holds until a try
  // succeeds).
  step_ = BootStep::Idle;
  expect_boot_up_ = boot_up_until.has_value();
  boot_up_seen_ = false;
  software_updated_ = false;
  identity_sub_ = 0;
  software_ = {};
  software_id_ = 0;
  update_.reset();
  verify_ = {};
  cob_ids_to_read_.clear();
  cob_ids_read_.clear();
  configuration_.clear();
  plan_.clear();
  next_ = 0;
  bytes_ = 0;
  configured_ = false;
  no_configuration_ = false;
  keep_alive_operational_ = false;
  left_to_application_ = false;
  cob_ids_checked_ = false;
  booted_ = false;
  final_error_ = false;
  running_ = true;
  const auto a = port_->expectations(node_).assignment;
  // §3.4 a: a device that is not an NMT slave of this master ends with status A.
  if (!a.is_slave()) {
    failed(BootError::A, {.reason = BootFailure::Reason::NotListed}, now, out);
    return;
  }
  // §3.4 b, Table 20: with bit 2 clear the application configures and starts the slave.
  if (!a.boot_slave() && !asked_by_application) {
    left_to_application_ = true;
    succeeded(now, out);
    return;
  }
  if (boot_up_until) {
    phase_ = Phase::AwaitBootUp;
    set_deadline(*boot_up_until);
    set_step(BootStep::AwaitBootUp, now, out);
    return;
  }
  identify(now, out);
}

void BootSlaveProcess::identify(TimePoint now, Output& out) {
  set_step(BootStep::Identify, now, out);
  upload(Phase::ReadDeviceType, obj::kDeviceType, 0, now);
}

void BootSlaveProcess::upload(Phase phase, std::uint16_t index, std::uint8_t sub, TimePoint now) {
  phase_ = phase;
  port_->transfer(try_id_,
                  {.node = node_,
                   .object = {index, sub},
                   .upload = true,
                   .timeout = options_.sdo_timeout,
                   .retries = options_.sdo_retries},
                  now);
}

void BootSlaveProcess::download(Phase phase, std::uint16_t index, std::uint8_t sub,
                                std::vector<std::uint8_t> data, TimePoint now) {
  phase_ = phase;
  port_->transfer(try_id_,
                  {.node = node_,
                   .object = {index, sub},
                   .data = std::move(data),
                   .timeout = options_.sdo_timeout,
                   .retries = options_.sdo_retries},
                  now);
}

void BootSlaveProcess::on_sdo_result(const SdoResult& r, TimePoint now, Output& out) {
  const bool reads_u32 = phase_ == Phase::ReadDeviceType || phase_ == Phase::ReadIdentity ||
                         phase_ == Phase::ReadSoftwareDate || phase_ == Phase::ReadSoftwareTime ||
                         phase_ == Phase::ReadSoftwareId || phase_ == Phase::ReadFlashStatus;
  if (reads_u32 && r.ok() && r.data.empty()) {
    // A 0-byte answer (a segmented or block upload of nothing) has no UNSIGNED32 to compare: the
    // step fails as a failed upload does, with CiA 301 0607 0010 (length does not match).
    auto failed = r;
    failed.abort = SdoAbort::LengthMismatch;
    return on_sdo_result(failed, now, out);
  }
  switch (phase_) {
    case Phase::ReadDeviceType: {
      // §3.4 c: no response -> B; d: 1F84h non-zero and different -> C.
      if (!r.ok()) {
        failed(BootError::B, transfer_failed(r), now, out);
        return;
      }
      const auto actual = uploaded_u32(r);
      const auto expected = port_->expectations(node_).device_type;
      if (expected != 0 && actual != expected) {
        failed(BootError::C,
               {.reason = BootFailure::Reason::ValueDiffers,
                .object = {obj::kDeviceType, 0},
                .actual = actual,
                .expected_by = obj::kDeviceTypeIdentification,
                .expected = expected},
               now, out);
        return;
      }
      identity_sub_ = 0;
      next_identity(now, out);
      return;
    }
    case Phase::ReadIdentity: {
      // §3.4 e: 1F85h-1F88h against 1018h sub 1-4 (D, M, N, O).
      static constexpr BootError kLetters[] = {BootError::D, BootError::M, BootError::N,
                                               BootError::O};
      const auto sub = identity_sub_;
      const auto error = kLetters[sub - 1];
      if (!r.ok()) {
        failed(error, transfer_failed(r), now, out);
        return;
      }
      const auto actual = uploaded_u32(r);
      const auto expected = port_->expectations(node_).identity[sub - 1];
      bool match = actual == expected;
      if (sub == 3) {
        // §6.9: the major revision (high 16 bits) must be equal, the minor (low 16 bits) not
        // less than the expected one.
        match = (actual >> 16) == (expected >> 16) && (actual & 0xFFFF) >= (expected & 0xFFFF);
      }
      if (!match) {
        failed(error,
               {.reason = BootFailure::Reason::ValueDiffers,
                .object = {obj::kIdentity, sub},
                .actual = actual,
                .expected_by = static_cast<std::uint16_t>(obj::kVendorIdentification + sub - 1),
                .expected = expected},
               now, out);
        return;
      }
      next_identity(now, out);
      return;
    }
    case Phase::ReadSoftwareDate:
    case Phase::ReadSoftwareTime:
    case Phase::ReadSoftwareId:
    case Phase::ReadFlashStatus:
    case Phase::ProgramStop:
    case Phase::ProgramClear:
    case Phase::ProgramData:
    case Phase::ProgramStart:
      software_sdo_result(r, now, out);
      return;
    default:
      configuration_sdo_result(r, now, out);
      return;
  }
}

void BootSlaveProcess::next_identity(TimePoint now, Output& out) {
  const auto identity = port_->expectations(node_).identity;
  for (std::uint8_t sub = identity_sub_ + 1; sub <= 4; ++sub) {
    if (identity[sub - 1] != 0) {
      identity_sub_ = sub;
      upload(Phase::ReadIdentity, obj::kIdentity, sub, now);
      return;
    }
  }
  after_identity(now, out);
}

void BootSlaveProcess::after_identity(TimePoint now, Output& out) {
  if (!port_->expectations(node_).assignment.keep_alive()) {
    check_software(now, out);
    return;
  }
  // §3.4 part 2 a, §3.6 check NMT state: a heartbeat within the consumer time, else one
  // guarding request answered within 100 ms.
  set_step(BootStep::CheckNmtState, now, out);
  if (const auto time = port_->heartbeat_time(node_)) {
    const auto heard = port_->last_heartbeat(node_);
    const auto known = port_->known_state(node_).nmt_state();
    if (heard && now - *heard <= *time && known) {
      keep_alive_state(*known, now, out);
      return;
    }
    phase_ = Phase::CheckStateHeartbeat;
    set_deadline(now + *time);
    return;
  }
  phase_ = Phase::CheckStateGuarding;
  set_deadline(now + options_.guarding_reply_timeout);
  out.send(make_guarding_request(node_));
}

void BootSlaveProcess::keep_alive_state(NmtState state, TimePoint now, Output& out) {
  set_deadline(std::nullopt);
  phase_ = Phase::Idle;
  if (state == NmtState::Operational) {
    // §3.5 last paragraph: check configuration is skipped and the boot ends with status L
    // once error control runs (connection point D of DSP 302 §4).
    keep_alive_operational_ = true;
    start_error_control(now, out);
    return;
  }
  // Not operational: reset communication for that slave, then on with its boot.
  port_->queue_nmt(NmtCommand::ResetCommunication, node_);
  expect_boot_up_ = true;
  phase_ = Phase::AwaitResetBootUp;
  set_deadline(now + options_.reboot_timeout);
  set_step(BootStep::AwaitBootUp, now, out);
}

void BootSlaveProcess::start_error_control(TimePoint now, Output& out) {
  set_step(BootStep::StartErrorControl, now, out);
  // §4.1: heartbeat when 1016h has the node (its first heartbeat ends the step), else guarding.
  if (port_->start_error_control(node_, now)) {
    phase_ = Phase::AwaitFirstHeartbeat;
    return;
  }
  error_control_started(now, out);
}

void BootSlaveProcess::on_heartbeat(NmtState state, TimePoint now, Output& out) {
  if (phase_ == Phase::CheckStateHeartbeat) {
    keep_alive_state(state, now, out);
  } else if (phase_ == Phase::AwaitFirstHeartbeat) {
    phase_ = Phase::Idle;
    error_control_started(now, out);
  }
}

void BootSlaveProcess::on_guard_reply(NmtState state, TimePoint now, Output& out) {
  keep_alive_state(state, now, out);
}

void BootSlaveProcess::on_heartbeat_timeout(TimePoint now, Output& out) {
  const auto time = port_->heartbeat_time(node_).value_or(Duration{0});
  failed(BootError::K,
         {.reason = BootFailure::Reason::NoFirstHeartbeat,
          .consumer_time_ms = static_cast<std::uint64_t>(
              std::chrono::duration_cast<std::chrono::milliseconds>(time).count())},
         now, out);
}

void BootSlaveProcess::error_control_started(TimePoint now, Output& out) {
  if (keep_alive_operational_) {
    failed(BootError::L, {.reason = BootFailure::Reason::KeptAlive}, now, out);
    return;
  }
  succeeded(now, out);
}

void BootSlaveProcess::configuration_done(bool ok, TimePoint now, Output& out) {
  if (!running_ || phase_ != Phase::Application) return;
  phase_ = Phase::Idle;
  if (ok) {
    start_error_control(now, out);
  } else {
    failed(BootError::J, {.reason = BootFailure::Reason::ApplicationStepFailed}, now, out);
  }
}

void BootSlaveProcess::succeeded(TimePoint now, Output& out) {
  // §3.4 part 3 g-l (start remote node) is the master's: it knows the start-up's state.
  port_->boot_con(node_, std::nullopt, left_to_application_, now, out);
  running_ = false;
  phase_ = Phase::Idle;
  set_deadline(std::nullopt);
  tried_ = true;
  booted_ = true;
  reconfigure_ = false;
  final_error_ = false;
  last_error_.reset();
  reported_error_.reset();
  step_ = left_to_application_ ? BootStep::Idle : BootStep::Booted;
  auto e = master_event(MasterEvent::Kind::SlaveBooted, now, node_);
  e.step = step_;
  e.boot_try = tries_;
  e.configured = configured_;
  e.no_configuration = no_configuration_;
  e.written = configured_ ? plan_.size() : 0;
  e.total = plan_.size();
  e.bytes = bytes_;
  e.program = update_;
  e.boot_emergency = port_->take_boot_emergency(node_);
  out.report(std::move(e));
}

void BootSlaveProcess::failed(BootError error, BootFailure failure, TimePoint now, Output& out) {
  failure.step = step_;
  set_deadline(std::nullopt);
  phase_ = Phase::Idle;
  tried_ = true;
  last_error_ = error;
  const auto expect = port_->expectations(node_);
  port_->boot_con(node_, error, false, now, out);
  bool retry = false;
  if (error == BootError::L) {
    // The slave runs and is under error control: nothing to retry.
    booted_ = true;
  } else {
    booted_ = false;
    // §3.3: optional slaves are tried until they boot; mandatory ones after B until 1F89h
    // (boot time, 0: no limit) has elapsed since start-up began.
    const Duration boot_time = std::chrono::milliseconds(expect.boot_time_ms);
    if (error == BootError::A) {
      retry = false;
    } else if (!expect.assignment.mandatory()) {
      retry = true;
    } else if (error == BootError::B) {
      retry = boot_time.count() == 0 || now - port_->startup_began() < boot_time;
    }
  }
  final_error_ = !retry;
  // Taken at every end of a try, so that a retry's report names only its own.
  auto boot_emergency = port_->take_boot_emergency(node_);
  // Retries that end the same way are not reported again.
  if (reported_error_ != error || !retry) {
    reported_error_ = error;
    auto e = master_event(MasterEvent::Kind::BootError, now, node_);
    e.boot_emergency = boot_emergency;
    e.error = error;
    e.final = !retry;
    e.step = BootStep::Failed;
    e.boot_try = tries_;
    if (error == BootError::I) e.program = update_;
    if (!retry && expect.assignment.mandatory() && error == BootError::B &&
        expect.boot_time_ms != 0) {
      failure.boot_time_ms = expect.boot_time_ms;
    }
    e.failure = std::move(failure);
    out.report(std::move(e));
  }
  if (retry) {
    running_ = true;
    phase_ = Phase::RetryWait;
    step_ = BootStep::RetryWait;
    set_deadline(now + options_.retry_interval);
  } else {
    running_ = false;
    step_ = error == BootError::L ? BootStep::Booted : BootStep::Failed;
  }
}

void BootSlaveProcess::on_timer(TimePoint now, Output& out) {
  if (!deadline_ || now < *deadline_) return;
  set_deadline(std::nullopt);
  switch (phase_) {
    case Phase::AwaitBootUp:
      // No boot-up within the wait: identify anyway (a boot-up may have been missed); the gate
      // opens for all.
      gate_->open();
      identify(now, out);
      return;
    case Phase::CheckStateHeartbeat:
      failed(BootError::E, {.reason = BootFailure::Reason::NoHeartbeat}, now, out);
      return;
    case Phase::CheckStateGuarding:
      failed(BootError::F, {.reason = BootFailure::Reason::NoGuardingReply}, now, out);
      return;
    case Phase::AwaitResetBootUp:
      check_software(now, out);
      return;
    case Phase::AwaitRestoreBootUp:
      failed(BootError::J, {.reason = BootFailure::Reason::NoBootUpAfterRestore}, now, out);
      return;
    case Phase::RetryWait:
      start(now, out);
      return;
    case Phase::FlashStatusWait:
      upload(Phase::ReadFlashStatus, cfg::object::kFlashStatusIdentification, 1, now);
      return;
    default:
      return;
  }
}

bool BootSlaveProcess::on_boot_up(TimePoint now, Output& out) {
  if (!running_) return false;
  // A boot-up while the first upload (1000h) is under way: the device just (re)started, which
  // the try has not relied on yet; it goes on (a lost request is repeated after its timeout).
  if (phase_ == Phase::ReadDeviceType) {
    expect_boot_up_ = false;
    return true;
  }
  // §3.3: waiting for the next try, and the slave is there now: try at once.
  if (phase_ == Phase::RetryWait) {
    start(now, out);
    return true;
  }
  if (!expect_boot_up_) return false;
  expect_boot_up_ = false;
  switch (phase_) {
    case Phase::AwaitBootUp:
      if (gate_->closed()) {
        // It waits for the others (the master opens the gate after the last one).
        boot_up_seen_ = true;
        gate_->booted_up(now);
        break;
      }
      set_deadline(std::nullopt);
      identify(now, out);
      break;
    case Phase::AwaitResetBootUp:
      set_deadline(std::nullopt);
      phase_ = Phase::Idle;
      check_software(now, out);
      break;
    case Phase::AwaitRestoreBootUp:
      set_deadline(std::nullopt);
      phase_ = Phase::Idle;
      plan_download(now, out);
      break;
    default:
      // A late boot-up after the wait ran out: the try goes on (its SDO transfers repeat).
      break;
  }
  return true;
}

void BootSlaveProcess::pass_boot_up_gate(TimePoint now, Output& out) {
  // One not booted up yet keeps its deadline (boot_up_wait) and starts at its boot-up.
  if (!at_boot_up_gate() || !boot_up_seen_) return;
  set_deadline(std::nullopt);
  identify(now, out);
}

}  // namespace nmt
