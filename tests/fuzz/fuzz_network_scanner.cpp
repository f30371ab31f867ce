// libFuzzer target: nmt::NetworkScanner fed frames and time the input chooses (answers on the
// default SDO channels of the nodes it scans, heartbeats, anything else), with the application
// reading the entries the input names for every device found. Checks: no crash; every frame
// the scanner sends is an SDO request to a node it scans (an upload or an abort, never a
// download); each node ends once (absent, or found and scanned; a heartbeat may bring one
// more probe of an absent node-ID); a found node's EntryRead count is what read() was given;
// once the input ends, time alone ends the scan within a bounded number of steps.
#include <cstdint>
#include <map>
#include <set>
#include <vector>

#include "../support/fuzz_support.hpp"
#include "nmt/manager/network_scanner.hpp"

namespace {

using fuzz_support::Input;
using Scanner = nmt::NetworkScanner;
using namespace std::chrono_literals;

struct NodeLog {
  unsigned found = 0;
  unsigned absent = 0;
  unsigned scanned = 0;
  std::size_t asked = 0;
  std::size_t read = 0;
};

struct Harness {
  Scanner scanner;
  Scanner::Output out;
  std::set<std::uint8_t> scanned_ids;
  std::map<std::uint8_t, NodeLog> log;
  nmt::TimePoint now{};
  Input* input = nullptr;

  explicit Harness(nmt::ScanOptions options) : scanner(options) {}

  void drain() {
    // Events first: a NodeFound makes the application read (which may report at once).
    for (std::size_t guard = 0; !out.events.empty() && guard < 1000; ++guard) {
      auto events = std::move(out.events);
      out.events.clear();
      for (const auto& e : events) handle(e);
    }
    for (const auto& f : out.frames) {
      check(!f.extended && f.id > 0x600 && f.id <= 0x67F);
      check(scanned_ids.contains(static_cast<std::uint8_t>(f.id - 0x600)));
      const std::uint8_t ccs = f.data[0] >> 5;
      check(ccs == 2 || ccs == 3 || ccs == 4 || ccs == 5);  // upload, segment, abort, block
    }
    out.frames.clear();
  }

  void handle(const Scanner::Event& e) {
    if (const auto* found = std::get_if<Scanner::NodeFound>(&e)) {
      auto& l = log[found->node.value()];
      ++l.found;
      check(l.found == 1);
      std::vector<cfg::ObjectAddress> entries;
      const std::size_t n = input->next() % 6;
      for (std::size_t i = 0; i < n; ++i) {
        entries.push_back({static_cast<std::uint16_t>(0x2000 + input->next()), input->next()});
      }
      l.asked = entries.size();
      check(static_cast<bool>(scanner.read(found->node, entries, now, out)));
      check(!scanner.read(found->node, {}, now, out));  // not waiting any more
    } else if (const auto* absent = std::get_if<Scanner::NodeAbsent>(&e)) {
      auto& l = log[absent->node.value()];
      ++l.absent;
      check(l.absent <= 2 && l.found == 0);
    } else if (const auto* read = std::get_if<Scanner::EntryRead>(&e)) {
      auto& l = log[read->node.value()];
      check(l.found == 1 && l.scanned == 0);
      ++l.read;
    } else if (const auto* done = std::get_if<Scanner::NodeScanned>(&e)) {
      auto& l = log[done->node.value()];
      ++l.scanned;
      check(l.scanned == 1 && l.read == l.asked && done->read + done->skipped == l.asked);
    }
  }
};

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Input in{data, size};
  nmt::ScanOptions options;
  options.sdo.timeout = std::chrono::milliseconds(1 + in.next() % 50);
  options.retries = in.next() % 3;
  options.read_stored_eds = (in.next() & 1) != 0;
  options.bitrate_bps = (in.next() & 1) != 0 ? 500'000 : 0;
  Harness h(options);
  h.input = &in;
  std::vector<cfg::NodeId> ids;
  const unsigned count = 1 + in.next() % 4;
  for (unsigned i = 0; i < count; ++i) {
    const auto id = cfg::NodeId::from(1 + in.next() % 127);
    ids.push_back(*id);
    h.scanned_ids.insert(id->value());
  }
  h.scanner.start(ids, h.now, h.out);
  h.drain();
  while (!in.empty()) {
    const std::uint8_t op = in.next();
    if (op < 64) {
      h.now += std::chrono::microseconds(in.next() * 100);
      h.scanner.on_timer(h.now, h.out);
    } else {
      // A frame: an SDO answer of a scanned node, a heartbeat, or any identifier.
      const std::uint8_t node = ids[in.next() % ids.size()].value();
      const std::uint8_t kind = in.next() % 3;
      const std::uint32_t id = kind == 0   ? 0x580u + node
                               : kind == 1 ? 0x700u + node
                                           : (std::uint32_t{in.next()} << 3 | in.next()) & 0x7FF;
      std::uint8_t bytes[8];
      const std::uint8_t dlc = in.next() % 9;
      for (auto& b : bytes) b = in.next();
      h.scanner.on_frame(nmt::CanFrame::make(id, {bytes, dlc}), h.now, h.out);
    }
    h.drain();
  }
  // Silence and time: every node ends.
  for (int step = 0; step < 100000 && !h.scanner.finished(); ++step) {
    const auto due = h.scanner.next_deadline();
    check(due.has_value());
    h.now = std::max(h.now, *due);
    h.scanner.on_timer(h.now, h.out);
    h.drain();
  }
  check(h.scanner.finished());
  for (const auto id : h.scanned_ids) {
    const auto& l = h.log[id];
    check((l.found == 1 && l.scanned == 1) || (l.found == 0 && l.absent >= 1));
  }
  return 0;
}
