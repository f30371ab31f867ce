// The stall scenario ("The event loop judges by when frames arrived"), for any bus
// driver: a peer heartbeats every 100 ms on a second bus of the same network while the loop is
// stopped for 2 s (the test sleeps inside the loop's observer, and between two run*() calls).
// The consumer (1016h: 500 ms) must not report the live node lost, and must still report a node
// that really stopped one consumer time after its last heartbeat (CiA 301 §7.2.8.3.2.2).
// Used by tests/io/udp_stall_test.cpp (UDP, in a network namespace) and
// tests/io/socketcan_bus_test.cpp (vcan, in the VM tier).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <memory>
#include <thread>
#include <utility>
#include <vector>

#include "nmt/io/bus_event_loop.hpp"
#include "nmt/protocol/error_control.hpp"

namespace test_support {

using namespace std::chrono_literals;

constexpr std::uint8_t kPeer = 5;
constexpr auto kPeriod = 100ms;             // the peer's 1017h
constexpr std::uint16_t kConsumerMs = 500;  // our 1016h entry for it

// Node 5 in operational, heartbeating on its own bus and thread until stopped.
class HeartbeatPeer {
 public:
  explicit HeartbeatPeer(std::unique_ptr<nmt::Bus> bus) : bus_(std::move(bus)) {
    if (bus_) thread_ = std::thread([this] { run(); });
  }
  HeartbeatPeer(const HeartbeatPeer&) = delete;
  HeartbeatPeer& operator=(const HeartbeatPeer&) = delete;
  ~HeartbeatPeer() { stop(); }
  bool started() const { return bus_ != nullptr; }
  void stop() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }

 private:
  void run() {
    const nmt::CanFrame heartbeat =
        nmt::make_heartbeat(cfg::NodeId::from(kPeer).value(), nmt::NmtState::Operational);
    auto next = std::chrono::steady_clock::now();
    while (!stop_.load()) {
      (void)bus_->send(heartbeat);
      next += kPeriod;
      std::this_thread::sleep_until(next);
    }
  }
  std::unique_ptr<nmt::Bus> bus_;
  std::atomic<bool> stop_{false};
  std::thread thread_;
};

/// Runs the scenario with the loop on `bus` and node 5 heartbeating on `peer_bus`.
inline void check_stall_is_not_a_heartbeat_loss(nmt::Bus& bus, std::unique_ptr<nmt::Bus> peer_bus) {
  using namespace nmt;

  BusEventLoop loop(bus);
  HeartbeatConsumer consumer;
  std::vector<std::pair<HeartbeatEvent, TimePoint>> events;
  EngineRef ref(consumer,
                [&](const HeartbeatEvent& e, TimePoint now) { events.emplace_back(e, now); });
  loop.add(ref);
  std::vector<TimePoint> heartbeats;  // when the loop says each heartbeat arrived
  bool stall_in_observer = false;
  loop.set_observer([&](const CanFrame& f, TimePoint at, BusEventLoop::Direction d) {
    if (d != BusEventLoop::Direction::Received || f.id != 0x700U + kPeer) return;
    heartbeats.push_back(at);
    if (stall_in_observer) {
      stall_in_observer = false;
      std::this_thread::sleep_for(2s);  // the loop stops while a frame is being handled
    }
  });
  ref.apply([](HeartbeatConsumer& c, TimePoint now, auto&) {
    c.monitor(HeartbeatConsumerEntry{kPeer, kConsumerMs}, now);
  });

  HeartbeatPeer peer(std::move(peer_bus));
  ASSERT_TRUE(peer.started());
  ASSERT_TRUE(loop.run_for(600ms).ok());
  ASSERT_GE(heartbeats.size(), 3U) << "the peer's heartbeats do not arrive";
  // A 2 s stall inside the loop, then one between two run*() calls.
  stall_in_observer = true;
  ASSERT_TRUE(loop.run_for(2500ms).ok());
  ASSERT_FALSE(stall_in_observer) << "no heartbeat to stall on";
  std::this_thread::sleep_for(2s);
  ASSERT_TRUE(loop.run_for(500ms).ok());
  for (const auto& event : events) {
    ADD_FAILURE() << "node " << int{event.first.node_id} << ": " << to_string(event.first.kind)
                  << " while it sent every 100 ms";
  }
  // The heartbeats queued during the stalls were given their arrival times: never as far
  // apart as the consumer time (they would be 2 s apart, all read at once, without them).
  ASSERT_GE(heartbeats.size(), 40U);
  Duration widest{0};
  for (std::size_t i = 1; i < heartbeats.size(); ++i) {
    widest = std::max(widest, heartbeats[i] - heartbeats[i - 1]);
  }
  EXPECT_LT(widest, Duration{std::chrono::milliseconds(kConsumerMs)});

  // The node really stops: the loss is reported one consumer time after its last heartbeat,
  // as soon as the loop is due (a margin for a loaded machine's wake-up).
  peer.stop();
  ASSERT_TRUE(loop.run_for(1500ms).ok());
  ASSERT_EQ(events.size(), 1U);
  EXPECT_EQ(events[0].first.kind, HeartbeatEventKind::Timeout);
  const TimePoint last = heartbeats.back();
  const Duration consumer_time = std::chrono::milliseconds(kConsumerMs);
  EXPECT_EQ(events[0].first.at, last + consumer_time);
  EXPECT_GE(events[0].second, last + consumer_time);
  EXPECT_LE(events[0].second, last + consumer_time + 150ms);
}

}  // namespace test_support
