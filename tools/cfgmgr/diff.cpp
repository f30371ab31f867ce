// cfgmgr diff A.dcf B.dcf: the parameters two device files configure differently, by index,
// sub-index and name, with the values in words, and the [DynamicChannels] segments they declare
// differently (cfg/dcf_diff.hpp). Exit codes as diff(1).
#include <iostream>
#include <memory>
#include <optional>
#include <string>

#include "../common/tool_support.hpp"
#include "cfg/dcf_diff.hpp"
#include "cfg/device_file.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/node_id.hpp"
#include "commands.hpp"

namespace cfgmgr {
namespace {

// diff(1): 0 same, 1 different, 2 trouble.
constexpr int kExitSame = 0;
constexpr int kExitDifferent = 1;
constexpr int kExitTrouble = 2;

struct DiffCliOptions {
  std::string a;
  std::string b;
  std::string node_id;
  bool json = false;
};

[[noreturn]] void trouble(const std::string& message) {
  fail_command("diff", kExitTrouble, message);
}

cfg::DeviceDescription read_or_exit(const std::string& path) {
  cfg::ReadResult read = cfg::read_device_file(path);
  cfg::Diagnostics errors;
  for (const auto& d : read.diagnostics.items()) {
    if (d.severity == cfg::Severity::Error) errors.add(d);
  }
  tools::print_diagnostics(errors);
  if (!read.device) trouble(path + ": not a device description");
  if (!errors.empty()) trouble(path + ": has errors; nothing compared");
  return std::move(*read.device);
}

std::string at(const std::string& file, int line) {
  return line > 0 ? file + ":" + std::to_string(line) : file;
}

std::string address_text(const cfg::ParameterDifference& d) {
  return d.whole_object ? cfg::object_name(d.address.index) : cfg::to_string(d.address);
}

std::string segment_title(const cfg::SegmentDifference& d) {
  return "[DynamicChannels] segment at " + cfg::object_name(d.first_index);
}

void print_segments(const std::vector<cfg::SegmentDifference>& diffs, const DiffCliOptions& o) {
  using Kind = cfg::ParameterDifference::Kind;
  for (const auto& d : diffs) {
    std::cout << segment_title(d);
    if (d.kind == Kind::Changed) {
      std::cout << "\n  " << o.a << " (segment " << d.segment_a << "): " << d.a->text << "\n  "
                << o.b << " (segment " << d.segment_b << "): " << d.b->text << '\n';
      continue;
    }
    const bool in_a = d.kind == Kind::OnlyInA;
    std::cout << ": only in " << (in_a ? o.a : o.b) << " (segment "
              << (in_a ? d.segment_a : d.segment_b) << "): " << (in_a ? d.a : d.b)->text << '\n';
  }
}

void print_text(const std::vector<cfg::ParameterDifference>& diffs,
                const std::vector<cfg::SegmentDifference>& segments, const DiffCliOptions& o) {
  using Kind = cfg::ParameterDifference::Kind;
  for (const auto& d : diffs) {
    std::cout << address_text(d) << ' ' << d.name;
    if (d.kind == Kind::Changed) {
      std::cout << "\n  " << at(o.a, d.a->line) << ": " << d.a->text << "\n  " << at(o.b, d.b->line)
                << ": " << d.b->text << '\n';
      continue;
    }
    const bool in_a = d.kind == Kind::OnlyInA;
    const cfg::DiffSide& side = in_a ? *d.a : *d.b;
    const std::string& file = in_a ? o.a : o.b;
    std::cout << ": only in " << file << " (" << at(file, side.line) << ")";
    if (!d.whole_object) std::cout << ": " << side.text;
    std::cout << '\n';
  }
  print_segments(segments, o);
  const auto total = diffs.size() + segments.size();
  std::cout << (total == 0 ? "no differences" : tools::plural(total, "difference")) << '\n';
}

std::string json_side(const std::optional<cfg::DiffSide>& side, bool whole_object) {
  if (!side) return "null";
  return std::string("{\"value\": ") + (whole_object ? "null" : tools::json_string(side->text)) +
         ", \"line\": " + std::to_string(side->line) + "}";
}

std::string json_report(const std::vector<cfg::ParameterDifference>& diffs,
                        const std::vector<cfg::SegmentDifference>& segments,
                        const DiffCliOptions& o) {
  const bool same = diffs.empty() && segments.empty();
  std::string out = "{\"same\": " + std::string(same ? "true" : "false") +
                    ", \"a\": " + tools::json_string(o.a) + ", \"b\": " + tools::json_string(o.b) +
                    ", \"differences\": [";
  bool first = true;
  for (const auto& d : diffs) {
    out += std::string(first ? "" : ", ") + "{\"index\": " + std::to_string(d.address.index) +
           ", \"sub_index\": " + (d.whole_object ? "null" : std::to_string(d.address.sub_index)) +
           ", \"address\": " + tools::json_string(address_text(d)) +
           ", \"name\": " + tools::json_string(d.name) +
           ", \"kind\": " + tools::json_string(cfg::to_string(d.kind)) +
           ", \"a\": " + json_side(d.a, d.whole_object) +
           ", \"b\": " + json_side(d.b, d.whole_object) + "}";
    first = false;
  }
  out += "], \"dynamic_channels\": [";
  first = true;
  for (const auto& d : segments) {
    out += std::string(first ? "" : ", ") + "{\"first_index\": " + std::to_string(d.first_index) +
           ", \"segment_a\": " + (d.segment_a != 0 ? std::to_string(d.segment_a) : "null") +
           ", \"segment_b\": " + (d.segment_b != 0 ? std::to_string(d.segment_b) : "null") +
           ", \"kind\": " + tools::json_string(cfg::to_string(d.kind)) +
           ", \"a\": " + json_side(d.a, false) + ", \"b\": " + json_side(d.b, false) + "}";
    first = false;
  }
  return out + "]}\n";
}

void run_diff(const DiffCliOptions& options) {
  cfg::DiffOptions diff_options;
  if (!options.node_id.empty()) {
    const auto parsed = tools::parse_node_id_argument(options.node_id);
    if (!parsed) trouble(tools::node_id_argument_error("--node-id", options.node_id));
    diff_options.node_id_a = diff_options.node_id_b = *parsed;
  }
  const cfg::DeviceDescription a = read_or_exit(options.a);
  const cfg::DeviceDescription b = read_or_exit(options.b);
  const auto diffs = cfg::diff_parameters(a, b, diff_options);
  const auto segments = cfg::diff_dynamic_channels(a, b);
  if (options.json) {
    std::cout << json_report(diffs, segments, options);
  } else {
    print_text(diffs, segments, options);
  }
  std::cout.flush();
  if (!std::cout) trouble("write error on standard output");
  exit_with(diffs.empty() && segments.empty() ? kExitSame : kExitDifferent);
}

}  // namespace

void add_diff_command(CLI::App& app) {
  auto options = std::make_shared<DiffCliOptions>();
  auto* cmd = app.add_subcommand(
      "diff",
      "Print the parameters two EDS/DCF files configure differently: per entry the value a "
      "download writes (ParameterValue, else DefaultValue, CiA 306), compared as typed values, "
      "with index, sub-index, name and both values in words; objects and sub-objects only in "
      "one file; and the [DynamicChannels] segments (CiA DSP 302 §8.4) added, removed or "
      "changed, matched by the start of their range");
  cmd->add_option("a", options->a, "The first file (shown first)")->required()->type_name("A.dcf");
  cmd->add_option("b", options->b, "The second file")->required()->type_name("B.dcf");
  cmd->add_option("--node-id", options->node_id,
                  "Resolve $NODEID in both files with this node-ID (default: each file's "
                  "[DeviceComissioning] NodeID; without one, $NODEID values are compared as "
                  "written)")
      ->type_name("N");
  cmd->add_flag("--json", options->json,
                "Print JSON: same, a, b, differences [{index, sub_index, address, name, kind "
                "(changed/only_in_a/only_in_b), a {value, line}, b {value, line}}], "
                "dynamic_channels [{first_index, segment_a, segment_b, kind, a, b}]");
  cmd->footer(
      "Values in words: integers in decimal, unsigned ones with their hex (COB-IDs, mapping "
      "entries), strings quoted, REAL as a number, octet strings and domains as hex bytes.\n\n"
      "Examples:\n"
      "  cfgmgr diff drive_node3.dcf drive_node3.old.dcf\n"
      "  cfgmgr diff --node-id 5 vendor.eds node5.dcf\n"
      "  cfgmgr diff --json a.dcf b.dcf | jq '.differences[].address'\n\n"
      "Exit codes (as diff(1)):\n"
      "  0  no differences\n"
      "  1  the files differ\n"
      "  2  trouble: a file cannot be read, is no device description or has errors (printed "
      "as FILE:LINE: error: ...), or a usage error\n");
  cmd->callback([options] { run_diff(*options); });
}

}  // namespace cfgmgr
