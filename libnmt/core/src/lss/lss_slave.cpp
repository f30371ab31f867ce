#include "nmt/lss/lss_slave.hpp"

#include <utility>

#include "cfg/bytes.hpp"

namespace nmt {

using lss::Cs;

LssSlave::LssSlave(LssAddress address, std::uint8_t node_id, LssSlaveOptions options,
                   std::uint8_t bit_timing_index)
    : address_(address),
      options_(options),
      active_node_id_(node_id),
      pending_node_id_(node_id),
      bit_timing_index_(bit_timing_index) {}

void LssSlave::start(std::uint8_t node_id, std::optional<std::uint8_t> bit_timing_index) {
  state_ = LssState::Waiting;
  if (bit_timing_index) bit_timing_index_ = *bit_timing_index;
  active_node_id_ = node_id;
  pending_node_id_ = node_id;
  pending_bit_timing_.reset();
  selective_next_ = 0;
  identify_next_ = 0;
  fastscan_position_ = 0;
}

void LssSlave::activate_pending_bit_timing() {
  if (pending_bit_timing_) bit_timing_index_ = *pending_bit_timing_;
  pending_bit_timing_.reset();
}

void LssSlave::answer(Output& out, Cs cs, std::uint32_t value) {
  out.send(lss::make_frame(lss::kSlaveCobId, cs, value));
}

LssSlaveEvent LssSlave::make_event(LssSlaveEvent::Kind kind, TimePoint now,
                                   std::string text) const {
  LssSlaveEvent e;
  e.kind = kind;
  e.at = now;
  e.state = state_;
  e.text = std::move(text);
  return e;
}

bool LssSlave::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  if (!lss::is_lss_frame(frame, lss::kMasterCobId)) return false;
  const auto cs = static_cast<Cs>(frame.data[0]);
  const std::uint32_t value = cfg::load_le32(std::span(frame.data).subspan(1, 4));
  const bool configuration = state_ == LssState::Configuration;
  switch (cs) {
    case Cs::SwitchStateGlobal: {
      if (frame.data[1] > 1) return false;
      const auto to = static_cast<LssState>(frame.data[1]);
      const LssState from = state_;
      state_ = to;
      selective_next_ = 0;
      if (from != to) {
        {
          auto e = make_event(LssSlaveEvent::Kind::StateChanged, now,
                              "LSS " + std::string(to_string(to)));
          out.report(std::move(e));
        }
      }
      // CANopenNode 305/CO_LSSslave.c: a device without a node-ID that got one starts with it
      // when it leaves configuration.
      if (from == LssState::Configuration && to == LssState::Waiting &&
          active_node_id_ == lss::kUnconfigured && pending_node_id_ != lss::kUnconfigured) {
        {
          auto e = make_event(LssSlaveEvent::Kind::NodeIdActivate, now,
                              "LSS: starting with node-ID " + std::to_string(pending_node_id_));
          e.node_id = pending_node_id_;
          out.report(std::move(e));
        }
      }
      return true;
    }
    case Cs::SwitchSelectiveVendor:
    case Cs::SwitchSelectiveProduct:
    case Cs::SwitchSelectiveRevision:
    case Cs::SwitchSelectiveSerial: {
      if (configuration) return false;
      const int step = frame.data[0] - static_cast<int>(Cs::SwitchSelectiveVendor);
      // A first frame (40h) always starts a new selection.
      if ((step != selective_next_ && step != 0) || value != address_.part(step)) {
        selective_next_ = 0;
        return true;
      }
      if (step < 3) {
        ++selective_next_;
        return true;
      }
      selective_next_ = 0;
      state_ = LssState::Configuration;
      answer(out, Cs::SwitchSelectiveAnswer);
      {
        auto e = make_event(LssSlaveEvent::Kind::StateChanged, now, "LSS configuration (selected)");
        out.report(std::move(e));
      }
      return true;
    }
    case Cs::IdentifyVendor:
    case Cs::IdentifyProduct:
    case Cs::IdentifyRevisionLow:
    case Cs::IdentifyRevisionHigh:
    case Cs::IdentifySerialLow:
    case Cs::IdentifySerialHigh: {
      const int step = frame.data[0] - static_cast<int>(Cs::IdentifyVendor);
      bool match = step == identify_next_ || step == 0;
      if (match) {
        switch (step) {
          case 0:
            match = value == address_.vendor_id;
            break;
          case 1:
            match = value == address_.product_code;
            break;
          case 2:
            match = value <= address_.revision;
            break;
          case 3:
            match = value >= address_.revision;
            break;
          case 4:
            match = value <= address_.serial;
            break;
          default:
            match = value >= address_.serial;
            break;
        }
      }
      identify_next_ = match ? static_cast<std::uint8_t>(step + 1) : 0;
      if (match && step == 5) {
        identify_next_ = 0;
        answer(out, Cs::IdentifyAnswer);
      }
      return true;
    }
    case Cs::IdentifyNonConfigured:
      if (unconfigured()) answer(out, Cs::IdentifyNonConfiguredAnswer);
      return true;
    case Cs::Fastscan:
      if (configuration || !unconfigured()) return false;
      fastscan(frame, now, out);
      return true;
    default:
      break;
  }
  if (!configuration) return false;
  switch (cs) {
    case Cs::ConfigureNodeId: {
      const std::uint8_t id = frame.data[1];
      const bool valid = (id >= 1 && id <= 127) || id == lss::kUnconfigured;
      out.send(lss::make_frame(lss::kSlaveCobId, cs, {static_cast<std::uint8_t>(valid ? 0 : 1)}));
      if (valid) {
        pending_node_id_ = id;
        {
          auto e = make_event(LssSlaveEvent::Kind::NodeIdConfigured, now,
                              "LSS: pending node-ID " + std::to_string(id));
          e.node_id = id;
          out.report(std::move(e));
        }
      }
      return true;
    }
    case Cs::ConfigureBitTiming: {
      const std::uint8_t selector = frame.data[1];
      const std::uint8_t index = frame.data[2];
      const bool valid = selector == 0 && index < 16 && index != 5 &&
                         (options_.bit_timing_indices >> index & 1U) != 0;
      out.send(lss::make_frame(lss::kSlaveCobId, cs, {static_cast<std::uint8_t>(valid ? 0 : 1)}));
      if (valid) {
        pending_bit_timing_ = index;
        const auto kbit = lss::bit_rate_kbit(index);
        {
          auto e = make_event(
              LssSlaveEvent::Kind::BitTimingConfigured, now,
              "LSS: pending bit rate " + (kbit ? std::to_string(*kbit) + " kbit/s" : "automatic"));
          e.bit_timing_index = index;
          out.report(std::move(e));
        }
      }
      return true;
    }
    case Cs::ActivateBitTiming: {
      const auto delay = cfg::load_le16(std::span(frame.data).subspan(1, 2));
      {
        auto e =
            make_event(LssSlaveEvent::Kind::BitTimingActivate, now,
                       "LSS: activate bit timing, switch delay " + std::to_string(delay) + " ms");
        e.bit_timing_index = pending_bit_timing_.value_or(bit_timing_index_);
        e.switch_delay_ms = delay;
        out.report(std::move(e));
      }
      return true;
    }
    case Cs::StoreConfiguration:
      out.send(lss::make_frame(lss::kSlaveCobId, cs,
                               {static_cast<std::uint8_t>(options_.store_supported ? 0 : 1)}));
      if (options_.store_supported) {
        {
          auto e = make_event(LssSlaveEvent::Kind::StoreRequested, now,
                              "LSS: store node-ID " + std::to_string(pending_node_id_));
          e.node_id = pending_node_id_;
          e.bit_timing_index = pending_bit_timing_.value_or(bit_timing_index_);
          out.report(std::move(e));
        }
      }
      return true;
    case Cs::InquireVendor:
    case Cs::InquireProduct:
    case Cs::InquireRevision:
    case Cs::InquireSerial:
      answer(out, cs, address_.part(frame.data[0] - static_cast<int>(Cs::InquireVendor)));
      return true;
    case Cs::InquireNodeId:
      out.send(lss::make_frame(lss::kSlaveCobId, cs, {active_node_id_}));
      return true;
    default:
      return false;
  }
}

void LssSlave::fastscan(const CanFrame& frame, TimePoint now, Output& out) {
  const std::uint32_t id_number = cfg::load_le32(std::span(frame.data).subspan(1, 4));
  const std::uint8_t bit_check = frame.data[5];
  const std::uint8_t sub = frame.data[6];
  const std::uint8_t next = frame.data[7];
  if (bit_check == lss::kFastscanReset) {
    fastscan_position_ = 0;
    answer(out, Cs::IdentifyAnswer);
    return;
  }
  if (bit_check > 31 || sub > 3 || next > 3 || sub != fastscan_position_) return;
  // Bits bit_check..31 of IDNumber are compared.
  const std::uint32_t mask = ~std::uint32_t{0} << bit_check;
  if (((id_number ^ address_.part(sub)) & mask) != 0) return;
  fastscan_position_ = next;
  answer(out, Cs::IdentifyAnswer);
  if (bit_check == 0 && next < sub) {
    state_ = LssState::Configuration;
    fastscan_position_ = 0;
    {
      auto e = make_event(LssSlaveEvent::Kind::StateChanged, now, "LSS configuration (Fastscan)");
      out.report(std::move(e));
    }
  }
}

}  // namespace nmt
