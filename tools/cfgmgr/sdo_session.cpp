#include "sdo_session.hpp"

#include <algorithm>
#include <chrono>
#include <string_view>
#include <utility>

#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "cfg/object_address.hpp"
#include "master_run.hpp"

namespace cfgmgr {
namespace {

// The session as an SDO requesting device (DSP 302 §7.2.3: 1F10h, 1F11h, a client entry for the
// channel to the manager and one for the connection; CiA 301: 1000h, 1001h, 1018h). Its
// heartbeat (1017h, 200 ms) is what the manager watches while it is registered (§7.2.1).
constexpr std::string_view kSrdDescription = R"([FileInfo]
FileName=cfgmgr_sdo_srd.eds
FileVersion=1
FileRevision=0
EDSVersion=4.0
Description=cfgmgr sdo --via-manager as an SDO requesting device (DSP 302 Section 7)
CreatedBy=canopen-commissioning project

[DeviceInfo]
VendorName=canopen-commissioning project
VendorNumber=0x00000000
ProductName=cfgmgr sdo
ProductNumber=0x00000000
RevisionNumber=0x00000000
BaudRate_10=1
BaudRate_20=1
BaudRate_50=1
BaudRate_125=1
BaudRate_250=1
BaudRate_500=1
BaudRate_800=1
BaudRate_1000=1
SimpleBootUpMaster=0
SimpleBootUpSlave=1
Granularity=0
DynamicChannelsSupported=0
GroupMessaging=0
NrOfRXPDO=0
NrOfTXPDO=0
LSS_Supported=0

[MandatoryObjects]
SupportedObjects=3
1=0x1000
2=0x1001
3=0x1018

[1000]
ParameterName=Device type
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00000000
PDOMapping=0

[1001]
ParameterName=Error register
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=0
PDOMapping=0

[1018]
ParameterName=Identity object
ObjectType=0x9
SubNumber=2

[1018sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=1
PDOMapping=0

[1018sub1]
ParameterName=Vendor-ID
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=0x00000000
PDOMapping=0

[OptionalObjects]
SupportedObjects=6
1=0x1017
2=0x1200
3=0x1280
4=0x1281
5=0x1F10
6=0x1F11

[1017]
ParameterName=Producer heartbeat time
ObjectType=0x7
DataType=0x0006
AccessType=rw
DefaultValue=200
PDOMapping=0

[1200]
ParameterName=Server SDO parameter
ObjectType=0x9
SubNumber=3

[1200sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=2
PDOMapping=0

[1200sub1]
ParameterName=COB-ID client to server
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=$NODEID+0x600
PDOMapping=0

[1200sub2]
ParameterName=COB-ID server to client
ObjectType=0x7
DataType=0x0007
AccessType=ro
DefaultValue=$NODEID+0x580
PDOMapping=0

[1280]
ParameterName=Client SDO parameter
ObjectType=0x9
SubNumber=4

[1280sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=3
PDOMapping=0

[1280sub1]
ParameterName=COB-ID client to server
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x80000000
PDOMapping=0

[1280sub2]
ParameterName=COB-ID server to client
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x80000000
PDOMapping=0

[1280sub3]
ParameterName=Node-ID of the SDO server
ObjectType=0x7
DataType=0x0005
AccessType=rw
DefaultValue=0
PDOMapping=0

[1281]
ParameterName=Client SDO parameter
ObjectType=0x9
SubNumber=4

[1281sub0]
ParameterName=Highest sub-index supported
ObjectType=0x7
DataType=0x0005
AccessType=ro
DefaultValue=3
PDOMapping=0

[1281sub1]
ParameterName=COB-ID client to server
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x80000000
PDOMapping=0

[1281sub2]
ParameterName=COB-ID server to client
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x80000000
PDOMapping=0

[1281sub3]
ParameterName=Node-ID of the SDO server
ObjectType=0x7
DataType=0x0005
AccessType=rw
DefaultValue=0
PDOMapping=0

[1F10]
ParameterName=Dynamic SDO connection state
ObjectType=0x7
DataType=0x0007
AccessType=rw
DefaultValue=0x00000000
PDOMapping=0

[1F11]
ParameterName=Slave failed
ObjectType=0x7
DataType=0x0006
AccessType=wo
DefaultValue=0x0000
PDOMapping=0
)";

constexpr std::uint16_t kManagerClientIndex = 0x1280;
constexpr std::uint16_t kConnectionClientIndex = 0x1281;

std::string cob_ids_text(const nmt::SdoClientConfig& c) {
  return "COB-IDs " + cfg::hex_digits(c.request_cob_id.can_id().id, 3) + "h/" +
         cfg::hex_digits(c.response_cob_id.can_id().id, 3) + "h";
}

}  // namespace

cfg::Result<std::unique_ptr<SdoSession>> SdoSession::open(const std::string& url,
                                                          nmt::SdoClientConfig config) {
  auto bus = nmt::open_bus(url);
  if (!bus) return cfg::Error{bus.error().message, cfg::ErrorCategory::Io};
  return std::unique_ptr<SdoSession>(new SdoSession(std::move(bus).value(), config));
}

SdoSession::SdoSession(std::unique_ptr<nmt::Bus> bus, nmt::SdoClientConfig config)
    : bus_(std::move(bus)), loop_(*bus_), client_(config), ref_(client_), channel_{config} {
  ref_.set_event_handler([this](const nmt::SdoResult& r, nmt::TimePoint) {
    result_ = r;
    loop_.request_stop();
  });
  loop_.add(ref_);
}

SdoSession::~SdoSession() = default;

cfg::Result<nmt::SdoResult> SdoSession::upload(std::uint16_t index, std::uint8_t sub,
                                               const nmt::SdoTransferOptions& options) {
  if (srd_) {
    return run_srd([&](nmt::SdoRequestingDevice& srd, nmt::TimePoint now,
                       nmt::SdoRequestingDevice::Output& out) {
      return srd.upload(channel_.client_index, index, sub, now, out, options);
    });
  }
  return run([&](nmt::SdoClient& c, nmt::TimePoint now, nmt::SdoClient::Output& out) {
    return c.upload(index, sub, now, out, options);
  });
}

cfg::Result<nmt::SdoResult> SdoSession::download(std::uint16_t index, std::uint8_t sub,
                                                 std::vector<std::uint8_t> data,
                                                 const nmt::SdoTransferOptions& options) {
  if (srd_) {
    return run_srd([&](nmt::SdoRequestingDevice& srd, nmt::TimePoint now,
                       nmt::SdoRequestingDevice::Output& out) {
      return srd.download(channel_.client_index, index, sub, std::move(data), now, out, options);
    });
  }
  return run([&](nmt::SdoClient& c, nmt::TimePoint now, nmt::SdoClient::Output& out) {
    return c.download(index, sub, std::move(data), now, out, options);
  });
}

template <class Start>
cfg::Result<nmt::SdoResult> SdoSession::run(Start&& start) {
  result_.reset();
  loop_.clear_stop();
  ref_.apply(std::forward<Start>(start));
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
  if (route_.progress) route_.progress(line);
}

cfg::Result<bool> SdoSession::run_until(const std::function<bool()>& done, nmt::Duration timeout) {
  // On the loop's clock, which run_until() keeps to (the engines' time stands still during a
  // bus-off, the clock does not).
  const auto end = loop_.clock() + timeout;
  // `done` may depend on any frame (a write into the SRD's dictionary), not only on events.
  loop_.set_observer([this](const nmt::CanFrame&, nmt::TimePoint, auto) { loop_.request_stop(); });
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

std::optional<nmt::SrdEvent> SdoSession::take_event(
    std::initializer_list<nmt::SrdEvent::Kind> kinds) {
  return take_event([&](const nmt::SrdEvent& e) {
    return std::find(kinds.begin(), kinds.end(), e.kind) != kinds.end();
  });
}

std::optional<nmt::SrdEvent> SdoSession::take_event(
    const std::function<bool(const nmt::SrdEvent&)>& wanted) {
  const auto it = std::find_if(srd_events_.begin(), srd_events_.end(), wanted);
  if (it == srd_events_.end()) return std::nullopt;
  auto event = std::move(*it);
  srd_events_.erase(it);
  return event;
}

cfg::Status SdoSession::connect_via_manager(ManagerRoute route) {
  using Kind = nmt::SrdEvent::Kind;
  route_ = std::move(route);
  auto description = cfg::parse_device_description(kSrdDescription);
  if (!description.device) return cfg::Error{"the built-in SDO requesting device does not read"};
  nmt::SrdOptions options;
  options.registration_client_index = kManagerClientIndex;
  options.registration_timeout = route_.manager_timeout;
  options.connection_timeout = route_.manager_timeout;
  auto srd = nmt::SdoRequestingDevice::create(*description.device, route_.own_node_id, options);
  if (!srd) return srd.error();
  srd_ = std::move(srd).value();
  srd_ref_ = std::make_unique<nmt::EngineRef<nmt::SdoRequestingDevice>>(
      *srd_, [this](const nmt::SrdEvent& e, nmt::TimePoint) {
        if (e.kind == Kind::Device) return;  // its own boot-up and NMT states
        srd_events_.push_back(e);
        loop_.request_stop();
      });
  loop_.add(*srd_ref_);
  const std::string own = "node " + std::to_string(route_.own_node_id.value());

  // CiA 301 §7.2.8.3.2.1: the device boots (its boot-up goes out from its first timer).
  srd_ref_->apply([](nmt::SdoRequestingDevice& s, nmt::TimePoint now, auto&) { s.power_on(now); });
  auto booted = run_until([&] { return srd_->node().state() != nmt::NmtState::Initialising; },
                          std::chrono::seconds(1));
  if (!booted) return booted.error();
  // DSP 302 §7.2.1: 1F10h, then the Dynamic SDO Request; the manager scans and confirms.
  srd_ref_->apply([](nmt::SdoRequestingDevice& s, nmt::TimePoint now, auto& out) {
    return s.register_at_manager(now, out);
  });
  progress("registering as SDO requesting device " + own + " with the SDO manager");
  std::optional<nmt::SrdEvent> registered;
  auto answered = run_until(
      [&] {
        return (registered = take_event({Kind::Registered, Kind::RegistrationFailed})) ||
               srd_->registration() == nmt::SrdRegistration::Unregistered;
      },
      route_.manager_timeout + std::chrono::seconds(1));
  if (!answered) return answered.error();
  // A refusal carries an abort or a 1F10h word; a missing answer (the SRD's own timeout, or
  // none reported yet) neither.
  const bool refused =
      registered && registered->kind == Kind::RegistrationFailed &&
      (registered->abort != nmt::SdoAbort::None || registered->state.encode() != 0);
  if (refused) {
    return cfg::Error{"the SDO manager did not register " + own + ": " + registered->text,
                      cfg::ErrorCategory::Input};
  }
  if (!registered || registered->kind == Kind::RegistrationFailed) {
    return cfg::Error{
        "no SDO manager answered the Dynamic SDO Request (DSP 302 §7.2.1) of " + own + " within " +
            seconds_text(nmt::TimePoint{}, nmt::TimePoint{} + route_.manager_timeout) +
            " s: is an SDO manager running on the bus (e.g. `cfgmgr master NETWORK --bus URL "
            "--sdo-manager`)? A larger --manager-timeout helps when it scans many node-IDs",
        cfg::ErrorCategory::Io};
  }
  if (const auto to_manager =
          nmt::SdoClientConfig::from_dictionary(srd_->node().dictionary(), kManagerClientIndex)) {
    progress("registered with the SDO manager, node " + std::to_string(to_manager->node_id) + " (" +
             cfg::object_name(kManagerClientIndex) + ", " + cob_ids_text(*to_manager) + ")");
  }

  // DSP 302 §7.2.2: 1F00h at the manager; it answers in 1F10h with the client entry set up.
  const std::string slave = "node " + std::to_string(route_.slave);
  srd_ref_->apply([&](nmt::SdoRequestingDevice& s, nmt::TimePoint now, auto& out) {
    return s.request_connection(route_.slave, kConnectionClientIndex, now, out);
  });
  std::optional<nmt::SrdEvent> connected;
  auto granted = run_until(
      [&] {
        return (connected = take_event({Kind::Connected, Kind::ConnectionFailed})) ||
               srd_->registration() != nmt::SrdRegistration::Registered;
      },
      route_.manager_timeout + std::chrono::seconds(1));
  if (!granted) return granted.error();
  if (!connected || connected->kind == Kind::ConnectionFailed) {
    std::string why = connected
                          ? connected->text
                          : "the SDO manager ended the registration before it connected " + slave;
    (void)close();
    return cfg::Error{std::move(why), cfg::ErrorCategory::Input};
  }
  channel_.config = *srd_->connection(kConnectionClientIndex);
  channel_.srd_node_id = route_.own_node_id.value();
  channel_.client_index = kConnectionClientIndex;
  progress("connected to " + slave + " (" + cfg::object_name(kConnectionClientIndex) + ", " +
           cob_ids_text(channel_.config) + ")");
  return {};
}

cfg::Result<nmt::SdoResult> SdoSession::run_srd(
    const std::function<std::optional<nmt::SdoRequestingDevice::TransferId>(
        nmt::SdoRequestingDevice&, nmt::TimePoint, nmt::SdoRequestingDevice::Output&)>& start) {
  const auto id = srd_ref_->apply(start);
  if (!id) {
    return cfg::Error{"the connection the SDO manager granted is gone (released by the manager)",
                      cfg::ErrorCategory::Io};
  }
  std::optional<nmt::SrdEvent> ended;
  // As run(): the client ends every transfer itself; the bound guards against a server that
  // keeps answering for ever.
  auto done = run_until(
      [&] {
        ended = take_event([&](const nmt::SrdEvent& e) {
          return e.kind == nmt::SrdEvent::Kind::Transfer && e.transfer && e.transfer->id == *id;
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
  if (!srd_ || srd_->registration() != nmt::SrdRegistration::Registered) return {};
  // DSP 302 §7.2.3 1F01h with slave node-ID 0: release every connection and de-register.
  const bool sent = srd_ref_->apply([](nmt::SdoRequestingDevice& s, nmt::TimePoint now, auto& out) {
    return s.deregister(now, out);
  });
  if (!sent)
    return cfg::Error{"a request to the SDO manager is still pending", cfg::ErrorCategory::Io};
  std::optional<nmt::SrdEvent> ended;
  auto answered = run_until(
      [&] {
        return (ended = take_event(
                    {nmt::SrdEvent::Kind::Deregistered, nmt::SrdEvent::Kind::ReleaseFailed}))
            .has_value();
      },
      route_.manager_timeout);
  if (!answered) return answered.error();
  if (!ended) {
    return cfg::Error{"the SDO manager did not confirm the release", cfg::ErrorCategory::Io};
  }
  if (ended->kind == nmt::SrdEvent::Kind::ReleaseFailed) {
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
  auto cleared = run_until(invalidated, route_.manager_timeout);
  if (!cleared) return cleared.error();
  if (!cleared.value()) {
    return cfg::Error{"the SDO manager did not clear " + cfg::object_name(kManagerClientIndex) +
                          " and " + cfg::object_name(kConnectionClientIndex) + " of this tool",
                      cfg::ErrorCategory::Io};
  }
  progress("released and de-registered");
  return {};
}

}  // namespace cfgmgr
