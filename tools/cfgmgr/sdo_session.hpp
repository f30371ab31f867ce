// One SDO client on a real bus, one transfer at a time, each run to its end before the call
// returns: what the cfgmgr commands that read or write single objects of a running node share
// (`cfgmgr sdo`, `cfgmgr store --bus`). The protocol is libnmt's SdoClient; this only owns the
// bus and its event loop.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "cfg/result.hpp"
#include "nmt/bus.hpp"
#include "nmt/bus_event_loop.hpp"
#include "nmt/sdo_client.hpp"

namespace cfgmgr {

class SdoSession {
 public:
  /// Opens the bus at `url` (socketcan:IF, udp://GROUP:PORT; nmt::open_bus) with a client of
  /// the channel `config` names. Fails (category Io) when the bus cannot be opened.
  static cfg::Result<std::unique_ptr<SdoSession>> open(const std::string& url,
                                                       nmt::SdoClientConfig config);

  SdoSession(const SdoSession&) = delete;
  SdoSession& operator=(const SdoSession&) = delete;
  ~SdoSession();

  /// Reads (index, sub) and returns when the transfer has ended: the value, or the abort code
  /// (the server's, or the client's own, e.g. 0504 0000 when an answer did not come within
  /// options.timeout). An Error (category Io) only when the bus fails.
  cfg::Result<nmt::SdoResult> upload(std::uint16_t index, std::uint8_t sub,
                                     const nmt::SdoTransferOptions& options);
  /// Writes `data` to (index, sub); as upload().
  cfg::Result<nmt::SdoResult> download(std::uint16_t index, std::uint8_t sub,
                                       std::vector<std::uint8_t> data,
                                       const nmt::SdoTransferOptions& options);

  /// The channel transfers use from now on (e.g. one a manager granted).
  void use_channel(nmt::SdoClientConfig config);
  /// The loop, for engines that share the bus with the client (added before a transfer runs).
  nmt::BusEventLoop& loop() { return loop_; }

 private:
  SdoSession(std::unique_ptr<nmt::Bus> bus, nmt::SdoClientConfig config);
  template <class Start>
  cfg::Result<nmt::SdoResult> run(Start&& start);

  std::unique_ptr<nmt::Bus> bus_;
  nmt::BusEventLoop loop_;
  nmt::SdoClient client_;
  nmt::EngineRef<nmt::SdoClient> ref_;
  std::optional<nmt::SdoResult> result_;
};

}  // namespace cfgmgr
