// What the push tests (push_test.cpp, push_sim_test.cpp) share: running cfgmgr, reading the
// --json report, and counting a node's concise DCF as dcf2concise writes it.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "tool_test_support.hpp"

namespace push_test {

using tool_test::Json;
using tool_test::JsonParser;
using tool_test::ScratchDir;

using tool_test::cfgmgr;

struct Concise {
  std::size_t entries = 0;
  std::size_t bytes = 0;
};

// The node's concise DCF by dcf2concise, counted: CiA 302 §6.2 (count, then index u16,
// sub-index u8, size u32, data per entry; little-endian).
inline Concise concise_of(const ScratchDir& dir, const std::string& dcf) {
  const std::string out = dir / "node.bin";
  auto r = tool_test::run("dcf2concise", {dcf, "-o", out}, dir.path().string());
  EXPECT_EQ(r.exit_code, 0) << r.err;
  const std::string s = tool_test::slurp(out);
  const auto le = [&s](std::size_t at, int n) {
    std::uint32_t v = 0;
    for (int i = n - 1; i >= 0; --i) v = (v << 8) | static_cast<std::uint8_t>(s.at(at + i));
    return v;
  };
  Concise c;
  c.entries = le(0, 4);
  std::size_t at = 4;
  for (std::size_t i = 0; i < c.entries; ++i) {
    const std::uint32_t size = le(at + 3, 4);
    c.bytes += size;
    at += 7 + size;
  }
  EXPECT_EQ(at, s.size()) << "the stream has data after its last entry";
  return c;
}

inline Json parse_json(const std::string& path) {
  auto value = tool_test::parse_json_file(path);
  EXPECT_TRUE(value && value->is(Json::Kind::Object)) << path << " holds no JSON object";
  return value ? *value : Json{};
}

inline std::map<int, const Json*> nodes_of(const Json& report) {
  std::map<int, const Json*> out;
  const Json* nodes = report.get("nodes");
  EXPECT_TRUE(nodes != nullptr && nodes->is(Json::Kind::Array));
  if (nodes == nullptr) return out;
  for (const auto& n : nodes->array) out[static_cast<int>(n.get("node_id")->number)] = &n;
  return out;
}

}  // namespace push_test
