// The procedures of CiA 305 an LSS master runs, each a chain of the LSS master's services
// (nmt/lss/lss_master.hpp; the protocol and its sources in nmt/lss/lss.hpp), as one engine of the
// shape of nmt/engine.hpp: a procedure is started with `TimePoint now, Output& out` and puts its
// first frames into `out` at once; the next service starts in the call the previous one ended in,
// so a procedure adds no time of its own. Each ends with one Done or Failed event (Scan reports one
// Assigned or Skipped event per device before it). One procedure at a time: a start while one
// runs returns an error that says so and puts nothing into `out` (engine.hpp rule 5).
//
//   LssProcedure lss;
//   lss.find_unconfigured(now, out);             // the addresses of all devices without node-ID
//   lss.assign_node_id(address, node_id, true, now, out);   // one device, by its address
//   lss.scan(chooser, now, out, known);          // Execute LSS: find, configure, store each
//
// Behaviour where CiA 305 leaves room (each says why):
// - Scan first switches every device to LSS waiting, so that no device someone left in
//   configuration takes the node-IDs it hands out. Then Fastscan; the chooser gives the found
//   device its node-ID, configured, stored (LssMasterOptions::store) and then the device is
//   switched back to waiting, where it starts with its node-ID and no longer answers Fastscan. A
//   device the chooser gives none, or whose configure node-ID fails, is switched back
//   unconfigured and the next Fastscan looks above its address, so every device is found once. A
//   device that appears during the scan with an address below one already skipped is not found:
//   scan again. FindUnconfigured is the same walk with no node-ID for anyone.
// - Scan with known addresses (`targets`): first identify non-configured remote slave (4Ch):
//   its silence ends the scan at once (every device has a node-ID: a second push costs 04h, 4Ch
//   and one scan step). Then each target in turn is switched to LSS configuration by switch
//   state selective (40h-43h with its vendor-ID, product code, revision and serial number; only
//   the device with all four answers 44h), so no other device answers anything while it is
//   configured: per device 4 requests and 1 answer instead of the Fastscan confirmation's 5
//   steps, which every unconfigured device of the product answers up to the serial number
//   (about 2 N^2 answers). A configured device answers the selection too, so inquire node-ID
//   (5Eh) asks first: FFh (or no answer) and it gets its node-ID as below; a node-ID and it is
//   switched back untouched, no event, and when a device got its node-ID since the last such
//   question, 4Ch asks again whether any unconfigured device is left (its silence ends the
//   scan: the new device among configured ones costs the others one selection each until
//   it is done, then one 4Ch). A target that does not answer its selection within
//   LssMasterOptions::timeout falls back to LssMaster::fastscan_confirm, whose reset (80h) also
//   tells whether any unconfigured device is left (its silence ends the scan; no further target
//   is tried); an unanswered part ends that target (absent or configured). As selection costs
//   a timeout per absent target and the confirmation none, targets are selected only while
//   they mostly answer: while 2 x absent <= present + 2 (of the targets so far; present: found
//   by either); else confirmed by Fastscan (one absent target among many present ones costs
//   one timeout more than a Fastscan confirmation). When every target is done, the devices
//   left are found bit by bit as above. A target whose configure node-ID failed is left in
//   waiting unconfigured; the bit-by-bit Fastscan finds it again and passes it without a
//   second event. A target absent at its turn that appears later is found bit by bit and gets
//   its node-ID from the chooser.
// - Two devices with one LSS address (CiA 305 takes it to be unique; a factory mistake, a
//   cloned serial number) answer every Fastscan step alike and are in configuration together.
//   A second answer to the scan's configure node-ID, heard while the store waits for its
//   answer, tells: the scan then configures FFh (not configured) and stores it in all of them,
//   switches them back to waiting, and reports the address Skipped (LssScanOutcome::Duplicate);
//   the scan looks past it. It needs LssMasterOptions::store (the default): without the store's
//   wait nothing is listened for. On a real bus two identical answers sent in the same bit
//   time are one frame; then it is not seen (a known limit).
// - A procedure that addresses one device (AssignNodeId, InquireNodeId, InquireIdentity by
//   address) first switches every device to waiting: switch state selective is obeyed in waiting
//   only. A procedure that fails after devices entered LSS configuration switches every device
//   back to waiting before it reports Failed, so none is left in configuration (Scan excepted: a
//   device that stops answering Fastscan midway has not entered it). SetBitRate leaves the
//   devices in configuration after activate bit timing: they switch to the new rate, and a later
//   procedure (or LSS master) switches them back.
#pragma once

#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string_view>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/lss/lss_search.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

/// The procedures of LssProcedure.
enum class LssProcedureKind : std::uint8_t {
  Scan,              ///< every unconfigured device found and given the node-ID a chooser says
  FindUnconfigured,  ///< the addresses of every unconfigured device (Fastscan); none assigned
  AnyUnconfigured,   ///< whether any device has no node-ID (identify non-configured, 4Ch)
  FindProduct,       ///< every device of one product, configured or not (identify remote slave)
  AssignNodeId,      ///< one device, by its address: configure node-ID, store
  InquireNodeId,     ///< one device, by its address: its active node-ID
  InquireIdentity,   ///< one device, by its address or the only one: its LSS address, node-ID
  SetBitRate,        ///< every device: configure bit timing, store, activate bit timing
};
std::string_view to_string(LssProcedureKind procedure);  ///< "scan", "assign node-ID", ...

/// How a procedure went, as typed facts; the words for people are describe(event)
/// (nmt/lss/lss_event_text.hpp).
struct LssProcedureEvent {
  enum class Kind : std::uint8_t {
    Assigned,  ///< Scan: a found device got `node_id` (stored unless `outcome` says why not)
    Skipped,   ///< Scan: a found device was left without node-ID (`outcome` says why)
    Done,      ///< the procedure ended as asked; its results in the fields below
    /// A service ended otherwise than asked: `step` is its event (the service, Refused with the
    /// CiA 305 error code, Timeout, NotFound; Done when the answer is one CiA 305 does not
    /// allow, e.g. inquire node-ID 0).
    Failed,
  };
  LssProcedureKind procedure = LssProcedureKind::Scan;
  Kind kind = Kind::Done;
  TimePoint at{};
  /// Assigned/Skipped: the device; AssignNodeId, InquireNodeId: the address asked for;
  /// InquireIdentity: the address the device answered.
  LssAddress address{};
  /// Assigned, AssignNodeId: the node-ID given (AssignNodeId: nullopt for FFh);
  /// InquireNodeId, InquireIdentity: the active node-ID (nullopt: FFh, not configured).
  std::optional<cfg::NodeId> node_id;
  /// AssignNodeId: the node-ID the device answered inquire node-ID with before the configure
  /// (FFh: it had none, and boots with the new one when back in waiting; else it takes the new
  /// one at its next NMT reset); nullopt when it did not answer.
  std::optional<std::uint8_t> previous_node_id;
  /// FindUnconfigured, FindProduct: the addresses found, ascending.
  std::vector<LssAddress> addresses;
  /// Scan: the devices found (assigned and skipped); AnyUnconfigured: 1 when any answered.
  std::uint32_t found = 0;
  /// Assigned/Skipped: what became of the device; AssignNodeId Done: Stored, or
  /// NotStoredAsAsked when the store was not asked for.
  std::optional<LssScanOutcome> outcome;
  /// Assigned/Skipped: the error code of store configuration or configure node-ID when it
  /// refused (0: none), and the manufacturer-specific error with code FFh.
  std::uint8_t error_code = 0;
  std::uint8_t spec_error = 0;
  /// Failed: the event of the service that ended the procedure (none: the procedure could not
  /// start). Assigned/Skipped: the event of the service that refused or went unanswered
  /// (configure node-ID, store configuration), none when every service went as asked.
  std::optional<LssMasterEvent> step;

  bool ok() const { return kind == Kind::Done || kind == Kind::Assigned; }
};

class LssProcedure {
 public:
  using Event = LssProcedureEvent;
  using Output = Outbox<Event>;
  /// Scan: the node-ID a found device gets (1..127), or nullopt to leave it unconfigured.
  using NodeIdChooser = std::function<std::optional<cfg::NodeId>(const LssAddress&)>;

  /// The services' timing (and Scan's store) of `options`.
  explicit LssProcedure(LssMasterOptions options = {}) : lss_(options) {}

  // --- procedures: could not start (another one runs): an error that says why, nothing sent,
  // no event (engine.hpp rule 5) --------------------------------------------------------------
  /// Finds every unconfigured device one by one and gives each the node-ID `chooser` says (see
  /// the top); one Assigned or Skipped event per device, then Done (`found`) or, when a device
  /// stopped answering Fastscan midway, Failed. `targets` are tried first, in order, each by
  /// switch state selective (see the top).
  cfg::Status scan(NodeIdChooser chooser, TimePoint now, Output& out,
                   std::vector<LssAddress> targets = {});
  /// The addresses of every unconfigured device, each left unconfigured in waiting: Done with
  /// `addresses`, or Failed when a device stopped answering Fastscan midway.
  cfg::Status find_unconfigured(TimePoint now, Output& out);
  /// Identify non-configured remote slave (4Ch): Done, `found` 1 when any device without
  /// node-ID answered within the scan step, 0 when none did.
  cfg::Status any_unconfigured(TimePoint now, Output& out);
  /// Every device of the product, configured or not (LssAddressSearch, nmt/lss/lss_search.hpp):
  /// Done with `addresses`.
  cfg::Status find_product(std::uint32_t vendor_id, std::uint32_t product_code, TimePoint now,
                           Output& out);
  /// Gives the device with `address` the node-ID `node_id` (nullopt: FFh, not configured):
  /// switch state selective, inquire node-ID (`previous_node_id`), configure node-ID, store
  /// configuration when `store`, back to waiting. Done, or Failed (the device did not answer
  /// the selection, or refused).
  cfg::Status assign_node_id(const LssAddress& address, std::optional<cfg::NodeId> node_id,
                             bool store, TimePoint now, Output& out);
  /// The active node-ID of the device with `address`: switch state selective, inquire node-ID,
  /// back to waiting.
  cfg::Status inquire_node_id(const LssAddress& address, TimePoint now, Output& out);
  /// The LSS address and active node-ID of the device with `address`, or without it of every
  /// device switched to configuration (use it with one LSS device on the bus only): inquire
  /// vendor-ID, product code, revision, serial number, node-ID, back to waiting.
  cfg::Status inquire_identity(std::optional<LssAddress> address, TimePoint now, Output& out);
  /// Every device to the bit rate of `table_index` (table selector 0; lss::bit_timing_index):
  /// switch state global to configuration, configure bit timing, store configuration when
  /// `store`, activate bit timing with `switch_delay_ms`; Done twice the delay after it.
  cfg::Status set_bit_rate(std::uint8_t table_index, bool store, std::uint16_t switch_delay_ms,
                           TimePoint now, Output& out);

  // --- engine --------------------------------------------------------------------------------
  /// True for answers (8-byte frames on 7E4h) the running procedure waited for.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const { return lss_.next_deadline(); }

  bool busy() const { return run_.has_value(); }
  const LssMasterOptions& options() const { return lss_.options(); }

 private:
  enum class Step : std::uint8_t {
    Search,           // Scan, FindUnconfigured: a Fastscan runs
    Check,            // Scan with targets: identify non-configured remote slave (4Ch)
    SelectTarget,     // Scan: switch state selective of a target
    InquireTarget,    // Scan: inquire node-ID of the selected target
    Configure,        // Scan: configure node-ID of the device found
    Store,            // Scan: its store configuration
    Unconfigure,      // Scan: FFh configured again after a duplicate LSS address
    Unstore,          // Scan: and stored
    Probe,            // AnyUnconfigured: identify non-configured remote slave
    Identify,         // FindProduct: identify remote slave of the search's next range
    Select,           // switch state selective
    InquireBefore,    // AssignNodeId: inquire node-ID before the configure
    ConfigureId,      // AssignNodeId: configure node-ID
    StoreId,          // AssignNodeId: store configuration
    Inquire,          // InquireNodeId, InquireIdentity: the inquiry `inquiry`
    ConfigureTiming,  // SetBitRate: configure bit timing
    StoreTiming,      // SetBitRate: store configuration
    Activate,         // SetBitRate: activate bit timing
  };
  struct Running {
    LssProcedureKind kind = LssProcedureKind::Scan;
    Step step = Step::Search;
    LssAddress address;                  // the device asked for, found, or answered
    std::optional<LssAddress> selected;  // InquireIdentity: the address given
    std::optional<cfg::NodeId> node_id;  // the node-ID to give, chosen or answered
    std::optional<std::uint8_t> previous_node_id;
    bool store = true;
    std::uint8_t table_index = 0;
    std::uint16_t switch_delay_ms = 0;
    int inquiry = 0;  // InquireIdentity: vendor-ID .. node-ID
    std::optional<LssAddressSearch> search;
    // Scan, FindUnconfigured.
    NodeIdChooser chooser;
    std::optional<LssAddress> cursor;  // the highest address skipped
    std::uint32_t found = 0;
    std::vector<LssAddress> addresses;
    std::vector<LssAddress> targets;  // known addresses, confirmed before the bit-by-bit search
    std::size_t next_target = 0;
    bool confirming = false;      // the device being dealt with is a target
    std::uint32_t present = 0;    // targets found (selected or confirmed)
    std::uint32_t absent = 0;     // targets not found
    bool check_due = false;       // a device got its node-ID since 4Ch or 80h was last answered
    std::set<LssAddress> failed;  // targets whose configure node-ID failed (reported once)
    bool duplicate = false;       // a second device answered this device's configure node-ID
  };

  cfg::Status begin(LssProcedureKind kind);
  void forward(TimePoint now, Output& out);
  void handle(const LssMasterEvent& e, TimePoint now, Output& out);
  void switch_all(LssState state, TimePoint now);
  void select(const LssAddress& address, TimePoint now);
  void inquire_next(TimePoint now);
  void identify_next(TimePoint now, Output& out);
  void done(Event e, Output& out);
  void failed(const LssMasterEvent& step, bool to_waiting, TimePoint now, Output& out);
  void after_inquiry(const LssMasterEvent& e, TimePoint now, Output& out);
  void search_next(TimePoint now);
  void search_event(const LssMasterEvent& e, TimePoint now, Output& out);
  void device_found(const LssAddress& address, TimePoint now, Output& out);
  /// A scan's device ends Assigned or Skipped with `outcome`; `step` the event of the service
  /// the device refused or did not answer, nullopt when none.
  void device_done(Event::Kind kind, LssScanOutcome outcome, std::optional<LssMasterEvent> step,
                   TimePoint now, Output& out);
  void scan_event(const LssMasterEvent& e, TimePoint now, Output& out);
  void target_event(const LssMasterEvent& e, TimePoint now, Output& out);
  void check_unconfigured(TimePoint now);
  void scan_done(TimePoint now, Output& out);
  Event event(Event::Kind kind, TimePoint now) const;

  LssMaster lss_;
  LssMaster::Output lss_out_;  ///< scratch output of lss_
  std::optional<Running> run_;
};
static_assert(Engine<LssProcedure>);

}  // namespace nmt
