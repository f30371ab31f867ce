#include "program_updates.hpp"

#include <cstdio>

#include "../common/tool_support.hpp"

namespace cfgmgr {

double ProgramUpdate::seconds() const {
  if (!ended) return 0;
  return static_cast<double>((*ended - began).count()) / 1e6;
}

std::optional<std::string> ProgramUpdates::observe(const nmt::MasterEvent& e) {
  using K = nmt::MasterEvent::Kind;
  using S = nmt::BootStep;
  if (!network_ || e.node_id == 0) return std::nullopt;
  if (e.kind == K::BootStepChanged && e.step == S::UpdateSoftware) {
    ProgramUpdate update;
    update.began = e.at;
    const cfg::NetworkNode* node = network_->find(*cfg::NodeId::from(e.node_id));
    if (node != nullptr && node->program) update.total = node->program->image.size();
    updates_[e.node_id] = update;
    return std::nullopt;
  }
  const auto it = updates_.find(e.node_id);
  if (it == updates_.end()) return std::nullopt;
  ProgramUpdate& u = it->second;
  if (u.updated || u.failed) return std::nullopt;
  if (e.kind == K::BootError) {
    u.failed = true;
    if (!u.ended) u.ended = e.at;
    return std::nullopt;
  }
  const bool step = e.kind == K::BootStepChanged;
  if (!u.ended) {
    // Start confirmed: the master reads 1F52h again (DSP 302 §4 figure 7).
    if (step && e.step == S::CheckSoftware) {
      u.ended = e.at;
      u.bytes = u.total;
    }
    return std::nullopt;
  }
  // 1F52h matched (the boot went on), or the boot ended well.
  if (!(step && e.step != S::CheckSoftware && e.step != S::Failed) && e.kind != K::SlaveBooted) {
    return std::nullopt;
  }
  u.updated = true;
  const cfg::NetworkNode* node = network_->find(*cfg::NodeId::from(e.node_id));
  if (node != nullptr && node->program) u.after = node->program->version;
  char seconds[32];
  std::snprintf(seconds, sizeof seconds, "%.3f s", u.seconds());
  std::string line = "node " + std::to_string(e.node_id) +
                     ": program updated: " + tools::plural(u.total, "byte") + " in " + seconds;
  if (u.before) line += ", was " + cfg::to_string(*u.before);
  if (u.after) line += ", now " + cfg::to_string(*u.after);
  return line;
}

const ProgramUpdate* ProgramUpdates::find(std::uint8_t node) const {
  const auto it = updates_.find(node);
  return it == updates_.end() ? nullptr : &it->second;
}

namespace {

std::string version_json(const std::optional<cfg::ProgramVersion>& version) {
  if (!version) return "null";
  return "{\"date_days\": " + std::to_string(version->date_days) +
         ", \"time_ms\": " + std::to_string(version->time_ms) +
         ", \"text\": " + tools::json_string(cfg::to_string(*version)) + "}";
}

}  // namespace

std::string ProgramUpdates::json(std::uint8_t node) const {
  const ProgramUpdate* u = find(node);
  if (u == nullptr) return "null";
  char seconds[32];
  std::snprintf(seconds, sizeof seconds, "%.6f", u->seconds());
  return std::string("{\"updated\": ") + (u->updated ? "true" : "false") +
         ", \"before\": " + version_json(u->before) + ", \"after\": " + version_json(u->after) +
         ", \"bytes\": " + std::to_string(u->bytes) + ", \"seconds\": " + seconds + "}";
}

}  // namespace cfgmgr
