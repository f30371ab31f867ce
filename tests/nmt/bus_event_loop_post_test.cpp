// BusEventLoop::post (bus_event_loop.hpp, "Threads"): other
// threads call into a running loop; each posted function runs exactly once, on the loop's thread,
// in each poster's order, and a loop waiting for frames wakes for it at once. The bus here is a
// virtual one on a socketpair: a descriptor the loop polls (Bus::readable_fd) like the SocketCAN
// and UDP drivers', fed by a "device" thread; no network traffic at all. Run under
// ThreadSanitizer too (CANOPEN_SANITIZE=thread, README.md).
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cstring>
#include <fstream>
#include <future>
#include <iterator>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "nmt/io/bus_event_loop.hpp"
#include "socket_pair_bus.hpp"

namespace nmt {
namespace {

using namespace std::chrono_literals;

// Whether thread `tid` of this process is asleep in poll(2)/ppoll(2) within `limit`, from
// /proc/self/task/TID (proc(5): stat's state S, and wchan, when the kernel tells it, naming a
// poll function). Nothing else puts the loop's thread to sleep while no frame and no posted call
// is there.
bool sleeping_in_poll_within(pid_t tid, std::chrono::milliseconds limit) {
  const std::string task = "/proc/self/task/" + std::to_string(tid);
  const auto end = std::chrono::steady_clock::now() + limit;
  while (std::chrono::steady_clock::now() < end) {
    std::ifstream stat_file(task + "/stat");
    std::string stat((std::istreambuf_iterator<char>(stat_file)), {});
    std::ifstream wchan_file(task + "/wchan");
    std::string wchan;
    wchan_file >> wchan;
    // stat: "tid (comm) S ...": the state follows the last ')'.
    const auto paren = stat.rfind(')');
    const bool sleeping = paren != std::string::npos && stat.compare(paren, 3, ") S") == 0;
    const bool in_poll = wchan.empty() || wchan == "0" || wchan.find("poll") != std::string::npos;
    if (sleeping && in_poll) return true;
    std::this_thread::sleep_for(1ms);
  }
  return false;
}

// Records what posted calls ask, hears frames, and keeps a 1 ms timer so the loop is busy in
// engine calls while the posters post.
struct Recorder {
  using Event = NoEvent;
  using Output = Outbox<NoEvent>;
  bool on_frame(const CanFrame& /*f*/, TimePoint /*now*/, Output& /*out*/) {
    ++heard;
    return true;
  }
  void on_timer(TimePoint now, Output& /*out*/) {
    ++timers;
    due = now + 1ms;
  }
  std::optional<TimePoint> next_deadline() const { return due; }
  void record(int thread, int seq, Output& out) {
    calls[static_cast<std::size_t>(thread)].push_back(seq);
    out.send(*from_candump("181#01"));
  }
  std::vector<std::vector<int>> calls;
  std::size_t heard = 0;
  std::size_t timers = 0;
  TimePoint due{};
};

TEST(BusEventLoopPost, EveryPostedCallRunsOnceInEachThreadsOrderWhileFramesAndTimersFlow) {
  constexpr int kThreads = 8;
  constexpr int kPerThread = 2000;
  constexpr std::size_t kFrames = 3000;
  SocketPairBus bus;
  BusEventLoop loop(bus);
  Recorder recorder;
  recorder.calls.resize(kThreads);
  EngineRef ref(recorder);
  loop.add(ref);
  const std::thread::id loop_thread = std::this_thread::get_id();
  std::atomic<int> wrong_thread{0};

  std::vector<std::thread> posters;
  for (int t = 0; t < kThreads; ++t) {
    posters.emplace_back([&, t] {
      for (int i = 0; i < kPerThread; ++i) {
        ref.post([&, t, i](Recorder& r, TimePoint /*now*/, Recorder::Output& out) {
          if (std::this_thread::get_id() != loop_thread) ++wrong_thread;
          r.record(t, i, out);
        });
      }
    });
  }
  std::thread device([&] {
    for (std::size_t i = 0; i < kFrames; ++i) bus.inject("701#05");
  });
  // Once every poster and the device are done, a last call stops the loop as soon as the engine
  // heard every frame (they are all in the socket by then).
  bool armed = false;
  std::thread closer([&] {
    for (auto& p : posters) p.join();
    device.join();
    loop.post([&] { armed = true; });
  });
  const TimePoint bound = loop.clock() + std::chrono::seconds(120);
  while (loop.clock() < bound && !(armed && recorder.heard == kFrames)) {
    ASSERT_TRUE(loop.run_until(std::min(bound, loop.clock() + Duration{10ms})));
  }
  closer.join();

  EXPECT_EQ(wrong_thread.load(), 0);
  ASSERT_TRUE(armed);
  EXPECT_EQ(recorder.heard, kFrames);
  std::vector<int> expected(kPerThread);
  for (int i = 0; i < kPerThread; ++i) expected[static_cast<std::size_t>(i)] = i;
  for (int t = 0; t < kThreads; ++t) {
    EXPECT_EQ(recorder.calls[static_cast<std::size_t>(t)], expected) << "thread " << t;
  }
  EXPECT_EQ(bus.sent, std::uint64_t{kThreads} * kPerThread);  // each call's frame went out
  EXPECT_GT(recorder.timers, 0U);
  EXPECT_EQ(loop.posted(), 0U);
}

TEST(BusEventLoopPost, WakesALoopThatWaitsForFrames) {
  // Nothing on the bus and no deadline: without the wake-up the loop would sleep max_wait (an
  // hour here) before it looked at the posted call.
  SocketPairBus bus;
  BusEventLoopOptions options;
  options.max_wait = std::chrono::hours(1);
  BusEventLoop loop(bus, options);
  const TimePoint start = loop.clock();
  const pid_t loop_thread = static_cast<pid_t>(::syscall(SYS_gettid));
  std::thread poster([&] {
    // Posts once the loop waits in poll: the case the wake-up is for.
    EXPECT_TRUE(sleeping_in_poll_within(loop_thread, 10s)) << "the idle loop never slept in poll";
    loop.post([&] { loop.request_stop(); });
  });
  ASSERT_TRUE(loop.run_until(start + std::chrono::hours(2)));
  poster.join();
  EXPECT_TRUE(loop.stop_requested());
  EXPECT_LT(loop.clock() - start, Duration{std::chrono::seconds(60)});
}

TEST(BusEventLoopPost, CallsPostedBeforeARunWaitForItAndRunInOrderWithTheirResults) {
  // A move-only function (it owns a promise) hands its result back; calls posted from a posted
  // call run in the next pass.
  SocketPairBus bus;
  BusEventLoop loop(bus);
  Recorder recorder;
  recorder.calls.resize(1);
  EngineRef ref(recorder);
  loop.add(ref);
  std::promise<std::size_t> promise;
  auto future = promise.get_future();
  ref.post([&](Recorder& r, TimePoint, Recorder::Output& out) { r.record(0, 1, out); });
  loop.post([&, p = std::move(promise)]() mutable {
    ref.apply([&](Recorder& r, TimePoint, Recorder::Output& out) { r.record(0, 2, out); });
    p.set_value(recorder.calls[0].size());
    loop.post([&] { loop.request_stop(); });
  });
  EXPECT_EQ(loop.posted(), 2U);
  EXPECT_EQ(recorder.calls[0], std::vector<int>{});
  ASSERT_TRUE(loop.run_for(std::chrono::seconds(60)));
  EXPECT_EQ(recorder.calls[0], (std::vector<int>{1, 2}));
  ASSERT_EQ(future.wait_for(0s), std::future_status::ready);
  EXPECT_EQ(future.get(), 2U);
  EXPECT_TRUE(loop.stop_requested());
  EXPECT_EQ(bus.sent, 2U);
}

TEST(BusEventLoopPost, PostBeforeTheEngineIsAddedIsALogicError) {
  Recorder recorder;
  EngineRef ref(recorder);
  EXPECT_THROW(ref.post([](Recorder&, TimePoint, Recorder::Output&) {}), std::logic_error);
}

}  // namespace
}  // namespace nmt
