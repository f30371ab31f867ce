// libFuzzer target: decoding python-can udp_multicast datagrams (nmt/io/udp_datagram.hpp), the
// bytes any host on the group can send us. Checks: no crash and no allocation beyond the
// datagram's size (msgpack-c allocates containers by their announced size; -malloc_limit_mb
// catches a guard that lets one through); an accepted datagram re-encodes to one that decodes to
// the same frame.
#include <cstdint>
#include <cstdlib>
#include <span>

#include "nmt/io/udp_datagram.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  auto frame = nmt::decode_udp_datagram(std::span<const std::uint8_t>(data, size));
  if (!frame) return 0;
  auto again = nmt::encode_udp_datagram(*frame, 0.0);
  if (!again) std::abort();  // a frame we accept must be one python-can accepts
  auto back = nmt::decode_udp_datagram(*again);
  if (!back || !(*back == *frame)) std::abort();
  return 0;
}
