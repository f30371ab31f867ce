// Reading a live network without changing it: which node-IDs answer, what each device is, and
// the values it holds now. The engine under `cfgmgr scan`, for embedders that back up their
// devices from their own application. An nmt::Engine (nmt/engine.hpp) on an SdoClientMux, one
// client per node: every node is asked at once, each node's uploads one after the other.
//
// Only SDO upload requests leave it (and the abort CiA 301 §7.2.4.3.17 makes a client send when
// a response is overdue): no download, no NMT command, so a running machine keeps running while
// it is scanned.
//
// Per node, in this order:
//  1. probe: 1000h sub 0 (CiA 301 §7.5.2.1, every device has it). Any answer, an abort too, says
//     a device is there. No answer within the SDO timeout: the node-ID is absent. Every node is
//     probed at once, so the absent ones cost one timeout in all, not one each. A probe is
//     repeated (ScanOptions::retries) only for a node-ID the bus showed alive (a heartbeat or
//     boot-up on 700h + node-ID, CiA 301 §7.2.8.3.2): a silent absent node-ID costs no second
//     timeout, a present device whose answer was lost is asked again; a heartbeat of a node-ID
//     already taken as absent brings a new probe while the scan still runs.
//  2. identity: 1018h sub 1-4 (§7.5.2.23); a sub-index the device refuses stays nullopt.
//  3. the EDS the device stores (§7.5.2.20-21, CiA 306 §4.6): 1022h sub 0, and when its value
//     is 0 (ISO 10646, not compressed) 1021h sub 0 by block upload. A device without them
//     answers with an abort, which costs one exchange.
//  4. NodeFound is reported. The application matches the identity against its EDS files and
//     calls read() with the entries to read (none: the node is done). Each entry's value or
//     abort is an EntryRead; NodeScanned ends the node.
//
// Pacing: with ScanOptions::bitrate_bps the requests are spread so that they, their answers and
// the other frames on the bus take at most bus_load_limit of it, the rule of the master's boot
// (BootPacingOptions, docs/master.md "The boot's SDO transfers"): each request counts as itself
// and one answer of the same length at their exact lengths (nmt::frame_bits), frames of other
// nodes count while a request waits.
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <map>
#include <optional>
#include <span>
#include <variant>
#include <vector>

#include "cfg/network.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_abort.hpp"
#include "nmt/sdo/sdo_client.hpp"

namespace nmt {

struct ScanOptions {
  /// Timeout of each response and the largest value accepted (the stored EDS may be large).
  SdoTransferOptions sdo{};
  /// How often an upload that timed out is made again, to a device that answered before (or,
  /// for the probe, whose heartbeat was seen). Other aborts are the device's answer and final.
  unsigned retries = 2;
  /// Read the EDS the device stores (1021h/1022h).
  bool read_stored_eds = true;
  /// The bus bit rate (0: unknown, requests are not paced) and the share of the bus the scan's
  /// requests, their answers and the other frames may take (0.05..1).
  std::uint32_t bitrate_bps = 0;
  double bus_load_limit = 0.97;
};

class NetworkScanner {
 public:
  /// A device answered at `node`: what it is.
  struct NodeFound {
    cfg::NodeId node;
    /// 1000h and 1018h sub 1-4 as read; nullopt where the device refused the entry.
    cfg::DeviceIdentity identity{};
    /// 1022h sub 0 as read (nullopt: the device has none or refused it) and, when it is 0,
    /// the content of 1021h (nullopt: not read or refused).
    std::optional<std::uint16_t> stored_eds_format{};
    std::optional<std::vector<std::uint8_t>> stored_eds{};
    /// Identity entries that were not read (refused, or no answer after the retries).
    std::size_t skipped = 0;
  };
  /// No device answered at `node`.
  struct NodeAbsent {
    cfg::NodeId node;
  };
  /// One entry of read().
  struct EntryRead {
    cfg::NodeId node;
    cfg::ObjectAddress address;
    std::vector<std::uint8_t> data{};  ///< the value, as the device sent it (little-endian)
    SdoAbort abort = SdoAbort::None;   ///< None: read; else why not (last try)
    unsigned attempts = 1;
    bool ok() const { return abort == SdoAbort::None; }
  };
  /// The node's entries are all read (or skipped).
  struct NodeScanned {
    cfg::NodeId node;
    std::size_t read = 0;
    std::size_t skipped = 0;
    /// From the probe's request to the last answer: what this node cost.
    Duration took{0};
  };
  using Event = std::variant<NodeFound, NodeAbsent, EntryRead, NodeScanned>;
  using Output = Outbox<Event>;

  explicit NetworkScanner(ScanOptions options = {});

  /// Begins the scan of `nodes` (duplicates are scanned once); the first probes go into `out`
  /// (as many as the pacing lets go at once). Nodes already scanned are not scanned again.
  void start(std::span<const cfg::NodeId> nodes, TimePoint now, Output& out);

  /// Reads `entries` from a node reported by NodeFound, one after the other; an empty list
  /// ends the node at once (NodeScanned into `out`). Refused for a node that is not waiting
  /// for its entries.
  cfg::Status read(cfg::NodeId node, std::vector<cfg::ObjectAddress> entries, TimePoint now,
                   Output& out);

  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;

  /// Nodes still probed or read, or found and waiting for read().
  std::size_t pending() const { return pending_; }
  /// Every node started is absent or scanned.
  bool finished() const { return pending_ == 0; }

 private:
  enum class Phase : std::uint8_t { Probe, Identity, StoredEds, AwaitingEntries, Entries, Done };
  enum class Purpose : std::uint8_t { Probe, Identity, StoredEdsFormat, StoredEds, Entry };
  struct Upload {
    cfg::ObjectAddress address;
    Purpose purpose = Purpose::Entry;
    unsigned attempts = 1;
  };
  struct Node {
    cfg::NodeId id;
    Phase phase = Phase::Probe;
    std::deque<Upload> todo{};
    std::optional<Upload> running{};
    SdoClient::TransferId transfer = 0;
    bool heard = false;     // a heartbeat or boot-up of this node-ID was seen
    bool answered = false;  // the device answered at least once
    bool absent = false;    // reported NodeAbsent (a heartbeat may bring a new probe)
    bool queued = false;    // in ready_
    NodeFound found{.node = id};
    std::size_t read = 0;
    std::size_t skipped = 0;
    std::optional<TimePoint> began{};
  };

  Node& node(cfg::NodeId id);
  void probe(Node& n);
  void make_ready(Node& n);
  // Starts the uploads that may go now (pacing), then counts what went out.
  void pump(TimePoint now);
  void take(TimePoint now, Output& out);
  void finished_upload(Node& n, Upload upload, SdoResult result, TimePoint now, Output& out);
  void advance(Node& n, TimePoint now, Output& out);
  SdoTransferOptions options_for(Purpose purpose) const;
  Duration paced_time(double bits) const;
  bool paced(TimePoint now) const { return options_.bitrate_bps == 0 || now >= paced_until_; }

  ScanOptions options_;
  SdoClientMux mux_;
  Outbox<SdoResult> sdo_;  // the mux's output in a call, cleared before each use
  std::map<std::uint8_t, Node> nodes_;
  std::deque<std::uint8_t> ready_;  // nodes with an upload to start, in the order they got it
  std::size_t pending_ = 0;
  TimePoint paced_until_{};
};
static_assert(Engine<NetworkScanner>);

}  // namespace nmt
