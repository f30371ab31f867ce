// The CiA 305 procedures (nmt/lss/lss_procedure.hpp): chains of LssMaster services, each next one
// started in the call its predecessor ended in.
#include "nmt/lss/lss_procedure.hpp"

#include <utility>

namespace nmt {

using Kind = LssProcedureEvent::Kind;
using ServiceKind = LssMasterEvent::Kind;
using lss::Cs;

std::string_view to_string(LssProcedureKind procedure) {
  switch (procedure) {
    case LssProcedureKind::Scan:
      return "scan";
    case LssProcedureKind::FindUnconfigured:
      return "find unconfigured devices";
    case LssProcedureKind::AnyUnconfigured:
      return "look for unconfigured devices";
    case LssProcedureKind::FindProduct:
      return "find the devices of a product";
    case LssProcedureKind::AssignNodeId:
      return "assign node-ID";
    case LssProcedureKind::InquireNodeId:
      return "inquire node-ID";
    case LssProcedureKind::InquireIdentity:
      return "inquire identity";
    case LssProcedureKind::SetBitRate:
      return "set bit rate";
  }
  return "LSS procedure";
}

namespace {

constexpr LssService kInquiries[] = {LssService::InquireVendorId, LssService::InquireProductCode,
                                     LssService::InquireRevision, LssService::InquireSerial,
                                     LssService::InquireNodeId};

}  // namespace

LssProcedureEvent LssProcedure::event(Kind kind, TimePoint now) const {
  LssProcedureEvent e;
  e.procedure = run_->kind;
  e.kind = kind;
  e.at = now;
  return e;
}

cfg::Status LssProcedure::begin(LssProcedureKind kind) {
  // engine.hpp rule 5: could not start is the answer, not an event; nothing goes out.
  if (run_) {
    return cfg::Error{"LSS " + std::string(to_string(kind)) + " not started: " +
                      std::string(to_string(run_->kind)) + " runs (one LSS procedure at a time)"};
  }
  run_ = Running{};
  run_->kind = kind;
  lss_out_.clear();
  return {};
}

// --- procedures --------------------------------------------------------------------------------

cfg::Status LssProcedure::scan(NodeIdChooser chooser, TimePoint now, Output& out,
                               std::vector<LssAddress> targets) {
  if (auto started = begin(LssProcedureKind::Scan); !started) return started;
  run_->chooser = std::move(chooser);
  run_->targets = std::move(targets);
  // No device someone left in configuration may take the node-IDs the scan hands out.
  switch_all(LssState::Waiting, now);
  if (run_->targets.empty()) {
    search_next(now);
  } else {
    // Selection is answered by configured devices too: first whether anyone needs LSS at all.
    check_unconfigured(now);
  }
  forward(now, out);
  return {};
}

cfg::Status LssProcedure::find_unconfigured(TimePoint now, Output& out) {
  if (auto started = begin(LssProcedureKind::FindUnconfigured); !started) return started;
  switch_all(LssState::Waiting, now);
  search_next(now);
  forward(now, out);
  return {};
}

cfg::Status LssProcedure::any_unconfigured(TimePoint now, Output& out) {
  if (auto started = begin(LssProcedureKind::AnyUnconfigured); !started) return started;
  run_->step = Step::Probe;
  (void)lss_.identify_non_configured(now, lss_out_);  // idle: it starts
  forward(now, out);
  return {};
}

cfg::Status LssProcedure::find_product(std::uint32_t vendor_id, std::uint32_t product_code,
                                       TimePoint now, Output& out) {
  if (auto started = begin(LssProcedureKind::FindProduct); !started) return started;
  run_->search.emplace(vendor_id, product_code);
  identify_next(now, out);
  forward(now, out);
  return {};
}

cfg::Status LssProcedure::assign_node_id(const LssAddress& address,
                                         std::optional<cfg::NodeId> node_id, bool store,
                                         TimePoint now, Output& out) {
  if (auto started = begin(LssProcedureKind::AssignNodeId); !started) return started;
  run_->address = address;
  run_->node_id = node_id;
  run_->store = store;
  select(address, now);
  forward(now, out);
  return {};
}

cfg::Status LssProcedure::inquire_node_id(const LssAddress& address, TimePoint now, Output& out) {
  if (auto started = begin(LssProcedureKind::InquireNodeId); !started) return started;
  run_->address = address;
  run_->inquiry = 4;  // node-ID only
  select(address, now);
  forward(now, out);
  return {};
}

cfg::Status LssProcedure::inquire_identity(std::optional<LssAddress> address, TimePoint now,
                                           Output& out) {
  if (auto started = begin(LssProcedureKind::InquireIdentity); !started) return started;
  run_->selected = address;
  if (address) {
    select(*address, now);
  } else {
    switch_all(LssState::Configuration, now);
    inquire_next(now);
  }
  forward(now, out);
  return {};
}

cfg::Status LssProcedure::set_bit_rate(std::uint8_t table_index, bool store,
                                       std::uint16_t switch_delay_ms, TimePoint now, Output& out) {
  if (auto started = begin(LssProcedureKind::SetBitRate); !started) return started;
  run_->table_index = table_index;
  run_->store = store;
  run_->switch_delay_ms = switch_delay_ms;
  switch_all(LssState::Configuration, now);
  run_->step = Step::ConfigureTiming;
  // Every device answers configure bit timing and store; the first answer is taken.
  (void)lss_.configure_bit_timing(table_index, now, lss_out_);
  forward(now, out);
  return {};
}

// --- engine ------------------------------------------------------------------------------------

bool LssProcedure::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (!run_) return false;
  const auto deadline = lss_.next_deadline();
  if (run_->step == Step::Store && deadline && now <= *deadline &&
      lss::is_lss_frame(frame, lss::kSlaveCobId) &&
      frame.data[0] == static_cast<std::uint8_t>(Cs::ConfigureNodeId)) {
    // A second answer to the scan's configure node-ID: more than one device has this LSS
    // address (see the top of lss_procedure.hpp); undone when the store has ended.
    run_->duplicate = true;
    return true;
  }
  lss_out_.clear();
  const bool taken = lss_.on_frame(frame, now, lss_out_);
  forward(now, out);
  return taken;
}

void LssProcedure::on_timer(TimePoint now, Output& out) {
  if (!run_) return;
  lss_out_.clear();
  lss_.on_timer(now, lss_out_);
  forward(now, out);
}

void LssProcedure::forward(TimePoint now, Output& out) {
  // handle() starts the next service into lss_out_: its frames follow, in the order sent.
  while (!lss_out_.frames.empty() || !lss_out_.events.empty()) {
    for (const auto& f : lss_out_.frames) out.send(f);
    lss_out_.frames.clear();
    auto events = std::move(lss_out_.events);
    lss_out_.events.clear();
    for (const auto& e : events) {
      if (run_) handle(e, now, out);
    }
  }
}

// --- steps -------------------------------------------------------------------------------------

void LssProcedure::switch_all(LssState state, TimePoint now) {
  // No answer: it ends at once; its event is passed over in handle().
  (void)lss_.switch_state_global(state, now, lss_out_);
}

void LssProcedure::select(const LssAddress& address, TimePoint now) {
  // Selective switching is obeyed in waiting only: everything there first.
  switch_all(LssState::Waiting, now);
  run_->step = Step::Select;
  (void)lss_.switch_state_selective(address, now, lss_out_);
}

void LssProcedure::inquire_next(TimePoint now) {
  run_->step = Step::Inquire;
  (void)lss_.inquire(kInquiries[run_->inquiry], now, lss_out_);
}

void LssProcedure::identify_next(TimePoint now, Output& out) {
  if (const auto range = run_->search->next()) {
    run_->step = Step::Identify;
    (void)lss_.identify_remote_slaves(*range, now, lss_out_);
    return;
  }
  auto e = event(Kind::Done, now);
  e.addresses = run_->search->found();
  done(std::move(e), out);
}

void LssProcedure::done(Event e, Output& out) {
  run_.reset();
  out.report(std::move(e));
}

void LssProcedure::failed(const LssMasterEvent& step, bool to_waiting, TimePoint now, Output& out) {
  // Devices this procedure put in LSS configuration go back to waiting first.
  if (to_waiting) switch_all(LssState::Waiting, now);
  auto e = event(Kind::Failed, now);
  e.address = run_->address;
  e.step = step;
  e.found = run_->found;
  done(std::move(e), out);
}

void LssProcedure::handle(const LssMasterEvent& e, TimePoint now, Output& out) {
  if (e.service == LssService::SwitchStateGlobal) return;  // ended at once; the step goes on
  Running& r = *run_;
  switch (r.step) {
    case Step::Search:
    case Step::Check:
    case Step::SelectTarget:
    case Step::InquireTarget:
    case Step::Configure:
    case Step::Store:
    case Step::Unconfigure:
    case Step::Unstore:
      scan_event(e, now, out);
      return;
    case Step::Probe: {
      auto d = event(Kind::Done, now);
      d.found = e.ok() ? 1 : 0;
      done(std::move(d), out);
      return;
    }
    case Step::Identify:
      // Identify remote slave ends Done (a device answered) or NotFound (none did).
      r.search->answered(e.ok());
      identify_next(now, out);
      return;
    case Step::Select:
      if (!e.ok()) {
        failed(e, /*to_waiting=*/false, now, out);
        return;
      }
      if (r.kind == LssProcedureKind::AssignNodeId) {
        // The node-ID it runs with now: one that had a node-ID takes the new one only at its
        // next NMT reset; an unconfigured one boots as soon as it is back in waiting.
        r.step = Step::InquireBefore;
        (void)lss_.inquire(LssService::InquireNodeId, now, lss_out_);
        return;
      }
      inquire_next(now);
      return;
    case Step::InquireBefore:
      if (e.ok()) r.previous_node_id = static_cast<std::uint8_t>(e.value);
      r.step = Step::ConfigureId;
      (void)lss_.configure_node_id(r.node_id, now, lss_out_);
      return;
    case Step::ConfigureId:
    case Step::StoreId:
      if (!e.ok()) {
        failed(e, /*to_waiting=*/true, now, out);
        return;
      }
      if (r.step == Step::ConfigureId && r.store) {
        r.step = Step::StoreId;
        (void)lss_.store_configuration(now, lss_out_);
        return;
      }
      switch_all(LssState::Waiting, now);
      {
        auto d = event(Kind::Done, now);
        d.address = r.address;
        d.node_id = r.node_id;
        d.outcome = r.store ? LssScanOutcome::Stored : LssScanOutcome::NotStoredAsAsked;
        d.previous_node_id = r.previous_node_id;
        done(std::move(d), out);
      }
      return;
    case Step::Inquire:
      after_inquiry(e, now, out);
      return;
    case Step::ConfigureTiming:
    case Step::StoreTiming:
      if (!e.ok()) {
        failed(e, /*to_waiting=*/true, now, out);
        return;
      }
      if (r.step == Step::ConfigureTiming && r.store) {
        r.step = Step::StoreTiming;
        (void)lss_.store_configuration(now, lss_out_);
        return;
      }
      r.step = Step::Activate;
      (void)lss_.activate_bit_timing(r.switch_delay_ms, now, lss_out_);
      return;
    case Step::Activate:
      if (!e.ok()) {
        failed(e, /*to_waiting=*/false, now, out);
        return;
      }
      done(event(Kind::Done, now), out);
      return;
  }
}

void LssProcedure::after_inquiry(const LssMasterEvent& e, TimePoint now, Output& out) {
  Running& r = *run_;
  if (!e.ok()) {
    failed(e, /*to_waiting=*/true, now, out);
    return;
  }
  if (kInquiries[r.inquiry] != LssService::InquireNodeId) {
    r.address.part(r.inquiry) = e.value;
    ++r.inquiry;
    inquire_next(now);
    return;
  }
  // InquireIdentity switches back before it looks at the node-ID; InquireNodeId after.
  if (r.kind == LssProcedureKind::InquireIdentity) switch_all(LssState::Waiting, now);
  if (e.value != lss::kUnconfigured && !cfg::NodeId::from(e.value)) {
    // A Failed whose step is Done: the answer is one CiA 305 does not allow.
    failed(e, /*to_waiting=*/true, now, out);
    return;
  }
  if (r.kind == LssProcedureKind::InquireNodeId) switch_all(LssState::Waiting, now);
  auto d = event(Kind::Done, now);
  d.address = r.address;
  if (e.value != lss::kUnconfigured) d.node_id = cfg::NodeId::from(e.value);
  done(std::move(d), out);
}

// --- Scan, FindUnconfigured --------------------------------------------------------------------

void LssProcedure::search_next(TimePoint now) {
  Running& r = *run_;
  r.step = Step::Search;
  r.confirming = r.next_target < r.targets.size();
  if (!r.confirming) {
    (void)lss_.fastscan(r.cursor, now, lss_out_);
    return;
  }
  r.address = r.targets[r.next_target++];
  // A selection costs an absent target one timeout, a Fastscan confirmation none: select while
  // the targets mostly answer (see the top).
  if (2 * r.absent <= r.present + 2) {
    r.step = Step::SelectTarget;
    (void)lss_.switch_state_selective(r.address, now, lss_out_);
  } else {
    r.check_due = false;  // its reset answers the question
    (void)lss_.fastscan_confirm(r.address, now, lss_out_);
  }
}

void LssProcedure::check_unconfigured(TimePoint now) {
  run_->step = Step::Check;
  run_->check_due = false;
  (void)lss_.identify_non_configured(now, lss_out_);
}

void LssProcedure::scan_done(TimePoint now, Output& out) {
  Running& r = *run_;
  auto d = event(Kind::Done, now);
  d.found = r.found;
  d.addresses = std::move(r.addresses);
  done(std::move(d), out);
}

void LssProcedure::target_event(const LssMasterEvent& e, TimePoint now, Output& out) {
  Running& r = *run_;
  switch (r.step) {
    case Step::Check:
      // Identify non-configured remote slave: Done when a device without node-ID answered.
      if (e.ok()) {
        search_next(now);
      } else {
        scan_done(now, out);
      }
      return;
    case Step::SelectTarget:
      if (e.ok()) {
        // Only the device with all four parts answered 44h; it is in LSS configuration.
        r.step = Step::InquireTarget;
        (void)lss_.inquire(LssService::InquireNodeId, now, lss_out_);
        return;
      }
      // No answer within the timeout: absent, or it missed a frame. Every device back to
      // waiting (a late answer left it in configuration, where Fastscan is not answered), then
      // the Fastscan confirmation, whose reset also tells whether anyone unconfigured is left.
      switch_all(LssState::Waiting, now);
      r.step = Step::Search;
      r.check_due = false;
      (void)lss_.fastscan_confirm(r.address, now, lss_out_);
      return;
    case Step::InquireTarget:
      if (e.ok() && e.value != lss::kUnconfigured) {
        // Configured already: left as it is, like a configured device Fastscan never finds.
        // Whether anyone unconfigured is left is asked again only when a device got its
        // node-ID since it was last asked (else the answer is still yes).
        ++r.present;
        switch_all(LssState::Waiting, now);
        if (r.check_due) {
          check_unconfigured(now);
        } else {
          search_next(now);
        }
        return;
      }
      // FFh, or no answer (inquire node-ID unsupported): it is a target in configuration.
      device_found(r.address, now, out);
      return;
    default:
      return;
  }
}

void LssProcedure::scan_event(const LssMasterEvent& e, TimePoint now, Output& out) {
  Running& r = *run_;
  switch (r.step) {
    case Step::Search:
      search_event(e, now, out);
      return;
    case Step::Check:
    case Step::SelectTarget:
    case Step::InquireTarget:
      target_event(e, now, out);
      return;
    case Step::Configure:
      if (e.kind == ServiceKind::Timeout) {
        device_done(Kind::Skipped, LssScanOutcome::ConfigureUnanswered, e, now, out);
      } else if (e.kind == ServiceKind::Refused) {
        device_done(Kind::Skipped, LssScanOutcome::ConfigureRefused, e, now, out);
      } else if (lss_.options().store) {
        r.step = Step::Store;
        (void)lss_.store_configuration(now, lss_out_);
      } else {
        device_done(Kind::Assigned, LssScanOutcome::NotStoredAsAsked, std::nullopt, now, out);
      }
      return;
    case Step::Store:
      if (r.duplicate) {
        // Every device with the address is in LSS configuration and took the node-ID: FFh (not
        // configured) to all of them, stored, then back to waiting without a node-ID.
        r.step = Step::Unconfigure;
        (void)lss_.configure_node_id(std::nullopt, now, lss_out_);
      } else if (e.kind == ServiceKind::Timeout) {
        device_done(Kind::Assigned, LssScanOutcome::StoreUnanswered, e, now, out);
      } else if (e.kind == ServiceKind::Refused) {
        device_done(Kind::Assigned, LssScanOutcome::StoreRefused, e, now, out);
      } else {
        device_done(Kind::Assigned, LssScanOutcome::Stored, std::nullopt, now, out);
      }
      return;
    case Step::Unconfigure:
    case Step::Unstore:
      if (e.kind == ServiceKind::Timeout) {
        device_done(Kind::Skipped, LssScanOutcome::DuplicateUndoUnanswered, e, now, out);
      } else if (r.step == Step::Unconfigure) {
        r.step = Step::Unstore;
        (void)lss_.store_configuration(now, lss_out_);
      } else {
        device_done(Kind::Skipped, LssScanOutcome::Duplicate, std::nullopt, now, out);
      }
      return;
    default:
      return;
  }
}

void LssProcedure::search_event(const LssMasterEvent& e, TimePoint now, Output& out) {
  Running& r = *run_;
  switch (e.kind) {
    case ServiceKind::Done:
      device_found(e.address, now, out);
      return;
    case ServiceKind::Absent:
      // The target's device is absent or configured: the next target, or bit by bit.
      ++r.absent;
      search_next(now);
      return;
    case ServiceKind::NotFound:
      scan_done(now, out);
      return;
    default:
      // A device stopped answering midway. FindUnconfigured switches every device back to
      // waiting (as its other services end), Scan ends as Fastscan left it.
      failed(e, /*to_waiting=*/r.kind == LssProcedureKind::FindUnconfigured, now, out);
      return;
  }
}

void LssProcedure::device_found(const LssAddress& address, TimePoint now, Output& out) {
  Running& r = *run_;
  r.address = address;
  if (!r.confirming && r.failed.contains(address)) {
    // A target whose configure node-ID failed, reported then: passed by without a second event.
    r.cursor = address;
    switch_all(LssState::Waiting, now);
    search_next(now);
    return;
  }
  ++r.found;
  if (r.confirming) ++r.present;
  if (r.kind == LssProcedureKind::FindUnconfigured) {
    r.addresses.push_back(address);
    // Back to waiting, still without node-ID; the next Fastscan looks above it.
    r.cursor = address;
    switch_all(LssState::Waiting, now);
    search_next(now);
    return;
  }
  std::optional<cfg::NodeId> node_id;
  if (r.chooser) node_id = r.chooser(address);
  if (!node_id) {
    device_done(Kind::Skipped, LssScanOutcome::NoNodeId, std::nullopt, now, out);
    return;
  }
  r.node_id = node_id;
  r.duplicate = false;
  r.step = Step::Configure;
  (void)lss_.configure_node_id(node_id, now, lss_out_);
}

void LssProcedure::device_done(Kind kind, LssScanOutcome outcome,
                               std::optional<LssMasterEvent> step, TimePoint now, Output& out) {
  Running& r = *run_;
  auto e = event(kind, now);
  e.address = r.address;
  if (kind == Kind::Assigned) e.node_id = r.node_id;
  e.outcome = outcome;
  // Only a refusal carries an error code; a timeout's event has none.
  if (step && step->kind == ServiceKind::Refused) {
    e.error_code = step->error_code;
    e.spec_error = step->error_code == 0xFF ? step->spec_error : 0;
  }
  e.step = std::move(step);
  out.report(std::move(e));
  r.check_due = true;  // one unconfigured device fewer
  if (kind == Kind::Skipped) {
    // A skipped target is found again bit by bit (only then is it looked past): devices with
    // lower addresses are still to be found after the targets.
    if (r.confirming) {
      r.failed.insert(r.address);
    } else {
      r.cursor = r.address;
    }
  }
  // Back to waiting: a device with its new node-ID starts with it and no longer answers
  // Fastscan; a skipped one is looked past.
  switch_all(LssState::Waiting, now);
  search_next(now);
}

}  // namespace nmt
