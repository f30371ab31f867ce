// How a tool's command ends before its work is done: one exception, thrown where the failure is
// found (the command's callback or any helper it calls) and caught once, in the tool's main,
// which prints its message on stderr and returns its exit code. Nothing else ends a command
// early; a command that runs to its end returns (or, with a code that is not 0, calls exit_with).
#pragma once

#include <exception>
#include <iostream>
#include <string>
#include <string_view>
#include <utility>

namespace tools {

/// The end of a command: the process exit code (a tools::ExitCode, or a command's own such as
/// diff's 1 "different") and the line main prints on stderr first (empty: none, e.g. when the
/// diagnostics were already printed).
class CommandFailure : public std::exception {
 public:
  CommandFailure(int code, std::string message) : code_(code), message_(std::move(message)) {}
  int code() const noexcept { return code_; }
  const std::string& message() const noexcept { return message_; }
  const char* what() const noexcept override { return message_.c_str(); }

 private:
  int code_;
  std::string message_;
};

/// Ends the running command with exit code `code`; `message`, when not empty, is printed on
/// stderr as given (a compiler-style "FILE: error: ..." or a tool's prefixed line), one line.
[[noreturn]] inline void exit_with(int code, std::string message = {}) {
  throw CommandFailure(code, std::move(message));
}

/// main's half: prints the failure's message (when there is one) and gives its exit code.
inline int finish_command(const CommandFailure& failure) {
  if (!failure.message().empty()) std::cerr << failure.message() << '\n' << std::flush;
  return failure.code();
}

}  // namespace tools

namespace cfgmgr {

using tools::exit_with;

/// "cfgmgr TOOL: ", the start of the lines the cfgmgr subcommand `tool` prints.
inline std::string command_prefix(std::string_view tool) {
  return "cfgmgr " + std::string(tool) + ": ";
}

/// Ends the cfgmgr subcommand `tool` with `code` and "cfgmgr TOOL: message" on stderr.
[[noreturn]] inline void fail_command(std::string_view tool, int code, const std::string& message) {
  exit_with(code, command_prefix(tool) + message);
}

}  // namespace cfgmgr
