// The configuration manager (cfg/config_manager.hpp) as the NMT master sees it: the source of
// the slaves' configurations (MasterOptions::configurations), and its abort codes as SdoAbort
// for the master's SDO server.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "cfg/config_manager.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sdo/sdo_abort.hpp"

namespace nmt {

/// Reads configurations from a shared manager; the owner may keep writing to it (1F20h/1F22h
/// over SDO, the C++ API): the master asks for a node's writes when it downloads them. Not
/// thread-safe, like the manager.
class ConfigurationManagerSource final : public ConfigurationSource {
 public:
  explicit ConfigurationManagerSource(std::shared_ptr<const cfg::ConfigManager> manager)
      : manager_(std::move(manager)) {}

  std::optional<std::vector<cfg::ObjectWrite>> configuration(cfg::NodeId node) const override {
    return manager_->configuration(node);
  }

 private:
  std::shared_ptr<const cfg::ConfigManager> manager_;
};

}  // namespace nmt
