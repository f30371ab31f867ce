// CANopen node-IDs (CiA 301 §7.2.8.3.1 and §7.3.3): 1..127 address one node; 0 in an NMT
// command addresses all nodes. The one place of the 1..127 rule.
#pragma once

#include <cstdint>
#include <optional>

namespace cfg {

inline constexpr unsigned kMinNodeId = 1;
inline constexpr unsigned kMaxNodeId = 127;

/// True for 1..127.
constexpr bool is_node_id(std::uint64_t value) {
  return value >= kMinNodeId && value <= kMaxNodeId;
}

/// A node-ID known to be 1..127: NodeId::from is the only way to build one (checked); converts to
/// its number.
class NodeId {
 public:
  /// nullopt outside 1..127.
  static constexpr std::optional<NodeId> from(std::uint64_t value) {
    if (!is_node_id(value)) return std::nullopt;
    return NodeId(static_cast<std::uint8_t>(value));
  }
  constexpr std::uint8_t value() const { return value_; }
  constexpr operator std::uint8_t() const { return value_; }  // NOLINT(google-explicit-constructor)
  constexpr bool operator==(const NodeId&) const = default;
  // NOLINTNEXTLINE(modernize-use-nullptr): clang-tidy 14 flags the 0 of the defaulted compare
  constexpr auto operator<=>(const NodeId&) const = default;

 private:
  constexpr explicit NodeId(std::uint8_t value) : value_(value) {}
  std::uint8_t value_;
};

}  // namespace cfg
