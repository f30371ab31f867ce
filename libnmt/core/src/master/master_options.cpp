// MasterOptions::validate: the durations the master's processes need, checked once when the
// master is built, so that no process meets a timeout it cannot use.
#include <array>
#include <string>
#include <utility>

#include "nmt/master/master_options.hpp"

namespace nmt {

namespace {

using Named = std::pair<const char*, Duration>;

cfg::Status below(const Named& option, const char* bound) {
  return cfg::Error{std::string("MasterOptions::") + option.first + " must be " + bound +
                    " (it is " + std::to_string(option.second.count()) + " us)"};
}

}  // namespace

cfg::Status MasterOptions::validate() const {
  const std::array<Named, 13> positive{{
      {"sdo.timeout", sdo.timeout},
      {"sdo.repeat_floor", sdo.repeat_floor},
      {"boot.retry_interval", boot.retry_interval},
      {"boot.reboot_timeout", boot.reboot_timeout},
      {"program.control_timeout", program.control_timeout},
      {"program.clear_timeout", program.clear_timeout},
      {"program.data_timeout", program.data_timeout},
      {"boot.guarding_reply_timeout", boot.guarding_reply_timeout},
      {"sdo_manager.scan_timeout", sdo_manager.scan_timeout},
      {"sdo_manager.srd_guard_time", sdo_manager.srd_guard_time},
      {"lss.timing.timeout", lss.timing.timeout},
      {"lss.timing.scan_step", lss.timing.scan_step},
      {"emcy.window", emcy.window},
  }};
  for (const auto& option : positive) {
    if (option.second <= Duration::zero()) return below(option, "positive");
  }
  const std::array<Named, 2> not_negative{{
      {"boot.boot_up_wait", boot.boot_up_wait},  // 0: no wait for boot-ups
      {"lss.period", lss.period},                // 0: no looks for unconfigured devices
  }};
  for (const auto& option : not_negative) {
    if (option.second < Duration::zero()) return below(option, "0 or more");
  }
  if (emcy.max_per_window == 0) {
    return cfg::Error{"MasterOptions::emcy.max_per_window must be 1 or more (it is 0)"};
  }
  return {};
}

}  // namespace nmt
