// How an NMT master is built (MasterOptions) and where it finds configurations and program
// images (ConfigurationSource). Included by nmt/master/nmt_master.hpp; the behaviour each option
// tunes is described in docs/master.md, by process.
#pragma once

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "cfg/cob_id.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_master.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sdo/sdo_client.hpp"

namespace cfg {
class ConfigManager;
}  // namespace cfg

namespace nmt {

/// Where check configuration (CiA 302-2 §3.5 d) and the software update find what to download.
/// The configuration manager implements it; NmtMaster calls it while a slave boots.
class ConfigurationSource {
 public:
  virtual ~ConfigurationSource() = default;
  /// The writes that configure `node`, in any order (the master orders them for download),
  /// without 1020h and 1010h, which the master adds. nullopt: nothing stored for the node.
  virtual std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const = 0;
  /// The image of program 1 (1F50h sub 1) for a software update; nullopt: none available
  /// (status H when an update is needed).
  virtual std::optional<std::vector<std::uint8_t>> program(cfg::NodeId /*node*/) const {
    return std::nullopt;
  }
  /// What the configuration manager's 1F22h sub node-ID reads for a node the manager stores no
  /// configuration for (DSP 302 §6.2): the concise DCF stream of configuration(), in the order
  /// the source gives it out. nullopt: none (the master DCF's own 1F22h, else the count-0 stream).
  virtual std::optional<std::vector<std::uint8_t>> concise_dcf(cfg::NodeId /*node*/) const {
    return std::nullopt;
  }
  /// What 1F20h sub node-ID reads for such a node (DSP 302 §6.1): the text of the DCF the
  /// configuration comes from. nullopt: the source has no DCF for the node (0800 0024h); an
  /// error: it has one that cannot be read now (0800 0020h, the message says why).
  virtual cfg::Result<std::optional<std::string>> dcf(cfg::NodeId /*node*/) const {
    return std::optional<std::string>{};
  }
};

/// "Execute LSS" in the master's boot (DSP 302 §4 figure 1 step 3; CiA 302-2 §3.1 c;
/// docs/master.md).
struct ExecuteLssOptions {
  /// Before NMT start-up's reset of all nodes, find every unconfigured device (CiA 305 Fastscan)
  /// and give the slave's node-ID to each whose LSS address is a slave's.
  bool enabled = false;
  /// A slave's LSS address (vendor-ID, product code, revision, serial number) by node-ID, for
  /// slaves whose 1F85h-1F88h do not give all four parts (a derived master leaves 1F88h 0; a
  /// DCF's [DeviceComissioning] LSS_SerialNumber, else its 1018h sub 4, names the serial).
  /// A slave in neither is never given its node-ID by LSS.
  std::map<cfg::NodeId, LssAddress> addresses;
  /// After the start-up pass, look for devices that appear unconfigured (a replaced device)
  /// this often: identify non-configured remote slave (4Ch, one frame), and a scan only when a
  /// device answers. 0: never.
  Duration period{0};
  /// The LSS services' timing: the answer timeout and the Fastscan step (lss_master.hpp).
  LssMasterOptions timing;
};

/// The SDO transfers of the boot, of the application and of the SDO manager (on the master's
/// default SDO clients).
struct MasterSdoOptions {
  /// Timeout of each SDO response, and how often a timed-out transfer is repeated.
  Duration timeout = std::chrono::milliseconds(500);
  unsigned retries = 2;
  /// Values longer than this many bytes go by block transfer (falling back to segmented).
  std::size_t block_threshold = kBlockDownloadThreshold;
  /// The boot's expedited requests (initiate upload, expedited download; never 1010h/1011h/
  /// 1F50h/1F51h writes) are sent again when no answer came within 2 x the slave's largest
  /// recent answer time (SdoResult::longest_answer of its last transfers), at least this long and
  /// below `timeout` (SdoTransferOptions::repeat_after, up to sdo::kMaxRepeats times); the
  /// transfer still fails only after `timeout`. A slave that has not answered yet gets only its
  /// reads repeated, by any slave's answer times, and only once the master heard from it
  /// (boot-up, heartbeat). A lost frame then costs about this long instead of `timeout`. At or
  /// above `timeout`: no repetition. docs/master.md, "The boot's SDO transfers".
  Duration repeat_floor = std::chrono::milliseconds(20);
};

/// The pacing of the boot's SDO requests to a share of the bus (docs/master.md, "The boot's SDO
/// transfers").
struct BootPacingOptions {
  /// The bus bit rate in bit/s, when known (0: unknown). With it the boot paces its SDO requests
  /// so that they, their answers and the frames of other nodes the master receives (heartbeats,
  /// PDOs, EMCY, others' SDO) take at most `bus_load_limit` of the bus: CAN arbitration lets
  /// lower identifiers starve higher ones, and on a full bus heartbeats (700h + node-ID, the
  /// highest identifiers of a slave) and the answers a device queues behind them wait until the
  /// master's SDO traffic leaves a gap. Each SDO request counts as itself and one answer as
  /// long, each frame at its exact length (nmt::frame_bits, stuff bits and intermission
  /// included). 0.97: 126 slaves with 100 ms heartbeats at 500 kbit/s keep every heartbeat
  /// within 128 ms of the previous one during a boot at 98 % bus load (BENCHMARKS.md).
  std::uint32_t bitrate = 0;
  double bus_load_limit = 0.97;
};

/// Start process boot NMT slave, boot NMT slave and check configuration (CiA 302-2 §3.3-§3.6).
struct BootOptions {
  /// §3.3: optional slaves (and mandatory ones after status B) are tried again this often.
  Duration retry_interval = std::chrono::seconds(1);
  /// How long boot NMT slave waits for a boot-up after NMT start-up's reset communication.
  Duration boot_up_wait = std::chrono::milliseconds(500);
  /// How long a restore or a software update waits for the boot-up after its reset node.
  Duration reboot_timeout = std::chrono::seconds(5);
  /// §3.6: the guarding reply to one RTR must come within this time.
  Duration guarding_reply_timeout = std::chrono::milliseconds(100);
  /// Write 1010h sub 1 'save' after a download.
  bool save_configuration = true;
  /// Download even when 1020h matches 1F26h/1F27h.
  bool force_download = false;
  /// After the download, wait for configuration_done() (MasterEvent::ApplicationStep).
  bool application_step = false;
};

/// The software update's response timeouts (DSP 302 §9, docs/master.md "Software update").
struct ProgramUpdateOptions {
  /// The wait for the answer to 1F51h sub 1 = 0 (stop) and = 1 (start), which a device may give
  /// only once its program stopped or booted.
  Duration control_timeout = std::chrono::seconds(10);
  /// The wait for the answer to 1F51h sub 1 = 3 (clear, CiA 302-3), during which a device may
  /// erase its flash (a few seconds for a few MiB of common microcontroller flash).
  Duration clear_timeout = std::chrono::seconds(30);
  /// The wait for each response of the 1F50h sub 1 download (a device may write a block to
  /// flash before it confirms it). A timeout repeats the download once from the start.
  Duration data_timeout = std::chrono::seconds(5);
};

/// The SDO manager of DSP 302 §7 (docs/master.md, "SDO manager").
struct SdoManagerOptions {
  /// On; also on when the master DCF has 1F00h.
  bool enabled = false;
  /// Own server channels 1201h.. the manager adds for SRDs (one per registered SRD), 1..127:
  /// also the bound of registrations (this many SRDs, plus one granted all default SDOs); the
  /// next SRD's 1F10h gets Cnxn 0 with error 01h.
  std::uint8_t channels = 16;
  /// 1F00h requests waiting in the SDO manager's queue (jobs run one at a time) at most; a
  /// 1F00h write beyond is refused with 0504 0005 (out of memory). 1F01h is never refused for
  /// it (a release frees resources and is bounded by the connections).
  std::size_t max_queued_requests = 64;
  /// The wait for each 1F10h read of the registration scan (tried once: no answer = nobody).
  Duration scan_timeout = std::chrono::milliseconds(50);
  /// Node guard time for an SRD (or a slave watched for one) without heartbeat or 1F81h
  /// guarding values; life time factor 3.
  Duration srd_guard_time = std::chrono::milliseconds(500);
};

/// Request NMT (1F82h, CiA 302-2 §6.4).
struct NmtRequestOptions {
  /// NMT commands waiting for the 102Ah inhibit time at most; a request that would queue more
  /// (80h excluding a requester queues one per node) is refused with 0504 0005. The master's
  /// own commands (start-up, error handler) are always queued.
  std::size_t max_queued_requests = 256;
};

/// What the master knows of a node's emergency producer from the node's DCF.
struct EmcySource {
  /// 1014h (its ParameterValue, else DefaultValue, $NODEID resolved); nullopt: 80h + node-ID.
  std::optional<cfg::CobId> cob_id;
  /// 1000h, for the device profile's words of its codes (CiA 402, 401); nullopt: the master's
  /// 1F84h sub node-ID when not 0.
  std::optional<std::uint32_t> device_type;
};

/// The emergency consumer (CiA 301 §7.2.7; docs/master.md, "Emergencies"). The master consumes
/// the EMCY of every slave in 1F81h and of every node in `sources`, on the COB-ID of the
/// master's 1028h sub node-ID where its dictionary has that entry (CiA 301 §7.5.2.30; bit 31
/// set: not consumed), else the source's 1014h, else 80h + node-ID.
struct EmcyOptions {
  std::map<cfg::NodeId, EmcySource> sources;
  /// Per node and error code at most this many EMCYs are reported per `window`; the rest are
  /// counted and reported as one MasterEvent::EmergencyFlood when the window ends (>= 1).
  unsigned max_per_window = 5;
  Duration window = std::chrono::seconds(1);
};

/// How an NMT master is built: what no object of its dictionary says, one member per process.
///
/// Where a slave's configuration comes from (check configuration, CiA 302-2 §3.5 d; the one
/// rule, in libnmt's manager/configuration_store_objects.cpp). Three sources may know a node; for
/// each node the first that applies wins:
///   1. `manager`, when it holds a configuration for the node
///      (cfg::ConfigManager::has_configuration);
///   2. else `configurations`, when it is set: its configuration(node), even when that is
///      nullopt (then there is nothing to download: the master DCF's 1F22h is not asked);
///   3. else, without `configurations`, the master DCF's own 1F22h sub node-ID (a concise DCF;
///      empty: nothing to download).
/// With a manager, SDO reads of 1F22h sub node-ID follow the same order, except that a source
/// whose concise_dcf(node) is nullopt falls back to the DCF's 1F22h (then the count-0 stream),
/// and 1F20h/1F21h read the source's dcf(); without one they read the master DCF's values.
/// 1F26h/1F27h (the expected configuration stamp) are the manager's for a node it holds
/// anything for (a configuration or a stamp), else the dictionary's (the master DCF's).
struct MasterOptions {
  /// The configuration and program images source (above). nullptr: configurations from the
  /// master's own 1F22h, no program images.
  std::shared_ptr<const ConfigurationSource> configurations;
  /// The configuration manager the master serves over SDO (1F20h-1F27h, docs/master.md) and asks
  /// first for a node's configuration and 1F26h/1F27h (above). Shared: the owner may use its C++
  /// API between the master's calls (not from another thread). SDO writes of 1F20h, 1F22h,
  /// 1F23h, 1F26h and 1F27h go to the manager's store directory when it has one, written by the
  /// driver, not the master: MasterEvent::PersistEntry and entry_persisted() (docs/master.md).
  /// nullptr: 1F20h-1F25h are served only as the master DCF has them, as plain values.
  std::shared_ptr<cfg::ConfigManager> manager;
  /// The master's SDO transfers.
  MasterSdoOptions sdo;
  /// The boot's bus-load pacing.
  BootPacingOptions pacing;
  /// Boot NMT slave and its start process.
  BootOptions boot;
  /// The software update.
  ProgramUpdateOptions program;
  /// The SDO manager (off by default).
  SdoManagerOptions sdo_manager;
  /// Request NMT.
  NmtRequestOptions nmt;
  /// Execute LSS (off by default).
  ExecuteLssOptions lss;
  /// The emergency consumer.
  EmcyOptions emcy;

  /// The durations checked: every timeout, wait and interval above (lss.timing's too) positive
  /// (an SDO response timeout of 0 can never be met, SdoClient::check_start refuses it; a retry
  /// interval of 0 would retry at the same instant without end), boot.boot_up_wait and
  /// lss.period not negative (0: no wait, no looks). The error names the field by its path
  /// ("MasterOptions::sdo.timeout must be positive (it is 0 us)"). NmtMaster::create refuses
  /// options that fail it.
  cfg::Status validate() const;
};

}  // namespace nmt
