// A simulated device's non-volatile memory on disk: the values 1010h 'save' stored
// (SlaveNode::stored(), 1020h included), one file per node in a directory, so that a device
// keeps its saved parameters from one run to the next as a real one keeps them across power
// cycles (`cfgmgr push --bus sim:?state=DIR`: a second push finds 1020h as the first left it).
//   auto saved = nmt::load_device_state(dir, node_id);   // before power_on()
//   if (saved && *saved) device.node().set_stored(std::move(**saved));
//   ... on SlaveEvent::Kind::Stored / Restored: nmt::save_device_state(dir, device.node());
//
// The file, "node-NN.saved" (NN the node-ID in two upper-case hex digits), is text:
//   ; comment lines
//   node=5
//   1017sub00=E803            one line per saved value: index, sub-index, bytes in bus order
//   end=12                    the number of value lines: a file cut short is never taken
#pragma once

#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "cfg/node_id.hpp"
#include "cfg/result.hpp"
#include "nmt/slave_node.hpp"

namespace nmt {

/// Saved values by key (cfg::ObjectAddress::key(): index << 8 | sub-index), as
/// SlaveNode::stored() holds them.
using SavedValues = std::map<std::uint32_t, std::vector<std::uint8_t>>;

/// The file's text for node `node` and `values` (format above).
std::string format_device_state(cfg::NodeId node, const SavedValues& values);

/// Parses the file's text (`file`: the name used in messages). Fails with
/// "FILE:LINE: error: ..." when a line does not parse, the text is cut short (no end= or one
/// that does not count the values) or names another node than `node`.
cfg::Result<SavedValues> parse_device_state(std::string_view text, const std::string& file,
                                            cfg::NodeId node);

/// The file that holds node `node`'s saved values in `directory`.
std::filesystem::path device_state_file(const std::filesystem::path& directory, cfg::NodeId node);

/// Writes `node.stored()` to its file in `directory` (created if missing), crash-safe
/// (cfg::write_file_atomically). Nothing saved writes a file without values, so that a 1011h
/// restore is kept too. Fails (Io) naming the file.
cfg::Status save_device_state(const std::filesystem::path& directory, const SlaveNode& node);

/// The saved values of node `node` from its file in `directory`; nullopt when there is no file
/// (the device has never saved). Fails as parse_device_state (Input), or when the file cannot be
/// read (Io).
cfg::Result<std::optional<SavedValues>> load_device_state(const std::filesystem::path& directory,
                                                          cfg::NodeId node);

}  // namespace nmt
