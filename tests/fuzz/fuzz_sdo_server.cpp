// libFuzzer target: random and mutated requests fed to an SDO server with time advancing.
// Input: byte 0 configures the server (block transfer on/off, response delay through
// nmt::Delayed, as a slow device is simulated); then a list of
// operations: a raw frame, a valid request template with one byte mutated, a frame on another
// COB-ID, or a step of time. Checks: no crash; every response is an 8-byte frame on the
// response COB-ID; after the input, once the timeout has passed, the server is idle with nothing
// pending (no stuck transfer) and reaching that takes a bounded number of timer events.
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <vector>

#include "../support/fuzz_support.hpp"
#include "../support/sdo_test_device.hpp"
#include "nmt/sdo/sdo.hpp"
#include "nmt/sim/fault_injection.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace {

using nmt::CanFrame;
using nmt::TimePoint;

// Requests a client could send to node 5 (candump bytes after "605#").
constexpr std::array<std::array<std::uint8_t, 8>, 14> kTemplates{{
    {0x2B, 0x17, 0x10, 0x00, 0xE8, 0x03, 0x00, 0x00},  // expedited download 1017
    {0x40, 0x08, 0x10, 0x00, 0x00, 0x00, 0x00, 0x00},  // upload 1008 (segmented)
    {0x21, 0x00, 0x20, 0x00, 0x20, 0x00, 0x00, 0x00},  // segmented download 2000, 32 bytes
    {0x00, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07},  // download segment t=0
    {0x10, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07},  // download segment t=1
    {0x60, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // upload segment t=0
    {0x70, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // upload segment t=1
    {0xC6, 0x00, 0x20, 0x00, 0x20, 0x00, 0x00, 0x00},  // block download 2000, 32 bytes
    {0x81, 0x01, 0x02, 0x03, 0x04, 0x05, 0x06, 0x07},  // block segment 1, last
    {0xD1, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // block download end
    {0xA4, 0x08, 0x10, 0x00, 0x7F, 0x00, 0x00, 0x00},  // block upload 1008
    {0xA3, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00},  // block upload start
    {0xA2, 0x01, 0x7F, 0x00, 0x00, 0x00, 0x00, 0x00},  // block upload ack
    {0x80, 0x00, 0x20, 0x00, 0x00, 0x00, 0x00, 0x08},  // abort
}};

using fuzz_support::Input;

struct Harness {
  nmt::LocalDictionary dict;
  nmt::Delayed<nmt::SdoServer> server;
  nmt::SdoServerConfig config;
  TimePoint now{};
  nmt::SdoServer::Output out;

  Harness(nmt::LocalDictionary d, nmt::SdoServerConfig c, nmt::Duration latency)
      : dict(std::move(d)), server(latency, dict, c), config(c) {}

  void check_output() {
    for (const auto& f : out.frames) {
      check(f.id == config.response_cob_id.can_id().id && f.dlc == 8 && !f.rtr && !f.extended);
    }
    out.clear();
  }
  void feed(const CanFrame& f) {
    server.on_frame(f, now, out);
    check_output();
  }
  // Moves time to `t`, firing the server's timer at each deadline on the way.
  void advance_to(TimePoint t) {
    for (int guard = 0;; ++guard) {
      check(guard < 10000);  // a deadline that never moves on would be a hang
      auto d = server.next_deadline();
      if (!d || *d > t) break;
      if (*d > now) now = *d;
      server.on_timer(now, out);
      check_output();
    }
    if (t > now) now = t;
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto device = test_support::sdo_test_device();
  auto dict = nmt::LocalDictionary::from_device(device, *cfg::NodeId::from(5));
  check(dict.ok());
  Input in{data, size};
  auto config = nmt::SdoServerConfig::for_node(*cfg::NodeId::from(5));
  const std::uint8_t setup = in.next();
  config.block_transfer = (setup & 0x01) == 0;
  const auto latency = std::chrono::milliseconds((setup >> 1) & 0x0F);
  config.block_size = static_cast<std::uint8_t>((setup >> 5) == 0 ? 127 : (setup >> 5));
  config.max_download_size = 4096;
  Harness h(std::move(dict).value(), config, latency);
  const std::uint32_t request_id = config.request_cob_id.can_id().id;

  while (!in.empty()) {
    const std::uint8_t op = in.next();
    switch (op % 5) {
      case 0: {  // raw frame
        std::array<std::uint8_t, 8> bytes{};
        const std::size_t dlc = in.next() % 9;
        for (std::size_t i = 0; i < dlc; ++i) bytes[i] = in.next();
        auto f = CanFrame::make(request_id, std::span(bytes.data(), dlc));
        h.feed(f);
        break;
      }
      case 1:
      case 2: {  // template, one byte changed
        auto bytes = kTemplates[in.next() % kTemplates.size()];
        const std::uint8_t where = in.next();
        if (where & 0x80) bytes[where & 0x07] ^= in.next();
        h.feed(CanFrame::make(request_id, bytes));
        break;
      }
      case 3: {  // another COB-ID or a remote frame: never answered
        auto f = CanFrame::make(0x600 + (in.next() & 0x7F), kTemplates[1]);
        f.rtr = (op & 0x08) != 0;
        const auto before = h.server.engine().busy();
        nmt::SdoServer::Output out;
        if (f.id != request_id || f.rtr) {
          check(!h.server.on_frame(f, h.now, out));
          check(out.empty() && h.server.engine().busy() == before);
        }
        break;
      }
      case 4:  // time passes
        h.advance_to(h.now + std::chrono::milliseconds(in.next()) * 10);
        break;
    }
  }
  // No stuck transfer: after the server timeout (and the latency of the abort it sends) the
  // server is idle and has nothing left to send.
  h.advance_to(h.now + config.timeout + latency * 2 + std::chrono::seconds(1));
  check(!h.server.engine().busy());
  check(h.server.held() == 0);
  check(!h.server.next_deadline().has_value());
  return 0;
}
