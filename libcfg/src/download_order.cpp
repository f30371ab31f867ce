#include "cfg/download_order.hpp"

#include <algorithm>
#include <map>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/cob_id.hpp"

namespace cfg {
namespace {

// CiA 301 1020h Verify configuration (configuration date and time).
constexpr std::uint16_t kVerifyConfiguration = 0x1020;

std::optional<CobId> as_cob_id(const std::vector<std::uint8_t>& data) {
  if (data.size() != 4) return std::nullopt;
  return CobId::from_word(load_le32(data));
}

// CiA 301 §7.5.2.35: the PDO COB-ID is sub-index 1 of the communication parameter (UNSIGNED32).
ObjectWrite cob_id_write(std::uint16_t comm_index, CobId cob_id) {
  ObjectWrite write{comm_index, 1, {}};
  append_le(write.data, cob_id.word(), 4);
  return write;
}

bool all_zero(const std::vector<std::uint8_t>& data) {
  return std::all_of(data.begin(), data.end(), [](std::uint8_t b) { return b == 0; });
}

// The writes of one object, by sub-index.
using ObjectWrites = std::map<std::uint8_t, ObjectWrite>;

// DSP 302 v3.2.1 §6.2 application hint, steps 1-5, for one PDO.
void order_pdo(const PdoIndices& pdo, const ObjectWrites* comm, const ObjectWrites* mapping,
               const CobIdLookup& current_cob_id, DownloadOrder& out) {
  const ObjectWrite* configured_cob = nullptr;
  if (comm != nullptr) {
    if (auto it = comm->find(1); it != comm->end()) configured_cob = &it->second;
  }
  std::optional<CobId> cob_id =
      configured_cob != nullptr ? as_cob_id(configured_cob->data) : std::nullopt;
  bool cob_id_from_lookup = false;
  if (!cob_id && current_cob_id) {
    if (auto word = current_cob_id(pdo.comm_index)) cob_id = CobId::from_word(*word);
    cob_id_from_lookup = cob_id.has_value();
  }

  // Step 1: delete the PDO (bit 31 = 1) so that its parameters may change.
  if (cob_id) {
    out.writes.push_back(cob_id_write(pdo.comm_index, cob_id->with_valid(false)));
  } else {
    out.unknown_cob_id.push_back(pdo.comm_index);
  }
  // Step 2: communication sub-indices other than the COB-ID (sub-index order; a writable sub 0
  // is unusual but goes here too).
  if (comm != nullptr) {
    for (const auto& [sub, write] : *comm) {
      if (sub != 1) out.writes.push_back(write);
    }
  }
  // Steps 3 and 4: deactivate the mapping, write the entries, activate with n entries.
  if (mapping != nullptr) {
    const ObjectWrite* count = nullptr;
    if (auto it = mapping->find(0); it != mapping->end()) count = &it->second;
    if (count != nullptr) {
      ObjectWrite zero = *count;
      std::fill(zero.data.begin(), zero.data.end(), std::uint8_t{0});
      out.writes.push_back(std::move(zero));
    } else {
      out.unknown_mapping_count.push_back(pdo.mapping_index);
    }
    for (const auto& [sub, write] : *mapping) {
      if (sub != 0) out.writes.push_back(write);
    }
    if (count != nullptr && !all_zero(count->data)) out.writes.push_back(*count);
  }
  // Step 5: create the PDO with the configured COB-ID. A COB-ID that is itself invalid was
  // already written in step 1.
  if (configured_cob != nullptr) {
    if (!(cob_id && !cob_id->valid())) out.writes.push_back(*configured_cob);
  } else if (cob_id_from_lookup && cob_id->valid()) {
    out.writes.push_back(cob_id_write(pdo.comm_index, *cob_id));
  }
}

}  // namespace

DownloadOrder order_for_download(std::span<const ObjectWrite> writes,
                                 const CobIdLookup& current_cob_id) {
  // Last write of an (index, sub-index) wins, as on a device.
  std::map<std::uint16_t, ObjectWrites> by_object;
  for (const auto& write : writes) by_object[write.index][write.sub_index] = write;

  // What to emit, by sort index: a PDO sorts at its communication index even when only its
  // mapping is written.
  std::map<std::uint16_t, std::optional<PdoIndices>> sequence;
  for (const auto& entry : by_object) {
    auto pdo = pdo_indices_of(entry.first);
    sequence[pdo ? pdo->comm_index : entry.first] = pdo;
  }
  auto find = [&by_object](std::uint16_t i) -> const ObjectWrites* {
    auto it = by_object.find(i);
    return it == by_object.end() ? nullptr : &it->second;
  };

  DownloadOrder out;
  out.writes.reserve(writes.size());
  for (const auto& [index, pdo] : sequence) {
    if (pdo) {
      order_pdo(*pdo, find(pdo->comm_index), find(pdo->mapping_index), current_cob_id, out);
    } else if (index != kVerifyConfiguration) {
      for (const auto& entry : by_object.at(index)) out.writes.push_back(entry.second);
    }
  }
  // DSP 302 v3.2.1 §6.3: "If any other command changes boot-up configuration values, the device
  // has to reset the object Verify Configuration to 0" - so 1020h goes last.
  if (const ObjectWrites* verify = find(kVerifyConfiguration)) {
    for (const auto& entry : *verify) out.writes.push_back(entry.second);
  }
  return out;
}

std::vector<ObjectWrite> pdo_safe_order(std::span<const ObjectWrite> writes,
                                        const CobIdLookup& current_cob_id) {
  return order_for_download(writes, current_cob_id).writes;
}

}  // namespace cfg
