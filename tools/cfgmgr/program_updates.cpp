#include "program_updates.hpp"

#include <cstdio>

#include "../common/tool_support.hpp"
#include "cfg/hex.hpp"
#include "nmt/master/master_event_text.hpp"

namespace cfgmgr {

double ProgramUpdate::seconds() const {
  if (!ended) return 0;
  return static_cast<double>((*ended - began).count()) / 1e6;
}

std::optional<std::string> ProgramUpdates::observe(const nmt::MasterEvent& e) {
  using K = nmt::MasterEvent::Kind;
  if (!network_ || !e.node_id) return std::nullopt;
  const std::uint8_t node_id = e.node_id->value();
  if (e.kind == K::BootStepChanged && e.step == nmt::BootStep::UpdateSoftware) {
    ProgramUpdate update;
    update.began = e.at;
    const cfg::NetworkNode* node = network_->find(*e.node_id);
    if (node != nullptr && node->program) update.total = node->program->image.size();
    updates_[node_id] = update;
    return std::nullopt;
  }
  const auto it = updates_.find(node_id);
  if (it == updates_.end()) return std::nullopt;
  ProgramUpdate& u = it->second;
  if (e.kind == K::ProgramProgress) {
    u.bytes = e.bytes;
    if (e.total != 0) u.total = e.total;
    return std::nullopt;
  }
  if (e.kind == K::ProgramClearRefused) {
    if (e.sdo) u.clear_refused = e.sdo->abort;
    return nmt::describe(e);
  }
  // The master's own account (MasterEvent::program) on SlaveBooted, or BootError I.
  if ((e.kind != K::SlaveBooted && e.kind != K::BootError) || !e.program || u.updated || u.failed) {
    return std::nullopt;
  }
  if (e.program->identification_before) {
    u.identification_before = e.program->identification_before;
    u.identification_after = e.program->identification_after;
  } else {
    u.before = e.program->before;
    u.after = e.program->after;
  }
  u.total = e.program->bytes;
  u.began = e.program->began;
  if (e.program->clear_refused) u.clear_refused = e.program->clear_refused;
  u.ended = e.program->ended ? e.program->ended : std::optional<nmt::TimePoint>(e.at);
  if (e.kind == K::BootError) {
    u.failed = true;
    return std::nullopt;
  }
  u.updated = true;
  u.bytes = u.total;
  char seconds[32];
  std::snprintf(seconds, sizeof seconds, "%.3f s", u.seconds());
  std::string line = "node " + std::to_string(node_id) +
                     ": program updated: " + tools::plural(u.total, "byte") + " in " + seconds;
  if (u.before) line += ", was " + cfg::to_string(*u.before);
  if (u.after) line += ", now " + cfg::to_string(*u.after);
  if (u.identification_before) {
    line += ", was software identification " + cfg::hex(*u.identification_before, 8);
  }
  if (u.identification_after) {
    line += ", now " + cfg::hex(*u.identification_after, 8) + " (1F56h sub 1)";
  }
  return line;
}

const ProgramUpdate* ProgramUpdates::find(std::uint8_t node) const {
  const auto it = updates_.find(node);
  return it == updates_.end() ? nullptr : &it->second;
}

namespace {

std::string number_json(const std::optional<std::uint32_t>& value) {
  return value ? std::to_string(*value) : std::string("null");
}

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
         ", \"identification_before\": " + number_json(u->identification_before) +
         ", \"identification_after\": " + number_json(u->identification_after) +
         ", \"bytes\": " + std::to_string(u->bytes) + ", \"seconds\": " + seconds +
         ", \"clear_refused\": " +
         (u->clear_refused ? tools::json_string(nmt::to_string(*u->clear_refused)) : "null") + "}";
}

}  // namespace cfgmgr
