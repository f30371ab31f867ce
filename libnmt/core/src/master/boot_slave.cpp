// The process boot NMT slave (CiA 302-2 §3.4) with its error status (§3.8, Table 1), check NMT
// state (§3.6), the software version check and update (§3.4 part 2, DSP 302 §9), start error
// control (§4.1) and start remote node (§3.4 part 3), and the retries of start process boot NMT
// slave (§3.3). Check configuration (§3.5) is in check_configuration.cpp.
#include <string>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;
using Phase = SlaveBoot::Phase;

namespace {

std::string stamp_text(cfg::ConfigurationStamp stamp) {
  return "day " + std::to_string(stamp.days) + ", " + std::to_string(stamp.ms) + " ms";
}

}  // namespace

std::uint32_t uploaded_u32(const SdoResult& result) {
  return low_u32(result.data);
}

std::string transfer_failure(const SdoResult& result) {
  return cfg::to_string({result.index, result.sub_index}) +
         (result.upload ? " upload" : " download") + " failed: " + to_string(result.abort);
}

std::vector<std::uint8_t> u32_bytes(std::uint32_t value) {
  return cfg::le32_bytes(value);
}

void NmtMaster::Impl::set_step(std::uint8_t node, BootStep step, TimePoint now, Output& out) {
  auto& s = slaves[node];
  if (s.step == step) return;
  s.step = step;
  auto e = master_event(MasterEvent::Kind::BootStepChanged, now, node, "");
  e.step = step;
  e.total = s.plan.size();
  e.written = s.next;
  e.text = node_text(node) + ": " + std::string(to_string(step));
  report(out, std::move(e));
}

void NmtMaster::Impl::cancel_boot(std::uint8_t node, TimePoint now) {
  auto& s = slaves[node];
  ++s.try_id;
  s.running = false;
  s.phase = Phase::Idle;
  s.deadline.reset();
  // The transfers of the ended try: forget them, and stop them on the bus.
  for (auto it = transfers.begin(); it != transfers.end();) {
    if (it->first.first == node && !it->second.for_application) {
      const auto id = it->first.second;
      forget_transfer(it++);
      clients.client(node).cancel(id, now, sdo_out);
    } else {
      ++it;
    }
  }
}

void NmtMaster::Impl::start_boot(std::uint8_t node, bool after_reset, TimePoint now, Output& out,
                                 bool asked_by_application) {
  cancel_boot(node, now);
  auto& s = slaves[node];
  const auto keep = s;
  s = SlaveBoot{};
  // What outlives a try.
  s.try_id = keep.try_id;
  s.tried = keep.tried;
  s.booted = false;
  s.last_error = keep.last_error;
  s.held = keep.held;
  s.known_state = keep.known_state;
  s.reported_error = keep.reported_error;
  s.heartbeat_at = keep.heartbeat_at;
  s.reconfigure = keep.reconfigure;  // a 1F25h request holds until a try succeeds
  s.running = true;
  s.expect_boot_up = after_reset;
  const auto a = assignment(node);
  // §3.4 a: a device that is not an NMT slave of this master ends with status A.
  if (!a.is_slave() || node == node_id.value()) {
    boot_failed(node, BootError::A, "1F81h sub " + cfg::hex(node, 2) + "h has bit 0 clear", now,
                out);
    return;
  }
  // §3.4 b, Table 20: with bit 2 clear the application configures and starts the slave.
  if (!a.boot_slave() && !asked_by_application) {
    s.left_to_application = true;
    boot_succeeded(node, now, out);
    return;
  }
  if (after_reset) {
    s.phase = Phase::AwaitBootUp;
    s.deadline = boot_up_gate.value_or(now + options.boot_up_wait);
    set_step(node, BootStep::AwaitBootUp, now, out);
    return;
  }
  set_step(node, BootStep::Identify, now, out);
  boot_upload(node, Phase::ReadDeviceType, obj::kDeviceType, 0, now);
}

void NmtMaster::Impl::boot_upload(std::uint8_t node, Phase phase, std::uint16_t index,
                                  std::uint8_t sub, TimePoint now) {
  auto& s = slaves[node];
  s.phase = phase;
  MasterTransfer t;
  t.try_id = s.try_id;
  t.index = index;
  t.sub = sub;
  t.upload = true;
  t.options.timeout = options.sdo_timeout;
  t.retries_left = options.sdo_retries;
  start_transfer(node, std::move(t), now);
}

void NmtMaster::Impl::boot_download(std::uint8_t node, Phase phase, std::uint16_t index,
                                    std::uint8_t sub, std::vector<std::uint8_t> data,
                                    TimePoint now) {
  auto& s = slaves[node];
  s.phase = phase;
  MasterTransfer t;
  t.try_id = s.try_id;
  t.index = index;
  t.sub = sub;
  t.data = std::move(data);
  t.options.timeout = options.sdo_timeout;
  // Large values by block transfer; SdoClient falls back to segmented when refused.
  if (t.data.size() > options.block_threshold) t.options.mode = SdoMode::Block;
  t.retries_left = options.sdo_retries;
  start_transfer(node, std::move(t), now);
}

void NmtMaster::Impl::boot_sdo_result(std::uint8_t node, const SdoResult& r, TimePoint now,
                                      Output& out) {
  auto& s = slaves[node];
  const bool reads_u32 = s.phase == Phase::ReadDeviceType || s.phase == Phase::ReadIdentity ||
                         s.phase == Phase::ReadSoftwareDate || s.phase == Phase::ReadSoftwareTime;
  if (reads_u32 && r.ok() && r.data.empty()) {
    // A 0-byte answer (a segmented or block upload of nothing) has no UNSIGNED32 to compare: the
    // step fails as a failed upload does, with CiA 301 0607 0010 (length does not match).
    auto failed = r;
    failed.abort = SdoAbort::LengthMismatch;
    return boot_sdo_result(node, failed, now, out);
  }
  switch (s.phase) {
    case Phase::ReadDeviceType: {
      // §3.4 c: no response -> B; d: 1F84h non-zero and different -> C.
      if (!r.ok()) {
        boot_failed(node, BootError::B, transfer_failure(r), now, out);
        return;
      }
      const auto actual = uploaded_u32(r);
      const auto expected = value_of(obj::kDeviceTypeIdentification, node);
      if (expected != 0 && actual != expected) {
        boot_failed(node, BootError::C,
                    "1000h is " + cfg::hex(actual, 8) + ", 1F84h expects " + cfg::hex(expected, 8),
                    now, out);
        return;
      }
      s.identity_sub = 0;
      next_identity(node, now, out);
      return;
    }
    case Phase::ReadIdentity: {
      // §3.4 e: 1F85h-1F88h against 1018h sub 1-4 (D, M, N, O).
      static constexpr BootError kLetters[] = {BootError::D, BootError::M, BootError::N,
                                               BootError::O};
      const auto sub = s.identity_sub;
      const auto error = kLetters[sub - 1];
      if (!r.ok()) {
        boot_failed(node, error, transfer_failure(r), now, out);
        return;
      }
      const auto actual = uploaded_u32(r);
      const auto expected =
          value_of(static_cast<std::uint16_t>(obj::kVendorIdentification + sub - 1), node);
      bool match = actual == expected;
      if (sub == 3) {
        // §6.9: the major revision (high 16 bits) must be equal, the minor (low 16 bits) not
        // less than the expected one.
        match = (actual >> 16) == (expected >> 16) && (actual & 0xFFFF) >= (expected & 0xFFFF);
      }
      if (!match) {
        boot_failed(
            node, error,
            cfg::to_string({obj::kIdentity, sub}) + " is " + cfg::hex(actual, 8) + ", " +
                cfg::object_name(static_cast<std::uint16_t>(obj::kVendorIdentification + sub - 1)) +
                " expects " + cfg::hex(expected, 8),
            now, out);
        return;
      }
      next_identity(node, now, out);
      return;
    }
    case Phase::ReadSoftwareDate:
    case Phase::ReadSoftwareTime: {
      if (!r.ok()) {
        // The slave's program objects do not answer as CiA 302-3 has them.
        boot_failed(node, s.software_updated ? BootError::I : BootError::G, transfer_failure(r),
                    now, out);
        return;
      }
      if (s.phase == Phase::ReadSoftwareDate) {
        s.software.days = uploaded_u32(r);
        boot_upload(node, Phase::ReadSoftwareTime, obj::kVerifyApplicationSoftware, 2, now);
      } else {
        s.software.ms = uploaded_u32(r);
        software_checked(node, now, out);
      }
      return;
    }
    case Phase::ProgramStop:
    case Phase::ProgramClear:
    case Phase::ProgramData:
    case Phase::ProgramStart: {
      if (!r.ok()) {
        boot_failed(node, BootError::I, "program download: " + transfer_failure(r), now, out);
        return;
      }
      // CiA 302-3 program download: stop (0), clear (3), 1F50h data, start (1).
      if (s.phase == Phase::ProgramStop) {
        boot_download(node, Phase::ProgramClear, obj::kProgramControl, 1, {3}, now);
      } else if (s.phase == Phase::ProgramClear) {
        auto image = options.configurations
                         ? options.configurations->program(*cfg::NodeId::from(node))
                         : std::nullopt;
        boot_download(node, Phase::ProgramData, obj::kProgramData, 1,
                      image ? std::move(*image) : std::vector<std::uint8_t>{}, now);
      } else if (s.phase == Phase::ProgramData) {
        boot_download(node, Phase::ProgramStart, obj::kProgramControl, 1, {1}, now);
      } else {
        s.software_updated = true;
        set_step(node, BootStep::CheckSoftware, now, out);
        boot_upload(node, Phase::ReadSoftwareDate, obj::kVerifyApplicationSoftware, 1, now);
      }
      return;
    }
    default:
      configuration_sdo_result(node, r, now, out);
      return;
  }
}

void NmtMaster::Impl::next_identity(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  for (std::uint8_t sub = s.identity_sub + 1; sub <= 4; ++sub) {
    if (value_of(static_cast<std::uint16_t>(obj::kVendorIdentification + sub - 1), node) != 0) {
      s.identity_sub = sub;
      boot_upload(node, Phase::ReadIdentity, obj::kIdentity, sub, now);
      return;
    }
  }
  after_identity(node, now, out);
}

void NmtMaster::Impl::after_identity(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  if (!assignment(node).keep_alive()) {
    check_software(node, now, out);
    return;
  }
  // §3.4 part 2 a, §3.6 check NMT state: a heartbeat within the consumer time, else one
  // guarding request answered within 100 ms.
  set_step(node, BootStep::CheckNmtState, now, out);
  if (const auto time = heartbeat_time(node)) {
    if (s.heartbeat_at && now - *s.heartbeat_at <= *time && s.known_state > 1) {
      keep_alive_state(node, static_cast<NmtState>(s.known_state), now, out);
      return;
    }
    s.phase = Phase::CheckStateHeartbeat;
    s.deadline = now + *time;
    return;
  }
  s.phase = Phase::CheckStateGuarding;
  s.deadline = now + options.guarding_reply_timeout;
  out.send(make_guarding_request(*cfg::NodeId::from(node)));
}

void NmtMaster::Impl::keep_alive_state(std::uint8_t node, NmtState state, TimePoint now,
                                       Output& out) {
  auto& s = slaves[node];
  s.deadline.reset();
  s.phase = Phase::Idle;
  if (state == NmtState::Operational) {
    // §3.5 last paragraph: check configuration is skipped and the boot ends with status L
    // once error control runs (connection point D of DSP 302 §4).
    s.keep_alive_operational = true;
    start_error_control(node, now, out);
    return;
  }
  // Not operational: reset communication for that slave, then on with its boot.
  queue_nmt(NmtCommand::ResetCommunication, node);
  s.expect_boot_up = true;
  s.phase = Phase::AwaitResetBootUp;
  s.deadline = now + options.reboot_timeout;
  set_step(node, BootStep::AwaitBootUp, now, out);
}

void NmtMaster::Impl::check_software(std::uint8_t node, TimePoint now, Output& out) {
  const auto a = assignment(node);
  if (!a.verify_software()) {
    check_configuration(node, now, out);
    return;
  }
  const cfg::ConfigurationStamp expected{value_of(obj::kExpectedApplicationSwDate, node),
                                         value_of(obj::kExpectedApplicationSwTime, node)};
  if (expected.is_zero()) {
    boot_failed(node, BootError::G,
                "1F81h bit 5 asks for a software version check, but 1F53h and 1F54h sub " +
                    cfg::hex(node, 2) + "h are 0",
                now, out);
    return;
  }
  set_step(node, BootStep::CheckSoftware, now, out);
  boot_upload(node, Phase::ReadSoftwareDate, obj::kVerifyApplicationSoftware, 1, now);
}

void NmtMaster::Impl::software_checked(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  const cfg::ConfigurationStamp expected{value_of(obj::kExpectedApplicationSwDate, node),
                                         value_of(obj::kExpectedApplicationSwTime, node)};
  if (s.software == expected) {
    check_configuration(node, now, out);
    return;
  }
  const std::string versions =
      "1F52h reports " + stamp_text(s.software) + ", 1F53h/1F54h expect " + stamp_text(expected);
  if (s.software_updated) {
    boot_failed(node, BootError::I, "after the program download " + versions, now, out);
    return;
  }
  if (!assignment(node).update_software()) {
    boot_failed(node, BootError::H, versions + "; 1F81h bit 6 does not allow an update", now, out);
    return;
  }
  const bool have_image = options.configurations &&
                          options.configurations->program(*cfg::NodeId::from(node)).has_value();
  if (!have_image) {
    boot_failed(node, BootError::H, versions + "; no program image is available", now, out);
    return;
  }
  set_step(node, BootStep::UpdateSoftware, now, out);
  boot_download(node, Phase::ProgramStop, obj::kProgramControl, 1, {0}, now);
}

void NmtMaster::Impl::start_error_control(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  set_step(node, BootStep::StartErrorControl, now, out);
  // §4.1: heartbeat when 1016h has the node; the first timeout counts from now.
  if (const auto time = heartbeat_time(node)) {
    heartbeats.monitor(
        {node, static_cast<std::uint16_t>(
                   std::chrono::duration_cast<std::chrono::milliseconds>(*time).count())},
        now);
    s.phase = Phase::AwaitFirstHeartbeat;
    return;
  }
  // Else guarding when 1F81h bytes 2-3 (guard time) and byte 1 (retry factor) are non-zero.
  const auto a = assignment(node);
  if (a.guard_time_ms() != 0 && a.retry_factor() != 0) {
    guarding.start(*cfg::NodeId::from(node), a.guard_time_ms(), a.retry_factor(), now);
  }
  error_control_started(node, now, out);
}

void NmtMaster::Impl::boot_heartbeat(std::uint8_t node, NmtState state, TimePoint now,
                                     Output& out) {
  auto& s = slaves[node];
  if (s.phase == Phase::CheckStateHeartbeat) {
    keep_alive_state(node, state, now, out);
  } else if (s.phase == Phase::AwaitFirstHeartbeat) {
    s.phase = Phase::Idle;
    error_control_started(node, now, out);
  }
}

void NmtMaster::Impl::boot_guard_reply(std::uint8_t node, NmtState state, TimePoint now,
                                       Output& out) {
  set_known_state(node, static_cast<std::uint8_t>(state), now, out);
  keep_alive_state(node, state, now, out);
}

void NmtMaster::Impl::boot_heartbeat_timeout(std::uint8_t node, TimePoint now, Output& out) {
  const auto time = heartbeat_time(node).value_or(Duration{0});
  boot_failed(
      node, BootError::K,
      "no heartbeat within the consumer time of " +
          std::to_string(std::chrono::duration_cast<std::chrono::milliseconds>(time).count()) +
          " ms (1016h)",
      now, out);
}

void NmtMaster::Impl::error_control_started(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  if (s.keep_alive_operational) {
    boot_failed(node, BootError::L, "kept alive (1F81h bit 4): configuration not checked", now,
                out);
    return;
  }
  start_remote_node(node, now, out);
}

void NmtMaster::Impl::start_remote_node(std::uint8_t node, TimePoint now, Output& out) {
  const auto config = startup_config();
  // §3.4 part 3 g-l. While NMT start-up runs, no slave is started: §3.1 h starts them once every
  // mandatory slave booted (finish_startup), and a halted start-up (§3.1 f) starts none.
  const bool operational =
      slaves[node].known_state == static_cast<std::uint8_t>(NmtState::Operational);
  const bool broadcast_later = config.start_all_nodes() && own_state != NmtState::Operational;
  if (!operational && !config.no_start_slaves() && !broadcast_later &&
      startup == StartupState::Operational) {
    queue_nmt(NmtCommand::Start, node);
  }
  boot_succeeded(node, now, out);
}

void NmtMaster::Impl::boot_succeeded(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  s.running = false;
  s.phase = Phase::Idle;
  s.deadline.reset();
  s.tried = true;
  s.booted = true;
  s.reconfigure = false;
  s.final_error = false;
  s.last_error.reset();
  s.reported_error.reset();
  s.step = s.left_to_application ? BootStep::Idle : BootStep::Booted;
  auto e = master_event(MasterEvent::Kind::SlaveBooted, now, node, "");
  e.step = s.step;
  e.configured = s.configured;
  e.written = s.configured ? s.plan.size() : 0;
  e.total = s.plan.size();
  e.bytes = s.bytes;
  e.text = node_text(node) + ": booted" +
           (s.left_to_application ? std::string(" and left to the application (1F81h bit 2 clear: "
                                                "no configuration, no start)")
            : s.configured ? " (configured: " + std::to_string(s.plan.size()) + " entries, " +
                                 std::to_string(s.bytes) + " bytes)"
                           : " (configuration up to date)");
  report(out, std::move(e));
}

void NmtMaster::Impl::boot_failed(std::uint8_t node, BootError error, const std::string& why,
                                  TimePoint now, Output& out) {
  auto& s = slaves[node];
  s.deadline.reset();
  s.phase = Phase::Idle;
  s.tried = true;
  s.last_error = error;
  const auto a = assignment(node);
  bool retry = false;
  if (error == BootError::L) {
    // The slave runs and is under error control: nothing to retry.
    s.booted = true;
  } else {
    stop_error_control(node);
    s.booted = false;
    if (error == BootError::B) set_known_state(node, 1, now, out);
    // §3.3: optional slaves are tried until they boot; mandatory ones after B until 1F89h
    // (boot time, 0: no limit) has elapsed since start-up began.
    const Duration boot_time = std::chrono::milliseconds(value_of(obj::kBootTime, 0));
    if (error == BootError::A) {
      retry = false;
    } else if (!a.mandatory()) {
      retry = true;
    } else if (error == BootError::B) {
      retry = boot_time.count() == 0 || now - startup_began < boot_time;
    }
  }
  s.final_error = !retry;
  // Retries that end the same way are not reported again.
  if (s.reported_error != error || !retry) {
    s.reported_error = error;
    auto e = master_event(MasterEvent::Kind::BootError, now, node, "");
    e.error = error;
    e.final = !retry;
    e.step = BootStep::Failed;
    e.text = node_text(node) + ": boot error " + std::string(1, letter(error)) + ": " +
             std::string(describe(error)) + " (" + why + ")";
    if (!retry && a.mandatory() && error == BootError::B && value_of(obj::kBootTime, 0) != 0) {
      e.text +=
          "; boot time 1F89h (" + std::to_string(value_of(obj::kBootTime, 0)) + " ms) elapsed";
    }
    report(out, std::move(e));
  }
  if (retry) {
    s.running = true;
    s.phase = Phase::RetryWait;
    s.step = BootStep::RetryWait;
    s.deadline = now + options.retry_interval;
  } else {
    s.running = false;
    s.step = error == BootError::L ? BootStep::Booted : BootStep::Failed;
  }
}

void NmtMaster::Impl::boot_timer(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  s.deadline.reset();
  switch (s.phase) {
    case Phase::AwaitBootUp:
      // No boot-up within boot_up_wait: identify anyway (a boot-up may have been missed).
      boot_up_gate.reset();
      boot_up_quiet.reset();
      set_step(node, BootStep::Identify, now, out);
      boot_upload(node, Phase::ReadDeviceType, obj::kDeviceType, 0, now);
      return;
    case Phase::CheckStateHeartbeat:
      boot_failed(node, BootError::E, "no heartbeat within the consumer time (1016h)", now, out);
      return;
    case Phase::CheckStateGuarding:
      boot_failed(node, BootError::F, "no reply to the node guarding request", now, out);
      return;
    case Phase::AwaitResetBootUp:
      check_software(node, now, out);
      return;
    case Phase::AwaitRestoreBootUp:
      boot_failed(node, BootError::J, "no boot-up after the restore and reset", now, out);
      return;
    case Phase::RetryWait:
      start_boot(node, false, now, out);
      return;
    default:
      return;
  }
}

bool NmtMaster::Impl::boot_took_boot_up(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  if (!s.running) return false;
  // A boot-up while the first upload (1000h) is under way: the device just (re)started, which
  // the try has not relied on yet; it goes on (a lost request is repeated after its timeout).
  if (s.phase == Phase::ReadDeviceType) {
    s.expect_boot_up = false;
    return true;
  }
  // §3.3: waiting for the next try, and the slave is there now: try at once.
  if (s.phase == Phase::RetryWait) {
    start_boot(node, false, now, out);
    return true;
  }
  if (!s.expect_boot_up) return false;
  s.expect_boot_up = false;
  switch (s.phase) {
    case Phase::AwaitBootUp:
      if (boot_up_gate) {
        s.boot_up_seen = true;
        if (options.bitrate != 0) boot_up_quiet = now + kBootUpQuiet;
        open_boot_up_gate(now, out);  // when it was the last one
        break;
      }
      s.deadline.reset();
      set_step(node, BootStep::Identify, now, out);
      boot_upload(node, Phase::ReadDeviceType, obj::kDeviceType, 0, now);
      break;
    case Phase::AwaitResetBootUp:
      s.deadline.reset();
      s.phase = Phase::Idle;
      check_software(node, now, out);
      break;
    case Phase::AwaitRestoreBootUp:
      s.deadline.reset();
      s.phase = Phase::Idle;
      plan_download(node, now, out);
      break;
    default:
      // A late boot-up after the wait ran out: the try goes on (its SDO transfers repeat).
      break;
  }
  return true;
}

}  // namespace nmt

namespace nmt {

void NmtMaster::Impl::open_boot_up_gate(TimePoint now, Output& out, bool quiet) {
  for (unsigned node = cfg::kMinNodeId; node <= cfg::kMaxNodeId && !quiet; ++node) {
    const auto& s = slaves[node];
    if (s.running && s.phase == Phase::AwaitBootUp && !s.boot_up_seen) return;  // not yet
  }
  boot_up_gate.reset();
  boot_up_quiet.reset();
  for (unsigned node = cfg::kMinNodeId; node <= cfg::kMaxNodeId; ++node) {
    const auto n = static_cast<std::uint8_t>(node);
    auto& s = slaves[n];
    // One not booted up yet keeps its deadline (boot_up_wait) and starts at its boot-up.
    if (!s.running || s.phase != Phase::AwaitBootUp || !s.boot_up_seen) continue;
    s.deadline.reset();
    set_step(n, BootStep::Identify, now, out);
    boot_upload(n, Phase::ReadDeviceType, obj::kDeviceType, 0, now);
  }
}

}  // namespace nmt
