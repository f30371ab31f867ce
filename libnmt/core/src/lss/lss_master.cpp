#include "nmt/lss/lss_master.hpp"

#include <algorithm>
#include <utility>

#include "cfg/bytes.hpp"

namespace nmt {

using lss::Cs;
using Kind = LssMasterEvent::Kind;

std::string_view to_string(LssService service) {
  switch (service) {
    case LssService::SwitchStateGlobal:
      return "switch state global";
    case LssService::SwitchStateSelective:
      return "switch state selective";
    case LssService::ConfigureNodeId:
      return "configure node-ID";
    case LssService::ConfigureBitTiming:
      return "configure bit timing";
    case LssService::ActivateBitTiming:
      return "activate bit timing";
    case LssService::StoreConfiguration:
      return "store configuration";
    case LssService::InquireVendorId:
      return "inquire vendor-ID";
    case LssService::InquireProductCode:
      return "inquire product code";
    case LssService::InquireRevision:
      return "inquire revision number";
    case LssService::InquireSerial:
      return "inquire serial number";
    case LssService::InquireNodeId:
      return "inquire node-ID";
    case LssService::IdentifyRemoteSlaves:
      return "identify remote slave";
    case LssService::IdentifyNonConfigured:
      return "identify non-configured remote slave";
    case LssService::Fastscan:
      return "Fastscan";
  }
  return "LSS service";
}

namespace {
CanFrame request(Cs cs, std::uint32_t value = 0) {
  return lss::make_frame(lss::kMasterCobId, cs, value);
}
}  // namespace

LssMasterEvent LssMaster::event(LssService service, Kind kind, TimePoint now) const {
  LssMasterEvent e;
  e.service = service;
  e.kind = kind;
  e.at = now;
  return e;
}

cfg::Status LssMaster::start(LssService service) {
  // engine.hpp rule 5: could not start is the answer, not an event; nothing goes out.
  if (service_) {
    return cfg::Error{"LSS " + std::string(to_string(service)) + " not started: " +
                      std::string(to_string(*service_)) + " runs (one LSS service at a time)"};
  }
  service_ = service;
  return {};
}

void LssMaster::await(Cs cs, Wait wait, Duration d, TimePoint now) {
  expect_ = cs;
  wait_ = wait;
  heard_ = false;
  deadline_ = now + d;
}

void LssMaster::finish(Event e, Output& out) {
  service_.reset();
  deadline_.reset();
  out.report(std::move(e));
}

// --- services ----------------------------------------------------------------------------------

cfg::Status LssMaster::switch_state_global(LssState state, TimePoint now, Output& out) {
  if (auto started = start(LssService::SwitchStateGlobal); !started) return started;
  out.send(lss::make_frame(lss::kMasterCobId, Cs::SwitchStateGlobal,
                           {static_cast<std::uint8_t>(state)}));
  auto e = event(LssService::SwitchStateGlobal, Kind::Done, now);
  e.state = state;
  finish(std::move(e), out);
  return {};
}

cfg::Status LssMaster::switch_state_selective(const LssAddress& address, TimePoint now,
                                              Output& out) {
  if (auto started = start(LssService::SwitchStateSelective); !started) return started;
  fs_.id = address;  // reported with the result
  out.send(request(Cs::SwitchSelectiveVendor, address.vendor_id));
  out.send(request(Cs::SwitchSelectiveProduct, address.product_code));
  out.send(request(Cs::SwitchSelectiveRevision, address.revision));
  out.send(request(Cs::SwitchSelectiveSerial, address.serial));
  await(Cs::SwitchSelectiveAnswer, Wait::Answer, options_.timeout, now);
  return {};
}

cfg::Status LssMaster::configure_node_id(std::optional<cfg::NodeId> node_id, TimePoint now,
                                         Output& out) {
  if (auto started = start(LssService::ConfigureNodeId); !started) return started;
  node_id_ = node_id;
  out.send(lss::make_frame(lss::kMasterCobId, Cs::ConfigureNodeId,
                           {node_id ? node_id->value() : lss::kUnconfigured}));
  await(Cs::ConfigureNodeId, Wait::Answer, options_.timeout, now);
  return {};
}

cfg::Status LssMaster::configure_bit_timing(std::uint8_t table_index, TimePoint now, Output& out,
                                            std::uint8_t table_selector) {
  if (auto started = start(LssService::ConfigureBitTiming); !started) return started;
  out.send(
      lss::make_frame(lss::kMasterCobId, Cs::ConfigureBitTiming, {table_selector, table_index}));
  await(Cs::ConfigureBitTiming, Wait::Answer, options_.timeout, now);
  return {};
}

cfg::Status LssMaster::activate_bit_timing(std::uint16_t switch_delay_ms, TimePoint now,
                                           Output& out) {
  if (auto started = start(LssService::ActivateBitTiming); !started) return started;
  out.send(request(Cs::ActivateBitTiming, switch_delay_ms));
  await(Cs::ActivateBitTiming, Wait::Delay, std::chrono::milliseconds(2 * switch_delay_ms), now);
  return {};
}

cfg::Status LssMaster::store_configuration(TimePoint now, Output& out) {
  if (auto started = start(LssService::StoreConfiguration); !started) return started;
  out.send(request(Cs::StoreConfiguration));
  await(Cs::StoreConfiguration, Wait::Answer, options_.timeout, now);
  return {};
}

cfg::Status LssMaster::inquire(LssService what, TimePoint now, Output& out) {
  Cs cs{};
  switch (what) {
    case LssService::InquireVendorId:
      cs = Cs::InquireVendor;
      break;
    case LssService::InquireProductCode:
      cs = Cs::InquireProduct;
      break;
    case LssService::InquireRevision:
      cs = Cs::InquireRevision;
      break;
    case LssService::InquireSerial:
      cs = Cs::InquireSerial;
      break;
    case LssService::InquireNodeId:
      cs = Cs::InquireNodeId;
      break;
    default:
      return cfg::Error{"LSS " + std::string(to_string(what)) + " is not an inquire service"};
  }
  if (auto started = start(what); !started) return started;
  out.send(request(cs));
  await(cs, Wait::Answer, options_.timeout, now);
  return {};
}

cfg::Status LssMaster::identify_remote_slaves(const LssAddressRange& range, TimePoint now,
                                              Output& out) {
  if (auto started = start(LssService::IdentifyRemoteSlaves); !started) return started;
  out.send(request(Cs::IdentifyVendor, range.vendor_id));
  out.send(request(Cs::IdentifyProduct, range.product_code));
  out.send(request(Cs::IdentifyRevisionLow, range.revision_low));
  out.send(request(Cs::IdentifyRevisionHigh, range.revision_high));
  out.send(request(Cs::IdentifySerialLow, range.serial_low));
  out.send(request(Cs::IdentifySerialHigh, range.serial_high));
  await(Cs::IdentifyAnswer, Wait::Collect, options_.scan_step, now);
  return {};
}

cfg::Status LssMaster::identify_non_configured(TimePoint now, Output& out) {
  if (auto started = start(LssService::IdentifyNonConfigured); !started) return started;
  out.send(request(Cs::IdentifyNonConfigured));
  await(Cs::IdentifyNonConfiguredAnswer, Wait::Collect, options_.scan_step, now);
  return {};
}

cfg::Status LssMaster::fastscan(std::optional<LssAddress> after, TimePoint now, Output& out) {
  if (auto started = start(LssService::Fastscan); !started) return started;
  fs_ = FastscanState{};
  fs_.after = after;
  fastscan_start(now, out);
  return {};
}

cfg::Status LssMaster::fastscan_confirm(const LssAddress& address, TimePoint now, Output& out) {
  if (auto started = start(LssService::Fastscan); !started) return started;
  fs_ = FastscanState{};
  fs_.confirm = true;
  fs_.id = address;
  fastscan_start(now, out);
  return {};
}

// --- engine ------------------------------------------------------------------------------------

bool LssMaster::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (!deadline_ || wait_ == Wait::Delay || !lss::is_lss_frame(frame, lss::kSlaveCobId)) {
    return false;
  }
  if (now > *deadline_) {
    // It arrived after the service's time: the service ended before it (receive time counts).
    on_timer(now, out);
    return false;
  }
  if (frame.data[0] != static_cast<std::uint8_t>(expect_)) return false;
  if (wait_ == Wait::Collect) {
    heard_ = true;
    deadline_ = std::max(*deadline_, now + options_.scan_step);
    return true;
  }
  answered(frame, now, out);
  return true;
}

void LssMaster::on_timer(TimePoint now, Output& out) {
  if (!deadline_ || now < *deadline_) return;
  switch (wait_) {
    case Wait::Answer:
      timed_out(now, out);
      break;
    case Wait::Collect:
      step_ended(now, out);
      break;
    case Wait::Delay:
      finish(event(LssService::ActivateBitTiming, Kind::Done, now), out);
      break;
  }
}

void LssMaster::answered(const CanFrame& frame, TimePoint now, Output& out) {
  const LssService service = *service_;
  const std::uint8_t code = frame.data[1];
  const std::uint8_t spec = frame.data[2];
  switch (expect_) {
    case Cs::SwitchSelectiveAnswer: {
      auto e = event(service, Kind::Done, now);
      e.address = fs_.id;
      finish(std::move(e), out);
      return;
    }
    case Cs::ConfigureNodeId:
    case Cs::ConfigureBitTiming:
    case Cs::StoreConfiguration: {
      auto e = event(service, code == 0 ? Kind::Done : Kind::Refused, now);
      e.error_code = code;
      e.spec_error = code == 0xFF ? spec : 0;
      if (expect_ == Cs::ConfigureNodeId) e.node_id = node_id_;
      finish(std::move(e), out);
      return;
    }
    case Cs::InquireNodeId: {
      auto e = event(service, Kind::Done, now);
      e.value = code;
      finish(std::move(e), out);
      return;
    }
    default: {  // inquire identity
      auto e = event(service, Kind::Done, now);
      e.value = cfg::load_le32(std::span(frame.data).subspan(1, 4));
      finish(std::move(e), out);
      return;
    }
  }
}

void LssMaster::timed_out(TimePoint now, Output& out) {
  auto e = event(*service_, Kind::Timeout, now);
  e.timeout = options_.timeout;
  if (*service_ == LssService::SwitchStateSelective) e.address = fs_.id;
  finish(std::move(e), out);
}

void LssMaster::step_ended(TimePoint now, Output& out) {
  const LssService service = *service_;
  if (service == LssService::IdentifyRemoteSlaves || service == LssService::IdentifyNonConfigured) {
    finish(event(service, heard_ ? Kind::Done : Kind::NotFound, now), out);
    return;
  }
  fastscan_step(heard_, now, out);
}

// --- Fastscan ----------------------------------------------------------------------------------

void LssMaster::send_fastscan(std::uint32_t id, int bit_check, int sub, int next, Output& out,
                              TimePoint now) {
  out.send(lss::make_fastscan(id, static_cast<std::uint8_t>(bit_check),
                              static_cast<std::uint8_t>(sub), static_cast<std::uint8_t>(next)));
  await(Cs::IdentifyAnswer, Wait::Collect, options_.scan_step, now);
}

void LssMaster::fastscan_start(TimePoint now, Output& out) {
  fs_.step = Step::Reset;
  send_fastscan(0, lss::kFastscanReset, 0, 0, out, now);
}

void LssMaster::fastscan_descend(TimePoint now, Output& out) {
  if (fs_.bit < 0) {
    // The part is known: confirm it; the devices that match move on to the next part, and after
    // the serial number (LSSNext 0 < LSSSub 3) the one found enters LSS configuration.
    fs_.step = Step::Confirm;
    send_fastscan(fs_.id.part(fs_.sub), 0, fs_.sub, fs_.sub == 3 ? 0 : fs_.sub + 1, out, now);
    return;
  }
  // Bit `bit` queried as 0 (bits below it are 0 too and not compared).
  fs_.step = Step::Descend;
  send_fastscan(fs_.id.part(fs_.sub), fs_.bit, fs_.sub, fs_.sub, out, now);
}

void LssMaster::fastscan_probe(TimePoint now, Output& out, int from_bit) {
  const std::uint32_t x = fs_.after->part(fs_.level);
  for (int b = from_bit; b < 32; ++b) {
    if ((x >> b & 1U) != 0) continue;
    // Is there a device whose part `level` has the bits of `after` above b and a 1 at b?
    fs_.step = Step::Probe;
    fs_.bit = b;
    send_fastscan(((x >> b) | 1U) << b, b, fs_.level, fs_.level, out, now);
    return;
  }
  if (fs_.level == 0) {
    // Unconfigured devices answered the reset, none of them above `after`.
    auto e = fastscan_event(Kind::NotFound, now);
    e.after = fs_.after;
    finish(std::move(e), out);
    return;
  }
  // Nothing higher below this part: probe the part before it, from a fresh start.
  --fs_.level;
  fs_.step = Step::Reset;
  send_fastscan(0, lss::kFastscanReset, 0, 0, out, now);
}

void LssMaster::fastscan_step(bool answer, TimePoint now, Output& out) {
  switch (fs_.step) {
    case Step::Reset:
      if (!answer) {
        finish(fastscan_event(Kind::NotFound, now), out);
        return;
      }
      if (fs_.confirm) {
        fastscan_target(now, out);
        return;
      }
      if (!fs_.after) {
        fs_.sub = 0;
        fs_.bit = 31;
        fastscan_descend(now, out);
        return;
      }
      fs_.position = 0;
      [[fallthrough]];
    case Step::Position:
      // Move the devices that share `after`'s parts before `level` to that part.
      if (fs_.step == Step::Position) {
        if (!answer) {
          // None has `after`'s part `position`: higher addresses branch off before it.
          fs_.level = fs_.position;
          fastscan_probe(now, out, 0);
          return;
        }
        ++fs_.position;
      }
      if (fs_.position >= fs_.level) {
        fastscan_probe(now, out, 0);
        return;
      }
      fs_.step = Step::Position;
      send_fastscan(fs_.after->part(fs_.position), 0, fs_.position, fs_.position + 1, out, now);
      return;
    case Step::Probe:
      if (!answer) {
        fastscan_probe(now, out, fs_.bit + 1);
        return;
      }
      fs_.id = *fs_.after;
      for (int s = fs_.level + 1; s < 4; ++s) fs_.id.part(s) = 0;
      fs_.id.part(fs_.level) = ((fs_.after->part(fs_.level) >> fs_.bit) | 1U) << fs_.bit;
      fs_.sub = fs_.level;
      --fs_.bit;
      fastscan_descend(now, out);
      return;
    case Step::Descend:
      if (!answer) fs_.id.part(fs_.sub) |= 1U << fs_.bit;  // nobody has a 0 there
      --fs_.bit;
      fastscan_descend(now, out);
      return;
    case Step::Confirm:
      if (!answer) {
        auto e = fastscan_event(Kind::Timeout, now);
        e.part = static_cast<std::uint8_t>(fs_.sub);
        finish(std::move(e), out);
        return;
      }
      if (fs_.sub == 3) {
        finish(fastscan_event(Kind::Done, now), out);
        return;
      }
      ++fs_.sub;
      fs_.bit = 31;
      fs_.id.part(fs_.sub) = 0;
      fastscan_descend(now, out);
      return;
    case Step::Target:
      if (!answer) {
        // Its device is absent or configured; the devices that matched the parts before stay
        // there until the next reset brings every unconfigured device back to part 0.
        finish(fastscan_event(Kind::Absent, now), out);
        return;
      }
      if (fs_.sub == 3) {
        finish(fastscan_event(Kind::Done, now), out);
        return;
      }
      ++fs_.sub;
      send_fastscan(fs_.id.part(fs_.sub), 0, fs_.sub, fs_.sub == 3 ? 0 : fs_.sub + 1, out, now);
      return;
  }
}

void LssMaster::fastscan_target(TimePoint now, Output& out) {
  // Confirm the known address part by part (BitCheck 0: all 32 bits compared).
  fs_.step = Step::Target;
  fs_.sub = 0;
  send_fastscan(fs_.id.part(0), 0, 0, 1, out, now);
}

LssMasterEvent LssMaster::fastscan_event(Kind kind, TimePoint now) const {
  auto e = event(LssService::Fastscan, kind, now);
  if (kind == Kind::Done || kind == Kind::Absent) e.address = fs_.id;
  return e;
}

}  // namespace nmt
