#include "cfg/download_order.hpp"

#include <algorithm>
#include <span>
#include <type_traits>
#include <utility>

#include "cfg/bytes.hpp"
#include "cfg/cob_id.hpp"
#include "cfg/object_index.hpp"
#include "download_order_detail.hpp"

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

// The writes of one object, by sub-index, one per sub-index (views into the caller's writes:
// no copy until a write goes out). W is `const ObjectWrite` (the caller keeps its writes: each
// one that goes out is copied) or `ObjectWrite` (the caller gave them up: each one is moved,
// which is one allocation fewer per write; each input write goes out at most once).
template <class W>
using ObjectWrites = std::span<W* const>;

template <class W>
W* find_sub(const ObjectWrites<W>* writes, std::uint8_t sub) {
  if (writes == nullptr) return nullptr;
  for (W* w : *writes) {
    if (w->sub_index == sub) return w;
  }
  return nullptr;
}

template <class W>
void emit(W* write, DownloadOrder& out) {
  if constexpr (std::is_const_v<W>) {
    out.writes.push_back(*write);
  } else {
    out.writes.push_back(std::move(*write));
  }
}

// DSP 302 v3.2.1 §6.2 application hint, steps 1-5, for one PDO.
template <class W>
void order_pdo(const PdoIndices& pdo, const ObjectWrites<W>* comm, const ObjectWrites<W>* mapping,
               const CobIdLookup& current_cob_id, DownloadOrder& out) {
  W* configured_cob = find_sub(comm, 1);
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
    for (W* write : *comm) {
      if (write->sub_index != 1) emit(write, out);
    }
  }
  // Steps 3 and 4: deactivate the mapping, write the entries, activate with n entries.
  if (mapping != nullptr) {
    W* count = find_sub(mapping, 0);
    const bool count_is_zero = count != nullptr && all_zero(count->data);
    if (count != nullptr) {
      ObjectWrite zero = *count;
      std::fill(zero.data.begin(), zero.data.end(), std::uint8_t{0});
      out.writes.push_back(std::move(zero));
    } else {
      out.unknown_mapping_count.push_back(pdo.mapping_index);
    }
    for (W* write : *mapping) {
      if (write->sub_index != 0) emit(write, out);
    }
    if (count != nullptr && !count_is_zero) emit(count, out);
  }
  // Step 5: create the PDO with the configured COB-ID. A COB-ID that is itself invalid was
  // already written in step 1.
  if (configured_cob != nullptr) {
    if (!(cob_id && !cob_id->valid())) emit(configured_cob, out);
  } else if (cob_id_from_lookup && cob_id->valid()) {
    out.writes.push_back(cob_id_write(pdo.comm_index, *cob_id));
  }
}

template <class W>
DownloadOrder order(std::span<W> writes, const CobIdLookup& current_cob_id) {
  // Last write of an (index, sub-index) wins, as on a device: a stable sort keeps equal keys in
  // input order, and the last of each run is kept. Pointers, not copies: a DCF has tens of
  // thousands of writes.
  std::vector<W*> sorted;
  sorted.reserve(writes.size());
  for (auto& write : writes) sorted.push_back(&write);
  auto key = [](const W* w) { return (std::uint32_t{w->index} << 8) | w->sub_index; };
  auto by_key = [&key](const W* a, const W* b) { return key(a) < key(b); };
  // Writes made from a DCF come in index order nearly always: then there is nothing to sort
  // (stable_sort would still take a buffer of the writes' size).
  if (!std::is_sorted(sorted.begin(), sorted.end(), by_key)) {
    std::stable_sort(sorted.begin(), sorted.end(), by_key);
  }
  std::size_t kept = 0;
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    if (i + 1 < sorted.size() && key(sorted[i]) == key(sorted[i + 1])) continue;
    sorted[kept++] = sorted[i];
  }
  sorted.resize(kept);
  // The writes of each object, in index order (sorted above): vectors, not maps, as a DCF
  // writes to a thousand objects or more.
  std::vector<std::pair<std::uint16_t, ObjectWrites<W>>> by_object;
  for (std::size_t begin = 0; begin < sorted.size();) {
    std::size_t end = begin + 1;
    while (end < sorted.size() && sorted[end]->index == sorted[begin]->index) ++end;
    by_object.emplace_back(sorted[begin]->index,
                           ObjectWrites<W>(sorted).subspan(begin, end - begin));
    begin = end;
  }

  // What to emit, by sort index: a PDO sorts at its communication index even when only its
  // mapping is written (its entry then appears twice, with the same PdoIndices).
  std::vector<std::pair<std::uint16_t, std::optional<PdoIndices>>> sequence;
  sequence.reserve(by_object.size());
  for (const auto& entry : by_object) {
    auto pdo = pdo_indices_of(entry.first);
    sequence.emplace_back(pdo ? pdo->comm_index : entry.first, pdo);
  }
  auto by_index = [](const auto& a, const auto& b) { return a.first < b.first; };
  std::stable_sort(sequence.begin(), sequence.end(), by_index);
  sequence.erase(std::unique(sequence.begin(), sequence.end(),
                             [](const auto& a, const auto& b) { return a.first == b.first; }),
                 sequence.end());
  auto find = [&by_object](std::uint16_t i) -> const ObjectWrites<W>* {
    auto it = std::lower_bound(by_object.begin(), by_object.end(), i,
                               [](const std::pair<std::uint16_t, ObjectWrites<W>>& e,
                                  std::uint16_t k) { return e.first < k; });
    return it == by_object.end() || it->first != i ? nullptr : &it->second;
  };

  DownloadOrder out;
  out.writes.reserve(writes.size());
  for (const auto& [index, pdo] : sequence) {
    if (pdo) {
      order_pdo(*pdo, find(pdo->comm_index), find(pdo->mapping_index), current_cob_id, out);
    } else if (index == object::kCobIdEmcy) {
      // A device whose EMCY is valid at another COB-ID refuses a valid one written alone: it is
      // written with bit 31 set first (always allowed), then as configured. The lookup says
      // what the device has; when it does not know, the pair goes out anyway.
      for (W* write : *find(index)) {
        const auto cob_id = write->sub_index == 0 ? as_cob_id(write->data) : std::nullopt;
        const auto current = cob_id && current_cob_id ? current_cob_id(object::kCobIdEmcy)
                                                      : std::optional<std::uint32_t>();
        if (cob_id && cob_id->valid() &&
            (!current || (CobId::from_word(*current).valid() && *current != cob_id->word()))) {
          ObjectWrite invalid{object::kCobIdEmcy, 0, {}};
          append_le(invalid.data, cob_id->with_valid(false).word(), 4);
          out.writes.push_back(std::move(invalid));
        }
        emit(write, out);
      }
    } else if (index != kVerifyConfiguration) {
      for (W* write : *find(index)) emit(write, out);
    }
  }
  // DSP 302 v3.2.1 §6.3: "If any other command changes boot-up configuration values, the device
  // has to reset the object Verify Configuration to 0" - so 1020h goes last.
  if (const ObjectWrites<W>* verify = find(kVerifyConfiguration)) {
    for (W* write : *verify) emit(write, out);
  }
  return out;
}

}  // namespace

DownloadOrder order_for_download(std::span<const ObjectWrite> writes,
                                 const CobIdLookup& current_cob_id) {
  return order(writes, current_cob_id);
}

DownloadOrder detail::order_for_download_moving(std::vector<ObjectWrite>&& writes,
                                                const CobIdLookup& current_cob_id) {
  return order(std::span<ObjectWrite>(writes), current_cob_id);
}

DownloadOrder plan_download(std::span<const ObjectWrite> configuration, const DownloadTail& tail,
                            const CobIdLookup& current_cob_id) {
  DownloadOrder plan = order_for_download(configuration, current_cob_id);
  if (!tail.stamp.is_zero()) {
    plan.writes.push_back({object::kVerifyConfiguration, 1, le32_bytes(tail.stamp.days)});
    plan.writes.push_back({object::kVerifyConfiguration, 2, le32_bytes(tail.stamp.ms)});
  }
  if (tail.save) plan.writes.push_back({object::kStoreParameters, 1, le32_bytes(kSaveSignature)});
  return plan;
}

std::vector<ObjectWrite> pdo_safe_order(std::span<const ObjectWrite> writes,
                                        const CobIdLookup& current_cob_id) {
  return order_for_download(writes, current_cob_id).writes;
}

}  // namespace cfg
