// An embedder's program against the installed libraries (tests/install/install_test.sh): a CAN
// frame of libnmt's core and the CiA 301 schema of libcfg, read from the installed schemas.
// Prints what it found; the test compares it with the standard's values.
#include <iostream>

#include "cfg/hex.hpp"
#include "cfg/schema.hpp"
#include "nmt/protocol/frame.hpp"

int main() {
  // CiA 301 NMT module control: COB-ID 0, command specifier 1 (start remote node), node-ID 5.
  const std::uint8_t start_node_5[] = {0x01, 0x05};
  std::cout << nmt::to_candump(nmt::CanFrame::make(0x000, start_node_5)) << '\n';
  auto schema = cfg::load_schema(cfg::kCia301Schema, SCHEMA_DIR);
  if (!schema) {
    std::cerr << schema.error().message << '\n';
    return 1;
  }
  // CiA 301 object 1017h, producer heartbeat time: UNSIGNED16 (data type 0006h).
  const auto* heartbeat = schema->object(0x1017);
  if (heartbeat == nullptr || heartbeat->sub(0) == nullptr) return 1;
  std::cout << "1017h " << cfg::hex(heartbeat->sub(0)->data_type, 4) << '\n';
  return 0;
}
