// A simulated device's non-volatile memory on disk: the values 1010h 'save' stored
// (SlaveNode::stored(), 1020h included), the node-ID and bit rate LSS store configuration
// saved (SlaveNode::lss_stored(), CiA 305) and the program images downloaded into 1F50h
// (SlaveNode::program_images(), DSP 302 §9), one file per device in a directory (plus one per
// image), so that a device
// keeps them from one run to the next as a real one keeps them across power cycles (`cfgmgr push
// --bus sim:?state=DIR`: a second push finds 1020h as the first left it; `cfgmgr simulate
// --state DIR FILE@255`: a device given node-ID 5 by LSS boots as node 5 next time).
//   auto saved = nmt::load_device_state(dir, owner);   // before start()
//   if (saved && *saved) nmt::restore_device_state(device.node(), std::move(**saved));
//   ... on changes_device_state(event.kind): nmt::save_device_state(dir, owner, device.node());
//
// A file belongs to the device's place, not to its current node-ID (LSS may change that): the
// node-ID it was started with ("node-NN.saved", NN two upper-case hex digits), or for a device
// started without one (LSS, FFh) its LSS address ("lss-VVVVVVVV-PPPPPPPP-RRRRRRRR-SSSSSSSS.saved").
// The file is text:
//   ; comment lines
//   node=5                    or lss=7E57C0DE:00000305:00010002:00001001 (whose file it is)
//   1017sub00=E803            one line per saved value: index, sub-index, bytes in bus order
//   lss_node=5                what LSS stored, when it did: node-ID (255: not configured) and
//   lss_bit_timing=2          bit timing table index (CiA 305 table 0, 2 = 500 kbit/s)
//   program01=262156,89ABCDEF program memory (DSP 302 §9, SlaveNode::program_images()): program
//                             number (two hex digits), the image's size and CRC-32; the image
//                             itself is the file "node-05.program01.bin" next to this one
//   end=12                    the number of value lines: a file cut short is never taken
// The images are written before the text file (each crash-safe), so a listed image is complete;
// one whose size or CRC differs from its line is an error, never a program the device runs.
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
#include "nmt/lss/lss.hpp"
#include "nmt/lss/lss_slave.hpp"
#include "nmt/slave/slave_node.hpp"

namespace nmt {

/// Saved values by key (cfg::ObjectAddress::key(): index << 8 | sub-index), as
/// SlaveNode::stored() holds them.
using SavedValues = std::map<std::uint32_t, std::vector<std::uint8_t>>;

/// Whose a state file is: the node-ID the device was started with, or the LSS address of a
/// device started unconfigured (see the top of this file).
struct DeviceStateOwner {
  DeviceStateOwner(cfg::NodeId id) : node(id) {}  // NOLINT(google-explicit-constructor)
  DeviceStateOwner(const LssAddress& address)     // NOLINT(google-explicit-constructor)
      : lss(address) {}
  std::optional<cfg::NodeId> node;
  LssAddress lss;  ///< when !node
};

/// Program images by program number (1F50h sub N), as SlaveNode::program_images() holds them.
using ProgramImages = std::map<std::uint8_t, std::vector<std::uint8_t>>;

/// What a device keeps over power cycles: its 1010h-saved values, what LSS stored and its
/// program memory.
struct DeviceState {
  SavedValues values;
  std::optional<LssStoredConfig> lss;
  ProgramImages programs;
  bool operator==(const DeviceState&) const = default;
};

/// The file's text for `owner` and `state` (format above).
std::string format_device_state(const DeviceStateOwner& owner, const DeviceState& state);

/// Parses the file's text (`file`: the name used in messages). Fails with
/// "FILE:LINE: error: ..." when a line does not parse, the text is cut short (no end= or one
/// that does not count the values) or names another owner than `owner`. The program images
/// are in files of their own (load_device_state reads them): `programs` is left empty.
cfg::Result<DeviceState> parse_device_state(std::string_view text, const std::string& file,
                                            const DeviceStateOwner& owner);

/// The file that holds `owner`'s image of program `program` in `directory`.
std::filesystem::path program_image_file(const std::filesystem::path& directory,
                                         const DeviceStateOwner& owner, std::uint8_t program);

/// The file that holds `owner`'s state in `directory`.
std::filesystem::path device_state_file(const std::filesystem::path& directory,
                                        const DeviceStateOwner& owner);

/// Writes what `node` stores (stored(), lss_stored(), program_images()) to `owner`'s files in
/// `directory` (created if missing), crash-safe (cfg::write_file_atomically). Nothing saved
/// writes a file without values, so that a 1011h restore is kept too; the image of a cleared
/// program is removed. Fails (Io) naming the file.
cfg::Status save_device_state(const std::filesystem::path& directory, const DeviceStateOwner& owner,
                              const SlaveNode& node);

/// `owner`'s state from its files in `directory`; nullopt when there is no file (the device has
/// never saved). Fails as parse_device_state (Input), when a listed image is missing or its
/// size or CRC-32 differs from its line (Input), or when a file cannot be read (Io).
cfg::Result<std::optional<DeviceState>> load_device_state(const std::filesystem::path& directory,
                                                          const DeviceStateOwner& owner);

/// Gives `node` the state as its non-volatile memory (set_stored, set_lss_stored,
/// set_program_images): it acts at the next start().
void restore_device_state(SlaveNode& node, DeviceState state);

/// True for the events after which a device's state file is written again: 1010h save, 1011h
/// restore, LSS services (store configuration among them; the others write what was already
/// there) and program download and control (1F50h, 1F51h).
bool changes_device_state(SlaveEvent::Kind kind);

}  // namespace nmt
