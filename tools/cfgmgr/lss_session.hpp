// The LSS master (CiA 305, nmt/lss_master.hpp) on a real bus, one service at a time, each run to
// its end before the call returns: what `cfgmgr lss` runs its commands on. The protocol is
// libnmt's LssMaster; this only owns the bus and its event loop. Also the text form of an LSS
// address the commands print and read (`cfgmgr simulate` prints it for unconfigured devices).
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/result.hpp"
#include "nmt/bus.hpp"
#include "nmt/bus_event_loop.hpp"
#include "nmt/lss.hpp"
#include "nmt/lss_master.hpp"

namespace cfgmgr {

/// "7E57C0DE:00000508:00020001:00000101": vendor-ID, product code, revision number, serial
/// number (1018h sub 1-4), each 8 hex digits; what `cfgmgr lss set-id` takes.
std::string lss_address_text(const nmt::LssAddress& address);
/// VENDOR:PRODUCT:REVISION:SERIAL, each part hex with up to 8 digits (0x prefix or h suffix
/// allowed); nullopt for anything else.
std::optional<nmt::LssAddress> parse_lss_address(std::string_view text);

class LssSession {
 public:
  using Event = nmt::LssMasterEvent;
  /// Starts one service (an LssMaster call); its error when it could not start.
  using Start =
      std::function<cfg::Status(nmt::LssMaster&, nmt::TimePoint, nmt::LssMaster::Output&)>;

  /// Opens the bus at `url` (socketcan:IF, udp://GROUP:PORT; nmt::open_bus) with an LSS master
  /// of `options`. Fails (category Io) when the bus cannot be opened.
  static cfg::Result<std::unique_ptr<LssSession>> open(const std::string& url,
                                                       nmt::LssMasterOptions options);
  LssSession(const LssSession&) = delete;
  LssSession& operator=(const LssSession&) = delete;
  ~LssSession();

  /// Starts a service with `start` and runs the loop until it ended: the events it reported,
  /// the one that ended it last. An Error when the service could not start (its words), or
  /// (category Io) when the bus fails.
  cfg::Result<std::vector<Event>> run(const Start& start);
  /// As run(), for services that end with one event: that event.
  cfg::Result<Event> run_one(const Start& start);

 private:
  explicit LssSession(std::unique_ptr<nmt::Bus> bus, nmt::LssMasterOptions options);

  std::unique_ptr<nmt::Bus> bus_;
  nmt::BusEventLoop loop_;
  nmt::LssMaster master_;
  nmt::EngineRef<nmt::LssMaster> ref_;
  std::vector<Event> events_;
};

}  // namespace cfgmgr
