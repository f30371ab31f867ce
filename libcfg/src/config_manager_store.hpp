// The configuration manager's entry files and their directory (config_manager.hpp): the parts
// config_manager.cpp builds on.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/config_manager.hpp"

namespace cfg::detail {

/// How an entry's value is held in its file (and, for DCF/EDS texts, in memory).
enum class EntryEncoding : std::uint8_t { Raw = 0, Zlib = 1 };

/// An entry file's content: `stored` as in the file, `value` decoded.
struct DecodedEntry {
  std::uint16_t index = 0;
  NodeId node = *NodeId::from(1);
  EntryEncoding encoding = EntryEncoding::Raw;
  std::uint32_t value_size = 0;
  std::vector<std::uint8_t> stored;
  std::vector<std::uint8_t> value;
};

/// zlib-compressed bytes (compress2 at the default level).
std::vector<std::uint8_t> deflate_bytes(std::span<const std::uint8_t> bytes);
/// Inflates a zlib stream that must give exactly `size` bytes and end where `bytes` ends.
Result<std::vector<std::uint8_t>> inflate_bytes(std::span<const std::uint8_t> bytes,
                                                std::uint32_t size);

/// The file content for an entry whose value is already encoded (`stored`).
std::vector<std::uint8_t> encode_entry_file(std::uint16_t index, NodeId node,
                                            EntryEncoding encoding,
                                            std::span<const std::uint8_t> stored,
                                            std::uint32_t value_size);
/// decode_store_entry with the stored bytes kept.
Result<DecodedEntry> decode_entry_file(std::span<const std::uint8_t> bytes,
                                       std::string_view file_name);

/// The index and node a file name stands for ("1F22-05"); false for any other name.
bool parse_entry_file_name(std::string_view name, std::uint16_t& index, NodeId& node);

/// Replaces `directory`/`name` atomically: a temporary file ".<name>.<pid>.tmp" written, fsync'd,
/// renamed over `name`, then the directory fsync'd. Fails (Io) naming the file and the reason;
/// the old file is then untouched.
Status write_file_atomically(const std::string& directory, const std::string& name,
                             std::span<const std::uint8_t> bytes, const StoreWriteHooks& hooks);
/// Removes `directory`/`name` (absent is fine) and fsyncs the directory.
Status remove_file_durably(const std::string& directory, const std::string& name);

}  // namespace cfg::detail
