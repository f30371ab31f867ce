// Small helpers the master's engines share (messages, events, SDO values); defined with the
// master (master_dictionary.cpp, boot_slave.cpp, nmt_master.cpp). Private to the library.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "cfg/data_type.hpp"
#include "cfg/node_id.hpp"
#include "master/master_text.hpp"
#include "nmt/master/nmt_master.hpp"
#include "nmt/sdo/sdo_client.hpp"
#include "nmt/slave/local_dictionary.hpp"

namespace nmt {

/// An entry of the master's own objects with `value` in the type's size (0 bytes for DOMAIN).
DictionaryEntry make_entry(std::uint16_t index, std::uint8_t sub, std::string name,
                           cfg::DataType type, cfg::AccessType access, std::uint64_t value);
/// The first up to 4 bytes of an upload, little-endian (UNSIGNED32 objects); 0 when empty.
std::uint32_t uploaded_u32(const SdoResult& result);
/// A boot that failed on `result` (describe() words it "1018h sub 01h upload failed: ...").
BootFailure transfer_failed(const SdoResult& result,
                            BootFailure::Reason reason = BootFailure::Reason::TransferFailed);
/// 1..127 in order: the master's loops over every node-ID, without a cast and a check per node.
constexpr std::array<cfg::NodeId, cfg::kMaxNodeId> all_node_ids() {
  return []<std::size_t... I>(std::index_sequence<I...>) {
    return std::array<cfg::NodeId, cfg::kMaxNodeId>{*cfg::NodeId::from(I + cfg::kMinNodeId)...};
  }
  (std::make_index_sequence<cfg::kMaxNodeId>{});
}

}  // namespace nmt
