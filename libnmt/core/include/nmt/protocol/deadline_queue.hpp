// The deadlines of many parts of one engine (one per monitored node, one per SDO client), kept in
// order so that next_deadline() reads the earliest in O(1) and on_timer visits only the due
// parts, instead of scanning all of them after every call (engine.hpp rule 4: drivers read
// next_deadline() after every call).
#pragma once

#include <optional>
#include <set>
#include <utility>

#include "nmt/protocol/frame.hpp"

namespace nmt {

/// Keys ordered by their deadline (ties: by key). The owner keeps each key's current deadline
/// next to its state and calls move() whenever it changes, so the queue holds exactly one entry
/// per key that has a deadline.
template <class Key>
class DeadlineQueue {
 public:
  /// `key`'s deadline changes from `from` to `to` (nullopt: none). Reuses the entry's node, so a
  /// deadline that only moves allocates nothing.
  void move(const Key& key, std::optional<TimePoint> from, std::optional<TimePoint> to) {
    if (from == to) return;
    if (from && to) {
      auto node = entries_.extract({*from, key});
      if (!node.empty()) {
        node.value().first = *to;
        entries_.insert(std::move(node));
        return;
      }
    } else if (from) {
      entries_.erase({*from, key});
      return;
    }
    entries_.insert({*to, key});
  }
  void clear() { entries_.clear(); }
  bool empty() const { return entries_.empty(); }

  /// The earliest deadline; nullopt when no key has one.
  std::optional<TimePoint> earliest() const {
    if (entries_.empty()) return std::nullopt;
    return entries_.begin()->first;
  }
  /// The key with the earliest deadline at or before `now` (ties: the smallest key); nullopt when
  /// none is due.
  std::optional<Key> first_due(TimePoint now) const {
    if (entries_.empty() || now < entries_.begin()->first) return std::nullopt;
    return entries_.begin()->second;
  }
  /// Appends the keys due at `now` to `keys`, earliest first, for an owner whose visit may leave
  /// a key due again (it visits each once, as one scan did).
  template <class Container>
  void due(TimePoint now, Container& keys) const {
    for (auto it = entries_.begin(); it != entries_.end() && !(now < it->first); ++it) {
      keys.push_back(it->second);
    }
  }

 private:
  std::set<std::pair<TimePoint, Key>> entries_;
};

}  // namespace nmt
