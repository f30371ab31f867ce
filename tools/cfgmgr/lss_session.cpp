#include "lss_session.hpp"

#include <chrono>
#include <utility>

#include "master_run.hpp"

namespace cfgmgr {

std::string lss_address_text(const nmt::LssAddress& a) {
  return nmt::address_digits(a);
}

std::optional<nmt::LssAddress> parse_lss_address(std::string_view text) {
  nmt::LssAddress address;
  for (int part = 0; part < 4; ++part) {
    const auto colon = text.find(':');
    if ((colon == std::string_view::npos) != (part == 3)) return std::nullopt;
    const auto value = parse_hex_argument(text.substr(0, colon), 8);
    if (!value) return std::nullopt;
    address.part(part) = static_cast<std::uint32_t>(*value);
    if (colon != std::string_view::npos) text.remove_prefix(colon + 1);
  }
  return address;
}

cfg::Result<std::unique_ptr<LssSession>> LssSession::open(const std::string& url,
                                                          nmt::LssMasterOptions options) {
  auto bus = nmt::open_bus(url);
  if (!bus) return cfg::Error{bus.error().message, cfg::ErrorCategory::Io};
  return std::unique_ptr<LssSession>(new LssSession(std::move(bus).value(), options));
}

LssSession::LssSession(std::unique_ptr<nmt::Bus> bus, nmt::LssMasterOptions options)
    : bus_(std::move(bus)), loop_(*bus_), master_(options), ref_(master_) {
  ref_.set_event_handler([this](const Event& e, nmt::TimePoint) {
    events_.push_back(e);
    if (!master_.busy()) loop_.request_stop();
  });
  loop_.add(ref_);
}

LssSession::~LssSession() = default;

cfg::Result<std::vector<LssSession::Event>> LssSession::run(const Start& start) {
  events_.clear();
  loop_.clear_stop();
  if (auto started = ref_.apply(start); !started) return started.error();
  // The master ends every service itself (an answer, or its timeout or scan step); the bound
  // only guards against devices that keep a Fastscan going for ever.
  const auto end = loop_.now() + std::chrono::minutes(10);
  while (master_.busy() && loop_.now() < end) {
    loop_.clear_stop();
    if (auto status = loop_.run_until(end); !status) {
      return cfg::Error{status.error().message, cfg::ErrorCategory::Io};
    }
  }
  if (master_.busy() || events_.empty()) {
    return cfg::Error{"the LSS service did not end within 10 minutes", cfg::ErrorCategory::Io};
  }
  // A service's last frame (e.g. the switch back to waiting, which has no answer) may still
  // wait in the loop's transmit queue behind a full interface queue: it goes out before the
  // session moves on or the program ends, as SdoSession's transfers do.
  loop_.clear_stop();
  if (auto sent = loop_.run_until_sent(std::chrono::seconds(1)); !sent) {
    return cfg::Error{sent.error().message, cfg::ErrorCategory::Io};
  }
  return std::move(events_);
}

cfg::Result<LssSession::Event> LssSession::run_one(const Start& start) {
  auto events = run(start);
  if (!events) return events.error();
  return std::move(events.value().back());
}

}  // namespace cfgmgr
