// The software version check and update of boot NMT slave (CiA 302-2 §3.4 part 2 with
// Table 1's status G, H and I; DSP 302 §9; CiA 302-3 program download), with either set of
// objects per node:
// - DSP 302 v3.2.1 §9: 1F52h against 1F53h/1F54h; when they differ and 1F81h bit 6 allows it,
//   stop, clear, 1F50h image, start, and 1F52h read again.
// - CiA 302-3 as lely-core's master does it (src/co/nmt_boot.c, co_nmt_boot_chk_sw_* and
//   co_nmt_boot_wait_flash_*): 1F56h sub 1 against the master's 1F55h sub node-ID; the update
//   is the same stop, clear and 1F50h image, then the flash status 1F57h sub 1 is read (bit 0
//   "in progress" is read again every 100 ms; bits 1-7 non-zero are an error), then start and
//   1F56h read again. Chosen per node: a non-zero 1F55h sub node-ID selects CiA 302-3.
// Part of BootSlaveProcess (boot_slave_process.hpp, boot_slave.cpp).
#include <chrono>
#include <string>
#include <utility>
#include <vector>

#include "cfg/hex.hpp"
#include "cfg/object_index.hpp"
#include "master/boot_slave_process.hpp"
#include "master/master_support.hpp"

namespace nmt {

namespace obj = cfg::object;
using Phase = BootSlaveProcess::Phase;

namespace {

/// How long before 1F57h is read again while it says "in progress" (lely-core's
/// LELY_CO_NMT_BOOT_CHECK_TIMEOUT, 100 ms).
constexpr Duration kFlashStatusPoll = std::chrono::milliseconds(100);

bool uses_identification(const BootSlaveExpectations& expect) {
  return expect.software_identification != 0;
}

}  // namespace

void BootSlaveProcess::check_software(TimePoint now, Output& out) {
  const auto expect = port_->expectations(node_);
  if (!expect.assignment.verify_software()) {
    check_configuration(now, out);
    return;
  }
  if (expect.software == cfg::ProgramVersion{} && !uses_identification(expect)) {
    failed(BootError::G, {.reason = BootFailure::Reason::NoExpectedSoftware}, now, out);
    return;
  }
  set_step(BootStep::CheckSoftware, now, out);
  read_software(now);
}

void BootSlaveProcess::read_software(TimePoint now) {
  if (uses_identification(port_->expectations(node_))) {
    upload(Phase::ReadSoftwareId, obj::kProgramSoftwareIdentification, 1, now);
  } else {
    upload(Phase::ReadSoftwareDate, obj::kVerifyApplicationSoftware, 1, now);
  }
}

void BootSlaveProcess::software_checked(TimePoint now, Output& out) {
  const auto expect = port_->expectations(node_);
  const bool by_id = uses_identification(expect);
  if (by_id ? software_id_ == expect.software_identification : software_ == expect.software) {
    check_configuration(now, out);
    return;
  }
  const auto differs = [&](BootFailure::Reason reason) {
    if (by_id) {
      return BootFailure{.reason = reason,
                         .object = {obj::kProgramSoftwareIdentification, 1},
                         .actual = software_id_,
                         .expected_by = obj::kExpectedSoftwareIdentification,
                         .expected = expect.software_identification};
    }
    return BootFailure{
        .reason = reason, .software = software_, .expected_software = expect.software};
  };
  if (software_updated_) {
    failed(BootError::I, differs(BootFailure::Reason::SoftwareDiffersAfterUpdate), now, out);
    return;
  }
  if (!expect.assignment.update_software()) {
    failed(BootError::H, differs(BootFailure::Reason::UpdateNotAllowed), now, out);
    return;
  }
  if (!port_->program(node_).has_value()) {
    failed(BootError::H, differs(BootFailure::Reason::NoProgramImage), now, out);
    return;
  }
  set_step(BootStep::UpdateSoftware, now, out);
  update_ = MasterEvent::ProgramUpdate{
      .before = software_,
      .after = std::nullopt,
      .identification_before = by_id ? std::optional(software_id_) : std::nullopt,
      .identification_after = std::nullopt,
      .bytes = 0,
      .began = now,
      .ended = std::nullopt,
      .clear_refused = std::nullopt};
  program_step(Phase::ProgramStop, now);
}

void BootSlaveProcess::program_step(Phase phase, TimePoint now) {
  // DSP 302 §9 1F51h sub 1: 0 stop, 1 start; CiA 302-3: 3 clear. Each with its own wait
  // (MasterOptions::program_*_timeout); the image is repeated once after a timeout.
  phase_ = phase;
  const auto control = [&](std::uint8_t value, Duration timeout) {
    port_->transfer(try_id_,
                    {.node = node_,
                     .object = {obj::kProgramControl, 1},
                     .data = {value},
                     .timeout = timeout,
                     .retries = options_.sdo_retries},
                    now);
  };
  switch (phase) {
    case Phase::ProgramStop:
      control(0, options_.program_control_timeout);
      return;
    case Phase::ProgramClear:
      control(3, options_.program_clear_timeout);
      return;
    case Phase::ProgramStart:
      control(1, options_.program_control_timeout);
      return;
    default: {
      auto image = port_->program(node_);
      update_->bytes = image ? image->size() : 0;
      port_->transfer(try_id_,
                      {.node = node_,
                       .object = {obj::kProgramData, 1},
                       .data = image ? std::move(*image) : std::vector<std::uint8_t>{},
                       .timeout = options_.program_data_timeout,
                       .retries = 1},
                      now);
      return;
    }
  }
}

void BootSlaveProcess::software_sdo_result(const SdoResult& r, TimePoint now, Output& out) {
  switch (phase_) {
    case Phase::ReadSoftwareId: {
      if (!r.ok()) {
        failed(software_updated_ ? BootError::I : BootError::G, transfer_failed(r), now, out);
        return;
      }
      software_id_ = uploaded_u32(r);
      if (software_updated_) update_->identification_after = software_id_;
      software_checked(now, out);
      return;
    }
    case Phase::ReadFlashStatus:
      flash_status_read(r, now, out);
      return;
    case Phase::ReadSoftwareDate:
    case Phase::ReadSoftwareTime: {
      if (!r.ok()) {
        // The slave's program objects do not answer as CiA 302-3 has them.
        failed(software_updated_ ? BootError::I : BootError::G, transfer_failed(r), now, out);
        return;
      }
      if (phase_ == Phase::ReadSoftwareDate) {
        software_.date_days = uploaded_u32(r);
        upload(Phase::ReadSoftwareTime, obj::kVerifyApplicationSoftware, 2, now);
      } else {
        software_.time_ms = uploaded_u32(r);
        if (software_updated_) update_->after = software_;
        software_checked(now, out);
      }
      return;
    }
    case Phase::ProgramStop:
    case Phase::ProgramClear:
    case Phase::ProgramData:
    case Phase::ProgramStart: {
      // A device built to DSP 302 v3.2.1 §9 (1F51h range 0..2) refuses CiA 302-3's clear:
      // no failure, the download goes on (docs/master.md, "Software update").
      const bool clear_refused =
          phase_ == Phase::ProgramClear && r.aborted_by_server &&
          (r.abort == SdoAbort::ValueRangeExceeded || r.abort == SdoAbort::ValueTooHigh ||
           r.abort == SdoAbort::ValueTooLow || r.abort == SdoAbort::NoDataAvailable ||
           r.abort == SdoAbort::General || r.abort == SdoAbort::CannotStoreOrTransfer);
      if (!r.ok() && !clear_refused) {
        failed(BootError::I, transfer_failed(r, BootFailure::Reason::ProgramDownloadFailed), now,
               out);
        return;
      }
      if (clear_refused) {
        // Reported, else only the bus would show it: the memory was not cleared before the
        // image (the device's own affair by DSP 302 §9; 1F50h says when it cannot take it).
        update_->clear_refused = r.abort;
        auto e = master_event(MasterEvent::Kind::ProgramClearRefused, now, node_);
        e.step = BootStep::UpdateSoftware;
        e.boot_try = tries_;
        e.sdo = r;
        out.report(std::move(e));
      }
      // CiA 302-3 program download: stop (0), clear (3), 1F50h data, start (1).
      if (phase_ == Phase::ProgramStop) {
        program_step(Phase::ProgramClear, now);
      } else if (phase_ == Phase::ProgramClear) {
        program_step(Phase::ProgramData, now);
      } else if (phase_ == Phase::ProgramData) {
        if (uses_identification(port_->expectations(node_))) {
          image_sent_ = now;
          upload(Phase::ReadFlashStatus, obj::kFlashStatusIdentification, 1, now);
        } else {
          program_step(Phase::ProgramStart, now);
        }
      } else {
        update_->ended = now;
        software_updated_ = true;
        set_step(BootStep::CheckSoftware, now, out);
        read_software(now);
      }
      return;
    }
    default:
      return;
  }
}

void BootSlaveProcess::flash_status_read(const SdoResult& r, TimePoint now, Output& out) {
  if (!r.ok()) {
    // CiA 302-3 makes 1F57h optional: a device without it has nothing to report, and its
    // 1F56h after the start says whether the image took.
    const bool absent = r.aborted_by_server && (r.abort == SdoAbort::ObjectDoesNotExist ||
                                                r.abort == SdoAbort::SubIndexDoesNotExist);
    if (absent) {
      program_step(Phase::ProgramStart, now);
    } else {
      failed(BootError::I, transfer_failed(r, BootFailure::Reason::ProgramDownloadFailed), now,
             out);
    }
    return;
  }
  const auto value = uploaded_u32(r);
  const BootFailure seen{.object = {obj::kFlashStatusIdentification, 1}, .actual = value};
  if ((value & 1U) != 0) {
    // Bit 0: the device is still writing the image.
    if (now - image_sent_ >= options_.program_data_timeout) {
      auto f = seen;
      f.reason = BootFailure::Reason::FlashNeverReady;
      failed(BootError::I, f, now, out);
      return;
    }
    phase_ = Phase::FlashStatusWait;
    set_deadline(now + kFlashStatusPoll);
    return;
  }
  if (((value >> 1) & 0x7FU) != 0) {
    auto f = seen;
    f.reason = BootFailure::Reason::FlashStatusError;
    failed(BootError::I, f, now, out);
    return;
  }
  program_step(Phase::ProgramStart, now);
}

}  // namespace nmt
