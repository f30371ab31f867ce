// The NMT master's configuration as types: what a master DCF
// says in the objects of CiA 302-2 §6, in words an embedder writes without little-endian bytes
// or object indices, checked before the master is built:
//
//   nmt::MasterConfig config{cfg::NodeId::from(1).value()};
//   config.startup.start_all_nodes = true;                   // 1F80h bit 1 (§6.2, Table 9)
//   nmt::SlaveConfig& drive = config.add_slave(cfg::NodeId::from(3).value());
//   drive.mandatory = true;                                  // 1F81h bit 3 (§6.3, Table 21)
//   drive.identity.vendor_id = 0x0000ABCD;                   // 1F85h (§6.7)
//   drive.heartbeat = std::chrono::milliseconds(300);        // 1016h, CiA 301
//   auto master = config.build();                            // cfg::Result<NmtMaster>
//
// The DCF path is the same type: MasterConfig::from_dcf(dcf, node_id) reads these objects out
// of a master DCF (with the defaults NmtMaster::create gives the objects it lacks) and keeps the
// DCF for everything else it carries (1F22h configurations, 1F26h/1F27h, SDO channels, ...);
// build() of that config gives the dictionary NmtMaster::create(dcf) gives. A config read that
// way can be changed in code before it is built (a slave added or removed, a time changed).
//
// What build() owns: 1F80h, 1F81h/1F84h-1F88h/1F26h/1F27h and 1F53h/1F54h sub 1..127 (0 for
// nodes not in `slaves`, or without a stamp or program version), 1016h (the entries of the nodes
// in `slaves` that have a heartbeat time, the others cleared), 1017h, 1F89h, 102Ah, 1F90h sub
// 1..6, and 1F8Ah sub node of each node in `slaves`. Every error says what is wrong and what to
// do about it. The rest of the master's
// dictionary comes from `dcf` (or the defaults, NmtMaster::create).
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

#include "cfg/master_objects.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/program_image.hpp"
#include "cfg/result.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace cfg {
struct Network;
}  // namespace cfg

namespace nmt {

/// 1F80h NMT startup (CiA 302-2 §6.2), bit by bit.
struct StartupFlags {
  bool master = true;                ///< bit 0, Table 8: this device is the NMT master
  bool start_all_nodes = false;      ///< bit 1, Table 9: start remote node with node-ID 0
  bool no_auto_operational = false;  ///< bit 2, Table 10: the application calls
                                     ///< NmtMaster::enter_operational()
  bool no_start_slaves = false;      ///< bit 3, Table 11: the application starts the slaves
  bool reset_all_nodes = false;      ///< bit 4, Table 12: a mandatory slave's error control
                                     ///< event resets all nodes (else only that node)
  bool flying_master = false;        ///< bit 5, Table 13: take part in the flying master
                                     ///< negotiation (§5.3)
  bool stop_all_nodes = false;       ///< bit 6, Table 14: such an event stops all nodes (bit 4
                                     ///< is then ignored)

  cfg::NmtStartup value() const;
  static StartupFlags from(cfg::NmtStartup value);
  bool operator==(const StartupFlags&) const = default;
};

/// Node guarding of a slave by the master (1F81h bytes 1-3, CiA 302-2 §6.3). The heartbeat has
/// priority when the slave also has one (§6.3 NOTE).
struct GuardingConfig {
  Duration guard_time{0};         ///< 1..65535 ms, whole ms (1F81h bytes 2-3)
  std::uint8_t retry_factor = 0;  ///< 1..255 (1F81h byte 1)
  bool operator==(const GuardingConfig&) const = default;
};

/// What the master expects of a slave's 1000h and 1018h (1F84h-1F88h, CiA 302-2 §6.6-§6.10);
/// unset: not checked (the object's value 0).
struct ExpectedIdentity {
  std::optional<std::uint32_t> device_type;    ///< 1F84h: 1000h
  std::optional<std::uint32_t> vendor_id;      ///< 1F85h: 1018h sub 1 (boot error D)
  std::optional<std::uint32_t> product_code;   ///< 1F86h: 1018h sub 2 (M)
  std::optional<std::uint32_t> revision;       ///< 1F87h: 1018h sub 3 (N; docs/master.md)
  std::optional<std::uint32_t> serial_number;  ///< 1F88h: 1018h sub 4 (O)
  bool operator==(const ExpectedIdentity&) const = default;
};

/// One node the master knows: a sub-index of 1F81h with its 1F84h-1F88h, 1F8Ah and 1016h entry.
struct SlaveConfig {
  explicit SlaveConfig(cfg::NodeId id) : node(id) {}

  cfg::NodeId node;
  bool slave = true;             ///< bit 0, Table 19: an NMT slave of this master (false: a
                                 ///< node it only knows, e.g. a heartbeat it consumes)
  bool boot = true;              ///< bit 2, Table 20: the master configures and starts it
  bool mandatory = false;        ///< bit 3, Table 21: present before the network starts
  bool keep_alive = false;       ///< bit 4, Table 22: no reset communication when operational
  bool verify_software = false;  ///< bit 5, Table 23
  bool update_software = false;  ///< bit 6, Table 24
  bool restore = false;          ///< bit 7, Table 25: restore factory defaults (1011h) first
  std::optional<GuardingConfig> guarding;  ///< 1F81h bytes 1-3; unset: not guarded
  ExpectedIdentity identity;               ///< 1F84h-1F88h
  /// 1F53h/1F54h sub node (DSP 302 §9): the application program version the slave should run,
  /// checked against its 1F52h with verify_software (bit 5; unset with bit 5: status G).
  std::optional<cfg::ProgramVersion> program_version;
  /// 1016h: the master consumes the node's heartbeat with this time (1..65535 ms, whole ms).
  std::optional<Duration> heartbeat;
  /// 1F8Ah (§6.12): the 1011h sub-index of the restore (1: all parameters; 0: none).
  std::uint8_t restore_subindex = 1;
  /// 1F26h/1F27h sub node (DSP 302 §6.6): the configuration date (days since 1984-01-01) and
  /// time (ms after midnight) the master expects in the slave's 1020h; while both match, check
  /// configuration skips the download. Zero: not verified. A configuration manager that holds
  /// a stamp for the node owns it instead (docs/master.md, "Configuration manager").
  cfg::ConfigurationStamp expected_configuration;

  cfg::SlaveAssignment assignment() const;
  bool operator==(const SlaveConfig&) const = default;
};

/// 1F90h NMT flying master timing parameters (CiA 302-2 §6.13, Table 50), used with
/// StartupFlags::flying_master.
struct FlyingMasterConfig {
  enum class Priority : std::uint8_t { High = 0, Medium = 1, Low = 2 };  ///< Table 48
  Duration timeout = std::chrono::milliseconds(100);                     ///< sub 1
  Duration negotiation_delay = std::chrono::milliseconds(500);           ///< sub 2
  Priority priority = Priority::Medium;                                  ///< sub 3
  Duration priority_time_slot = std::chrono::milliseconds(1500);         ///< sub 4
  Duration device_time_slot = std::chrono::milliseconds(10);             ///< sub 5
  /// Sub 6: multiple NMT master detect cycle time (0: none); unset: 4000 + 10 x node-ID ms.
  std::optional<Duration> detect_cycle;
  bool operator==(const FlyingMasterConfig&) const = default;
};

/// The master: its own objects, its slaves, the engine's options and the master DCF it builds on.
struct MasterConfig {
  explicit MasterConfig(cfg::NodeId id) : node_id(id) {}

  cfg::NodeId node_id;
  StartupFlags startup;             ///< 1F80h
  std::vector<SlaveConfig> slaves;  ///< 1F81h, 1F84h-1F88h, 1F8Ah, 1016h; each node once
  /// 1F89h (§6.11): how long mandatory slaves are retried after status B; 0: without end. Whole
  /// ms.
  Duration boot_time{0};
  /// 102Ah (§6.1): the least time between two NMT commands the master sends; multiples of
  /// 100 us up to 6.5535 s.
  Duration nmt_inhibit_time{0};
  FlyingMasterConfig flying_master;  ///< 1F90h
  /// 1017h (CiA 301): the master's own heartbeat period; 0: it produces none. Whole ms up to
  /// 65535.
  Duration heartbeat_producer{0};
  /// The engine's SDO, timing and configuration options (timeouts, retries, bit rate, ...).
  MasterOptions options;
  /// The master DCF the rest of the dictionary comes from (none: CiA 302-2 defaults).
  cfg::DeviceDescription dcf;

  /// Adds a slave for `node` (boot and start it, optional, no checks) and returns it to set up;
  /// the one already there when `node` has one.
  SlaveConfig& add_slave(cfg::NodeId node);
  /// The entry of `node`; nullptr when there is none.
  const SlaveConfig* slave(cfg::NodeId node) const;

  /// The values checked against CiA 302-2 §6 and the ranges of their objects; the error names
  /// the node and the value in words ("slave 3: heartbeat time 70000 ms does not fit 1016h").
  cfg::Status validate() const;
  /// validate(), then the master built from `dcf` with these values. Fails also when `dcf`
  /// lacks room for them (a 1016h with too few entries) or breaks NmtMaster::create's rules.
  cfg::Result<NmtMaster> build() const;

  /// Reads the objects above from a master DCF (or EDS) as NmtMaster::create(dcf, node_id)
  /// sees them, defaults included, and keeps the DCF (`dcf`) and `options` for build(). Fails
  /// as NmtMaster::create does on a value it cannot take. What the master ignores is read as
  /// nothing, so build() writes 0 there: the sub-indices of its own node-ID (§6.3), half a
  /// guarding configuration (a guard time or a retry factor of 0 disables guarding, §6.3), 1016h
  /// entries with a time of 0.
  static cfg::Result<MasterConfig> from_dcf(const cfg::DeviceDescription& dcf, cfg::NodeId node_id,
                                            MasterOptions options = {});
  /// The same, from the dictionary of a built master.
  static MasterConfig from_dictionary(const LocalDictionary& dictionary, cfg::NodeId node_id);
  /// The master of a loaded network (cfg::load_network) as the network's configuration manager
  /// (DSP 302 §6, 1F20h-1F27h): from_dcf of the network's master DCF at `node_id`, its
  /// configurations from the network (options.configurations becomes a NetworkSource,
  /// nmt/master/network_source.hpp), and options.manager, or a manager in memory when there is none
  /// (what is written over SDO then lives as long as the master), so that a node with nothing
  /// stored reads the network's configuration. Fails as from_dcf does, and when `node_id` is the
  /// node-ID of one of the network's nodes.
  static cfg::Result<MasterConfig> from_network(std::shared_ptr<const cfg::Network> network,
                                                cfg::NodeId node_id, MasterOptions options = {});
  /// The master's node-ID for a network when none is chosen: its master DCF's NodeID, else 7Fh,
  /// the highest, so that the slaves keep the low node-IDs (and their higher-priority COB-IDs).
  static cfg::NodeId default_node_id(const cfg::Network& network);
};

}  // namespace nmt
