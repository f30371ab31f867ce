// dcf2concise DCF -> concise DCF: read the DCF, let libcfg choose and order the writes, encode,
// write the file atomically.
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <string>

#include "../common/command_failure.hpp"
#include "../common/tool_support.hpp"
#include "cfg/concise_dcf.hpp"
#include "cfg/device_file.hpp"
#include "cfg/hex.hpp"
#include "dcf2concise.hpp"

namespace dcf2concise {
namespace {

std::string index_text(const cfg::ObjectWrite& w) {
  return cfg::hex_digits(w.index, 4);
}

// Why the stream has no entries, in the terms of the selection the user made, and that this is
// a valid result.
std::string empty_stream_note(cfg::ConciseSelection selection) {
  std::string why;
  switch (selection) {
    case cfg::ConciseSelection::ChangedOnly:
      why = "no ParameterValue differs from its DefaultValue";
      break;
    case cfg::ConciseSelection::WithDefaults:
      why = "no writable entry has a ParameterValue or DefaultValue";
      break;
    case cfg::ConciseSelection::Configured:
      why = "no ParameterValue to download";
      break;
  }
  why +=
      ": the concise DCF is empty, a valid configuration (DSP 302 §6.2: only the entry "
      "count, 0)";
  if (selection == cfg::ConciseSelection::Configured) {
    why += "; use --with-defaults to include DefaultValues";
  }
  return why;
}

}  // namespace

std::string default_output(const std::string& input) {
  if (input == "-") return "-";
  return std::filesystem::path(input).replace_extension(".bin").string();
}

int run_encode(const EncodeOptions& options) {
  auto text = tools::read_input(options.input);
  if (!text) tools::exit_with(tools::exit_code_for(text.error()), text.error().message);
  const std::string name = options.input == "-" ? "<stdin>" : options.input;
  cfg::ReadOptions read_options;
  read_options.mode = options.strict ? cfg::ReadMode::Strict : cfg::ReadMode::Tolerant;
  read_options.file_name = name;
  cfg::ReadResult read = cfg::parse_device_description(*text, read_options);
  text->release();  // the model holds copies: give the file's bytes back now

  cfg::Diagnostics diagnostics = read.diagnostics;
  std::optional<std::vector<cfg::ObjectWrite>> writes;
  if (read.device && options.node_id) {
    // Said because the file's own node-ID is what a reader of the DCF expects to be used.
    const auto file_node_id = read.device->node_id();
    if (file_node_id && *file_node_id != *options.node_id) {
      diagnostics.add(name, 0, cfg::Severity::Note,
                      "--node-id " + std::to_string(*options.node_id) + " overrides NodeID " +
                          std::to_string(*file_node_id) + " of [DeviceComissioning]");
    }
  }
  if (read.device && !read.diagnostics.has_errors()) {
    cfg::ConciseOptions concise;
    concise.node_id = options.node_id;
    concise.selection = options.selection;
    concise.file_name = name;
    concise.node_id_hint = "give one with --node-id N";
    concise.base_dir = options.input == "-"
                           ? std::string(".")
                           : std::filesystem::path(options.input).parent_path().string();
    writes = cfg::concise_writes_from_dcf(*read.device, concise, diagnostics);
    // An empty configuration is valid (DSP 302 §6.2: the stream is then just its count, 0), so
    // it is a note, which --strict does not promote: said, because from an EDS or an
    // unfinished DCF it is rarely what was meant, but no failure.
    if (writes && writes->empty()) {
      diagnostics.add(name, 0, cfg::Severity::Note, empty_stream_note(options.selection));
    }
  }
  if (options.strict) diagnostics = tools::promote_warnings(diagnostics);
  tools::print_diagnostics(diagnostics);

  const std::string output =
      options.output.empty() ? default_output(options.input) : options.output;
  const bool ok = writes.has_value() && !diagnostics.has_errors();
  std::vector<std::uint8_t> stream;
  int code = ok ? tools::kExitOk : tools::kExitInputErrors;
  if (ok) {
    stream = cfg::encode_concise_dcf(*writes);
    auto status = tools::write_output(
        output, std::string_view(reinterpret_cast<const char*>(stream.data()), stream.size()));
    if (!status) {
      std::cerr << status.error().message << '\n';
      code = tools::exit_code_for(status.error());
    }
  }

  if (options.json) {
    std::string out = "{\"input\": " + tools::json_string(name) + ", \"output\": " +
                      (code == tools::kExitOk ? tools::json_string(output) : "null") +
                      ", \"ok\": " + (code == tools::kExitOk ? "true" : "false") +
                      ", \"size\": " + std::to_string(stream.size()) + ", \"entries\": [";
    if (ok) {
      bool first = true;
      for (const auto& w : *writes) {
        if (!first) out += ", ";
        first = false;
        out += "{\"index\": " + std::to_string(w.index) + ", \"index_hex\": \"" + index_text(w) +
               "\", \"sub_index\": " + std::to_string(w.sub_index) +
               ", \"size\": " + std::to_string(w.data.size()) + ", \"data\": \"" +
               tools::hex_string(w.data) + "\"}";
      }
    }
    out += "], \"diagnostics\": " + tools::json_diagnostics(diagnostics) + "}\n";
    std::cout << out;
  }
  // The process exits next: the model and the writes go with it, unfreed.
  tools::keep_until_exit(std::move(read));
  tools::keep_until_exit(std::move(writes));
  return code;
}

}  // namespace dcf2concise
