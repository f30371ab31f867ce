// NMT flying master start-up and the watch over the active master (CiA 302-2 §3.7, §5.2-§5.5),
// and NMT master detection (§5.1) for self-starting devices and master-capable ones, as one
// engine of the shape of nmt/engine.hpp. Private to the library. The COB-IDs and bytes are
// DSP 302 §5.5's (Figures 15-19: 71h-76h), which the 302-2 text lacks; the choices where the
// spec leaves room are listed in docs/master.md.
//
// The engine owns its state (the phase of the start-up, the active master it knows, the force
// it sent, the detection of §5.1) and talks to the NMT master only through FlyingMasterPort:
// "this device is the active master now" (§3.7 h: NMT start-up goes on), "this device resets
// its communication" (boot-up and start-up again, warm), "reset communication of all nodes"
// (§3.1 d's keep-alive rule is the master's), "queue an NMT command", "obey this NMT command as
// a slave", "the start-up state is now ...", and the reads it needs of the master's dictionary
// that may change while it runs (1F80h bit 0, 1016h, 1017h). Its own node-ID is given at
// construction, 1F90h at start() (and again by set_timing() when 1F90h is written), 1F91h when
// a detection starts (and by set_detection_timing()).
//
// Its events are the master's own (MasterEvent: NegotiationBegan, ActiveMaster, Standby,
// ForceNegotiation, MultipleMasters, ActiveMasterLost, MasterDetection), so the master routes
// frames and time to it with its own Output and nothing is translated or reordered.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "cfg/node_id.hpp"
#include "nmt/engine.hpp"
#include "nmt/master/nmt_master.hpp"

namespace nmt {

/// 1F90h (CiA 302-2 §6.13), in the units of the engine.
struct FlyingTiming {
  Duration timeout;        ///< sub 1: answer of the active master
  Duration delay;          ///< sub 2: before the detection
  std::uint16_t priority;  ///< sub 3: 0 high .. 2 low
  Duration priority_slot;  ///< sub 4
  Duration node_slot;      ///< sub 5
  Duration cycle;          ///< sub 6: multiple master detection (0: off)
};

/// 1F91h (CiA 302-2 §6.14, DSP 302 §5.5.6), in the units of the engine.
struct DetectionTiming {
  Duration timeout;    ///< sub 1: answer (74h) of a master-capable device
  Duration delay;      ///< sub 2: after entering pre-operational, before the request (75h)
  Duration node_slot;  ///< sub 3: x node-ID before starting all nodes
};

/// What the flying master needs of the NMT master that holds it.
class FlyingMasterPort {
 public:
  using Output = Outbox<MasterEvent>;
  virtual ~FlyingMasterPort() = default;

  /// §3.7 h: this device won (or the master decision goes on): NMT start-up of the master.
  virtual void became_active(TimePoint now, Output& out) = 0;
  /// The master's StartupState follows the flying master (Negotiating, Standby).
  virtual void set_startup(StartupState state) = 0;
  /// A reset communication of this device: its boot-up and NMT start-up again at `now`.
  virtual void restart(TimePoint now) = 0;
  /// Reset communication of all nodes as §3.1 d words it (the master knows the keep-alives).
  virtual void reset_all_nodes() = 0;
  /// An NMT command for the master's NMT command queue.
  virtual void queue_nmt(NmtCommand command, NmtTarget target) = 0;
  /// An NMT command for this device while another master is (or may become) the active one:
  /// it obeys as an NMT slave.
  virtual void obey(NmtCommand command, TimePoint now, Output& out) = 0;
  /// 1F80h bit 0: this device is capable of the NMT master mode (answers 75h, §5.1).
  virtual bool master_capable() const = 0;
  /// 1016h: the heartbeat consumer time for `node`; nullopt when not consumed.
  virtual std::optional<Duration> heartbeat_time(cfg::NodeId node) const = 0;
  /// 1017h in ms: this device's own heartbeat period (0: none).
  virtual std::uint32_t own_heartbeat_ms() const = 0;
};

class FlyingMasterProcess {
 public:
  using Event = MasterEvent;
  using Output = Outbox<MasterEvent>;

  enum class Phase : std::uint8_t {
    Off,        // 1F80h bit 5 clear, or not a master
    Delay,      // §3.7 b: the negotiation time delay (1F90h sub 2)
    Detect,     // §3.7 c: 73h sent, a 71h within 1F90h sub 1
    Negotiate,  // §5.3: 72h seen, own waiting time running
    Forced,     // §3.7 g/i: 76h sent, waiting for the active master's reset communication
    Active,     // this device is the NMT master
    Standby,    // an NMT slave watching the active master's heartbeat
  };

  FlyingMasterProcess(cfg::NodeId node, FlyingMasterPort& port) : node_(node), port_(port) {}
  FlyingMasterProcess(const FlyingMasterProcess&) = delete;
  FlyingMasterProcess& operator=(const FlyingMasterProcess&) = delete;

  /// §3.1 b with 1F80h bit 5: flying master start-up (§3.7 b: the negotiation time delay
  /// first). After a reset communication of this device (on_frame, on_timer) it starts warm.
  void start(const FlyingTiming& timing, TimePoint now, Output& out);
  /// Not a flying master (1F80h bit 0 or 5 clear): Off, everything forgotten.
  void stop();
  /// 1F90h was written: the values the next steps use.
  void set_timing(const FlyingTiming& timing) { timing_ = timing; }

  /// §5.1: a self-starting device with 1F80h bit 1 starts all nodes only when no
  /// master-capable device answers (with 1F91h; without it, at once).
  void detect_master(std::optional<DetectionTiming> timing, TimePoint now);
  /// No detection (the device is not self-starting, or start-up begins again).
  void stop_detection() { detection_ = {}; }
  /// 1F91h was written: the values the next steps of a detection use.
  void set_detection_timing(const DetectionTiming& timing) { detection_.timing = timing; }

  /// Frames of the flying master protocols, of master detection and the NMT commands a
  /// standby master obeys; true when the frame was taken.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;

  Phase phase() const { return flying_.phase; }
  /// False while a flying master is not the active one (standby or negotiating).
  bool acts_as_master() const {
    return flying_.phase == Phase::Off || flying_.phase == Phase::Active;
  }
  /// Active or Standby: the active master's node-ID; else nullopt.
  std::optional<cfg::NodeId> active_master() const;

 private:
  /// §3.7 and §5.2-§5.5.
  struct Flying {
    Phase phase = Phase::Off;
    bool warm = false;  ///< this start came from a reset communication (§3.7 d/e)
    std::optional<TimePoint> deadline;
    std::optional<TimePoint> cycle_due;  ///< Active: the next 76h (1F90h sub 6)
    std::optional<cfg::NodeId> active;   ///< the active master, nullopt: none known
    std::uint16_t active_priority = 0;
    std::optional<TimePoint> heartbeat_due;  ///< Standby: the active master's heartbeat by then
    std::optional<Duration> watch;           ///< Standby: its heartbeat consumer time
    bool forced = false;       ///< sent 76h since it last stood by or won (DSP 302 §5.5.2 hint)
    unsigned force_tries = 0;  ///< 76h sent in a row without the reset they ask for
  };
  /// §5.1, DSP 302 §5.5.3.1, 1F91h: is there a device that will be the master?
  struct Detection {
    enum class Phase : std::uint8_t {
      Off,
      Delay,   // 1F91h sub 2 after entering pre-operational
      Detect,  // 75h sent, a 74h within sub 1
      Wait,    // no answer: node-ID x sub 3, then start all nodes
    };
    Phase phase = Phase::Off;
    std::optional<TimePoint> deadline;
    DetectionTiming timing{};
  };

  bool detection_frame(const CanFrame& frame, TimePoint now, Output& out);
  void detection_timer(TimePoint now, Output& out);
  void restart(TimePoint now);
  void wait(TimePoint now, Output& out, FlyingMasterReason why);
  void win(TimePoint now, Output& out);
  void standby(cfg::NodeId node, std::uint16_t priority, TimePoint now, Output& out,
               FlyingMasterReason why);
  void force(TimePoint now, Output& out, cfg::NodeId node, std::uint16_t priority);
  void master_response(std::uint16_t priority, cfg::NodeId node, TimePoint now, Output& out);

  cfg::NodeId node_;
  FlyingMasterPort& port_;
  FlyingTiming timing_{};
  Flying flying_;
  Detection detection_;
};

static_assert(Engine<FlyingMasterProcess>);

}  // namespace nmt
