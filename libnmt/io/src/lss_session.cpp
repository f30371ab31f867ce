#include "nmt/io/lss_session.hpp"

#include <chrono>
#include <utility>

namespace nmt {

cfg::Result<std::unique_ptr<LssSession>> LssSession::open(const std::string& url,
                                                          LssMasterOptions options) {
  auto bus = open_bus(url);
  if (!bus) return cfg::Error{bus.error().message, cfg::ErrorCategory::Io};
  return std::unique_ptr<LssSession>(new LssSession(std::move(bus).value(), options));
}

LssSession::LssSession(std::unique_ptr<Bus> bus, LssMasterOptions options)
    : bus_(std::move(bus)), loop_(*bus_), procedure_(options), ref_(procedure_) {
  ref_.set_event_handler([this](const Event& e, TimePoint) {
    events_.push_back(e);
    if (!procedure_.busy()) loop_.request_stop();
  });
  loop_.add(ref_);
}

LssSession::~LssSession() = default;

cfg::Result<std::vector<LssSession::Event>> LssSession::run(const Start& start) {
  events_.clear();
  loop_.clear_stop();
  if (auto started = ref_.apply(start); !started) return started.error();
  // The procedure ends itself (an answer, or a timeout or scan step of its last service); the
  // bound only guards against devices that keep a Fastscan going for ever.
  const auto end = loop_.now() + std::chrono::minutes(10);
  while (procedure_.busy() && loop_.now() < end) {
    loop_.clear_stop();
    if (auto status = loop_.run_until(end); !status) {
      return cfg::Error{status.error().message, cfg::ErrorCategory::Io};
    }
  }
  if (procedure_.busy() || events_.empty()) {
    return cfg::Error{"the LSS procedure did not end within 10 minutes", cfg::ErrorCategory::Io};
  }
  // A procedure's last frame (e.g. the switch back to waiting, which has no answer) may still
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

cfg::Result<LssSession::Event> LssSession::find_unconfigured() {
  return run_one([](LssProcedure& p, TimePoint now, LssProcedure::Output& out) {
    return p.find_unconfigured(now, out);
  });
}

cfg::Result<LssSession::Event> LssSession::find_product(std::uint32_t vendor_id,
                                                        std::uint32_t product_code) {
  return run_one([=](LssProcedure& p, TimePoint now, LssProcedure::Output& out) {
    return p.find_product(vendor_id, product_code, now, out);
  });
}

cfg::Result<LssSession::Event> LssSession::assign_node_id(const LssAddress& address,
                                                          std::optional<cfg::NodeId> node_id,
                                                          bool store) {
  return run_one([&](LssProcedure& p, TimePoint now, LssProcedure::Output& out) {
    return p.assign_node_id(address, node_id, store, now, out);
  });
}

cfg::Result<LssSession::Event> LssSession::inquire_node_id(const LssAddress& address) {
  return run_one([&](LssProcedure& p, TimePoint now, LssProcedure::Output& out) {
    return p.inquire_node_id(address, now, out);
  });
}

cfg::Result<LssSession::Event> LssSession::inquire_identity(std::optional<LssAddress> address) {
  return run_one([&](LssProcedure& p, TimePoint now, LssProcedure::Output& out) {
    return p.inquire_identity(address, now, out);
  });
}

cfg::Result<LssSession::Event> LssSession::set_bit_rate(std::uint8_t table_index, bool store,
                                                        std::uint16_t switch_delay_ms) {
  return run_one([=](LssProcedure& p, TimePoint now, LssProcedure::Output& out) {
    return p.set_bit_rate(table_index, store, switch_delay_ms, now, out);
  });
}

}  // namespace nmt
