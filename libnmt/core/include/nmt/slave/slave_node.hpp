// A CANopen slave node built from any EDS/DCF, as one engine of the shape of nmt/engine.hpp: its
// own runtime dictionary, NMT slave, SDO server, heartbeat producer and consumer or node/life
// guarding, EMCY, the PDO parameter rules real devices enforce, parameter storage
// (1010h/1011h/1020h) and program download (1F50h-1F57h). It has no faults and no test knobs:
// an embedder can put it on a real bus (EngineRef of nmt/io/bus_event_loop.hpp) as it is; the
// simulated devices of nmt/sim/simulated_device.hpp wrap it with the faults of
// nmt/sim/fault_injection.hpp.
//   node->start(now, out);           // initialising; the boot-up is sent from on_timer
//   node->on_frame(frame, now, out);    // frames to send and events go into `out`
//   node->on_timer(now, out);           // call when now >= node->next_deadline()
//
// Behaviour where CiA 301 leaves room (chosen after what common devices do; each says why):
// - Initialisation ends at the first on_timer() call after a reset (next_deadline() is the time
//   of the reset): the restores happen at once, the boot-up message follows from on_timer().
// - Stored parameters are the writable entries except 1010h, 1011h and the program objects
//   1F50h-1F57h (the program lives in its own memory). 1010h/1011h sub 1 = all, 2 = 1000h-1FFFh,
//   3 = 6000h-9FFFh, 4 = 2000h-5FFFh, other sub-indices = all.
// - Every successful SDO write of a stored parameter other than 1020h sets 1020h sub 1 and 2 to 0,
//   even when the value is unchanged (CiA 302 §6.3 / DSP 302 §6.3: the device "has to reset the
//   object Verify Configuration to 0" when boot-up configuration values change; a configuration
//   manager writes 1020h last).
// - PDO mapping writes while the PDO is valid, and mapping entry writes while mapping sub 0 is
//   not 0, abort with 0800 0022 (device state), as e.g. Turck and Bonfiglioli manuals document.
// - A mapping entry write is checked at once (CiA 301 §7.5.2.36/38 step 3): an object the
//   dictionary lacks aborts with 0602 0000, one that cannot go into this PDO (no PDOMapping,
//   wrong access direction, wrong length, a dummy the device does not support) with 0604 0041.
//   An entry value of 0 (cleared entry) is accepted. Enabling (sub 0) checks the entries again.
// - 1014h bits 0-29 change only while bit 31 is 1 (CiA 301 §7.5.2.5), as for the PDO COB-IDs;
//   otherwise 0609 0030. Setting bit 31 is always allowed.
// - A 1016h write that would give a node-ID a second non-zero consumer heartbeat time aborts with
//   0604 0043 (CiA 301 §7.5.2.33).
// - 1F52h (verify application software) is served as the device file declares it: SDO writes
//   follow its AccessType (0601 0002 when ro/const). A file that declares 1F50h/1F51h but no 1F52h
//   gets none (the object is optional; real devices, e.g. Nanotec CL4-E, omit it), so a master
//   reading it sees 0602 0000. Program 1's image tells its version when it ends in our version
//   trailer (cfg/program_image.hpp, "CPV1"): once that program is started (1F51h sub 1 = 1, a
//   reset application or a power-on), 1F52h sub 1/2 report the trailer's date and time; until
//   then 1F52h keeps the running program's. An image without a trailer sets 1F52h at its
//   download from SlaveNodeOptions::downloaded_program_version, or leaves it unchanged when that
//   is unset. Like 1F50h-1F57h as a whole, it lives in program memory: resets and power cycles
//   keep it, and so do the images (program_images(); nmt/sim/device_state.hpp keeps them on disk).
// - SDO server channels (CiA 301 §7.5.2.33): the default channel 1200h and every 1201h-127Fh
//   entry of the device file (or inserted into the dictionary later: found at the next reset or
//   write of a server entry), each served by its own SdoServer (one transfer per channel, so
//   clients on different channels never disturb each other). An additional channel answers while
//   bit 31 of both sub 1 and sub 2 is 0; a frame is served by the first channel in index order
//   whose request COB-ID it carries.
// - 1200h sub 1/2 are the pre-defined connection set: writes of another value abort with
//   0601 0002 even when a file declares them rw (the value they hold is accepted, so a whole-DCF
//   download succeeds). 1201h-12FFh sub 1/2: bits 0-29 change only while bit 31 is 1,
//   otherwise 0609 0030 (CiA 301 §7.5.2.33/34, the rule of 1014h and the PDO COB-IDs); setting
//   bit 31 is always allowed. A written 1201h-127Fh entry takes effect without a reset, once the
//   response to the write is sent (a client that rewrites the channel it talks on gets its
//   confirmation on the COB-ID it used).
// - LSS (CiA 305, nmt/lss/lss_slave.hpp) when the device file says [DeviceInfo] LSS_Supported=1:
// the
//   LSS address is 1018h sub 1-4 (sub 4 from a DCF's [DeviceComissioning] LSS_SerialNumber when
//   given). A node created unconfigured (create_unconfigured) powers on without boot-up and
//   serves only LSS (no NMT, SDO, heartbeat) until LSS gives it a node-ID and switches it back
//   to waiting; then it boots as usual with the dictionary of that node-ID. A node-ID configured
//   by LSS on a running node takes effect at its next NMT reset (communication or application),
//   FFh there makes it unconfigured. Store configuration keeps the node-ID over power cycles
//   (like 1010h values, in stored()'s memory of this object).
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/program_image.hpp"
#include "cfg/result.hpp"
#include "nmt/engine.hpp"
#include "nmt/lss/lss_slave.hpp"
#include "nmt/protocol/emcy.hpp"
#include "nmt/protocol/error_control.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo.hpp"
#include "nmt/sdo/sdo_abort.hpp"
#include "nmt/slave/local_dictionary.hpp"
#include "nmt/slave/nmt_slave.hpp"

namespace nmt {

/// What a slave node reports to whoever watches it (the simulate tool prints these with -v).
struct SlaveEvent {
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
    Fault,  ///< an injected fault acted (reported by nmt/sim/fault_injection.hpp, never here)
    Lss,    ///< an LSS service acted (node-ID configured, stored, bit timing)
  };
  Kind kind;
  TimePoint at;
  std::string text;  ///< one line for people
  /// SdoWrite: the entry written (an owner such as the SDO requesting device acts on it).
  std::optional<cfg::ObjectAddress> object = std::nullopt;
};
std::string_view to_string(SlaveEvent::Kind kind);

/// Program control states as 1F51h reads them (CiA 302-3; DSP 302 §9 has 0-2).
enum class ProgramState : std::uint8_t { Stopped = 0, Running = 1, NoProgram = 3 };

/// What a slave node cannot take from its device file.
struct SlaveNodeOptions {
  /// The version 1F52h reports once a new program number 1 has been downloaded (1F50h sub 1
  /// written successfully). The node cannot know a real image's build date, so whoever
  /// downloads says it here. nullopt (default): 1F52h keeps the value it had. Only program 1:
  /// DSP 302 §9 gives 1F52h to "the stored program number 1". Has no effect when the device
  /// file has no 1F52h (nothing is added).
  std::optional<cfg::ProgramVersion> downloaded_program_version;
  /// A segmented or block SDO transfer with no request for this long is aborted with 0504 0000
  /// (SdoServerConfig::timeout).
  Duration sdo_server_timeout = std::chrono::milliseconds(2000);
};

/// One slave node. Not copyable or movable (its dictionary hooks refer to it): create() hands
/// out a unique_ptr.
class SlaveNode {
  struct Key {
    explicit Key() = default;
  };

 public:
  using Event = SlaveEvent;
  using Output = Outbox<Event>;

  /// Builds the node. Fails with a message when a value of the file does not parse. The node is
  /// off (sends and answers nothing) until start().
  static cfg::Result<std::unique_ptr<SlaveNode>> create(const cfg::DeviceDescription& description,
                                                        cfg::NodeId node_id,
                                                        SlaveNodeOptions options = {});
  /// Builds a node that powers on without a node-ID (FFh): it needs [DeviceInfo]
  /// LSS_Supported=1 and waits for LSS to give it one (see the top of this file).
  static cfg::Result<std::unique_ptr<SlaveNode>> create_unconfigured(
      const cfg::DeviceDescription& description, SlaveNodeOptions options = {});

  SlaveNode(const SlaveNode&) = delete;
  SlaveNode& operator=(const SlaveNode&) = delete;
  ~SlaveNode();

  // --- engine (nmt/engine.hpp) ---------------------------------------------------------------
  /// Power-on (or power cycle) at `now`: unsaved values are lost, stored ones reload; the
  /// boot-up message is due at `now` (next_deadline()). Events (an LSS node-ID taken) go into
  /// `out`.
  void start(TimePoint now, Output& out);
  /// True for frames the node acted on: NMT commands for it, its SDO requests, guarding
  /// requests, heartbeats it consumes.
  bool on_frame(const CanFrame& frame, TimePoint now, Output& out);
  void on_timer(TimePoint now, Output& out);
  std::optional<TimePoint> next_deadline() const;

  // --- application -------------------------------------------------------------------------
  /// Raises an emergency (application error) at `now`: `error_register_bits` are ORed into
  /// 1001h and the EMCY goes into `out` when the state allows EMCY (not stopped or
  /// initialising) and the inhibit time has passed (else it waits or is dropped, see
  /// EmcyProducer).
  void raise_emergency(std::uint16_t error_code, std::uint8_t error_register_bits, TimePoint now,
                       Output& out);

  // --- observation ---------------------------------------------------------------------------
  /// The node-ID (meaningless while !has_node_id()).
  cfg::NodeId node_id() const { return nmt_.node_id(); }
  /// False while the node waits for LSS to give it a node-ID.
  bool has_node_id() const { return !unconfigured_; }
  /// The LSS slave; nullptr when the device file does not say LSS_Supported=1.
  const LssSlave* lss() const { return lss_ ? &*lss_ : nullptr; }
  NmtState state() const { return nmt_.state(); }
  NmtServices services() const { return nmt_.services(); }
  bool powered() const { return powered_; }
  LocalDictionary& dictionary() { return dict_; }
  const LocalDictionary& dictionary() const { return dict_; }
  /// The default SDO server channel's COB-IDs and settings as the last reset configured them
  /// (1200h).
  const SdoServerConfig& sdo_config() const { return *sdo_config(0x1200); }
  /// The SDO server channels the node serves: 1200h, then the 1201h-127Fh entries of its
  /// dictionary in index order.
  std::vector<std::uint16_t> sdo_server_channels() const;
  /// The current configuration of server channel `index` (1200h-127Fh); nullptr when the node
  /// has no such channel. Valid until the next call of the node (a new channel may move it).
  const SdoServerConfig* sdo_config(std::uint16_t index) const;
  /// True while a segmented or block transfer runs on server channel `index`.
  bool sdo_busy(std::uint16_t index) const;
  /// The heartbeat producer as 1017h configured it (its next_deadline() is the next heartbeat).
  const HeartbeatProducer& heartbeat_producer() const { return heartbeat_; }
  const SlaveNodeOptions& options() const { return options_; }
  /// Replaces the options. The program version acts from the next SDO write on; a changed SDO
  /// server timeout reconfigures the server at once, dropping a transfer in progress.
  void set_options(SlaveNodeOptions options);
  /// Values 1010h saved, by LocalDictionary::key(); empty when nothing was saved.
  const std::map<std::uint32_t, std::vector<std::uint8_t>>& stored() const { return stored_; }
  /// Replaces the saved values (the device's non-volatile memory), e.g. with stored() of an
  /// earlier run kept in a file. Keys as stored(); a key that is not a stored parameter of this
  /// node (see the top of this file) is dropped. Like a save, they act at the next start() or
  /// reset.
  void set_stored(std::map<std::uint32_t, std::vector<std::uint8_t>> values);
  /// What LSS store configuration (17h) saved, the node-ID and bit rate the node powers on
  /// with; nullopt when it never stored (or has no LSS).
  const std::optional<LssStoredConfig>& lss_stored() const { return lss_stored_; }
  /// Replaces what LSS stored (the device's non-volatile memory, e.g. lss_stored() of an
  /// earlier run kept in a file); acts at the next start(). Ignored without LSS.
  void set_lss_stored(std::optional<LssStoredConfig> stored);
  /// Program state of 1F51h sub `program` (1..), nullopt when the node has no such program.
  std::optional<ProgramState> program_state(std::uint8_t program) const;
  /// The program memory: the images downloaded into 1F50h sub N (DSP 302 §9), by program
  /// number; a program cleared (1F51h = 3) has none. Like stored(), it survives power cycles.
  const std::map<std::uint8_t, std::vector<std::uint8_t>>& program_images() const {
    return program_images_;
  }
  /// Replaces the program memory (e.g. program_images() of an earlier run kept in a file).
  /// Each image is program N's as if downloaded (1F50h, 1F56h) and is started at the next
  /// start(); 1F52h then reports the version of program 1's image (see the top of this
  /// file). Program numbers the file has no 1F50h sub for are dropped.
  void set_program_images(std::map<std::uint8_t, std::vector<std::uint8_t>> images);

  /// Only create() can call this (Key is private).
  SlaveNode(Key, cfg::DeviceDescription description, LocalDictionary factory, cfg::NodeId node_id,
            SlaveNodeOptions options);

 private:
  void install_hooks();
  void enter_initialisation(ResetScope scope, TimePoint now);
  void restore(ResetScope scope);
  void configure_services(TimePoint now);
  void sync_parts();
  void emit(Output& out, SlaveEvent::Kind kind, TimePoint at, std::string text,
            std::optional<cfg::ObjectAddress> object = std::nullopt);
  void apply_nmt(const NmtTransition& t, TimePoint now, Output& out);
  void communication_error(const std::string& what, TimePoint now, Output& out);
  void communication_recovered(const std::string& what, TimePoint now, Output& out);
  void send_emcy(const Emergency& emcy, TimePoint now, Output& out);
  void set_error_register(std::uint8_t value);
  std::uint8_t error_register() const;

  SdoAbort check_write(std::uint16_t index, std::uint8_t sub,
                       std::span<const std::uint8_t> data) const;
  SdoAbort check_program_write(std::uint16_t index, std::uint8_t sub,
                               std::span<const std::uint8_t> data) const;
  void add_sdo_channels();
  void reconfigure_sdo_channels();
  void after_write(std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> data,
                   TimePoint now, HookOutput hooks);
  bool is_stored_parameter(std::uint16_t index, std::uint8_t sub) const;
  void save(std::uint8_t area, TimePoint now, Output& out);
  void restore_defaults(std::uint8_t area, TimePoint now, Output& out);
  void restart_consumer(TimePoint now);
  void set_program_state(std::uint8_t program, ProgramState state);
  // program_memory.cpp (DSP 302 §9)
  void program_downloaded(std::uint8_t program, std::span<const std::uint8_t> image, TimePoint now,
                          Output& out);
  void program_state_changed(std::uint8_t program, ProgramState state);
  void report_program_version(const cfg::ProgramVersion& version);
  /// CiA 302-3 1F57h sub `program`, where the device file has it: bit 0 "in progress", bits
  /// 1-7 the status (0 no error, 1 no valid program available).
  static constexpr std::uint32_t kFlashStatusOk = 0;
  static constexpr std::uint32_t kFlashStatusNoProgram = 1U << 1;
  void set_flash_status(std::uint8_t program, std::uint32_t value);
  bool on_lss_frame(const CanFrame& frame, TimePoint now, Output& out);
  void take_node_id(cfg::NodeId node_id, ResetScope scope, TimePoint now, Output& out);
  void become_unconfigured(TimePoint now);

  cfg::DeviceDescription description_;
  LocalDictionary factory_;  ///< values as the device file gives them (no hooks)
  LocalDictionary dict_;
  SlaveNodeOptions options_;
  NmtSlave nmt_;
  /// One SDO server per channel, 1200h first.
  SdoServerChannels sdo_{dict_};
  /// A server parameter was written: the channels are reconfigured when the SDO call that wrote
  /// it has answered (at once for writes outside an SDO call).
  bool sdo_changed_ = false;
  bool in_sdo_ = false;
  HeartbeatProducer heartbeat_;
  HeartbeatConsumer consumer_;
  NodeGuardingSlave guarding_;
  EmcyProducer emcy_;
  std::map<std::uint32_t, std::vector<std::uint8_t>> stored_;
  std::map<std::uint8_t, ProgramState> programs_;
  /// Program memory: 1F50h sub N images (non-volatile, like stored_).
  std::map<std::uint8_t, std::vector<std::uint8_t>> program_images_;

  std::optional<LssSlave> lss_;
  /// No node-ID: only LSS is served, no boot-up.
  bool unconfigured_ = false;
  /// The node-ID (FFh: unconfigured) and bit rate LSS store configuration saved; survive
  /// power cycles.
  std::optional<LssStoredConfig> lss_stored_;
  /// The node-ID the node powers on with when LSS stored none (FFh: created unconfigured).
  std::uint8_t power_on_node_id_ = lss::kUnconfigured;
  bool powered_ = false;
  std::optional<TimePoint> boot_at_;
  int communication_errors_ = 0;  ///< active life guarding / heartbeat consumer errors
  /// The parts' outputs, emptied before each use and kept so that no call allocates them anew.
  struct Scratch {
    NmtSlave::Output nmt;
    LssSlave::Output lss;
    SdoServer::Output sdo;
    HeartbeatProducer::Output heartbeat;
    HeartbeatConsumer::Output consumer;
    NodeGuardingSlave::Output guarding;
    EmcyProducer::Output emcy;
    /// What a dictionary write made outside any call of the node reports: nobody reads it.
    Output outside;
  } scratch_;
};
static_assert(Engine<SlaveNode>);

}  // namespace nmt
