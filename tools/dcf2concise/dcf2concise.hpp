// dcf2concise: the two modes of the tool, called by main.cpp after argument parsing.
#pragma once

#include <cstdint>
#include <optional>
#include <string>

#include "cfg/concise_dcf.hpp"

namespace dcf2concise {

struct EncodeOptions {
  std::string input;   ///< DCF path
  std::string output;  ///< path, "-" for stdout; empty: the input with extension .bin
  std::optional<std::uint8_t> node_id;
  cfg::ConciseSelection selection = cfg::ConciseSelection::Configured;
  bool strict = false;  ///< CiA 306 deviations and warnings are errors
  bool json = false;    ///< summary as JSON on stdout
};

struct DecodeOptions {
  std::string input;        ///< concise DCF path, "-" for stdin
  std::string device_file;  ///< EDS/DCF for names and typed values; may be empty
  bool strict = false;
  bool json = false;
};

/// The input with extension .bin ("-" for "-"): where the stream goes without -o.
std::string default_output(const std::string& input);

/// Each returns the process exit code (tools::ExitCode), or ends early with tools::exit_with
/// (an input that cannot be read).
int run_encode(const EncodeOptions& options);
int run_decode(const DecodeOptions& options);

}  // namespace dcf2concise
