// One SDO client on a real bus, one transfer at a time, each run to its end before the call
// returns: for programs that read or write single objects of a running node (`cfgmgr sdo`,
// `cfgmgr store --bus`). The protocol is the core engines': an SdoClient on a node's default
// SDO, or, after connect_via_manager(), an SdoRequestingDevice that asked the network's SDO
// manager (DSP 302 §7) for the channel. This only owns the bus and its event loop.
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
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/sdo/sdo_requesting_device.hpp"

namespace nmt {

/// How the session reaches a node through the SDO manager (connect_via_manager). Built with
/// designated initializers: `slave` has no default.
struct SdoManagerRoute {
  cfg::NodeId own_node_id = *cfg::NodeId::from(127);  ///< the session's node-ID as an SRD
  cfg::NodeId slave;                                  ///< the node to reach
  /// Longest wait for each answer of the manager: the registration (which includes its scan of
  /// node-IDs, DSP 302 §7.2.4), the connection, the release.
  Duration manager_timeout = std::chrono::seconds(10);
  /// Called with one line for people at each step (registered, connected, released); may be
  /// empty.
  std::function<void(const std::string&)> progress{};
};

/// The channel transfers use, for reports.
struct SdoSessionChannel {
  SdoClientConfig config;
  /// Set when the SDO manager granted the channel: the session's node-ID as an SRD and its
  /// client entry (1281h).
  std::optional<cfg::NodeId> srd_node_id{};
  std::uint16_t client_index = 0;
};

class SdoSession {
 public:
  /// Opens the bus at `url` (socketcan:IF, udp://GROUP:PORT; open_bus) with a client of
  /// the channel `config` names. Fails (category Io) when the bus cannot be opened.
  static cfg::Result<std::unique_ptr<SdoSession>> open(const std::string& url,
                                                       SdoClientConfig config);

  SdoSession(const SdoSession&) = delete;
  SdoSession& operator=(const SdoSession&) = delete;
  ~SdoSession();

  /// Reads (index, sub) and returns when the transfer has ended: the value, or the abort code
  /// (the server's, or the client's own, e.g. 0504 0000 when an answer did not come within
  /// options.timeout). An Error (category Io) only when the bus fails.
  cfg::Result<SdoResult> upload(std::uint16_t index, std::uint8_t sub,
                                const SdoTransferOptions& options);
  /// Writes `data` to (index, sub); as upload().
  cfg::Result<SdoResult> download(std::uint16_t index, std::uint8_t sub,
                                  std::vector<std::uint8_t> data,
                                  const SdoTransferOptions& options);

  /// Becomes an SDO requesting device with node-ID route.own_node_id (DSP 302 §7.2.1: boot-up,
  /// 1F10h, the Dynamic SDO Request), waits until the manager registered it, asks for a
  /// connection to route.slave (§7.2.2, 1F00h) and makes it the channel of later transfers.
  /// Fails with category Input when the manager refused (its words: 1F10h error code or SDO
  /// abort), with category Io when no manager answered within route.manager_timeout or the bus
  /// failed. After a failure the session is de-registered again (best effort).
  cfg::Status connect_via_manager(SdoManagerRoute route);
  /// Via the manager: releases the connection and de-registers (1F01h with slave 0), waiting
  /// for the manager's answer up to route.manager_timeout. Does nothing on a default SDO. The
  /// manager releases everything anyway when the session's heartbeat stops (§7.2.1), so a
  /// failure here leaves nothing behind for long.
  cfg::Status close();

  /// The channel transfers use now.
  const SdoSessionChannel& channel() const { return channel_; }

 private:
  SdoSession(std::unique_ptr<Bus> bus, SdoClientConfig config);
  template <class Start>
  cfg::Result<SdoResult> run(Start&& start);
  /// Runs the loop until `done()` holds (checked after each event) or `timeout` passed; false
  /// on timeout. A bus failure is returned as an Error.
  cfg::Result<bool> run_until(const std::function<bool()>& done, Duration timeout);
  /// The first event of `kinds` reported since the last call, removed from the list.
  std::optional<SrdEvent> take_event(std::initializer_list<SrdEvent::Kind> kinds);
  std::optional<SrdEvent> take_event(const std::function<bool(const SrdEvent&)>& wanted);
  cfg::Result<SdoResult> run_srd(
      const std::function<cfg::Result<SdoRequestingDevice::TransferId>(
          SdoRequestingDevice&, TimePoint, SdoRequestingDevice::Output&)>& start);
  void progress(const std::string& line) const;

  std::unique_ptr<Bus> bus_;
  BusEventLoop loop_;
  SdoClient client_;
  EngineRef<SdoClient> ref_;
  std::optional<SdoResult> result_;
  SdoSessionChannel channel_;
  // Via the SDO manager: the SRD, its loop adapter, the events it reported, the route.
  std::unique_ptr<SdoRequestingDevice> srd_;
  std::unique_ptr<EngineRef<SdoRequestingDevice>> srd_ref_;
  std::vector<SrdEvent> srd_events_;
  std::optional<SdoManagerRoute> route_;  ///< set by connect_via_manager
};

}  // namespace nmt
