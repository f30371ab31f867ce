// The configuration manager's store and download plan (DSP 302 v3.2.1 §6, CiA 302-2 §3.5): per
// slave node-ID 1..127 its DCF (1F20h, storage format 1F21h), concise DCF (1F22h), EDS (1F23h,
// storage format 1F24h), expected configuration date/time (1F26h/1F27h), and the configure-slave
// request (1F25h). No bus I/O, no clock, no threads: an SDO server (the master's) feeds it the
// reads and writes it receives, and the NMT master asks it for a node's configuration.
//
// Persistence: optionally a directory, one file per entry, replaced atomically (written to a
// temporary file, fsync, rename, fsync of the directory), so that an interrupted write (kill -9,
// power cut) leaves the old or the new entry and never touches another; each file carries a
// CRC-32, and a damaged file is reported and never used.
//
// SDO abort codes (CiA 301 §7.2.4.3.17, cfg::SdoAbort of sdo_abort.hpp, which libnmt's SDO
// server sends as they are) as this manager answers them:
//   0504 0005h  (out of memory) an SDO write of 1F20h/1F22h/1F23h longer than
//               ConfigManagerLimits::max_entry_bytes, or one after which the values stored for
//               all nodes would exceed max_total_bytes (see ConfigManagerLimits, admits())
//   0601 0001h  read of 1F25h (write only: it is a command)
//   0601 0002h  write of sub-index 0 (NrOfEntries is read only)
//   0602 0000h  an index that is not 1F20h-1F27h
//   0607 0010h  1F21h/1F24h not 1 byte, 1F25h/1F26h/1F27h not 4 bytes
//   0609 0011h  sub-index above 7Fh (80h for 1F25h)
//   0609 0030h  1F21h/1F24h other than 0; 1F27h of 86 400 000 ms or more; a 1F22h stream that
//               is not a valid concise DCF; a 1F20h text that is no DCF or whose values cannot
//               be encoded (the message says why)
//   0800 0020h  1F25h with another value than 'conf'; the store directory could not be written
//               (the message names the file and the reason)
//   0800 0024h  read of 1F20h/1F21h/1F23h/1F24h with nothing stored (DSP 302 §6.1, §6.5);
//               1F25h sub 1..7Fh for a node with neither 1F22h nor 1F20h stored (§6.4)
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/concise_dcf.hpp"
#include "cfg/diagnostics.hpp"
#include "cfg/master_objects.hpp"
#include "cfg/node_id.hpp"
#include "cfg/object_index.hpp"
#include "cfg/result.hpp"
#include "cfg/sdo_abort.hpp"

namespace cfg {

/// 1F25h sub-index 80h: configure every node that has a configuration (DSP 302 §6.4).
inline constexpr std::uint8_t kConfigureAllNodes = 0x80;
/// 1F21h/1F24h value 0: "ASCII, not compressed", the only one defined (DSP 302 §6.1).
inline constexpr std::uint8_t kStorageFormatAscii = 0;
/// Milliseconds in a day: 1F27h/1020h sub 2 count ms after midnight.
inline constexpr std::uint32_t kMsPerDay = 86'400'000;

/// The answer to an SDO upload: the value's bytes, or an abort code and why.
struct ConfigRead {
  SdoAbort abort = SdoAbort::None;
  std::vector<std::uint8_t> data;  ///< little-endian for numbers, the file/stream for domains
  std::string message;             ///< why, when aborted
  bool ok() const { return abort == SdoAbort::None; }
};

/// The answer to an SDO download. A 1F25h write names the nodes the master is to configure now
/// (ascending; for sub 80h every node with a configuration, possibly none).
struct ConfigWrite {
  SdoAbort abort = SdoAbort::None;
  std::string message;  ///< why, when aborted (a 1F22h stream: the decoder's message)
  std::vector<NodeId> configure;
  bool ok() const { return abort == SdoAbort::None; }
};

/// A node's writes in download order, as the master sends them (CiA 302-2 §3.5).
struct DownloadPlan {
  /// The configuration in PDO-safe order (order_for_download), then 1020h sub 1 and sub 2 =
  /// 1F26h/1F27h when those are not both 0, then 1010h sub 1 = 'save' when asked for.
  std::vector<ObjectWrite> writes;
  /// From order_for_download: PDOs whose COB-ID is neither written nor known, and mappings
  /// written without their sub-index 0 (the master may read the device and order again).
  std::vector<std::uint16_t> unknown_cob_id;
  std::vector<std::uint16_t> unknown_mapping_count;
  /// Where the configuration came from.
  enum class Source : std::uint8_t { ConciseDcf, Dcf } source = Source::ConciseDcf;
};

struct PlanOptions {
  bool save = true;  ///< end with 1010h sub 1 = 'save' (kSaveSignature)
};

/// How the store writes files; for tests (the crash test) and nothing else.
struct StoreWriteHooks {
  /// Write each file in pieces of at most this many bytes (0: one write).
  std::size_t chunk_bytes = 0;
  /// Called after each piece is written (with the bytes written so far), after the fsync, after
  /// the rename and after the fsync of the directory (bytes = the file's size for those three).
  enum class Step : std::uint8_t { Wrote, Synced, Renamed, DirectorySynced };
  std::function<void(Step step, std::size_t bytes)> on_step;
};

// --- the entry files ----------------------------------------------------------------------------
// One file per entry, named "<index>-<node>" in upper-case hex ("1F22-05" is node 5's concise
// DCF; "1F26-05" holds 1F26h and 1F27h of node 5). Content, little-endian:
//   "CoCM" magic, UNSIGNED8 format version 1, UNSIGNED16 index, UNSIGNED8 node-ID,
//   UNSIGNED8 encoding (0 raw, 1 zlib), UNSIGNED32 stored size, UNSIGNED32 size once decoded,
//   the stored bytes, UNSIGNED32 CRC-32 (zlib's) of everything before it.
// Temporary files (".1F22-05.<pid>.tmp") start with '.' and are removed when the store is
// opened. Two processes may write one store; the last rename of an entry wins, and a manager
// sees the others' writes when it opens the store again.

/// What one entry file holds: the object, the node and the value (decoded).
struct StoreEntry {
  std::uint16_t index = 0;  ///< 1F20h, 1F22h, 1F23h or 1F26h (1F26h and 1F27h as 8 bytes)
  NodeId node = *NodeId::from(1);
  std::vector<std::uint8_t> value;
  bool operator==(const StoreEntry&) const = default;
};

/// The file name of an entry: "1F22-05".
std::string store_entry_file_name(std::uint16_t index, NodeId node);
/// The file content for an entry; DCF and EDS texts (1F20h, 1F23h) are zlib-compressed.
std::vector<std::uint8_t> encode_store_entry(const StoreEntry& entry);
/// Reads an entry file. Fails, saying what is wrong, on a short file, wrong magic or version, an
/// index other than 1F20h/1F22h/1F23h/1F26h, a node-ID outside 1..127, a size that does not
/// match the file, a CRC mismatch, a zlib stream that does not inflate to the announced size, a
/// 1F26h entry that is not 8 bytes, or (when `file_name` is not empty) a header that does not
/// match the file name. Never reads outside `bytes`; the announced decoded size is not trusted
/// beyond zlib's maximum ratio.
Result<StoreEntry> decode_store_entry(std::span<const std::uint8_t> bytes,
                                      std::string_view file_name = {});

/// A change of one entry that waits to be made durable: what an SDO write (stage()) or the C++
/// API decided, before anything is written. The owner writes it (ConfigManager::persist, disk
/// I/O) and then hands it back (ConfigManager::commit, memory only), so that a program that must
/// not wait for the disk in the middle of its work (the NMT master inside on_frame) can do the
/// write elsewhere and answer the SDO write once the entry is durable.
struct StoreUpdate {
  std::uint16_t index = 0;  ///< 1F20h, 1F22h, 1F23h or 1F26h (1F26h and 1F27h as one entry)
  NodeId node = *NodeId::from(1);
  bool remove = false;  ///< the entry goes (empty text, the empty data set, stamp {0, 0})
  /// The value as its file holds it (entry encoding `zlib`: DCF and EDS texts, compressed here,
  /// so the CPU work is done before the I/O), and its size once decoded.
  bool zlib = false;
  std::vector<std::uint8_t> stored;
  std::uint32_t value_size = 0;
};

// --- the manager --------------------------------------------------------------------------------

/// How much memory a peer on the bus can make the manager hold through SDO writes (write()):
/// a tool may write 1F20h, 1F22h and 1F23h for every node-ID, again and again. Beyond these
/// limits write() (and admits(), which an SDO server asks before it buffers a download) answers
/// 0504 0005h "out of memory": the manager has no room for the value, the value itself may be
/// fine (so not 0607 0012h, which says the data type's length is exceeded; a DOMAIN has none).
/// The owner's C++ API (put_dcf(), put_concise(), put_eds()) and the store directory are not
/// limited: a value stored that way counts against max_total_bytes all the same.
struct ConfigManagerLimits {
  /// Largest value of one 1F20h, 1F22h or 1F23h entry, in bytes as written (a DCF's text, a
  /// concise DCF's stream). The largest real DCF the project knows is about 290 KiB.
  std::size_t max_entry_bytes = std::size_t{1} << 20;
  /// Largest sum of the values of 1F20h, 1F22h and 1F23h of all nodes, in bytes as written
  /// (value_bytes(); texts are held zlib-compressed, so the heap they take, stored_bytes(), is
  /// at most this plus zlib's small overhead, about 0.03 % and 13 bytes per entry).
  std::size_t max_total_bytes = std::size_t{16} << 20;
};

class ConfigManager {
 public:
  /// An empty manager kept in memory only.
  ConfigManager();
  /// Opens (creating it when missing) a store directory and loads every entry file. A damaged
  /// file is one error diagnostic naming the file and what is wrong (see problems()); it is
  /// left on disk, unused, until the entry is written again. Fails (category Io) when the
  /// directory cannot be created, read or written.
  static Result<ConfigManager> open(const std::string& directory, StoreWriteHooks hooks = {});

  ConfigManager(ConfigManager&&) noexcept;
  ConfigManager& operator=(ConfigManager&&) noexcept;
  ConfigManager(const ConfigManager&) = delete;
  ConfigManager& operator=(const ConfigManager&) = delete;
  ~ConfigManager();

  /// The damaged entry files found by open(), with the file and what is wrong.
  const Diagnostics& problems() const;
  /// The directory, empty for a manager in memory.
  const std::string& directory() const;

  /// The limits of SDO writes (ConfigManagerLimits); a change applies to the next write.
  const ConfigManagerLimits& limits() const;
  void set_limits(ConfigManagerLimits limits);

  // SDO access, as the master's SDO server sees it (see the abort table at the top).
  ConfigRead read(std::uint16_t index, std::uint8_t sub_index) const;
  /// Whether an SDO write of `size` bytes to (index, sub_index) fits the limits: OutOfMemory
  /// when a 1F20h/1F22h/1F23h value of that size is longer than max_entry_bytes or would, in
  /// place of the node's value of that object, take value_bytes() above max_total_bytes; None
  /// otherwise (any other object, or a sub-index write() refuses for another reason). An SDO
  /// server asks it with the size a download indicates, else with the size received so far,
  /// so that an oversized download is refused before it is buffered; write() checks it too.
  SdoAbort admits(std::uint16_t index, std::uint8_t sub_index, std::size_t size) const;
  /// An SDO write: stage(), then persist() and commit() of its update at once. The disk I/O
  /// (fsync included) happens inside this call.
  ConfigWrite write(std::uint16_t index, std::uint8_t sub_index,
                    std::span<const std::uint8_t> data);
  /// An SDO write checked and decided as write() does (same answers, same abort codes), without
  /// I/O and without changing anything: when it is accepted and changes a stored entry,
  /// `update` holds the change, which takes effect with persist() and commit(); 1F21h/1F24h
  /// (nothing to store) and 1F25h leave it empty. The manager's values stay the old ones until
  /// commit(), so a read meanwhile gives the old value; two staged updates of one entry take
  /// effect in the order they are committed (each is the whole entry), so the owner stages 1F26h
  /// and 1F27h of a node one at a time (the master's SDO server answers one write at a time).
  ConfigWrite stage(std::uint16_t index, std::uint8_t sub_index, std::span<const std::uint8_t> data,
                    std::optional<StoreUpdate>& update) const;
  /// set_expected_stamp() staged: fails for ms >= kMsPerDay.
  Result<StoreUpdate> stage_expected_stamp(NodeId node, ConfigurationStamp stamp) const;
  /// True when the manager has a store directory, so an update needs persist() before commit().
  bool persistent() const { return !directory().empty(); }
  /// Writes (or removes) the update's entry file, atomically and durably (see the top); nothing
  /// without a store directory. Fails (category Io) naming the file and the reason; the old file
  /// is then untouched. Changes no value of the manager: only files, so a driver may run it
  /// where the disk may take its time (the master's event loop, after the engine's call).
  Status persist(const StoreUpdate& update) const;
  /// The manager takes the update's value (memory only). Call it after persist() succeeded, so
  /// that memory never holds a value the directory does not.
  void commit(StoreUpdate update);

  // The C++ API. Writes persist before they return (store directory), and fail with the
  // file and the reason when the directory cannot be written (the entry keeps its old value).

  /// Stores a DCF text (1F20h) after checking that it reads without errors and that its values
  /// encode (concise_writes_from_dcf with $NODEID = node). Empty text removes the entry.
  Status put_dcf(NodeId node, std::string_view text);
  /// Stores a concise DCF stream (1F22h) after decoding it. The empty data set (count 0, DSP
  /// 302 §6.2 application hint 1) removes the entry.
  Status put_concise(NodeId node, std::span<const std::uint8_t> stream);
  /// Stores an EDS text (1F23h), unchecked. Empty text removes the entry.
  Status put_eds(NodeId node, std::string_view text);
  /// Sets 1F26h/1F27h; {0, 0} ("do not verify") removes the entry. Precondition-free: fails for
  /// ms >= kMsPerDay.
  Status set_expected_stamp(NodeId node, ConfigurationStamp stamp);

  /// nullopt when nothing is stored.
  std::optional<std::string> dcf(NodeId node) const;
  std::optional<std::vector<std::uint8_t>> concise(NodeId node) const;
  std::optional<std::string> eds(NodeId node) const;
  /// {0, 0} when not set.
  ConfigurationStamp expected_stamp(NodeId node) const;

  /// True when the node has a concise DCF or a DCF (what 1F25h and the plan need).
  bool has_configuration(NodeId node) const;
  /// Nodes with a configuration, ascending.
  std::vector<NodeId> configured_nodes() const;

  /// The writes that configure `node`, without 1020h and 1010h (the master adds them): the
  /// concise DCF's entries as stored, else the DCF's (concise_writes_from_dcf, PDO-safe order).
  /// nullopt when neither is stored, or when a stored DCF no longer encodes (see
  /// configuration_or_error). This is nmt::ConfigurationSource::configuration.
  std::optional<std::vector<ObjectWrite>> configuration(NodeId node) const;
  /// The same, failing with a message when nothing is stored or the DCF does not encode.
  Result<std::vector<ObjectWrite>> configuration_or_error(NodeId node) const;
  /// The node's download plan (DownloadPlan); fails like configuration_or_error.
  Result<DownloadPlan> download_plan(NodeId node, const PlanOptions& options = {}) const;

  /// Bytes of heap the stored values take (their capacities; not the bookkeeping).
  std::size_t stored_bytes() const;
  /// The size of the stored 1F20h, 1F22h and 1F23h values of all nodes as written (texts
  /// before compression): what ConfigManagerLimits::max_total_bytes bounds.
  std::size_t value_bytes() const;

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace cfg
