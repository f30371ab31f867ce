// libFuzzer target: the concise DCF streaming decoder (DSP 302 v3.2.1 §6.2).
// Input: byte 0 seeds the chunking, the rest is the stream. Checks the promises of
// cfg/concise_dcf.hpp: no crash and no allocation beyond the bytes fed (libFuzzer's
// -rss_limit_mb / -malloc_limit_mb catch a decoder that trusts an announced size); feeding the
// stream in random chunks gives the same entries or the same error as decoding it at once; an
// accepted stream consumed every byte and encodes back to exactly the same bytes.
#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <span>
#include <vector>

#include "cfg/concise_dcf.hpp"

namespace {

void check(bool condition) {
  if (!condition) std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size == 0) return 0;
  std::uint32_t rng = data[0] * 2654435761u + 1u;
  const std::span<const std::uint8_t> stream(data + 1, size - 1);

  auto whole = cfg::decode_concise_dcf(stream);

  std::vector<cfg::ObjectWrite> entries;
  cfg::ConciseDcfDecoder decoder(
      [&entries](std::uint16_t index, std::uint8_t sub, std::span<const std::uint8_t> bytes) {
        entries.push_back({index, sub, {bytes.begin(), bytes.end()}});
      });
  cfg::Status status;
  std::size_t pos = 0;
  while (status.ok() && pos < stream.size()) {
    rng = rng * 1664525u + 1013904223u;  // LCG: chunk sizes 0..32, sometimes 0
    const std::size_t n = std::min<std::size_t>((rng >> 16) % 33, stream.size() - pos);
    status = decoder.feed(stream.subspan(pos, n));
    pos += n;
  }
  if (status.ok()) status = decoder.finish();

  check(whole.ok() == status.ok());
  if (!whole.ok()) {
    check(whole.error() == status.error());
    return 0;
  }
  check(*whole == entries);
  check(decoder.bytes_consumed() == stream.size());
  check(decoder.entries_read() == entries.size());
  const auto encoded = cfg::encode_concise_dcf(entries);
  check(encoded.size() == stream.size() &&
        std::equal(encoded.begin(), encoded.end(), stream.begin()));
  return 0;
}
