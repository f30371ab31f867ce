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

/// A node-ID known to be 1..127: built checked by NodeId::from at run time, or by the literal
/// `5_node` (cfg::literals) where the number is written in the program; converts to its number.
class NodeId {
 public:
  /// nullopt outside 1..127.
  static constexpr std::optional<NodeId> from(std::uint64_t value) {
    if (!is_node_id(value)) return std::nullopt;
    return NodeId(static_cast<std::uint8_t>(value));
  }
  /// A NodeId is already checked: no round trip through its number.
  static std::optional<NodeId> from(NodeId) = delete;
  constexpr std::uint8_t value() const { return value_; }
  constexpr operator std::uint8_t() const { return value_; }  // NOLINT(google-explicit-constructor)
  constexpr bool operator==(const NodeId&) const = default;
  // NOLINTNEXTLINE(modernize-use-nullptr): clang-tidy 14 flags the 0 of the defaulted compare
  constexpr auto operator<=>(const NodeId&) const = default;

 private:
  constexpr explicit NodeId(std::uint8_t value) : value_(value) {}
  std::uint8_t value_;
};

namespace literals {

/// A node-ID written in the program, `5_node` or `0x7F_node`, checked when it compiles: a number
/// outside 1..127 is no constant expression, so the program does not build.
consteval NodeId operator""_node(unsigned long long value) {  // NOLINT(google-runtime-int)
  if (!is_node_id(value)) throw "a node-ID is 1..127";        // NOLINT(hicpp-exception-baseclass)
  return *NodeId::from(value);
}

}  // namespace literals

}  // namespace cfg
