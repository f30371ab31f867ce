// libFuzzer target: an SDO client mid-transfer, talking to a real SDO server through a channel
// the input controls: frames are delivered, dropped, mutated or injected, and time advances.
// Input: bytes 0..1 configure the server and the transfers (count, kinds, sizes, timeouts);
// the rest are channel operations. Checks: no crash; once the input ends and frames flow again
// with time advancing, every transfer ends (its result is reported exactly once) within a
// bounded number of steps, the client and server end idle; while the channel is clean (see
// below) every successful upload returns the server's value and every successful download
// stored its data.
#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <functional>
#include <map>
#include <vector>

#include "../support/fuzz_support.hpp"
#include "../support/sdo_test_device.hpp"
#include "nmt/sdo/sdo.hpp"
#include "nmt/sim/fault_injection.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace {

using nmt::CanFrame;
using nmt::TimePoint;
using namespace std::chrono_literals;

using fuzz_support::Input;

constexpr std::uint16_t kIndices[] = {0x1000, 0x1008, 0x1017, 0x2000, 0x2005, 0x3000, 0x1018};

struct Harness {
  nmt::LocalDictionary dict;
  nmt::Delayed<nmt::SdoServer> server;
  nmt::SdoClient client{nmt::SdoClientConfig::for_node(*cfg::NodeId::from(5))};
  std::deque<CanFrame> to_server, to_client;
  TimePoint now{};
  nmt::SdoServer::Output server_out;
  nmt::SdoClient::Output client_out;
  std::function<void(const nmt::SdoResult&)> on_result;

  Harness(nmt::LocalDictionary d, nmt::SdoServerConfig c, nmt::Duration latency)
      : dict(std::move(d)), server(latency, dict, c) {}

  void from_server() {
    for (auto& o : server_out.frames) to_client.push_back(o);
    server_out.clear();
  }
  void from_client() {
    for (auto& o : client_out.frames) to_server.push_back(o);
    for (auto& r : client_out.events) on_result(r);
    client_out.clear();
  }
  void server_step() {
    if (to_server.empty()) return;
    auto f = to_server.front();
    to_server.pop_front();
    server.on_frame(f, now, server_out);
    from_server();
  }
  void client_step() {
    if (to_client.empty()) return;
    auto f = to_client.front();
    to_client.pop_front();
    client.on_frame(f, now, client_out);
    from_client();
  }
  void timers() {
    if (auto d = server.next_deadline(); d && *d <= now) {
      server.on_timer(now, server_out);
      from_server();
    }
    if (auto d = client.next_deadline(); d && *d <= now) {
      client.on_timer(now, client_out);
      from_client();
    }
  }
  // Jumps to the earliest deadline (at most `limit` ahead).
  void advance(nmt::Duration limit) {
    TimePoint t = now + limit;
    for (auto d : {server.next_deadline(), client.next_deadline()}) {
      if (d && *d < t) t = *d;
    }
    if (t > now) now = t;
    timers();
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  static const auto device = test_support::sdo_test_device();
  auto dict = nmt::LocalDictionary::from_device(device, *cfg::NodeId::from(5));
  check(dict.ok());
  Input in{data, size};
  const std::uint8_t setup = in.next();
  auto config = nmt::SdoServerConfig::for_node(*cfg::NodeId::from(5));
  config.block_transfer = (setup & 0x01) == 0;
  const auto latency = std::chrono::milliseconds(setup >> 1 & 0x07);
  config.block_size = static_cast<std::uint8_t>(1 + (setup >> 4) * 8);
  config.timeout = 300ms;
  Harness h(std::move(dict).value(), config, latency);

  int started = 0;
  int reported = 0;
  // Results are checked while the channel is clean: nothing corrupted or injected (expedited
  // and segmented transfers have no checksum) and no earlier transfer failed (after a timeout
  // or abort, late responses of the failed transfer may still be queued, and SDO frames carry
  // no transaction number to tell them from the next transfer's).
  bool corrupted = false;
  bool wrong_result = false;
  struct Expected {
    std::uint16_t index;
    std::vector<std::uint8_t> value;  // download: what was sent
  };
  std::map<nmt::SdoClient::TransferId, Expected> expected;
  h.on_result = [&](const nmt::SdoResult& r) {
    ++reported;
    auto it = expected.find(r.id);
    check(it != expected.end());  // reported once, and only for a transfer that was started
    const auto [index, value] = std::move(it->second);
    expected.erase(it);
    if (!r.ok()) corrupted = true;
    if (corrupted) return;
    if (r.upload) {
      auto stored = h.dict.get_bytes(index, 0);
      wrong_result |=
          !stored || !std::equal(stored->begin(), stored->end(), r.data.begin(), r.data.end());
    } else {
      auto stored = h.dict.get_bytes(index, 0);
      wrong_result |=
          !stored || !std::equal(stored->begin(), stored->end(), value.begin(), value.end());
    }
  };
  const int transfers = 1 + in.next() % 6;
  for (int i = 0; i < transfers; ++i) {
    const std::uint8_t kind = in.next();
    const std::uint16_t index = kIndices[(kind >> 3) % std::size(kIndices)];
    nmt::SdoTransferOptions o;
    o.mode = static_cast<nmt::SdoMode>(kind % 3);
    o.timeout = std::chrono::milliseconds(10 + in.next() * 2);
    o.block_size = static_cast<std::uint8_t>(in.next());  // 0 and >127 are clamped
    o.protocol_switch_threshold = (kind & 0x40) ? 4 : 0;
    o.max_size = 2048;
    std::vector<std::uint8_t> value;
    if ((kind & 0x80) == 0) {
      value.resize(in.next() * 11 % 1500);
      for (std::size_t k = 0; k < value.size(); ++k) value[k] = static_cast<std::uint8_t>(k);
    }
    const auto id = (kind & 0x80) ? h.client.upload(index, 0, h.now, h.client_out, o)
                                  : h.client.download(index, 0, value, h.now, h.client_out, o);
    check(id.ok());  // a positive timeout and a short value: nothing to refuse
    expected[*id] = {index, value};
    h.from_client();
    ++started;
  }
  h.timers();

  while (!in.empty()) {
    const std::uint8_t op = in.next();
    switch (op & 0x07) {
      case 0:
      case 1:
        h.server_step();
        break;
      case 2:
      case 3:
        h.client_step();
        break;
      case 4:  // lose a frame
        if (op & 0x08) {
          if (!h.to_server.empty()) h.to_server.pop_front();
        } else if (!h.to_client.empty()) {
          h.to_client.pop_front();
        }
        break;
      case 5: {  // corrupt a byte of the next response
        const std::uint8_t at = in.next() & 0x07;
        const std::uint8_t flip = in.next();
        if (!h.to_client.empty() && flip != 0) {
          h.to_client.front().data[at] ^= flip;
          corrupted = true;
        }
        break;
      }
      case 6: {  // a frame from nowhere on the response COB-ID
        std::uint8_t bytes[8];
        for (auto& b : bytes) b = in.next();
        h.to_client.push_front(CanFrame::make(0x585, std::span(bytes, (op >> 3) % 9)));
        corrupted = true;
        break;
      }
      case 7:
        h.advance(std::chrono::milliseconds(op >> 3));
        break;
    }
  }

  // The channel works again and time runs: everything must end.
  for (int guard = 0; h.client.busy() || h.server.engine().busy() || h.server.held() != 0 ||
                      !h.to_server.empty() || !h.to_client.empty();
       ++guard) {
    check(guard < 200000);
    if (!h.to_server.empty()) {
      h.server_step();
    } else if (!h.to_client.empty()) {
      h.client_step();
    } else {
      h.advance(1s);
    }
  }
  check(reported == started);
  check(!wrong_result);
  check(!h.client.next_deadline().has_value());
  return 0;
}
