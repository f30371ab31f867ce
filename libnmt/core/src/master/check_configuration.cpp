// Check configuration (CiA 302-2 §3.5; DSP 302 §4 step 5, §6): 1020h of the slave against
// 1F26h/1F27h, the restore of 1F81h bit 7 / 1F8Ah, the download in PDO-safe order
// (cfg::plan_download), then 1020h and 1010h 'save', so that the next start-up skips it.
#include <algorithm>
#include <string>

#include "cfg/bytes.hpp"
#include "cfg/download_order.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "master/boot_slave_process.hpp"
#include "master/master_support.hpp"
#include "nmt/protocol/emcy.hpp"

namespace nmt {

namespace obj = cfg::object;
using Phase = BootSlaveProcess::Phase;

namespace {

/// A device without parameter storage answers 1010h with "object/sub-index does not exist":
/// the configuration is applied, only not kept over a power cycle.
bool no_storage(SdoAbort code) {
  return code == SdoAbort::ObjectDoesNotExist || code == SdoAbort::SubIndexDoesNotExist;
}

}  // namespace

void BootSlaveProcess::check_configuration(TimePoint now, Output& out) {
  set_step(BootStep::VerifyConfiguration, now, out);
  // §3.5 a-c: verify only when 1F26h/1F27h are not 0.
  if (!port_->expectations(node_).configuration.is_zero() && !options_.force_download &&
      !reconfigure_) {
    upload(Phase::ReadVerifyDate, obj::kVerifyConfiguration, 1, now);
    return;
  }
  begin_download(now, out);
}

void BootSlaveProcess::begin_download(TimePoint now, Output& out) {
  const auto expect = port_->expectations(node_);
  const auto expected = expect.configuration;
  auto configuration = port_->configuration(node_);
  const auto restore_sub = expect.restore_sub;
  const bool restore = expect.assignment.restore() && restore_sub != 0;
  if (!configuration && !restore) {
    if (!expected.is_zero()) {
      failed(BootError::J, {.reason = BootFailure::Reason::NoConfigurationStored}, now, out);
      return;
    }
    no_configuration_ = true;  // nothing to configure: neither compared nor downloaded
    start_error_control(now, out);
    return;
  }
  // Storage commands are the master's to send; 1020h too when it verifies (it writes 1F26h/1F27h
  // at the end).
  if (!configuration) configuration.emplace();  // a restore alone: factory defaults
  std::erase_if(*configuration, [&](const cfg::ObjectWrite& w) {
    return w.index == obj::kStoreParameters || w.index == obj::kRestoreDefaultParameters ||
           (w.index == obj::kVerifyConfiguration && !expected.is_zero());
  });
  configuration_ = std::move(*configuration);
  // §3.5 d, Table 25, §6.12: restore first when 1F81h bit 7 asks and 1F8Ah names a sub-index.
  if (restore) {
    set_step(BootStep::Restore, now, out);
    download(Phase::RestoreLoad, obj::kRestoreDefaultParameters, restore_sub,
             cfg::le32_bytes(cfg::kLoadSignature), now);
    return;
  }
  plan_download(now, out);
}

void BootSlaveProcess::plan_download(TimePoint now, Output& out) {
  // The tail (1020h, 1010h) is written as steps of their own (write_next).
  // A PDO's COB-ID as read from the slave; its EMCY's (1014h) as the pre-defined connection set
  // gives it (CiA 301 §7.3.5), so that a configuration that keeps it writes no pair around it.
  auto order = cfg::plan_download(configuration_, {},
                                  [this](std::uint16_t comm_index) -> std::optional<std::uint32_t> {
                                    if (comm_index == obj::kCobIdEmcy) {
                                      return default_emcy_cob_id(node_).word();
                                    }
                                    const auto it = cob_ids_read_.find(comm_index);
                                    if (it == cob_ids_read_.end()) return std::nullopt;
                                    return it->second;
                                  });
  // PDO COB-IDs the configuration does not carry: read them from the slave, so the PDO can be
  // made invalid around its mapping (download_order.hpp).
  if (!order.unknown_cob_id.empty() && !cob_ids_checked_) {
    cob_ids_checked_ = true;
    cob_ids_to_read_ = std::move(order.unknown_cob_id);
    set_step(BootStep::Download, now, out);
    upload(Phase::ReadPdoCobId, cob_ids_to_read_.front(), 1, now);
    return;
  }
  plan_ = std::move(order.writes);
  next_ = 0;
  bytes_ = 0;
  set_step(BootStep::Download, now, out);
  write_next(now, out);
}

void BootSlaveProcess::write_next(TimePoint now, Output& out) {
  if (next_ < plan_.size()) {
    const auto& w = plan_[next_];
    download(Phase::Write, w.index, w.sub_index, w.data, now);
    return;
  }
  configured_ = true;
  const auto expected = port_->expectations(node_).configuration;
  set_step(BootStep::Save, now, out);
  if (!expected.is_zero()) {
    download(Phase::WriteVerifyDate, obj::kVerifyConfiguration, 1, cfg::le32_bytes(expected.days),
             now);
    return;
  }
  // Nothing written (a node the description knows by its identity only, cfgmgr scan's device
  // without EDS): nothing to save, and a save would store whatever the device holds in RAM.
  if (options_.save_configuration && !plan_.empty()) {
    download(Phase::WriteSave, obj::kStoreParameters, 1, cfg::le32_bytes(cfg::kSaveSignature), now);
    return;
  }
  phase_ = Phase::WriteSave;
  configuration_sdo_result(SdoResult{}, now, out);  // no save asked: as if saved
}

void BootSlaveProcess::configuration_sdo_result(const SdoResult& r, TimePoint now, Output& out) {
  switch (phase_) {
    case Phase::ReadVerifyDate:
      // §3.5 c (DSP 302 §4 step 5: a failed read also leads to the download).
      if (!r.ok()) {
        begin_download(now, out);
        return;
      }
      verify_.days = uploaded_u32(r);
      if (verify_.days != port_->expectations(node_).configuration.days) {
        begin_download(now, out);  // sub 2 cannot make it match
        return;
      }
      upload(Phase::ReadVerifyTime, obj::kVerifyConfiguration, 2, now);
      return;
    case Phase::ReadVerifyTime:
      if (!r.ok()) {
        begin_download(now, out);
        return;
      }
      verify_.ms = uploaded_u32(r);
      if (verify_ == port_->expectations(node_).configuration) {
        configured_ = false;
        start_error_control(now, out);
      } else {
        begin_download(now, out);
      }
      return;
    case Phase::RestoreLoad: {
      if (!r.ok()) {
        failed(BootError::J, transfer_failed(r, BootFailure::Reason::RestoreFailed), now, out);
        return;
      }
      // CiA 301 §7.5.2.14: restored values take effect at the next reset: reset communication
      // for the communication area (sub 2), else reset node.
      port_->queue_nmt(
          r.address.sub_index == 2 ? NmtCommand::ResetCommunication : NmtCommand::ResetNode, node_);
      expect_boot_up_ = true;
      phase_ = Phase::AwaitRestoreBootUp;
      set_deadline(now + options_.reboot_timeout);
      return;
    }
    case Phase::ReadPdoCobId: {
      if (r.ok()) cob_ids_read_[cob_ids_to_read_.front()] = uploaded_u32(r);
      cob_ids_to_read_.erase(cob_ids_to_read_.begin());
      if (!cob_ids_to_read_.empty()) {
        upload(Phase::ReadPdoCobId, cob_ids_to_read_.front(), 1, now);
      } else {
        plan_download(now, out);
      }
      return;
    }
    case Phase::Write: {
      if (!r.ok()) {
        auto failure = transfer_failed(r, BootFailure::Reason::WriteFailed);
        failure.entry = next_ + 1;
        failure.entries = plan_.size();
        failed(BootError::J, std::move(failure), now, out);
        return;
      }
      bytes_ += plan_[next_].data.size();
      ++next_;
      auto e = master_event(MasterEvent::Kind::BootStepChanged, now, node_);
      e.step = BootStep::Download;
      e.boot_try = tries_;
      e.entry_written = true;
      e.written = next_;
      e.total = plan_.size();
      e.bytes = bytes_;
      out.report(std::move(e));
      write_next(now, out);
      return;
    }
    case Phase::WriteVerifyDate:
      if (!r.ok()) {
        failed(BootError::J, transfer_failed(r), now, out);
        return;
      }
      download(Phase::WriteVerifyTime, obj::kVerifyConfiguration, 2,
               cfg::le32_bytes(port_->expectations(node_).configuration.ms), now);
      return;
    case Phase::WriteVerifyTime:
      if (!r.ok()) {
        failed(BootError::J, transfer_failed(r), now, out);
        return;
      }
      if (options_.save_configuration) {
        download(Phase::WriteSave, obj::kStoreParameters, 1, cfg::le32_bytes(cfg::kSaveSignature),
                 now);
        return;
      }
      [[fallthrough]];
    case Phase::WriteSave:
      if (phase_ == Phase::WriteSave && !r.ok() && !no_storage(r.abort)) {
        failed(BootError::J, transfer_failed(r, BootFailure::Reason::SaveFailed), now, out);
        return;
      }
      if (options_.application_step) {
        phase_ = Phase::Application;
        set_step(BootStep::ApplicationStep, now, out);
        auto e = master_event(MasterEvent::Kind::ApplicationStep, now, node_);
        e.step = BootStep::ApplicationStep;
        e.boot_try = tries_;
        out.report(std::move(e));
        return;
      }
      start_error_control(now, out);
      return;
    default:
      return;
  }
}

}  // namespace nmt
