// A virtual bus on a socketpair for tests of BusEventLoop across threads: a descriptor the loop
// polls (Bus::readable_fd) like the SocketCAN and UDP drivers', fed by inject() from any thread;
// no network traffic at all. (FakeClockBus, tests/support, is the single-threaded bus on a fake
// clock; these tests need a real descriptor and real threads.)
#pragma once

#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "nmt/io/bus.hpp"
#include "nmt/io/bus_event_loop.hpp"
#include "nmt/protocol/frame.hpp"

namespace nmt {

// Frames as candump text in SOCK_SEQPACKET records: inject() is the device's end, the loop reads
// the other. Sent frames are counted (only the loop's thread sends).
class SocketPairBus final : public Bus {
 public:
  SocketPairBus() {
    if (::socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, fds_.data()) != 0) {
      throw std::runtime_error(std::string("socketpair: ") + std::strerror(errno));
    }
  }
  SocketPairBus(const SocketPairBus&) = delete;
  SocketPairBus& operator=(const SocketPairBus&) = delete;
  ~SocketPairBus() override {
    ::close(fds_[0]);
    ::close(fds_[1]);
  }
  cfg::Status send(const CanFrame& frame) override {
    ++sent;
    if (keep_sent) sent_frames.push_back(frame);
    return {};
  }
  cfg::Result<std::optional<ReceivedFrame>> receive(Duration timeout) override {
    if (timeout > Duration::zero()) std::this_thread::sleep_for(timeout);  // not used by the loop
    std::array<char, 64> text{};
    const ssize_t n = ::recv(fds_[0], text.data(), text.size(), MSG_DONTWAIT);
    if (n <= 0) return std::optional<ReceivedFrame>{};
    auto frame = from_candump(std::string(text.data(), static_cast<std::size_t>(n)));
    if (!frame) return cfg::Error{"bad record"};
    return std::optional<ReceivedFrame>(ReceivedFrame{*frame, steady_now()});
  }
  std::string url() const override { return "socketpair:"; }
  int readable_fd() const override { return fds_[0]; }

  // From any thread: a frame arrives.
  void inject(const std::string& candump) {
    ASSERT_EQ(::send(fds_[1], candump.data(), candump.size(), 0),
              static_cast<ssize_t>(candump.size()));
  }

  std::uint64_t sent = 0;
  /// With keep_sent: every frame sent, in order (read it only while the loop does not run).
  bool keep_sent = false;
  std::vector<CanFrame> sent_frames;

 private:
  std::array<int, 2> fds_{};
};

}  // namespace nmt
