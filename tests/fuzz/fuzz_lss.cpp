// libFuzzer target: an LSS master (nmt/lss/lss_master.hpp) and up to four LSS slaves
// (nmt/lss/lss_slave.hpp) on a bus the input controls (lss_fuzz_harness.hpp): frames are delivered
// or lost, frames of any content are injected on 7E5h and 7E4h, services start, time advances.
// Checks (beyond the harness's): no crash; a running service always has a deadline; a start
// while one runs is refused with words and sends nothing (engine.hpp rule 5); once the input
// ends and frames flow with time advancing, the master ends its service within a bounded
// number of steps.
#include <cstdint>
#include <optional>

#include "lss_fuzz_harness.hpp"

namespace {

using namespace std::chrono_literals;
using lss_fuzz::Harness;
using lss_fuzz::Input;

using LssHarness = Harness<nmt::LssMaster>;

void check_master_deadline(const LssHarness& h) {
  check(h.master.busy() == h.master.next_deadline().has_value());
}

void start_service(LssHarness& h, Input& in) {
  const std::uint8_t op = in.next();
  const bool was_busy = h.master.busy();
  nmt::LssMaster::Output out;
  cfg::Status started;
  switch (op % 12) {
    case 0:
      started = h.master.switch_state_global(static_cast<nmt::LssState>(op >> 4 & 1), h.now, out);
      break;
    case 1:
      started = h.master.switch_state_selective(lss_fuzz::address_from(in), h.now, out);
      break;
    case 2:
      // 1..127 a node-ID; other bytes none (FFh, unconfigured): the rest cannot reach the bus.
      started = h.master.configure_node_id(cfg::NodeId::from(in.next()), h.now, out);
      break;
    case 3:
      started = h.master.configure_bit_timing(in.next() % 12, h.now, out, in.next() % 2);
      break;
    case 4:
      started = h.master.activate_bit_timing(in.next() % 50, h.now, out);
      break;
    case 5:
      started = h.master.store_configuration(h.now, out);
      break;
    case 6:
      started = h.master.inquire(static_cast<nmt::LssService>(in.next() % 16), h.now, out);
      break;
    case 7: {
      const auto a = lss_fuzz::address_from(in);
      started = h.master.identify_remote_slaves(
          {a.vendor_id, a.product_code, 0, a.revision, 0, a.serial}, h.now, out);
      break;
    }
    case 8:
      started = h.master.identify_non_configured(h.now, out);
      break;
    case 9:
      started = h.master.fastscan(h.now, out);
      break;
    case 10:
      started = h.master.fastscan(lss_fuzz::address_from(in), h.now, out);
      break;
    default:
      // The scan that chains these services (LssProcedure) runs in fuzz_execute_lss.
      started = h.master.fastscan_confirm(lss_fuzz::address_from(in), h.now, out);
      break;
  }
  // engine.hpp rule 5: a start that cannot happen says why and puts nothing into `out`.
  if (!started) {
    check(!started.error().message.empty());
    check(out.empty());
  } else {
    check(!was_busy);
  }
  h.take_master(out);
  check_master_deadline(h);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Input in{data, size};
  const std::uint8_t setup = in.next();
  nmt::LssMaster master(lss_fuzz::timing_from(setup));
  LssHarness h(master);
  lss_fuzz::add_slaves(h, setup, in);
  lss_fuzz::run_ops(
      h, in, [&] { start_service(h, in); }, [&] { check_master_deadline(h); });

  // Frames flow and time runs: the service ends.
  for (int guard = 0; h.master.busy() || !h.bus.empty(); ++guard) {
    check(guard < 100000);
    if (!h.bus.empty()) {
      h.deliver();
    } else {
      h.advance(1s);
    }
  }
  check(!h.master.next_deadline().has_value());
  return 0;
}
