// The LSS master of CiA 305 (nmt/lss/lss.hpp has the protocol and its sources), an engine of the
// shape of nmt/engine.hpp: services are started with `TimePoint now, Output& out` and put their
// first frames into `out` at once; each ends with one LssMasterEvent. One service at a time: a
// start while one runs returns an error that says so and puts nothing into `out` (engine.hpp rule
// 5).
//
//   LssMaster master;
//   master.switch_state_selective(address, now, out);   // 40h..43h, answer 44h
//   master.configure_node_id(cfg::NodeId::from(5), now, out);  // 11h, answer 11h + error code
//   master.store_configuration(now, out);               // 17h
//   master.switch_state_global(LssState::Waiting, now, out);
//   master.fastscan(now, out);                          // 51h: the lowest unconfigured device
//   master.fastscan_confirm(known, now, out);           // 51h: a known address in 4 requests
// The procedures of CiA 305 that chain these services (find and configure every unconfigured
// device, give one device its node-ID, set the bit rate) are nmt/lss/lss_procedure.hpp's.
//
// Behaviour where CiA 305 leaves room (each says why):
// - Services one device answers (switch state selective, configure, store, inquire) end at the
//   answer or after LssMasterOptions::timeout. Services many devices may answer at once
//   (identify remote slave, identify non-configured remote slave, each Fastscan step) end when
//   LssMasterOptions::scan_step has passed since the request and since the last answer: a
//   slower device's answer cannot be taken for the answer to the next request (LSS answers
//   carry no address), and many devices answering one after another on the bus are all heard.
// - Switch state global has no answer (python-canopen, CANopenNode): it ends at once.
//   Activate bit timing ends after twice the switch delay: CiA 305 has the devices stay silent
//   for the delay, switch, and stay silent for the delay again, so the master sends nothing
//   before that.
// - Frames of one request (switch state selective, identify remote slave) are handed out back
//   to back; the driver's transmit queue paces them.
// - Fastscan queries each bit with the bit 0 and reads no answer as 1 (lely-core), 32 queries
//   and a confirmation per part: 1 + 4 x 33 = 133 requests find one device. It finds the lowest
//   unconfigured LSS address (ordered as LssAddress), or with `after` the lowest above it: it
//   probes, from the deepest bit up, the branches of `after`'s address that hold higher
//   addresses. A device that stops answering in the middle ends the scan with Timeout.
// - Fastscan of a known address (fastscan_confirm): Fastscan with BitCheck 0 compares all 32
//   bits of part LSSSub, and a device whose part matches answers and moves on to part LSSNext; a
//   match of the serial number with LSSNext < LSSSub puts it in LSS configuration (CiA 305
//   Fastscan; read in CANopenNode 305/CO_LSSslave.c, which answers BitCheck 80h always and
//   otherwise only when LSSSub is its position and the bits BitCheck..31 match, and whose master,
//   CO_LSSmaster.h CO_LSSmaster_FS_MATCH, confirms a part it is given instead of scanning it;
//   lely-core src/co/lss.c's slave keeps such a position, lsspos; our LssSlave::fastscan compares
//   the same way). So a known address is confirmed in 4 requests instead of 128 bit queries:
//   first the reset (BitCheck 80h), which tells whether any unconfigured device is left (no
//   answer: NotFound), then part 0..3 with BitCheck 0 and LSSNext the next part (0 after the
//   serial number). A missing answer ends it after one scan step with Absent (its device is
//   absent or configured; the devices that matched the parts before stay there until the next
//   reset brings every unconfigured device back to part 0); all 4 answered: Done, the device is
//   in LSS configuration.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

enum class LssService : std::uint8_t {
  SwitchStateGlobal,
  SwitchStateSelective,
  ConfigureNodeId,
  ConfigureBitTiming,
  ActivateBitTiming,
  StoreConfiguration,
  InquireVendorId,
  InquireProductCode,
  InquireRevision,
  InquireSerial,
  InquireNodeId,
  IdentifyRemoteSlaves,
  IdentifyNonConfigured,
  Fastscan,
};
std::string_view to_string(LssService service);  ///< "configure node-ID", ...

/// What became of a device given a node-ID (CiA 305 configure node-ID, store configuration): an
/// LssProcedure scan's Assigned or Skipped event, or its AssignNodeId's Done
/// (nmt/lss/lss_procedure.hpp; in words: nmt/lss/lss_event_text.hpp).
enum class LssScanOutcome : std::uint8_t {
  Stored,                   ///< Assigned: node-ID configured and stored
  NotStoredAsAsked,         ///< Assigned: configured, not stored (LssMasterOptions::store)
  StoreRefused,             ///< Assigned: store configuration answered `error_code`
  StoreUnanswered,          ///< Assigned: no answer to store configuration within the timeout
  ConfigureRefused,         ///< Skipped: configure node-ID answered `error_code`
  ConfigureUnanswered,      ///< Skipped: no answer to configure node-ID within the timeout
  Duplicate,                ///< Skipped: more than one device answered with the LSS address
  DuplicateUndoUnanswered,  ///< Skipped: as Duplicate, and undoing its node-ID got no answer
  NoNodeId,                 ///< Skipped: the chooser gave no node-ID for it
};

/// How a service ended, as typed facts; the words for people are describe(event)
/// (nmt/lss/lss_event_text.hpp).
struct LssMasterEvent {
  enum class Kind : std::uint8_t {
    Done,      ///< the service ended as asked (Identify*: a device answered; Fastscan: found)
    NotFound,  ///< Identify* / Fastscan: no device answered in its time (an answer, not a fault)
    Refused,   ///< the device answered with an error code (`error_code`, `spec_error`)
    Timeout,   ///< no answer within the timeout (Fastscan: a device stopped answering midway)
    Absent,    ///< fastscan_confirm: unconfigured devices answered the reset, not that address
  };
  LssService service = LssService::SwitchStateGlobal;
  Kind kind = Kind::Done;
  TimePoint at{};
  LssAddress address{};     ///< Fastscan, switch state selective: the device's LSS address
  std::uint32_t value = 0;  ///< inquire: the value (InquireNodeId: the node-ID)
  /// ConfigureNodeId: the node-ID (nullopt for FFh, not configured)
  std::optional<cfg::NodeId> node_id;
  /// Refused: the error code of the answer (configure node-ID, configure bit timing, store
  /// configuration; CiA 305 as nmt/lss/lss.hpp cites it) and, for FFh, the manufacturer's code.
  std::uint8_t error_code = 0;
  std::uint8_t spec_error = 0;
  /// Fastscan Timeout of a device that stopped answering: the part (0..3) of its address.
  std::uint8_t part = 0;
  /// SwitchStateGlobal: the state every device was switched to.
  LssState state = LssState::Waiting;
  /// Timeout of a service one device answers: how long the master waited for the answer
  /// (LssMasterOptions::timeout); zero for Fastscan, whose steps end by the scan step.
  Duration timeout{};
  /// Fastscan NotFound of a scan above an address (fastscan(after)) that unconfigured devices
  /// answered: that address, none of them is above it. Nullopt when no unconfigured device
  /// answered the reset.
  std::optional<LssAddress> after;

  bool ok() const { return kind == Kind::Done; }
};

struct LssMasterOptions {
  /// Longest wait for the answer of a service one device answers.
  Duration timeout = std::chrono::milliseconds(100);
  /// The time a step of a service many devices may answer lasts (identify, each Fastscan
  /// request): from the request and from each answer. Choose it above the devices' answer time
  /// and the air time of all devices' answers (at 125 kbit/s one LSS frame takes about 1 ms).
  Duration scan_step = std::chrono::milliseconds(10);
  /// LssProcedure::scan (nmt/lss/lss_procedure.hpp): store each assigned node-ID (17h) before
  /// switching the device back.
  bool store = true;
};

/// The identify remote slave range: vendor-ID and product code exact, revision and serial
/// number ranges with both bounds included.
struct LssAddressRange {
  std::uint32_t vendor_id = 0;
  std::uint32_t product_code = 0;
  std::uint32_t revision_low = 0;
  std::uint32_t revision_high = 0xFFFFFFFF;
  std::uint32_t serial_low = 0;
  std::uint32_t serial_high = 0xFFFFFFFF;
};

class LssMaster {
 public:
  using Event = LssMasterEvent;
  using Output = Outbox<Event>;

  explicit LssMaster(LssMasterOptions options = {}) : options_(options) {}

  // --- services: could not start (another service runs; inquire of a service that is not an
  // inquiry): an error that says why, nothing sent, no event (engine.hpp rule 5) -----------
  cfg::Status switch_state_global(LssState state, TimePoint now, Output& out);
  cfg::Status switch_state_selective(const LssAddress& address, TimePoint now, Output& out);
  /// The node-ID (1..127), or nullopt: FFh, back to unconfigured (CiA 305).
  cfg::Status configure_node_id(std::optional<cfg::NodeId> node_id, TimePoint now, Output& out);
  /// `table_index` of table selector 0 (lss::bit_timing_index gives it for a rate).
  cfg::Status configure_bit_timing(std::uint8_t table_index, TimePoint now, Output& out,
                                   std::uint8_t table_selector = 0);
  cfg::Status activate_bit_timing(std::uint16_t switch_delay_ms, TimePoint now, Output& out);
  cfg::Status store_configuration(TimePoint now, Output& out);
  /// One of InquireVendorId .. InquireNodeId (others: an error, nothing sent, no event).
  cfg::Status inquire(LssService what, TimePoint now, Output& out);
  cfg::Status identify_remote_slaves(const LssAddressRange& range, TimePoint now, Output& out);
  cfg::Status identify_non_configured(TimePoint now, Output& out);
  /// Finds one unconfigured device (the lowest address, above `after` when given) and leaves it
  /// in LSS configuration: Done with its address, or NotFound.
  cfg::Status fastscan(std::optional<LssAddress> after, TimePoint now, Output& out);
  cfg::Status fastscan(TimePoint now, Output& out) { return fastscan(std::nullopt, now, out); }
  /// Fastscan for the known address `address` (see the top): Done with it (the device is in LSS
  /// configuration), Absent (not that device), or NotFound (no unconfigured device answered).
  cfg::Status fastscan_confirm(const LssAddress& address, TimePoint now, Output& out);

  // --- engine --------------------------------------------------------------------------------
  /// True for answers (8-byte frames on 7E4h) the running service waited for.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const { return deadline_; }

  bool busy() const { return service_.has_value(); }
  const LssMasterOptions& options() const { return options_; }
  void set_options(LssMasterOptions options) { options_ = options; }

 private:
  enum class Wait : std::uint8_t { Answer, Collect, Delay };
  enum class Step : std::uint8_t { Reset, Position, Probe, Descend, Confirm, Target };
  struct FastscanState {
    std::optional<LssAddress> after;
    bool confirm = false;  // fastscan_confirm: `id` is the known address
    LssAddress id;
    Step step = Step::Reset;
    int sub = 0;       // Descend/Confirm: the part being found; Target: the part confirmed
    int bit = 31;      // Descend: the bit queried
    int level = 3;     // Position/Probe: the part whose branches are probed
    int position = 0;  // Position: the part being confirmed
  };

  cfg::Status start(LssService service);
  void await(lss::Cs cs, Wait wait, Duration d, TimePoint now);
  void finish(Event event, Output& out);
  void answered(const CanFrame& frame, TimePoint now, Output& out);
  void step_ended(TimePoint now, Output& out);
  void timed_out(TimePoint now, Output& out);
  Event event(LssService service, LssMasterEvent::Kind kind, TimePoint now) const;

  void send_fastscan(std::uint32_t id, int bit_check, int sub, int next, Output& out,
                     TimePoint now);
  void fastscan_start(TimePoint now, Output& out);
  void fastscan_step(bool answer, TimePoint now, Output& out);
  void fastscan_probe(TimePoint now, Output& out, int from_bit);
  void fastscan_descend(TimePoint now, Output& out);
  void fastscan_target(TimePoint now, Output& out);
  // The Fastscan's end; Done and Absent carry the address.
  Event fastscan_event(LssMasterEvent::Kind kind, TimePoint now) const;

  LssMasterOptions options_;
  std::optional<LssService> service_;
  std::optional<TimePoint> deadline_;
  Wait wait_ = Wait::Answer;
  lss::Cs expect_{};
  bool heard_ = false;                  // Collect: an answer came in this step
  std::optional<cfg::NodeId> node_id_;  // configure node-ID: the node-ID asked for (nullopt: FFh)
  FastscanState fs_;
};
static_assert(Engine<LssMaster>);

}  // namespace nmt
