// The NMT command queue (CiA 302-2 §6.1); see nmt_command_queue.hpp.
#include "master/nmt_command_queue.hpp"

namespace nmt {

void NmtCommandQueue::on_timer(TimePoint now, Output& out) {
  // §6.1: queued NMT services go out in order, at least the inhibit time apart (with 0, all at
  // once).
  while (!queue_.empty() && !inhibited(now)) {
    const auto [command, target] = queue_.front();
    queue_.pop_front();
    out.send(make_nmt_command(command, target));
    out.report(Sent{command, target});
    last_ = now;
  }
}

std::optional<TimePoint> NmtCommandQueue::next_deadline() const {
  if (queue_.empty()) return std::nullopt;
  if (inhibit_.count() > 0 && last_) return *last_ + inhibit_;
  return TimePoint{};
}

}  // namespace nmt
