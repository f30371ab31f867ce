// A simulated CANopen slave built from any EDS/DCF: its own runtime dictionary, NMT slave, SDO
// server, heartbeat producer/consumer or node/life guarding, EMCY, the PDO parameter rules real
// devices enforce, parameter storage (1010h/1011h/1020h) and program download (1F50h-1F52h),
// plus fault injection. Sans-I/O like every engine here:
//   device.power_on(now);                    // boot-up follows after the boot delay
//   device.on_frame(frame, now, out);        // frames to send are appended to `out`
//   device.on_timer(now, out);               // call when now >= device.next_deadline()
// It runs on the simulated bus (SimulatedDeviceNode below) and on real buses (BusEventLoop).
//
// Behaviour where CiA 301 leaves room (chosen after what common devices do; each says why):
// - Stored parameters are the writable entries except 1010h, 1011h and the program objects
//   1F50h-1F57h (the program lives in its own memory). 1010h/1011h sub 1 = all, 2 = 1000h-1FFFh,
//   3 = 6000h-9FFFh, 4 = 2000h-5FFFh, other sub-indices = all.
// - Every successful SDO write of a stored parameter other than 1020h sets 1020h sub 1 and 2 to 0,
//   even when the value is unchanged (CiA 302 §6.3 / DSP 302 §6.3: the device "has to reset the
//   object Verify Configuration to 0" when boot-up configuration values change; a configuration
//   manager writes 1020h last).
// - PDO mapping writes while the PDO is valid, and mapping entry writes while mapping sub 0 is
//   not 0, abort with 0800 0022 (device state), as e.g. Turck and Bonfiglioli manuals document.
// - 1F52h (verify application software) is served as the device file declares it: SDO writes
//   follow its AccessType (0601 0002 when ro/const). A file that declares 1F50h/1F51h but no 1F52h
//   gets none (the object is optional; real devices, e.g. Nanotec CL4-E, omit it), so a master
//   reading it sees 0602 0000. A download of program 1 sets it from
//   SimulatedDeviceOptions::downloaded_program_version, or leaves it unchanged when that is unset.
//   Like 1F50h-1F57h as a whole, it lives in program memory: resets and power cycles keep it.
#pragma once

#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <random>
#include <string>
#include <vector>

#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"
#include "nmt/emcy.hpp"
#include "nmt/error_control.hpp"
#include "nmt/fault_injection.hpp"
#include "nmt/frame.hpp"
#include "nmt/local_dictionary.hpp"
#include "nmt/nmt_slave.hpp"
#include "nmt/sdo.hpp"
#include "nmt/sdo_abort.hpp"
#include "nmt/sim_bus.hpp"

namespace nmt {

/// An SDO abort the device answers for chosen objects instead of doing the access.
struct InjectedAbort {
  std::uint16_t index = 0;
  std::optional<std::uint8_t> sub_index;  ///< nullopt: every sub-index of `index`
  SdoAbort code = SdoAbort::General;
  bool on_read = true;
  bool on_write = true;
};

/// Faults a simulated device can show. All default to a well-behaved device.
struct DeviceFaults {
  /// The node is not on the bus at all: no boot-up, no answers, no heartbeat.
  bool absent = false;
  /// Initialisation takes this long: the boot-up message follows power-on or an NMT reset
  /// after this delay (late boot).
  Duration boot_delay{0};
  /// Wrong identity: these values replace 1000h and 1018h sub 1-4 after every reset (the entry
  /// is added when the device file lacks it).
  std::optional<std::uint32_t> device_type;
  std::optional<std::uint32_t> vendor_id;
  std::optional<std::uint32_t> product_code;
  std::optional<std::uint32_t> revision_number;
  std::optional<std::uint32_t> serial_number;
  /// SDO accesses answered with an abort (checked after the dictionary's own checks).
  std::vector<InjectedAbort> sdo_aborts;
  /// Every SDO response leaves this long after its request (slow device).
  Duration sdo_latency{0};
  /// Each frame the device receives, and each it sends, is lost with this probability (0..1),
  /// drawn from a PRNG seeded with `loss_seed`. For loss on the whole bus use
  /// SimBus::set_loss_rate.
  double frame_loss_rate = 0.0;
  std::uint64_t loss_seed = 1;
  /// The device power-cycles when it receives its Nth SDO request frame (N >= 1, counted from
  /// create() or set_faults()), without answering it: a reboot in the middle of a
  /// configuration or program download. Fires once.
  std::optional<std::uint32_t> reboot_at_sdo_request;
  /// From this time on no heartbeat is produced (the device otherwise keeps working).
  std::optional<TimePoint> heartbeat_stops_at;
  /// Node guarding requests (RTR) are never answered.
  bool ignore_guarding = false;
};

/// What the device reports to whoever watches it (the simulate tool prints these with -v).
struct DeviceEvent {
  enum class Kind {
    Boot,          ///< boot-up message sent
    StateChange,   ///< NMT command changed the state (also resets)
    SdoWrite,      ///< an SDO download stored a value
    Stored,        ///< 1010h save executed
    Restored,      ///< 1011h restore-defaults requested
    LifeGuarding,  ///< life guarding event or its resolution
    Heartbeat,     ///< heartbeat consumer event (1016h)
    Emergency,     ///< an EMCY was raised
    Program,       ///< program control (1F51h) or program download (1F50h)
    Fault,         ///< an injected fault acted (reboot, lost frame)
  };
  Kind kind;
  TimePoint at;
  std::string text;  ///< one line for people
};
std::string_view to_string(DeviceEvent::Kind kind);

/// Program control states as 1F51h reads them (CiA 302-3; DSP 302 §9 has 0-2).
enum class ProgramState : std::uint8_t { Stopped = 0, Running = 1, NoProgram = 3 };

/// Version of an application program as 1F52h sub 1/2 hold it (DSP 302 §9, CiA 302-3).
struct ApplicationSoftwareVersion {
  std::uint32_t date_days = 0;  ///< days since 1 January 1984 (sub 1)
  std::uint32_t time_ms = 0;    ///< milliseconds after midnight (sub 2)
  bool operator==(const ApplicationSoftwareVersion&) const = default;
};

/// What a simulated device cannot take from its device file. All default to "not simulated".
struct SimulatedDeviceOptions {
  /// The version 1F52h reports once a new program number 1 has been downloaded (1F50h sub 1
  /// written successfully). The simulator cannot know a real image's build date, so whoever
  /// downloads says it here. nullopt (default): 1F52h keeps the value it had. Only program 1:
  /// DSP 302 §9 gives 1F52h to "the stored program number 1". Has no effect when the device
  /// file has no 1F52h (nothing is added).
  std::optional<ApplicationSoftwareVersion> downloaded_program_version;
};

/// A simulated slave. Not copyable or movable (its dictionary hooks refer to it): create() hands
/// out a unique_ptr.
class SimulatedDevice {
  struct Key {
    explicit Key() = default;
  };

 public:
  /// Builds the device. node_id: 1..127; nullopt takes [DeviceComissioning] NodeID. Fails with
  /// a message when there is no valid node-ID or a value of the file does not parse. The device
  /// is off until power_on().
  static cfg::Result<std::unique_ptr<SimulatedDevice>> create(
      const cfg::DeviceDescription& description, std::optional<std::uint8_t> node_id,
      DeviceFaults faults = {}, SimulatedDeviceOptions options = {});

  SimulatedDevice(const SimulatedDevice&) = delete;
  SimulatedDevice& operator=(const SimulatedDevice&) = delete;
  ~SimulatedDevice();

  // --- engine interface (see the top of the file) -------------------------------------------
  /// Power-on (or power cycle) at `now`: unsaved values are lost, stored ones reload, and the
  /// boot-up message follows after faults().boot_delay.
  using Event = NoEvent;
  using Output = Outbox<NoEvent>;
  void power_on(TimePoint now);
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;

  // --- observation and control --------------------------------------------------------------
  std::uint8_t node_id() const { return nmt_.node_id(); }
  NmtState state() const { return nmt_.state(); }
  bool powered() const { return powered_; }
  LocalDictionary& dictionary() { return dict_; }
  const LocalDictionary& dictionary() const { return dict_; }
  const DeviceFaults& faults() const { return faults_; }
  /// Replaces the faults. Latency, loss, guarding and heartbeat faults take effect at once,
  /// identity and boot delay at the next reset; after changing `absent`, power_on() again.
  void set_faults(DeviceFaults faults);
  const SimulatedDeviceOptions& options() const { return options_; }
  /// Replaces the options; they act from the next SDO write on.
  void set_options(SimulatedDeviceOptions options) { options_ = std::move(options); }
  /// Values 1010h saved, by LocalDictionary::key(); empty when nothing was saved.
  const std::map<std::uint32_t, std::vector<std::uint8_t>>& stored() const { return stored_; }
  /// Program state of 1F51h sub `program` (1..), nullopt when the device has no such program.
  std::optional<ProgramState> program_state(std::uint8_t program) const;
  /// Raises an emergency (application error). `error_register_bits` are ORed into 1001h.
  /// Frames are appended to `out` when the state allows EMCY (not in stopped).
  void raise_emergency(std::uint16_t error_code, std::uint8_t error_register_bits, TimePoint now,
                       std::vector<CanFrame>& out);
  /// Watches the device. Called synchronously from the engine calls.
  void set_event_handler(std::function<void(const DeviceEvent&)> handler) {
    on_event_ = std::move(handler);
  }
  std::uint64_t sdo_requests() const { return sdo_requests_; }

  /// Only create() can call this (Key is private).
  SimulatedDevice(Key, cfg::DeviceDescription description, LocalDictionary factory,
                  std::uint8_t node_id, DeviceFaults faults, SimulatedDeviceOptions options);

 private:
  void install_hooks();
  void enter_initialisation(ResetScope scope, TimePoint now);
  void restore(ResetScope scope);
  void apply_identity();
  void configure_services();
  void emit(DeviceEvent::Kind kind, TimePoint at, std::string text);
  void flush(std::vector<CanFrame>& local, std::vector<CanFrame>& out);
  bool lose();
  void apply_nmt(const NmtSlave::Transition& t, TimePoint now);
  void communication_error(const std::string& what, TimePoint now, std::vector<CanFrame>& out);
  void communication_recovered(const std::string& what, TimePoint now, std::vector<CanFrame>& out);
  void set_error_register(std::uint8_t value);
  std::uint8_t error_register() const;
  bool heartbeat_stopped_by_fault(TimePoint at) const;

  SdoAbort check_write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data);
  SdoAbort check_pdo_write(std::uint16_t index, std::uint8_t sub,
                           std::span<const std::uint8_t> data) const;
  SdoAbort check_pdo_mapping(std::uint16_t mapping_index, std::uint8_t count) const;
  SdoAbort check_program_write(std::uint16_t index, std::uint8_t sub,
                               std::span<const std::uint8_t> data) const;
  SdoAbort injected_abort(std::uint16_t index, std::uint8_t sub, bool write) const;
  void after_write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data);
  bool is_stored_parameter(std::uint16_t index, std::uint8_t sub) const;
  void save(std::uint8_t area);
  void restore_defaults(std::uint8_t area);
  void restart_consumer();
  void set_program_state(std::uint8_t program, ProgramState state);

  cfg::DeviceDescription description_;
  LocalDictionary factory_;  ///< values as the device file gives them (no hooks)
  LocalDictionary dict_;
  DeviceFaults faults_;
  SimulatedDeviceOptions options_;
  NmtSlave nmt_;
  Delayed<SdoServer> sdo_;  ///< faults_.sdo_latency
  HeartbeatProducer heartbeat_;
  HeartbeatConsumer consumer_;
  NodeGuardingSlave guarding_;
  EmcyProducer emcy_;
  std::map<std::uint32_t, std::vector<std::uint8_t>> stored_;
  std::map<std::uint8_t, ProgramState> programs_;
  std::mt19937_64 rng_;
  std::function<void(const DeviceEvent&)> on_event_;

  bool powered_ = false;
  std::optional<TimePoint> boot_at_;
  TimePoint now_{0};  ///< time of the engine call in progress, for the dictionary hooks
  std::uint64_t sdo_requests_ = 0;
  bool reboot_fired_ = false;
  int communication_errors_ = 0;  ///< active life guarding / heartbeat consumer errors
};

/// A SimulatedDevice on the simulated bus. power_on() uses the bus's time; the device is off
/// until then.
class SimulatedDeviceNode : public SimNode {
 public:
  explicit SimulatedDeviceNode(std::unique_ptr<SimulatedDevice> device)
      : device_(std::move(device)) {}
  SimulatedDevice& device() { return *device_; }
  const SimulatedDevice& device() const { return *device_; }

  /// Powers the device on (or cycles it) at the bus's current time. Attach first.
  void power_on();
  /// Runs `fn(device, now, out)` and sends what it appends (e.g. raise_emergency).
  void apply(const std::function<void(SimulatedDevice&, TimePoint, std::vector<CanFrame>&)>& fn);

  void on_frame(const CanFrame& frame, TimePoint now) override;
  void on_timer(TimePoint now) override;

 private:
  void flush();
  std::unique_ptr<SimulatedDevice> device_;
  SimulatedDevice::Output out_;
};

}  // namespace nmt
