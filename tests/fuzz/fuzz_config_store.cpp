// libFuzzer target: the configuration manager's entry files (cfg/config_manager.hpp), as
// decode_store_entry reads them and as ConfigManager::open loads them from a store directory.
// Input: byte 0, then the bytes of one entry file; when byte 0 is odd, the file's last 4 bytes
// are replaced by the right CRC-32 first, so that the fuzzer gets past the checksum to the
// header, zlib and concise DCF checks behind it. Checks: no crash, no allocation beyond zlib's
// ratio of the input (-rss_limit_mb / -malloc_limit_mb); an accepted file decodes again to the same
// entry once re-encoded, and re-encodes to the same bytes when it is stored raw (1F22h, 1F26h); the
// store directory never both uses an entry and reports its file as damaged, and reports every file
// decode_store_entry rejects.
#include <stdlib.h>
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <span>
#include <string>
#include <vector>

#include "cfg/config_manager.hpp"

namespace {

/// Aborts (a crash for libFuzzer) naming the check's line, so a finding says which rule broke.
/// (A function with std::source_location would do, but clang 14 lacks it.)
void fail_check(int line) {
  std::fprintf(stderr, "fuzz_config_store: check at line %d failed\n", line);
  std::abort();
}
#define check(condition) ((condition) ? void() : fail_check(__LINE__))

const std::string& store_directory() {
  static const std::string dir = [] {
    std::string pattern = (std::filesystem::temp_directory_path() / "fuzz-config-store-XXXXXX");
    check(::mkdtemp(pattern.data()) != nullptr);
    return pattern;
  }();
  return dir;
}

/// CRC-32 (IEEE 802.3, reflected, as zlib's crc32), bit by bit: an independent implementation.
std::uint32_t crc32(std::span<const std::uint8_t> bytes) {
  std::uint32_t crc = 0xFFFFFFFF;
  for (std::uint8_t b : bytes) {
    crc ^= b;
    for (int bit = 0; bit < 8; ++bit) crc = (crc >> 1) ^ (0xEDB88320U & (0U - (crc & 1U)));
  }
  return ~crc;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* input, std::size_t input_size) {
  if (input_size == 0) return 0;
  std::vector<std::uint8_t> file(input + 1, input + input_size);
  if ((input[0] & 1) != 0 && file.size() >= 4) {
    const std::uint32_t crc = crc32(std::span(file).first(file.size() - 4));
    for (int i = 0; i < 4; ++i)
      file[file.size() - 4 + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  }
  const std::uint8_t* data = file.data();
  const std::size_t size = file.size();
  const std::span<const std::uint8_t> bytes(file);
  auto entry = cfg::decode_store_entry(bytes);
  if (entry) {
    const auto encoded = cfg::encode_store_entry(*entry);
    auto again =
        cfg::decode_store_entry(encoded, cfg::store_entry_file_name(entry->index, entry->node));
    check(again.ok() && *again == *entry);
    // The writer stores 1F22h and 1F26h raw; a file that holds them zlib-compressed (header byte
    // 8) decodes to the same entry but is not the writer's form, so the bytes differ.
    constexpr std::size_t kEncodingByte = 8;
    const bool raw = size > kEncodingByte && data[kEncodingByte] == 0;
    if (raw && (entry->index == cfg::object::kConciseDcf ||
                entry->index == cfg::object::kExpectedConfigurationDate)) {
      check(encoded.size() == size && std::equal(encoded.begin(), encoded.end(), data));
    }
  }

  // The same bytes as a file of a store directory, under the name its header claims (or a
  // concise DCF's name when it has none).
  const std::string& dir = store_directory();
  for (const auto& old : std::filesystem::directory_iterator(dir)) {
    std::filesystem::remove(old.path());
  }
  const cfg::NodeId node = entry ? entry->node : *cfg::NodeId::from(1);
  const std::uint16_t index = entry ? entry->index : cfg::object::kConciseDcf;
  const std::string name = cfg::store_entry_file_name(index, node);
  std::ofstream(dir + "/" + name, std::ios::binary)
      .write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
  auto manager = cfg::ConfigManager::open(dir);
  check(manager.ok());
  const bool reported = !manager->problems().empty();
  const bool used = manager->has_configuration(node) || manager->dcf(node).has_value() ||
                    manager->eds(node).has_value() || !manager->expected_stamp(node).is_zero();
  check(!(reported && used));
  if (!entry) check(reported);
  if (used) {
    // Whatever is used is served: the SDO view of it reads.
    check(manager->read(index, node.value()).ok());
    if (manager->has_configuration(node)) check(manager->download_plan(node).ok());
  }
  return 0;
}
