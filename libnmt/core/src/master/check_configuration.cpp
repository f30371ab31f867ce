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
#include "master/nmt_master_impl.hpp"

namespace nmt {

namespace obj = cfg::object;
using Phase = SlaveBoot::Phase;

namespace {

/// A device without parameter storage answers 1010h with "object/sub-index does not exist":
/// the configuration is applied, only not kept over a power cycle.
bool no_storage(SdoAbort code) {
  return code == SdoAbort::ObjectDoesNotExist || code == SdoAbort::SubIndexDoesNotExist;
}

}  // namespace

std::optional<std::vector<cfg::ObjectWrite>> NmtMaster::Impl::configuration_of(
    std::uint8_t node) const {
  const auto id = *cfg::NodeId::from(node);
  // The configuration manager first (MasterOptions::manager), then the source, then 1F22h.
  if (options.manager && options.manager->has_configuration(id)) {
    return options.manager->configuration(id);
  }
  if (options.configurations) return options.configurations->configuration(id);
  // §3.5 d: "The DCF may be read from ... object 1F22h on the configuration manager."
  const auto stream = own_concise_dcf(node);
  if (stream.empty()) return std::nullopt;
  auto decoded = cfg::decode_concise_dcf(stream);
  if (!decoded) return std::nullopt;
  return std::move(decoded.value());
}

void NmtMaster::Impl::check_configuration(std::uint8_t node, TimePoint now, Output& out) {
  set_step(node, BootStep::VerifyConfiguration, now, out);
  // §3.5 a-c: verify only when 1F26h/1F27h are not 0.
  if (!expected_configuration(node).is_zero() && !options.force_download &&
      !slaves[node].reconfigure) {
    boot_upload(node, Phase::ReadVerifyDate, obj::kVerifyConfiguration, 1, now);
    return;
  }
  begin_download(node, now, out);
}

void NmtMaster::Impl::begin_download(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  const auto expected = expected_configuration(node);
  auto configuration = configuration_of(node);
  const auto restore_sub = static_cast<std::uint8_t>(value_of(obj::kRestoreConfiguration, node));
  const bool restore = assignment(node).restore() && restore_sub != 0;
  if (!configuration && !restore) {
    if (!expected.is_zero()) {
      boot_failed(node, BootError::J,
                  "1F26h/1F27h expect a configuration, but none is stored for the node", now, out);
      return;
    }
    start_error_control(node, now, out);  // nothing to configure
    return;
  }
  // Storage commands are the master's to send; 1020h too when it verifies (it writes 1F26h/1F27h
  // at the end).
  if (!configuration) configuration.emplace();  // a restore alone: factory defaults
  std::erase_if(*configuration, [&](const cfg::ObjectWrite& w) {
    return w.index == obj::kStoreParameters || w.index == obj::kRestoreDefaultParameters ||
           (w.index == obj::kVerifyConfiguration && !expected.is_zero());
  });
  s.configuration = std::move(*configuration);
  // §3.5 d, Table 25, §6.12: restore first when 1F81h bit 7 asks and 1F8Ah names a sub-index.
  if (restore) {
    set_step(node, BootStep::Restore, now, out);
    boot_download(node, Phase::RestoreLoad, obj::kRestoreDefaultParameters, restore_sub,
                  u32_bytes(cfg::kLoadSignature), now);
    return;
  }
  plan_download(node, now, out);
}

void NmtMaster::Impl::plan_download(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  // The tail (1020h, 1010h) is written as steps of their own (write_next).
  auto order = cfg::plan_download(s.configuration, {},
                                  [&s](std::uint16_t comm_index) -> std::optional<std::uint32_t> {
                                    const auto it = s.cob_ids_read.find(comm_index);
                                    if (it == s.cob_ids_read.end()) return std::nullopt;
                                    return it->second;
                                  });
  // PDO COB-IDs the configuration does not carry: read them from the slave, so the PDO can be
  // made invalid around its mapping (download_order.hpp).
  if (!order.unknown_cob_id.empty() && !s.cob_ids_checked) {
    s.cob_ids_checked = true;
    s.cob_ids_to_read = std::move(order.unknown_cob_id);
    set_step(node, BootStep::Download, now, out);
    boot_upload(node, Phase::ReadPdoCobId, s.cob_ids_to_read.front(), 1, now);
    return;
  }
  s.plan = std::move(order.writes);
  s.next = 0;
  s.bytes = 0;
  set_step(node, BootStep::Download, now, out);
  write_next(node, now, out);
}

void NmtMaster::Impl::write_next(std::uint8_t node, TimePoint now, Output& out) {
  auto& s = slaves[node];
  if (s.next < s.plan.size()) {
    const auto& w = s.plan[s.next];
    boot_download(node, Phase::Write, w.index, w.sub_index, w.data, now);
    return;
  }
  s.configured = true;
  const auto expected = expected_configuration(node);
  set_step(node, BootStep::Save, now, out);
  if (!expected.is_zero()) {
    boot_download(node, Phase::WriteVerifyDate, obj::kVerifyConfiguration, 1,
                  u32_bytes(expected.days), now);
    return;
  }
  if (options.save_configuration) {
    boot_download(node, Phase::WriteSave, obj::kStoreParameters, 1, u32_bytes(cfg::kSaveSignature),
                  now);
    return;
  }
  s.phase = Phase::WriteSave;
  configuration_sdo_result(node, SdoResult{}, now, out);  // no save asked: as if saved
}

void NmtMaster::Impl::configuration_sdo_result(std::uint8_t node, const SdoResult& r, TimePoint now,
                                               Output& out) {
  auto& s = slaves[node];
  switch (s.phase) {
    case Phase::ReadVerifyDate:
      // §3.5 c (DSP 302 §4 step 5: a failed read also leads to the download).
      if (!r.ok()) {
        begin_download(node, now, out);
        return;
      }
      s.verify.days = uploaded_u32(r);
      if (s.verify.days != expected_configuration(node).days) {
        begin_download(node, now, out);  // sub 2 cannot make it match
        return;
      }
      boot_upload(node, Phase::ReadVerifyTime, obj::kVerifyConfiguration, 2, now);
      return;
    case Phase::ReadVerifyTime:
      if (!r.ok()) {
        begin_download(node, now, out);
        return;
      }
      s.verify.ms = uploaded_u32(r);
      if (s.verify == expected_configuration(node)) {
        s.configured = false;
        start_error_control(node, now, out);
      } else {
        begin_download(node, now, out);
      }
      return;
    case Phase::RestoreLoad: {
      if (!r.ok()) {
        boot_failed(node, BootError::J, "restore: " + transfer_failure(r), now, out);
        return;
      }
      // CiA 301 §7.5.2.14: restored values take effect at the next reset: reset communication
      // for the communication area (sub 2), else reset node.
      queue_nmt(r.sub_index == 2 ? NmtCommand::ResetCommunication : NmtCommand::ResetNode, node);
      s.expect_boot_up = true;
      s.phase = Phase::AwaitRestoreBootUp;
      s.deadline = now + options.reboot_timeout;
      return;
    }
    case Phase::ReadPdoCobId: {
      if (r.ok()) s.cob_ids_read[s.cob_ids_to_read.front()] = uploaded_u32(r);
      s.cob_ids_to_read.erase(s.cob_ids_to_read.begin());
      if (!s.cob_ids_to_read.empty()) {
        boot_upload(node, Phase::ReadPdoCobId, s.cob_ids_to_read.front(), 1, now);
      } else {
        plan_download(node, now, out);
      }
      return;
    }
    case Phase::Write: {
      if (!r.ok()) {
        boot_failed(node, BootError::J,
                    transfer_failure(r) + " (entry " + std::to_string(s.next + 1) + " of " +
                        std::to_string(s.plan.size()) + ")",
                    now, out);
        return;
      }
      s.bytes += s.plan[s.next].data.size();
      ++s.next;
      auto e = master_event(MasterEvent::Kind::BootStepChanged, now, node, "");
      e.step = BootStep::Download;
      e.written = s.next;
      e.total = s.plan.size();
      e.bytes = s.bytes;
      e.text = node_text(node) + ": " + std::to_string(s.next) + " of " +
               std::to_string(s.plan.size()) + " entries written";
      report(out, std::move(e));
      write_next(node, now, out);
      return;
    }
    case Phase::WriteVerifyDate:
      if (!r.ok()) {
        boot_failed(node, BootError::J, transfer_failure(r), now, out);
        return;
      }
      boot_download(node, Phase::WriteVerifyTime, obj::kVerifyConfiguration, 2,
                    u32_bytes(expected_configuration(node).ms), now);
      return;
    case Phase::WriteVerifyTime:
      if (!r.ok()) {
        boot_failed(node, BootError::J, transfer_failure(r), now, out);
        return;
      }
      if (options.save_configuration) {
        boot_download(node, Phase::WriteSave, obj::kStoreParameters, 1,
                      u32_bytes(cfg::kSaveSignature), now);
        return;
      }
      [[fallthrough]];
    case Phase::WriteSave:
      if (s.phase == Phase::WriteSave && !r.ok() && !no_storage(r.abort)) {
        boot_failed(node, BootError::J, "save: " + transfer_failure(r), now, out);
        return;
      }
      if (options.application_step) {
        s.phase = Phase::Application;
        set_step(node, BootStep::ApplicationStep, now, out);
        auto e = master_event(MasterEvent::Kind::ApplicationStep, now, node, "");
        e.step = BootStep::ApplicationStep;
        e.text = node_text(node) + ": the application's configuration step";
        report(out, std::move(e));
        return;
      }
      start_error_control(node, now, out);
      return;
    default:
      return;
  }
}

}  // namespace nmt
