// The configuration manager's entry files (format in config_manager.hpp) and their crash-safe
// replacement in the store directory.
#include <fcntl.h>
#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <new>

#include "cfg/atomic_file.hpp"
#include "cfg/bytes.hpp"
#include "cfg/hex.hpp"
#include "config_manager_store.hpp"

namespace cfg {
namespace detail {
namespace {

constexpr std::uint8_t kMagic[4] = {'C', 'o', 'C', 'M'};
constexpr std::uint8_t kFormatVersion = 1;
// magic 4, version 1, index 2, node 1, encoding 1, stored size 4, value size 4
constexpr std::size_t kHeaderSize = 17;
constexpr std::size_t kCrcSize = 4;
// deflate cannot do better than about 1032:1 (zlib technical details), so a header announcing
// more is damaged, and inflating never allocates more than that for a given file.
constexpr std::uint64_t kMaxDeflateRatio = 1032;
// The 8 bytes of a 1F26h entry: 1F26h then 1F27h, each UNSIGNED32.
constexpr std::uint32_t kStampEntrySize = 8;

bool is_entry_index(std::uint16_t index) {
  return index == object::kStoreDcf || index == object::kConciseDcf || index == object::kStoreEds ||
         index == object::kExpectedConfigurationDate;
}

Error io_error(const std::string& what, const std::string& path) {
  return Error{what + " '" + path + "': " + std::strerror(errno), ErrorCategory::Io};
}

Status sync_directory(const std::string& directory) {
  const int fd = ::open(directory.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return io_error("cannot open the store directory", directory);
  // The rename or unlink is durable only once the directory itself is on disk.
  const bool ok = ::fsync(fd) == 0;
  const Error error = ok ? Error{} : io_error("cannot sync the store directory", directory);
  ::close(fd);
  if (!ok) return error;
  return {};
}

}  // namespace

std::vector<std::uint8_t> deflate_bytes(std::span<const std::uint8_t> bytes) {
  uLongf size = ::compressBound(static_cast<uLong>(bytes.size()));
  std::vector<std::uint8_t> out(size);
  if (::compress2(out.data(), &size, bytes.data(), static_cast<uLong>(bytes.size()),
                  Z_DEFAULT_COMPRESSION) != Z_OK) {
    throw std::bad_alloc();  // compress2 fails only for lack of memory with a bound-sized buffer
  }
  out.resize(size);
  out.shrink_to_fit();
  return out;
}

Result<std::vector<std::uint8_t>> inflate_bytes(std::span<const std::uint8_t> bytes,
                                                std::uint32_t size) {
  if (size > bytes.size() * kMaxDeflateRatio + 64) {
    return Error{"the decoded size " + std::to_string(size) + " is more than " +
                 std::to_string(bytes.size()) + " compressed bytes can give"};
  }
  // One spare byte tells "exactly size" from "more than size".
  std::vector<std::uint8_t> out(std::size_t{size} + 1);
  uLongf out_size = static_cast<uLongf>(out.size());
  uLong in_size = static_cast<uLong>(bytes.size());
  const int rc = ::uncompress2(out.data(), &out_size, bytes.data(), &in_size);
  if (rc != Z_OK) {
    return Error{std::string("the compressed value does not inflate (zlib: ") +
                 (rc == Z_DATA_ERROR  ? "data error"
                  : rc == Z_BUF_ERROR ? "longer than announced or truncated"
                                      : "out of memory") +
                 ")"};
  }
  if (out_size != size) {
    return Error{"the compressed value inflates to " + std::to_string(out_size) +
                 " bytes, the header announces " + std::to_string(size)};
  }
  if (in_size != bytes.size()) {
    return Error{"bytes after the end of the compressed value"};
  }
  out.pop_back();
  return out;
}

std::vector<std::uint8_t> encode_entry_file(std::uint16_t index, NodeId node,
                                            EntryEncoding encoding,
                                            std::span<const std::uint8_t> stored,
                                            std::uint32_t value_size) {
  // Sized once and filled in place (inserting piece by piece trips GCC 12's
  // -Wstringop-overflow false positive).
  std::vector<std::uint8_t> out(kHeaderSize + stored.size() + kCrcSize);
  const std::span<std::uint8_t> bytes(out);
  std::copy(std::begin(kMagic), std::end(kMagic), out.begin());
  out[4] = kFormatVersion;
  store_le(index, bytes.subspan(5), 2);
  out[7] = node.value();
  out[8] = static_cast<std::uint8_t>(encoding);
  store_le(stored.size(), bytes.subspan(9), 4);
  store_le(value_size, bytes.subspan(13), 4);
  std::copy(stored.begin(), stored.end(), out.begin() + kHeaderSize);
  const std::size_t body = kHeaderSize + stored.size();
  store_le(cfg::crc32(bytes.first(body)), bytes.subspan(body), 4);
  return out;
}

Result<DecodedEntry> decode_entry_file(std::span<const std::uint8_t> bytes,
                                       std::string_view file_name) {
  if (bytes.size() < kHeaderSize + kCrcSize) {
    return Error{"the file has " + std::to_string(bytes.size()) + " bytes, less than the " +
                 std::to_string(kHeaderSize + kCrcSize) + " of an empty entry"};
  }
  if (!std::equal(std::begin(kMagic), std::end(kMagic), bytes.begin())) {
    return Error{"not an entry file of the configuration manager (no 'CoCM' at the start)"};
  }
  if (bytes[4] != kFormatVersion) {
    return Error{"format version " + std::to_string(bytes[4]) + ", expected " +
                 std::to_string(kFormatVersion)};
  }
  const std::uint32_t stored_size = load_le32(bytes.subspan(9));
  if (stored_size != bytes.size() - kHeaderSize - kCrcSize) {
    return Error{"the header announces " + std::to_string(stored_size) +
                 " stored bytes, the file holds " +
                 std::to_string(bytes.size() - kHeaderSize - kCrcSize) + " (truncated file?)"};
  }
  const std::uint32_t crc_read = load_le32(bytes.subspan(bytes.size() - kCrcSize));
  const std::uint32_t crc_computed = cfg::crc32(bytes.first(bytes.size() - kCrcSize));
  if (crc_read != crc_computed) {
    return Error{"CRC-32 mismatch: the file says " + hex(crc_read, 8) + ", its content gives " +
                 hex(crc_computed, 8)};
  }
  DecodedEntry entry;
  entry.index = load_le16(bytes.subspan(5));
  if (!is_entry_index(entry.index)) {
    return Error{"index " + hex(entry.index, 4) + " is not 1F20h, 1F22h, 1F23h or 1F26h"};
  }
  const auto node = NodeId::from(bytes[7]);
  if (!node) return Error{"node-ID " + std::to_string(bytes[7]) + " is not 1..127"};
  entry.node = *node;
  if (!file_name.empty()) {
    std::uint16_t name_index = 0;
    NodeId name_node = entry.node;
    if (!parse_entry_file_name(file_name, name_index, name_node) || name_index != entry.index ||
        name_node != entry.node) {
      return Error{"the file holds " + store_entry_file_name(entry.index, entry.node) +
                   ", not what its name says"};
    }
  }
  entry.value_size = load_le32(bytes.subspan(13));
  const auto stored = bytes.subspan(kHeaderSize, stored_size);
  switch (bytes[8]) {
    case static_cast<std::uint8_t>(EntryEncoding::Raw):
      if (entry.value_size != stored_size) {
        return Error{"the header announces " + std::to_string(entry.value_size) + " value bytes, " +
                     std::to_string(stored_size) + " are stored"};
      }
      entry.value.assign(stored.begin(), stored.end());
      break;
    case static_cast<std::uint8_t>(EntryEncoding::Zlib): {
      entry.encoding = EntryEncoding::Zlib;
      auto value = inflate_bytes(stored, entry.value_size);
      if (!value) return value.error();
      entry.value = std::move(*value);
      break;
    }
    default:
      return Error{"encoding " + std::to_string(bytes[8]) + " is neither 0 (raw) nor 1 (zlib)"};
  }
  if (entry.index == object::kExpectedConfigurationDate && entry.value.size() != kStampEntrySize) {
    return Error{"a 1F26h/1F27h entry holds " + std::to_string(entry.value.size()) +
                 " bytes, not 8"};
  }
  entry.stored.assign(stored.begin(), stored.end());
  return entry;
}

bool parse_entry_file_name(std::string_view name, std::uint16_t& index, NodeId& node) {
  if (name.size() != 7 || name[4] != '-') return false;
  const auto i = parse_hex_number(name.substr(0, 4), 4);
  const auto n = parse_hex_number(name.substr(5, 2), 2);
  if (!i || !n || !is_entry_index(static_cast<std::uint16_t>(*i))) return false;
  const auto id = NodeId::from(*n);
  if (!id) return false;
  // Upper-case only, so one entry has one name.
  if (store_entry_file_name(static_cast<std::uint16_t>(*i), *id) != name) return false;
  index = static_cast<std::uint16_t>(*i);
  node = *id;
  return true;
}

Status write_file_atomically(const std::string& directory, const std::string& name,
                             std::span<const std::uint8_t> bytes, const StoreWriteHooks& hooks) {
  const std::string path = directory + "/" + name;
  // Named after the process too, so that two processes writing one entry at once (a tool and a
  // running master on one store) never write into the same temporary file.
  const std::string temporary = directory + "/." + name + "." + std::to_string(::getpid()) + ".tmp";
  const int fd = ::open(temporary.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return io_error("cannot create", temporary);
  auto fail = [&](const std::string& what) {
    Error error = io_error(what, temporary);
    ::close(fd);
    ::unlink(temporary.c_str());
    return error;
  };
  const std::size_t chunk = hooks.chunk_bytes == 0 ? bytes.size() : hooks.chunk_bytes;
  std::size_t written = 0;
  while (written < bytes.size()) {
    const std::size_t n = std::min(chunk, bytes.size() - written);
    const ssize_t rc = ::write(fd, bytes.data() + written, n);
    if (rc < 0 && errno == EINTR) continue;
    if (rc < 0) return fail("cannot write");
    written += static_cast<std::size_t>(rc);
    if (hooks.on_step) hooks.on_step(StoreWriteHooks::Step::Wrote, written);
  }
  // The content is on disk before the name points at it: a crash after the rename never finds
  // a name with missing data.
  if (::fsync(fd) != 0) return fail("cannot sync");
  if (hooks.on_step) hooks.on_step(StoreWriteHooks::Step::Synced, bytes.size());
  if (::close(fd) != 0) {
    Error error = io_error("cannot close", temporary);
    ::unlink(temporary.c_str());
    return error;
  }
  // rename(2) replaces atomically: every reader (and a restart) sees the old or the new file.
  if (::rename(temporary.c_str(), path.c_str()) != 0) {
    Error error = io_error("cannot rename to '" + path + "'", temporary);
    ::unlink(temporary.c_str());
    return error;
  }
  if (hooks.on_step) hooks.on_step(StoreWriteHooks::Step::Renamed, bytes.size());
  if (auto synced = sync_directory(directory); !synced) return synced;
  if (hooks.on_step) hooks.on_step(StoreWriteHooks::Step::DirectorySynced, bytes.size());
  return {};
}

Status remove_file_durably(const std::string& directory, const std::string& name) {
  const std::string path = directory + "/" + name;
  if (::unlink(path.c_str()) != 0 && errno != ENOENT) return io_error("cannot remove", path);
  return sync_directory(directory);
}

}  // namespace detail

Status write_file_atomically(const std::string& directory, const std::string& name,
                             std::span<const std::uint8_t> bytes) {
  return detail::write_file_atomically(directory, name, bytes, {});
}

std::string store_entry_file_name(std::uint16_t index, NodeId node) {
  return hex_digits(index, 4) + "-" + hex_digits(node.value(), 2);
}

std::vector<std::uint8_t> encode_store_entry(const StoreEntry& entry) {
  const auto size = static_cast<std::uint32_t>(entry.value.size());
  if (entry.index == object::kStoreDcf || entry.index == object::kStoreEds) {
    return detail::encode_entry_file(entry.index, entry.node, detail::EntryEncoding::Zlib,
                                     detail::deflate_bytes(entry.value), size);
  }
  return detail::encode_entry_file(entry.index, entry.node, detail::EntryEncoding::Raw, entry.value,
                                   size);
}

Result<StoreEntry> decode_store_entry(std::span<const std::uint8_t> bytes,
                                      std::string_view file_name) {
  auto decoded = detail::decode_entry_file(bytes, file_name);
  if (!decoded) return decoded.error();
  return StoreEntry{decoded->index, decoded->node, std::move(decoded->value)};
}

}  // namespace cfg
