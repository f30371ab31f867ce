// CiA 302 concise DCF: the stream stored in object 1F22h (DSP 302 v3.2.1 §6.2 "Concise
// configuration storage").
//   UNSIGNED32 number of entries, then per entry: UNSIGNED16 index, UNSIGNED8 sub-index,
//   UNSIGNED32 data size in bytes, data. All little-endian. A count of 0 is the empty data set.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "cfg/diagnostics.hpp"
#include "cfg/object_dictionary.hpp"
#include "cfg/result.hpp"

namespace cfg {

/// One SDO write of a configuration: what a concise DCF entry holds, and what the configuration
/// manager downloads.
struct ObjectWrite {
  std::uint16_t index = 0;
  std::uint8_t sub_index = 0;
  std::vector<std::uint8_t> data;
  bool operator==(const ObjectWrite&) const = default;
};

/// Encodes entries as a concise DCF stream, in the given order. Precondition: every entry's data
/// is below 4 GiB (the size field is UNSIGNED32); throws std::length_error otherwise.
std::vector<std::uint8_t> encode_concise_dcf(std::span<const ObjectWrite> entries);

/// Streaming decoder: feed bytes in chunks of any size; it holds at most one entry, and grows
/// an entry's buffer as its bytes arrive (an announced size is not trusted, so a stream that
/// announces 4 GiB and ends costs nothing). Byte offsets in messages count from 0 at the first
/// byte of the stream. Entries are delivered as they complete, so a stream that fails later
/// has already delivered its good entries: use decode_concise_dcf or check finish() before
/// acting on them.
class ConciseDcfDecoder {
 public:
  /// Called for each complete entry; data is valid only during the call.
  using EntryHandler = std::function<void(std::uint16_t index, std::uint8_t sub_index,
                                          std::span<const std::uint8_t> data)>;
  explicit ConciseDcfDecoder(EntryHandler on_entry);

  /// Consumes bytes. Fails (and stays failed) on bytes after the last announced entry; the
  /// message names the byte offset.
  Status feed(std::span<const std::uint8_t> bytes);
  /// Ends the stream. Fails on a truncated stream (count or an entry incomplete), naming the
  /// byte offset and how many entries were announced and read.
  Status finish();

  std::uint64_t bytes_consumed() const { return offset_; }
  std::uint32_t entries_read() const { return entries_read_; }
  /// The entry count from the first 4 bytes (0 until they were fed).
  std::uint32_t entries_announced() const { return entries_announced_; }

 private:
  Status fail(std::string message);
  void deliver();

  enum class Stage { Count, Header, Data, Done, Failed };
  EntryHandler on_entry_;
  Stage stage_ = Stage::Count;
  std::uint64_t offset_ = 0;
  std::uint32_t entries_announced_ = 0;
  std::uint32_t entries_read_ = 0;
  std::uint8_t header_[7] = {};
  std::size_t header_fill_ = 0;
  std::uint64_t entry_start_ = 0;
  std::uint16_t index_ = 0;
  std::uint8_t sub_index_ = 0;
  std::uint32_t size_ = 0;
  std::vector<std::uint8_t> data_;
  Error error_;
};

/// Decodes a whole stream held in memory; fails like the streaming decoder.
Result<std::vector<ObjectWrite>> decode_concise_dcf(std::span<const std::uint8_t> bytes);

/// Which values of a DCF go into its concise DCF. An empty ParameterValue/DefaultValue counts
/// as absent (CANopenEditor writes "ParameterValue=" for every entry it does not configure).
/// A DOMAIN with a DownloadFile is always taken, its content being the file.
enum class ConciseSelection {
  Configured,    ///< every writable sub-object with a ParameterValue (default)
  ChangedOnly,   ///< only ParameterValues whose value differs from DefaultValue's
  WithDefaults,  ///< ParameterValue, else DefaultValue, for every writable sub-object
};

struct ConciseOptions {
  std::optional<std::uint8_t> node_id;  ///< overrides [DeviceComissioning] NodeID
  ConciseSelection selection = ConciseSelection::Configured;
  /// Directory DownloadFile/UploadFile paths are relative to (usually the DCF's directory).
  std::string base_dir;
  std::string file_name;  ///< for diagnostics
  /// How the caller's user gives a node-ID (e.g. a tool's "give one with --node-id N"), added to
  /// the message when a value needs one and none is known. Empty: the message ends there.
  std::string node_id_hint;
};

/// The writes a DCF configures, in PDO-safe order (see download_order.hpp). Never 1010h/1011h,
/// never ro/const entries, never 0001h-0FFFh (data type definitions), never entries whose
/// ObjFlags bit 0 is set (CiA 306 "refuse write on download"). $NODEID is resolved with the
/// node-ID of the options, else of [DeviceComissioning]; a value that needs one when there is
/// none is an error. A value that cannot be encoded (not a value of its type, out of range,
/// DataType not basic, DownloadFile missing) is an error diagnostic with file:line; the result
/// is nullopt when there is any error. When a PDO mapping's entries are selected but not its
/// sub-index 0, sub-index 0 is added with the DCF's value so that the mapping can be
/// deactivated and restored around them; the COB-ID for the invalid/valid pair comes from the
/// writes or else from the DCF (ParameterValue, else DefaultValue). Where neither is there, a
/// warning says the PDO rule could not be applied in full.
std::optional<std::vector<ObjectWrite>> concise_writes_from_dcf(const DeviceDescription& dcf,
                                                                const ConciseOptions& options,
                                                                Diagnostics& diagnostics);

}  // namespace cfg
