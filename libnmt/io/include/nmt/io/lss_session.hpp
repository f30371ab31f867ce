// The CiA 305 procedures (nmt/lss/lss_procedure.hpp) on a real bus, one at a time, each run to its
// end before the call returns: for programs that find devices without node-ID, give one its
// node-ID or set the bit rate of a running bus (`cfgmgr lss`). The protocol is the core's
// LssProcedure over its LssMaster; this only owns the bus and its event loop, as SdoSession
// (nmt/io/sdo_session.hpp) does for SDO.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/lss/lss_procedure.hpp"

namespace nmt {

class LssSession {
 public:
  using Event = LssProcedureEvent;
  /// Starts one procedure (an LssProcedure call); its error when it could not start.
  using Start = std::function<cfg::Status(LssProcedure&, TimePoint, LssProcedure::Output&)>;

  /// Opens the bus at `url` (socketcan:IF, udp://GROUP:PORT; open_bus) with LSS services of
  /// `options`' timing. Fails (category Io) when the bus cannot be opened.
  static cfg::Result<std::unique_ptr<LssSession>> open(const std::string& url,
                                                       LssMasterOptions options);
  LssSession(const LssSession&) = delete;
  LssSession& operator=(const LssSession&) = delete;
  ~LssSession();

  /// Starts a procedure with `start` and runs the loop until it ended: the events it reported,
  /// the one that ended it (Done or Failed) last. An Error when the procedure could not start
  /// (its words), or (category Io) when the bus fails or it did not end within 10 minutes.
  cfg::Result<std::vector<Event>> run(const Start& start);
  /// As run(): the event that ended the procedure.
  cfg::Result<Event> run_one(const Start& start);

  // The procedures of LssProcedure, each run to its end (as run_one; a device's refusal or
  // silence is a Failed event, not an Error).
  cfg::Result<Event> find_unconfigured();
  cfg::Result<Event> find_product(std::uint32_t vendor_id, std::uint32_t product_code);
  cfg::Result<Event> assign_node_id(const LssAddress& address, std::optional<cfg::NodeId> node_id,
                                    bool store);
  cfg::Result<Event> inquire_node_id(const LssAddress& address);
  cfg::Result<Event> inquire_identity(std::optional<LssAddress> address);
  cfg::Result<Event> set_bit_rate(std::uint8_t table_index, bool store,
                                  std::uint16_t switch_delay_ms);

 private:
  LssSession(std::unique_ptr<Bus> bus, LssMasterOptions options);

  std::unique_ptr<Bus> bus_;
  BusEventLoop loop_;
  LssProcedure procedure_;
  EngineRef<LssProcedure> ref_;
  std::vector<Event> events_;
};

}  // namespace nmt
