#include "nmt/sdo/sdo_requesting_device.hpp"

#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_index.hpp"
#include "sdo/saturating_time.hpp"

namespace nmt {

namespace obj = cfg::object;
using cfg::sdo_manager::ConnectionState;
using cfg::sdo_manager::DynamicSdoState;

namespace {

std::string entry_name(std::uint32_t key) {
  return key <= obj::kSdoClientLast ? cfg::object_name(static_cast<std::uint16_t>(key))
                                    : "the default SDO of node " + std::to_string(key & 0xFF);
}

// The client entry of a channel key; 0 for a default-SDO channel.
std::uint16_t client_index_of(std::uint32_t key) {
  return key <= obj::kSdoClientLast ? static_cast<std::uint16_t>(key) : std::uint16_t{0};
}

template <class Part>
void forward_frames(const Outbox<Part>& part, SdoRequestingDevice::Output& out) {
  out.frames.insert(out.frames.end(), part.frames.begin(), part.frames.end());
}

/// The node-ID in messages; 0 for a request about no single node (1F01h slave 0).
std::string node_number(std::optional<cfg::NodeId> node) {
  return std::to_string(node ? node->value() : 0);
}

}  // namespace

cfg::Result<std::unique_ptr<SdoRequestingDevice>> SdoRequestingDevice::create(
    const cfg::DeviceDescription& description, cfg::NodeId node_id, SrdOptions options) {
  if (description.sub(obj::kDynamicSdoConnectionState, 0) == nullptr) {
    return cfg::Error{"an SDO requesting device needs object " +
                      cfg::object_name(obj::kDynamicSdoConnectionState) +
                      " (DSP 302 §7.2.3, dynamic SDO connection state)"};
  }
  if (!options.all_default_sdos &&
      (!obj::is_sdo_client_parameter(options.registration_client_index) ||
       description.sub(options.registration_client_index, 2) == nullptr)) {
    return cfg::Error{"the client entry for the channel to the manager, " +
                      cfg::object_name(options.registration_client_index) +
                      ", is no client SDO parameter (1280h-12FFh with sub 1 and 2) of the device"};
  }
  auto node = SlaveNode::create(description, node_id, options.node);
  if (!node.ok()) return node.error();
  return std::make_unique<SdoRequestingDevice>(Key{}, std::move(node).value(), std::move(options));
}

SdoRequestingDevice::SdoRequestingDevice(Key, std::unique_ptr<SlaveNode> node, SrdOptions options)
    : node_(std::move(node)), options_(std::move(options)) {}

SdoRequestingDevice::~SdoRequestingDevice() = default;

void SdoRequestingDevice::report(SrdEvent event, Output& out) {
  out.report(std::move(event));
}

// --- engine ----------------------------------------------------------------------------------

void SdoRequestingDevice::start(TimePoint now, Output& out) {
  auto& node_out = scratch_.node;
  node_out.clear();
  node_->start(now, node_out);
  take_node_output(node_out, out);
  // A power cycle ends every connection and the registration (the dictionary reloads).
  registration_ = SrdRegistration::Unregistered;
  registration_deadline_.reset();
  manager_index_.reset();
  manager_.reset();
  pending_.reset();
  channels_.clear();
}

std::vector<cfg::ObjectAddress> SdoRequestingDevice::take_node_output(SlaveNode::Output& node_out,
                                                                      Output& out) {
  forward_frames(node_out, out);
  // The node reports every write its dictionary took (SlaveEvent::object); the SRD acts on the
  // manager's writes of 1F10h, 1F11h and the client entries after the node's call.
  std::vector<cfg::ObjectAddress> written;
  for (auto& e : node_out.events) {
    if (e.object && (e.object->index == obj::kDynamicSdoConnectionState ||
                     e.object->index == obj::kSlaveFailed ||
                     (obj::is_sdo_client_parameter(e.object->index) &&
                      (e.object->sub_index == 1 || e.object->sub_index == 2)))) {
      written.push_back(*e.object);
    }
    report({.kind = SrdEvent::Kind::Device, .at = e.at, .text = std::move(e.text)}, out);
  }
  return written;
}

bool SdoRequestingDevice::on_frame(const CanFrame& frame, TimePoint now, Output& out) {
  auto& node_out = scratch_.node;
  node_out.clear();
  bool taken = node_->on_frame(frame, now, node_out);
  const auto written = take_node_output(node_out, out);
  if (manager_) {
    auto& manager_out = scratch_.manager;
    manager_out.clear();
    taken = manager_->on_frame(frame, now, manager_out) || taken;
    forward_frames(manager_out, out);
    manager_results(manager_out, now, out);
  }
  for (auto& [key, channel] : channels_) {
    auto& channel_out = scratch_.channel;
    channel_out.clear();
    if (!channel.client->on_frame(frame, now, channel_out)) continue;
    taken = true;
    forward_frames(channel_out, out);
    channel_results(key, channel_out, out);
  }
  process(written, now, out);
  return taken;
}

void SdoRequestingDevice::on_timer(TimePoint now, Output& out) {
  auto& node_out = scratch_.node;
  node_out.clear();
  node_->on_timer(now, node_out);
  const auto written = take_node_output(node_out, out);
  if (manager_) {
    auto& manager_out = scratch_.manager;
    manager_out.clear();
    manager_->on_timer(now, manager_out);
    forward_frames(manager_out, out);
    manager_results(manager_out, now, out);
  }
  for (auto& [key, channel] : channels_) {
    auto& channel_out = scratch_.channel;
    channel_out.clear();
    channel.client->on_timer(now, channel_out);
    forward_frames(channel_out, out);
    channel_results(key, channel_out, out);
  }
  process(written, now, out);
  // DSP 302 §7.2.4 1: no answer to the Dynamic SDO Request: the user decides what to do.
  if (registration_deadline_ && now >= *registration_deadline_) {
    registration_deadline_.reset();
    registration_ = SrdRegistration::Unregistered;
    report({.kind = SrdEvent::Kind::RegistrationFailed,
            .at = now,
            .client_index = options_.registration_client_index,
            .text = "no SDO manager answered the Dynamic SDO Request"},
           out);
  }
  if (pending_ && pending_->deadline && now >= *pending_->deadline) {
    const Pending p = *pending_;
    pending_.reset();
    report(
        {.kind = SrdEvent::Kind::ConnectionFailed,
         .at = now,
         .client_index = p.client_index,
         .slave_node_id = p.slave,
         .text = "the SDO manager did not confirm the connection to node " + node_number(p.slave) +
                 " in " + cfg::object_name(obj::kDynamicSdoConnectionState)},
        out);
  }
}

std::optional<TimePoint> SdoRequestingDevice::next_deadline() const {
  auto next = node_->next_deadline();
  next = earliest(next, registration_deadline_);
  if (pending_) next = earliest(next, pending_->deadline);
  if (manager_) next = earliest(next, manager_->next_deadline());
  for (const auto& [key, channel] : channels_) {
    next = earliest(next, channel.client->next_deadline());
  }
  return next;
}

// --- requests --------------------------------------------------------------------------------

cfg::Status SdoRequestingDevice::register_at_manager(TimePoint now, Output& out) {
  if (!node_->powered() || node_->state() == NmtState::Initialising) {
    return cfg::Error{"the SDO requesting device has not booted"};
  }
  if (registration_ != SrdRegistration::Unregistered) {
    return cfg::Error{"a registration is already requested or done"};
  }
  // DSP 302 §7.2.3: xxxx0001h (xxxx0009h with error control of the slaves), or 00000003h.
  const auto state = options_.all_default_sdos
                         ? DynamicSdoState::all_default_sdos_request()
                         : DynamicSdoState::registration(options_.registration_client_index,
                                                         options_.request_error_control);
  node_->dictionary().set_unsigned(obj::kDynamicSdoConnectionState, 0, state.encode());
  // DSP 302 §7.2.1: the Dynamic SDO Request is a data frame without data bytes on 1760.
  out.send(CanFrame::make(cfg::sdo_manager::kDynamicSdoRequestCanId, {}));
  registration_ = SrdRegistration::Requested;
  registration_deadline_ = later(now, options_.registration_timeout);
  return {};
}

cfg::Status SdoRequestingDevice::send_to_manager(Pending pending, std::uint32_t word,
                                                 std::uint16_t object, TimePoint now, Output& out) {
  if (registration_ != SrdRegistration::Registered || !manager_) {
    return cfg::Error{"not registered with an SDO manager"};
  }
  if (pending_) return cfg::Error{"a request to the SDO manager is still pending"};
  std::vector<std::uint8_t> data;
  cfg::append_le(data, word, 4);
  auto& manager_out = scratch_.manager;
  manager_out.clear();
  const auto transfer =
      manager_->download(object, 0, std::move(data), now, manager_out, options_.manager_transfer);
  if (!transfer) return transfer.error();  // engine rule 5: nothing into `out`
  pending.transfer = *transfer;
  pending_ = pending;
  forward_frames(manager_out, out);
  manager_results(manager_out, now, out);
  return {};
}

cfg::Status SdoRequestingDevice::request_connection(cfg::NodeId slave, std::uint16_t client_index,
                                                    TimePoint now, Output& out) {
  if (!obj::is_sdo_client_parameter(client_index) || client_index == manager_index_ ||
      !node_->dictionary().entry(client_index, 2)) {
    return cfg::Error{cfg::object_name(client_index) +
                      " is no client entry of this device free for a connection"};
  }
  const cfg::sdo_manager::SdoRequest request{client_index, node_->node_id().value(), slave};
  return send_to_manager(
      {.what = Pending::What::Request, .slave = slave, .client_index = client_index},
      request.encode(), obj::kSdoRequest, now, out);
}

cfg::Status SdoRequestingDevice::release(cfg::NodeId slave, std::uint16_t client_index,
                                         TimePoint now, Output& out) {
  const cfg::sdo_manager::SdoRequest request{client_index, node_->node_id().value(), slave};
  return send_to_manager(
      {.what = Pending::What::Release, .slave = slave, .client_index = client_index},
      request.encode(), obj::kSdoRelease, now, out);
}

cfg::Status SdoRequestingDevice::deregister(TimePoint now, Output& out) {
  // DSP 302 §7.2.1: 1F01h with slave node-ID 0 releases everything and de-registers.
  const cfg::sdo_manager::SdoRequest request{0, node_->node_id().value(), 0};
  return send_to_manager({.what = Pending::What::Deregister}, request.encode(), obj::kSdoRelease,
                         now, out);
}

// --- what the manager wrote ------------------------------------------------------------------

void SdoRequestingDevice::process(std::span<const cfg::ObjectAddress> written, TimePoint now,
                                  Output& out) {
  for (const cfg::ObjectAddress& address : written) {
    const std::uint16_t index = address.index;
    if (index == obj::kDynamicSdoConnectionState) {
      const auto word = node_->dictionary().get_unsigned(index, 0).value_or(0);
      on_state_written(DynamicSdoState::decode(static_cast<std::uint32_t>(word)), now, out);
    } else if (index == obj::kSlaveFailed) {
      const auto failed = cfg::sdo_manager::SlaveFailed::decode(
          static_cast<std::uint16_t>(node_->dictionary().get_unsigned(index, 0).value_or(0)));
      report({.kind = SrdEvent::Kind::SlaveFailed,
              .at = now,
              .slave_node_id = cfg::NodeId::from(failed.slave_node_id),
              .text = "node " + std::to_string(failed.slave_node_id) + ": " +
                      std::string(cfg::sdo_manager::describe(
                          static_cast<cfg::sdo_manager::SlaveFailedReason>(failed.reason)))},
             out);
    } else {
      on_client_entry_written(index, now, out);
    }
  }
}

void SdoRequestingDevice::on_state_written(DynamicSdoState state, TimePoint now, Output& out) {
  if (registration_ == SrdRegistration::Requested) {
    // The manager's reset of 1F10h after its scan, or a write that keeps the request open.
    if (state.encode() == 0 || state.request_indication) return;
    registration_deadline_.reset();
    switch (state.state) {
      case ConnectionState::kManagerConnected: {
        const std::uint16_t index =
            state.client_index != 0 ? state.client_index : options_.registration_client_index;
        auto config = SdoClientConfig::from_dictionary(node_->dictionary(), index);
        if (!config) {
          registration_ = SrdRegistration::Unregistered;
          report({.kind = SrdEvent::Kind::RegistrationFailed,
                  .at = now,
                  .client_index = index,
                  .state = state,
                  .text = "the SDO manager confirmed the registration but " +
                          cfg::object_name(index) + " holds no valid channel"},
                 out);
          return;
        }
        manager_ = std::make_unique<SdoClient>(*config);
        manager_index_ = index;
        registration_ = SrdRegistration::Registered;
        report({.kind = SrdEvent::Kind::Registered,
                .at = now,
                .client_index = index,
                .slave_node_id = config->node_id,
                .state = state,
                .text = "registered at the SDO manager (node " + node_number(config->node_id) +
                        ") on " + cfg::object_name(index) +
                        (options_.request_error_control
                             ? (state.request_error_control ? ", error control of slaves granted"
                                                            : ", error control of slaves refused")
                             : "")},
               out);
        return;
      }
      case ConnectionState::kAllDefaultSdosOwned:
        registration_ = SrdRegistration::AllDefaultSdos;
        report({.kind = SrdEvent::Kind::Registered,
                .at = now,
                .state = state,
                .text = "registered at the SDO manager, owning all default SDOs"},
               out);
        return;
      case ConnectionState::kFailed:
        registration_ = SrdRegistration::Unregistered;
        report({.kind = SrdEvent::Kind::RegistrationFailed,
                .at = now,
                .client_index = state.client_index,
                .state = state,
                .text = "the SDO manager refused the registration: " +
                        std::string(describe(state.error()))},
               out);
        return;
      case ConnectionState::kSlaveConnected:
        registration_deadline_ = later(now, options_.registration_timeout);
        return;  // not an answer to a registration: keep waiting
    }
    return;
  }
  if (!pending_ || pending_->what != Pending::What::Request ||
      state.client_index != pending_->client_index || state.request_indication) {
    return;
  }
  const Pending p = *pending_;
  if (state.state == ConnectionState::kSlaveConnected) {
    pending_.reset();
    auto config = SdoClientConfig::from_dictionary(node_->dictionary(), p.client_index);
    if (!config) {
      report({.kind = SrdEvent::Kind::ConnectionFailed,
              .at = now,
              .client_index = p.client_index,
              .slave_node_id = p.slave,
              .state = state,
              .text = "the SDO manager confirmed the connection but " +
                      cfg::object_name(p.client_index) + " holds no valid channel"},
             out);
      return;
    }
    channels_[p.client_index] = Channel{std::make_unique<SdoClient>(*config), {}};
    const auto server = config->node_id;  // sub 3 of the entry (0: not given)
    report({.kind = SrdEvent::Kind::Connected,
            .at = now,
            .client_index = p.client_index,
            .slave_node_id = server ? server : p.slave,
            .state = state,
            .text = "connected to node " + node_number(p.slave) + " on " +
                    cfg::object_name(p.client_index) + " (request " +
                    cfg::hex_digits(config->request_cob_id.word(), 3) + "h, response " +
                    cfg::hex_digits(config->response_cob_id.word(), 3) + "h)"},
           out);
  } else if (state.state == ConnectionState::kFailed) {
    pending_.reset();
    report({.kind = SrdEvent::Kind::ConnectionFailed,
            .at = now,
            .client_index = p.client_index,
            .slave_node_id = p.slave,
            .state = state,
            .text = "the SDO manager could not connect to node " + node_number(p.slave) + ": " +
                    std::string(describe(state.error()))},
           out);
  }
}

void SdoRequestingDevice::on_client_entry_written(std::uint16_t client_index, TimePoint now,
                                                  Output& out) {
  if (SdoClientConfig::from_dictionary(node_->dictionary(), client_index)) return;  // still valid
  if (manager_index_ == client_index && registration_ == SrdRegistration::Registered) {
    if (pending_ && pending_->what == Pending::What::Deregister) pending_.reset();
    forget_registration(now, out);
    return;
  }
  if (channels_.contains(client_index)) {
    const auto slave = channels_.at(client_index).client->config().node_id;
    drop_channel(client_index, now, out);
    report({.kind = SrdEvent::Kind::ConnectionReleased,
            .at = now,
            .client_index = client_index,
            .slave_node_id = slave,
            .text = "the SDO manager released " + cfg::object_name(client_index) +
                    " (connection to node " + node_number(slave) + ")"},
           out);
  }
}

void SdoRequestingDevice::manager_results(const SdoClient::Output& results, TimePoint now,
                                          Output& out) {
  for (const auto& r : results.events) {
    if (!pending_ || r.id != pending_->transfer) continue;
    Pending& p = *pending_;
    if (!r.ok()) {
      const Pending failed = p;
      pending_.reset();
      const bool request = failed.what == Pending::What::Request;
      report({.kind = request ? SrdEvent::Kind::ConnectionFailed : SrdEvent::Kind::ReleaseFailed,
              .at = now,
              .client_index = failed.client_index,
              .slave_node_id = failed.slave,
              .abort = r.abort,
              .text = std::string(request ? "the SDO manager refused the connection to node "
                                          : "the SDO manager refused the release of node ") +
                      node_number(failed.slave) + ": " + to_string(r.abort)},
             out);
      continue;
    }
    switch (p.what) {
      case Pending::What::Request:
        p.accepted = true;
        p.deadline = later(now, options_.connection_timeout);
        break;
      case Pending::What::Release:
        pending_.reset();  // the release shows as the manager invalidates the entries
        break;
      case Pending::What::Deregister:
        pending_.reset();
        forget_registration(now, out);
        break;
    }
  }
}

void SdoRequestingDevice::forget_registration(TimePoint now, Output& out) {
  std::vector<std::uint32_t> keys;
  for (const auto& [key, channel] : channels_) keys.push_back(key);
  for (auto key : keys) {
    const auto slave = channels_.at(key).client->config().node_id;
    drop_channel(key, now, out);
    report({.kind = SrdEvent::Kind::ConnectionReleased,
            .at = now,
            .client_index = client_index_of(key),
            .slave_node_id = slave,
            .text = entry_name(key) + " released with the registration"},
           out);
  }
  const auto index = manager_index_.value_or(0);
  manager_.reset();
  manager_index_.reset();
  registration_ = SrdRegistration::Unregistered;
  report({.kind = SrdEvent::Kind::Deregistered,
          .at = now,
          .client_index = index,
          .text = "de-registered from the SDO manager"},
         out);
}

// --- transfers -------------------------------------------------------------------------------

void SdoRequestingDevice::drop_channel(std::uint32_t key, TimePoint now, Output& out) {
  auto it = channels_.find(key);
  if (it == channels_.end()) return;
  // The COB-IDs are no longer the SRD's: transfers end without an abort frame on them.
  auto& dropped = scratch_.dropped;
  dropped.clear();
  for (const auto& [inner, outer] : std::map(it->second.transfers)) {
    it->second.client->cancel(inner, now, dropped, SdoAbort::General);
  }
  dropped.frames.clear();
  channel_results(key, dropped, out);
  channels_.erase(it);
}

void SdoRequestingDevice::channel_results(std::uint32_t key, const SdoClient::Output& results,
                                          Output& out) {
  auto it = channels_.find(key);
  if (it == channels_.end()) return;
  for (auto r : results.events) {
    auto t = it->second.transfers.find(r.id);
    if (t == it->second.transfers.end()) continue;
    r.id = t->second;
    it->second.transfers.erase(t);
    const auto at = r.finished;
    std::string text = std::string(r.upload ? "upload " : "download ") + cfg::to_string(r.address) +
                       " over " + entry_name(key) + ": " + (r.ok() ? "done" : to_string(r.abort));
    report({.kind = SrdEvent::Kind::Transfer,
            .at = at,
            .client_index = client_index_of(key),
            .slave_node_id = r.node_id,
            .transfer = std::move(r),
            .text = std::move(text)},
           out);
  }
}

cfg::Result<SdoRequestingDevice::TransferId> SdoRequestingDevice::start(
    std::uint32_t key, bool upload, std::uint16_t index, std::uint8_t sub,
    std::vector<std::uint8_t> data, TimePoint now, Output& out, const SdoTransferOptions& options) {
  auto it = channels_.find(key);
  if (it == channels_.end()) return cfg::Error{"no connection on that channel"};
  auto& channel_out = scratch_.channel;
  channel_out.clear();
  const auto inner =
      upload ? it->second.client->upload(index, sub, now, channel_out, options)
             : it->second.client->download(index, sub, std::move(data), now, channel_out, options);
  if (!inner) return inner.error();  // engine rule 5: nothing into `out`
  const TransferId id = next_transfer_++;
  it->second.transfers[*inner] = id;
  forward_frames(channel_out, out);
  channel_results(key, channel_out, out);
  return id;
}

cfg::Result<SdoRequestingDevice::TransferId> SdoRequestingDevice::upload(
    std::uint16_t client_index, std::uint16_t index, std::uint8_t sub, TimePoint now, Output& out,
    SdoTransferOptions options) {
  return start(client_index, true, index, sub, {}, now, out, options);
}

cfg::Result<SdoRequestingDevice::TransferId> SdoRequestingDevice::download(
    std::uint16_t client_index, std::uint16_t index, std::uint8_t sub,
    std::vector<std::uint8_t> data, TimePoint now, Output& out, SdoTransferOptions options) {
  return start(client_index, false, index, sub, std::move(data), now, out, options);
}

std::uint32_t SdoRequestingDevice::open_default(cfg::NodeId slave) {
  const auto key = default_channel(slave);
  if (!channels_.contains(key)) {
    channels_[key] = Channel{std::make_unique<SdoClient>(SdoClientConfig::for_node(slave)), {}};
  }
  return key;
}

cfg::Result<SdoRequestingDevice::TransferId> SdoRequestingDevice::upload_default(
    cfg::NodeId slave, std::uint16_t index, std::uint8_t sub, TimePoint now, Output& out,
    SdoTransferOptions options) {
  if (registration_ != SrdRegistration::AllDefaultSdos) {
    return cfg::Error{"the SDO manager gave this device no default SDOs"};
  }
  return start(open_default(slave), true, index, sub, {}, now, out, options);
}

cfg::Result<SdoRequestingDevice::TransferId> SdoRequestingDevice::download_default(
    cfg::NodeId slave, std::uint16_t index, std::uint8_t sub, std::vector<std::uint8_t> data,
    TimePoint now, Output& out, SdoTransferOptions options) {
  if (registration_ != SrdRegistration::AllDefaultSdos) {
    return cfg::Error{"the SDO manager gave this device no default SDOs"};
  }
  return start(open_default(slave), false, index, sub, std::move(data), now, out, options);
}

// --- observation -----------------------------------------------------------------------------

std::optional<std::uint16_t> SdoRequestingDevice::manager_channel() const {
  return registration_ == SrdRegistration::Registered ? manager_index_ : std::nullopt;
}

std::optional<SdoClientConfig> SdoRequestingDevice::connection(std::uint16_t client_index) const {
  auto it = channels_.find(client_index);
  if (it == channels_.end()) return std::nullopt;
  return it->second.client->config();
}

std::vector<std::uint16_t> SdoRequestingDevice::connections() const {
  std::vector<std::uint16_t> indices;
  for (const auto& [key, channel] : channels_) {
    if (key <= obj::kSdoClientLast) indices.push_back(static_cast<std::uint16_t>(key));
  }
  return indices;
}

}  // namespace nmt
