// libFuzzer target: the SDO frame codec (nmt/sdo/sdo_frame.hpp). Input: any bytes, read as
// payloads of up to 8 bytes (a short one is padded with zeros, as sdo_payload does). Checks: no
// crash; for every payload that parses, as a client frame, a server frame or a sub-block frame,
// parsing its encoding gives the same value (parse(encode(x)) == x).
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <variant>

#include "nmt/sdo/sdo_frame.hpp"

namespace {

// Stops with the failed condition and its line, so a crash report says which promise broke.
#define check(condition) check_at((condition), #condition, __LINE__)
void check_at(bool ok, const char* what, int line) {
  if (ok) return;
  std::fprintf(stderr, "check failed at line %d: %s\n", line, what);
  std::abort();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace nmt::sdo;
  for (std::size_t at = 0; at < size || at == 0; at += 8) {
    Payload p{};
    std::copy_n(data + std::min(at, size), std::min<std::size_t>(8, size - std::min(at, size)),
                p.begin());
    if (auto f = parse_client_frame(p)) {
      auto again = parse_client_frame(encode(*f));
      check(again.has_value() && *again == *f);
    }
    if (auto f = parse_server_frame(p)) {
      auto again = parse_server_frame(encode(*f));
      check(again.has_value() && *again == *f);
    }
    const auto sub_block = parse_sub_block_frame(p);
    check(parse_sub_block_frame(encode(sub_block)) == sub_block);
    if (size == 0) break;
  }
  return 0;
}
