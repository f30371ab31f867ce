// The fixtures the tests of the LSS master engines share (lss_master_test.cpp for LssMaster,
// lss_procedure_test.cpp for LssProcedure): the engine alone, fed frame by frame in simulated
// time, and the engine on the simulated bus with LSS slaves (nmt::LssSlave).
#pragma once

#include <gtest/gtest.h>

#include <chrono>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/result.hpp"
#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_slave.hpp"
#include "nmt/protocol/frame.hpp"
#include "nmt/sim/sim_bus.hpp"

namespace nmt::lss_test {

using Frames = std::vector<std::string>;

/// An engine of the shape of nmt/engine.hpp alone: each start, frame and tick gives the frames
/// the engine put out (candump text, in order); its events pile up in `events`.
template <class Engine>
class EngineTest : public ::testing::Test {
 protected:
  using Event = typename Engine::Event;
  using Output = typename Engine::Output;

  Engine engine;  // LssMasterOptions{}: 100 ms timeout, 10 ms scan step
  TimePoint now{};
  std::vector<Event> events;

  Frames take(Output& out) {
    for (auto& e : out.events) events.push_back(e);
    Frames frames;
    for (auto& f : out.frames) frames.push_back(to_candump(f));
    out.clear();
    return frames;
  }
  // Starts a service or procedure that must start (engine.hpp rule 5: a start that fails says
  // why): `fn(engine, now, out)`.
  template <class Fn>
  Frames call(Fn fn) {
    Output out;
    const cfg::Status started = fn(engine, now, out);
    EXPECT_TRUE(started.ok()) << started.error().message;
    return take(out);
  }
  // A frame received at `now`, which the engine takes (`expect_taken`) or passes over.
  Frames answer(std::string_view candump, bool expect_taken = true) {
    Output out;
    EXPECT_EQ(engine.on_frame(*from_candump(candump), now, out), expect_taken) << candump;
    return take(out);
  }
  // A frame received at `at` (the time moves there), which the engine takes.
  Frames answer(std::string_view candump, TimePoint at) {
    now = at;
    return answer(candump);
  }
  Frames tick(TimePoint t) {
    now = t;
    Output out;
    engine.on_timer(now, out);
    return take(out);
  }
};

/// An LSS master engine (LssMaster, LssProcedure) on a simulated bus of 500 kbit/s with the LSS
/// slaves `add` puts there; its events pile up in `events`.
template <class Master>
class LssBusTest : public ::testing::Test {
 protected:
  using Event = typename Master::Event;

  SimBus bus{500'000};
  SimEngineNode<Master> master;
  std::vector<std::unique_ptr<SimEngineNode<LssSlave>>> slaves;
  std::vector<Event> events;

  LssBusTest() {
    bus.attach(master);
    master.set_event_handler([this](const Event& e, TimePoint) { events.push_back(e); });
  }
  SimEngineNode<LssSlave>& add(LssAddress address, std::uint8_t node_id = lss::kUnconfigured) {
    auto node = std::make_unique<SimEngineNode<LssSlave>>(address, node_id);
    auto* raw = node.get();
    // The owner's part: a device that got its node-ID starts with it.
    raw->set_event_handler([raw](const LssSlaveEvent& e, TimePoint) {
      if (e.kind == LssSlaveEvent::Kind::NodeIdActivate) {
        raw->engine().activate_pending_node_id();
      }
    });
    bus.attach(*raw);
    slaves.push_back(std::move(node));
    return *raw;
  }
  // Starts a service or procedure that must start (engine.hpp rule 5: a start that fails says
  // why).
  template <class Fn>
  void start(Fn fn) {
    const cfg::Status started = master.apply(fn);
    EXPECT_TRUE(started.ok()) << started.error().message;
  }
  void run_until_done() {
    using namespace std::chrono_literals;
    ASSERT_TRUE(bus.run_until([this] { return !master.engine().busy(); }, TimePoint{3600s}));
  }
};

}  // namespace nmt::lss_test
