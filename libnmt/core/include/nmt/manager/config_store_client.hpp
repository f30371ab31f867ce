// A client of a configuration manager's store (DSP 302 §6): 1F20h DCF, 1F22h concise DCF,
// 1F23h EDS, 1F26h/1F27h expected configuration date/time and 1F25h configure slave, as a
// CANopen tool sees them: index, sub-index = node-ID, SDO abort codes. The operations
// (`cfgmgr store put|get|list|rm|configure`) are one sequence of object reads and writes,
// whatever holds the objects:
//   - a store directory: StoreDirectoryObjects (a cfg::ConfigManager, read and written directly);
//   - a running master's configuration manager over SDO: nmt::open_remote_store
//     (nmt/io/remote_config_store.hpp, libnmt io).
// Tools hold no protocol (an embedder needs the same rules): the rules of what a put also writes
// (1F26h/1F27h) and what a removal writes live here, with their tests.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cfg/config_manager.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_address.hpp"
#include "cfg/result.hpp"
#include "nmt/sdo/sdo_abort.hpp"

namespace nmt {

/// The three files a configuration manager stores per node (DSP 302 §6.1, §6.2, §6.5).
enum class StoreFile : std::uint8_t {
  Dcf,      ///< 1F20h store DCF
  Concise,  ///< 1F22h concise DCF
  Eds,      ///< 1F23h store EDS
};

/// The object a file is stored in.
std::uint16_t store_index(StoreFile file);

/// The answer of one object access.
struct StoreAccess {
  SdoAbort abort = SdoAbort::None;  ///< CiA 301 §7.2.4.3.17; None: done
  std::vector<std::uint8_t> data;   ///< the value read
  std::string message;              ///< the manager's words, when it has them
  /// The store directory could not be written, or the master did not answer: an I/O failure
  /// (tools: exit 3), not a refusal of the value.
  bool io = false;
  bool ok() const { return abort == SdoAbort::None; }
};

/// The objects of a configuration manager, however they are reached. An Error (category Io)
/// only when the way there failed (the bus); refusals are StoreAccess::abort.
class StoreObjects {
 public:
  virtual ~StoreObjects() = default;
  virtual cfg::Result<StoreAccess> read(cfg::ObjectAddress address) = 0;
  virtual cfg::Result<StoreAccess> write(cfg::ObjectAddress address,
                                         std::vector<std::uint8_t> data) = 0;
  /// True for a running master (1F25h configure slave asks it to act; a directory cannot).
  virtual bool remote() const = 0;
};

/// A store directory (or an in-memory manager) through cfg::ConfigManager's object view.
class StoreDirectoryObjects final : public StoreObjects {
 public:
  explicit StoreDirectoryObjects(cfg::ConfigManager manager) : manager_(std::move(manager)) {}
  cfg::Result<StoreAccess> read(cfg::ObjectAddress address) override;
  cfg::Result<StoreAccess> write(cfg::ObjectAddress address,
                                 std::vector<std::uint8_t> data) override;
  bool remote() const override { return false; }
  const cfg::ConfigManager& manager() const { return manager_; }

 private:
  cfg::ConfigManager manager_;
};

/// What is stored for one node.
struct StoreNodeSummary {
  cfg::NodeId node = *cfg::NodeId::from(1);
  std::optional<std::size_t> dcf_bytes;  ///< nullopt: nothing stored (0800 0024h)
  std::optional<std::size_t> eds_bytes;
  std::size_t concise_entries = 0;
  std::size_t concise_bytes = 0;  ///< 0: none (an empty 1F22h reads as the 4-byte count 0)
  cfg::ConfigurationStamp stamp;  ///< 1F26h/1F27h
  bool empty() const { return !dcf_bytes && !eds_bytes && concise_bytes == 0 && stamp.is_zero(); }
};

/// The store operations. Every failure is an Error naming the object ("1F22h sub 05h: ...")
/// with the manager's words and the CiA 301 code in words; category Io when the store could
/// not be written or the master did not answer, else Input.
class ConfigStoreClient {
 public:
  explicit ConfigStoreClient(StoreObjects& objects) : objects_(objects) {}
  /// Whether the objects are a running master's (configure() needs one).
  bool remote() const { return objects_.remote(); }

  /// Stores `data` as `file` of `node`. A DCF or concise DCF is first checked as the manager
  /// checks it (in memory, so a file the master would refuse is refused before the bus; the
  /// error is the manager's message), and afterwards 1F26h/1F27h are set to the stamp of its
  /// writes (cfg::configuration_stamp, the rule of derived masters, cfg/network.hpp), so the
  /// master downloads it once and then skips a device whose 1020h matches (DSP 302 §6.6).
  /// Returns that stamp (nullopt for an EDS).
  cfg::Result<std::optional<cfg::ConfigurationStamp>> put(cfg::NodeId node, StoreFile file,
                                                          std::vector<std::uint8_t> data);
  /// What is stored as `file` of `node` (for 1F22h with nothing stored: the network's
  /// configuration when the master has one, DSP 302 §6.2).
  cfg::Result<std::vector<std::uint8_t>> get(cfg::NodeId node, StoreFile file);
  /// What is stored for `node`.
  cfg::Result<StoreNodeSummary> summary(cfg::NodeId node);
  /// The summaries of nodes 1..127 with something stored, ascending.
  cfg::Result<std::vector<StoreNodeSummary>> list();
  /// Removes everything stored for `node`: 1F22h = the stream with count 0 (§6.2 application
  /// hint 1), empty 1F20h and 1F23h, 1F26h/1F27h = 0 ("do not verify", §6.6).
  cfg::Status remove(cfg::NodeId node);
  /// Asks a running master to configure `node` now, or every node (nullopt: sub 80h):
  /// 1F25h = 'conf' (666E6F63h, DSP 302 §6.4). Input error when the objects are not remote.
  cfg::Status configure(std::optional<cfg::NodeId> node);

 private:
  cfg::Result<StoreAccess> must(cfg::ObjectAddress address, cfg::Result<StoreAccess> access);
  cfg::Status write(cfg::ObjectAddress address, std::vector<std::uint8_t> data);
  cfg::Result<std::uint32_t> read_u32(cfg::ObjectAddress address);

  StoreObjects& objects_;
};

/// The error ConfigStoreClient reports for a refused access: the object, the manager's words
/// when it has them, and always the CiA 301 code with its text.
cfg::Error store_access_error(cfg::ObjectAddress address, const StoreAccess& access);

}  // namespace nmt
