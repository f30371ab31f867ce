#include "nmt/io/sdo_session.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <string_view>
#include <utility>

#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "nmt/sdo/srd_description.hpp"

namespace nmt {
namespace {

// "2.500": a duration in seconds, as the tools print them.
std::string seconds_text(Duration d) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", static_cast<double>(d.count()) / 1e6);
  return buf;
}

constexpr std::uint16_t kManagerClientIndex = 0x1280;
constexpr std::uint16_t kConnectionClientIndex = 0x1281;

std::string cob_ids_text(const SdoClientConfig& c) {
  return "COB-IDs " + cfg::hex_digits(c.request_cob_id.can_id().id, 3) + "h/" +
         cfg::hex_digits(c.response_cob_id.can_id().id, 3) + "h";
}

}  // namespace

cfg::Result<std::unique_ptr<SdoSession>> SdoSession::open(const std::string& url,
                                                          SdoClientConfig config) {
  auto bus = open_bus(url);
  if (!bus) return cfg::Error{bus.error().message, cfg::ErrorCategory::Io};
  return std::unique_ptr<SdoSession>(new SdoSession(std::move(bus).value(), config));
}

SdoSession::SdoSession(std::unique_ptr<Bus> bus, SdoClientConfig config)
    : bus_(std::move(bus)), loop_(*bus_), client_(config), ref_(client_), channel_{config} {
  ref_.set_event_handler([this](const SdoResult& r, TimePoint) {
    result_ = r;
    loop_.request_stop();
  });
  loop_.add(ref_);
}

SdoSession::~SdoSession() = default;

cfg::Result<SdoResult> SdoSession::upload(std::uint16_t index, std::uint8_t sub,
                                          const SdoTransferOptions& options) {
  // Refused options are the caller's, not the channel's: the same error on either route.
  if (auto ok = SdoClient::check_start(options, std::nullopt); !ok) return ok.error();
  if (srd_) {
    return run_srd([&](SdoRequestingDevice& srd, TimePoint now, SdoRequestingDevice::Output& out) {
      return srd.upload(channel_.client_index, index, sub, now, out, options);
    });
  }
  return run([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
    return c.upload(index, sub, now, out, options);
  });
}

cfg::Result<SdoResult> SdoSession::download(std::uint16_t index, std::uint8_t sub,
                                            std::vector<std::uint8_t> data,
                                            const SdoTransferOptions& options) {
  if (auto ok = SdoClient::check_start(options, data.size()); !ok) return ok.error();
  if (srd_) {
    return run_srd([&](SdoRequestingDevice& srd, TimePoint now, SdoRequestingDevice::Output& out) {
      return srd.download(channel_.client_index, index, sub, std::move(data), now, out, options);
    });
  }
  return run([&](SdoClient& c, TimePoint now, SdoClient::Output& out) {
    return c.download(index, sub, std::move(data), now, out, options);
  });
}

template <class Start>
cfg::Result<SdoResult> SdoSession::run(Start&& start) {
  result_.reset();
  loop_.clear_stop();
  if (auto started = ref_.apply(std::forward<Start>(start)); !started) return started.error();
  // The client ends every transfer itself (an answer, an abort, or its timeout); the bound only
  // guards against a server that keeps answering for ever.
  constexpr auto kBound = std::chrono::seconds(60);
  if (!result_) {
    auto status = loop_.run_for(kBound);
    if (!status) return cfg::Error{status.error().message, cfg::ErrorCategory::Io};
  }
  if (!result_) {
    return cfg::Error{"the SDO transfer did not end within 60 s", cfg::ErrorCategory::Io};
  }
  // The client's last frame (e.g. the end of a block upload) may still wait in the loop's
  // transmit queue behind a full interface queue: it goes out before the session moves on.
  loop_.clear_stop();
  if (auto sent = loop_.run_until_sent(std::chrono::seconds(1)); !sent) {
    return cfg::Error{sent.error().message, cfg::ErrorCategory::Io};
  }
  return std::move(*result_);
}

// --- via the SDO manager ---------------------------------------------------------------------

void SdoSession::progress(const std::string& line) const {
  if (route_ && route_->progress) route_->progress(line);
}

cfg::Result<bool> SdoSession::run_until(const std::function<bool()>& done, Duration timeout) {
  // On the loop's clock, which run_until() keeps to (the engines' time stands still during a
  // bus-off, the clock does not).
  const auto end = loop_.clock() + timeout;
  // `done` may depend on any frame (a write into the SRD's dictionary), not only on events.
  loop_.set_observer([this](const CanFrame&, TimePoint, auto) { loop_.request_stop(); });
  cfg::Result<bool> outcome = true;
  while (!done()) {
    if (loop_.clock() >= end) {
      outcome = false;
      break;
    }
    loop_.clear_stop();
    if (auto status = loop_.run_until(end); !status) {
      outcome = cfg::Error{status.error().message, cfg::ErrorCategory::Io};
      break;
    }
  }
  loop_.set_observer({});
  return outcome;
}

std::optional<SrdEvent> SdoSession::take_event(std::initializer_list<SrdEvent::Kind> kinds) {
  return take_event([&](const SrdEvent& e) {
    return std::find(kinds.begin(), kinds.end(), e.kind) != kinds.end();
  });
}

std::optional<SrdEvent> SdoSession::take_event(const std::function<bool(const SrdEvent&)>& wanted) {
  const auto it = std::find_if(srd_events_.begin(), srd_events_.end(), wanted);
  if (it == srd_events_.end()) return std::nullopt;
  auto event = std::move(*it);
  srd_events_.erase(it);
  return event;
}

cfg::Status SdoSession::connect_via_manager(SdoManagerRoute route) {
  using Kind = SrdEvent::Kind;
  route_ = std::move(route);
  auto description = cfg::parse_device_description(session_srd_description());
  if (!description.device) return cfg::Error{"the built-in SDO requesting device does not read"};
  SrdOptions options;
  options.registration_client_index = kManagerClientIndex;
  options.registration_timeout = route_->manager_timeout;
  options.connection_timeout = route_->manager_timeout;
  auto srd = SdoRequestingDevice::create(*description.device, route_->own_node_id, options);
  if (!srd) return srd.error();
  srd_ = std::move(srd).value();
  srd_ref_ =
      std::make_unique<EngineRef<SdoRequestingDevice>>(*srd_, [this](const SrdEvent& e, TimePoint) {
        if (e.kind == Kind::Device) return;  // its own boot-up and NMT states
        srd_events_.push_back(e);
        loop_.request_stop();
      });
  loop_.add(*srd_ref_);
  const std::string own = "node " + std::to_string(route_->own_node_id.value());

  // CiA 301 §7.2.8.3.2.1: the device boots (its boot-up goes out from its first timer).
  srd_ref_->apply([](SdoRequestingDevice& s, TimePoint now, auto& out) { s.start(now, out); });
  auto booted = run_until([&] { return srd_->node().state() != NmtState::Initialising; },
                          std::chrono::seconds(1));
  if (!booted) return booted.error();
  // DSP 302 §7.2.1: 1F10h, then the Dynamic SDO Request; the manager scans and confirms.
  // A device that cannot register says so through the events awaited below.
  (void)srd_ref_->apply([](SdoRequestingDevice& s, TimePoint now, auto& out) {
    return s.register_at_manager(now, out);
  });
  progress("registering as SDO requesting device " + own + " with the SDO manager");
  std::optional<SrdEvent> registered;
  auto answered = run_until(
      [&] {
        return (registered = take_event({Kind::Registered, Kind::RegistrationFailed})) ||
               srd_->registration() == SrdRegistration::Unregistered;
      },
      route_->manager_timeout + std::chrono::seconds(1));
  if (!answered) return answered.error();
  // A refusal carries an abort or a 1F10h word; a missing answer (the SRD's own timeout, or
  // none reported yet) neither.
  const bool refused = registered && registered->kind == Kind::RegistrationFailed &&
                       (registered->abort != SdoAbort::None || registered->state.encode() != 0);
  if (refused) {
    return cfg::Error{"the SDO manager did not register " + own + ": " + registered->text,
                      cfg::ErrorCategory::Input};
  }
  if (!registered || registered->kind == Kind::RegistrationFailed) {
    return cfg::Error{
        "no SDO manager answered the Dynamic SDO Request (DSP 302 §7.2.1) of " + own + " within " +
            seconds_text(route_->manager_timeout) +
            " s: is an SDO manager running on the bus (e.g. `cfgmgr master NETWORK --bus URL "
            "--sdo-manager`)? A larger --manager-timeout helps when it scans many node-IDs",
        cfg::ErrorCategory::Io};
  }
  if (const auto to_manager =
          SdoClientConfig::from_dictionary(srd_->node().dictionary(), kManagerClientIndex)) {
    progress("registered with the SDO manager, node " +
             (to_manager->node_id ? std::to_string(to_manager->node_id->value()) : "?") + " (" +
             cfg::object_name(kManagerClientIndex) + ", " + cob_ids_text(*to_manager) + ")");
  }

  // DSP 302 §7.2.2: 1F00h at the manager; it answers in 1F10h with the client entry set up.
  const std::string slave = "node " + std::to_string(route_->slave.value());
  (void)srd_ref_->apply([&](SdoRequestingDevice& s, TimePoint now, auto& out) {
    return s.request_connection(route_->slave, kConnectionClientIndex, now, out);
  });
  std::optional<SrdEvent> connected;
  auto granted = run_until(
      [&] {
        return (connected = take_event({Kind::Connected, Kind::ConnectionFailed})) ||
               srd_->registration() != SrdRegistration::Registered;
      },
      route_->manager_timeout + std::chrono::seconds(1));
  if (!granted) return granted.error();
  if (!connected || connected->kind == Kind::ConnectionFailed) {
    std::string why = connected
                          ? connected->text
                          : "the SDO manager ended the registration before it connected " + slave;
    (void)close();
    return cfg::Error{std::move(why), cfg::ErrorCategory::Input};
  }
  channel_.config = *srd_->connection(kConnectionClientIndex);
  channel_.srd_node_id = route_->own_node_id;
  channel_.client_index = kConnectionClientIndex;
  progress("connected to " + slave + " (" + cfg::object_name(kConnectionClientIndex) + ", " +
           cob_ids_text(channel_.config) + ")");
  return {};
}

cfg::Result<SdoResult> SdoSession::run_srd(
    const std::function<cfg::Result<SdoRequestingDevice::TransferId>(
        SdoRequestingDevice&, TimePoint, SdoRequestingDevice::Output&)>& start) {
  const auto id = srd_ref_->apply(start);
  if (!id) {
    return cfg::Error{"the connection the SDO manager granted is gone (released by the manager)",
                      cfg::ErrorCategory::Io};
  }
  std::optional<SrdEvent> ended;
  // As run(): the client ends every transfer itself; the bound guards against a server that
  // keeps answering for ever.
  auto done = run_until(
      [&] {
        ended = take_event([&](const SrdEvent& e) {
          return e.kind == SrdEvent::Kind::Transfer && e.transfer && e.transfer->id == *id;
        });
        return ended.has_value();
      },
      std::chrono::seconds(60));
  if (!done) return done.error();
  if (!ended) {
    return cfg::Error{"the SDO transfer did not end within 60 s", cfg::ErrorCategory::Io};
  }
  return std::move(*ended->transfer);
}

cfg::Status SdoSession::close() {
  if (!srd_ || srd_->registration() != SrdRegistration::Registered) return {};
  // DSP 302 §7.2.3 1F01h with slave node-ID 0: release every connection and de-register.
  const cfg::Status sent = srd_ref_->apply(
      [](SdoRequestingDevice& s, TimePoint now, auto& out) { return s.deregister(now, out); });
  if (!sent)
    return cfg::Error{"a request to the SDO manager is still pending", cfg::ErrorCategory::Io};
  std::optional<SrdEvent> ended;
  auto answered = run_until(
      [&] {
        return (ended = take_event({SrdEvent::Kind::Deregistered, SrdEvent::Kind::ReleaseFailed}))
            .has_value();
      },
      route_->manager_timeout);
  if (!answered) return answered.error();
  if (!ended) {
    return cfg::Error{"the SDO manager did not confirm the release", cfg::ErrorCategory::Io};
  }
  if (ended->kind == SrdEvent::Kind::ReleaseFailed) {
    return cfg::Error{"the SDO manager refused the release: " + ended->text};
  }
  // The manager accepts 1F01h first and then invalidates the client entries it wrote (§7.2.2):
  // stay on the bus until it has, or its writes would wait for answers from a device that left.
  // CiA 301 §7.5.2.34: bit 31 of sub 1 and sub 2 set, the channel is not valid.
  const auto invalidated = [this] {
    const auto& dict = srd_->node().dictionary();
    for (const std::uint16_t index : {kManagerClientIndex, kConnectionClientIndex}) {
      for (const std::uint8_t sub : {std::uint8_t{1}, std::uint8_t{2}}) {
        const auto cob_id = dict.get_cob_id(index, sub);
        if (cob_id && cob_id->valid()) return false;
      }
    }
    return true;
  };
  auto cleared = run_until(invalidated, route_->manager_timeout);
  if (!cleared) return cleared.error();
  if (!cleared.value()) {
    return cfg::Error{"the SDO manager did not clear " + cfg::object_name(kManagerClientIndex) +
                          " and " + cfg::object_name(kConnectionClientIndex) + " of this tool",
                      cfg::ErrorCategory::Io};
  }
  progress("released and de-registered");
  return {};
}

}  // namespace nmt
