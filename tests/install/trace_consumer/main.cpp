// An embedder's program against the installed libnmt_io (tests/install/install_test.sh): writes
// one frame to the pcap file named by its argument; the test reads the file's header.
#include <iostream>

#include "nmt/io/trace.hpp"
#include "nmt/protocol/frame.hpp"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: trace_consumer FILE.pcap\n";
    return 2;
  }
  auto writer = nmt::open_pcap(argv[1]);
  if (!writer) {
    std::cerr << writer.error().message << '\n';
    return 1;
  }
  // CiA 301 NMT module control: start remote node (command specifier 1), node-ID 5.
  const std::uint8_t start_node_5[] = {0x01, 0x05};
  auto written = (*writer)->write(nmt::CanFrame::make(0x000, start_node_5), nmt::TimePoint{});
  if (written) written = (*writer)->flush();
  if (!written) {
    std::cerr << written.error().message << '\n';
    return 1;
  }
  return 0;
}
