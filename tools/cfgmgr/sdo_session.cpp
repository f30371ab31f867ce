#include "sdo_session.hpp"

#include <chrono>
#include <utility>

namespace cfgmgr {

cfg::Result<std::unique_ptr<SdoSession>> SdoSession::open(const std::string& url,
                                                          nmt::SdoClientConfig config) {
  auto bus = nmt::open_bus(url);
  if (!bus) return cfg::Error{bus.error().message, cfg::ErrorCategory::Io};
  return std::unique_ptr<SdoSession>(new SdoSession(std::move(bus).value(), config));
}

SdoSession::SdoSession(std::unique_ptr<nmt::Bus> bus, nmt::SdoClientConfig config)
    : bus_(std::move(bus)), loop_(*bus_), client_(config), ref_(client_) {
  ref_.set_event_handler([this](const nmt::SdoResult& r, nmt::TimePoint) {
    result_ = r;
    loop_.request_stop();
  });
  loop_.add(ref_);
}

SdoSession::~SdoSession() = default;

void SdoSession::use_channel(nmt::SdoClientConfig config) {
  client_ = nmt::SdoClient(config);
}

cfg::Result<nmt::SdoResult> SdoSession::upload(std::uint16_t index, std::uint8_t sub,
                                               const nmt::SdoTransferOptions& options) {
  return run([&](nmt::SdoClient& c, nmt::TimePoint now, nmt::SdoClient::Output& out) {
    return c.upload(index, sub, now, out, options);
  });
}

cfg::Result<nmt::SdoResult> SdoSession::download(std::uint16_t index, std::uint8_t sub,
                                                 std::vector<std::uint8_t> data,
                                                 const nmt::SdoTransferOptions& options) {
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
  return std::move(*result_);
}

}  // namespace cfgmgr
