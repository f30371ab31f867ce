// Runs tests/io/python/can_peer.py (python-can as an independent peer) from a test.
// Uses Debian's /usr/bin/python3 explicitly: python3-can and python3-msgpack are Debian packages.
#pragma once

#include <sys/wait.h>

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "test_paths.hpp"

namespace test_support {

/// tests/io/python/`name`: the scripts of the python-can peers.
inline std::string python_script(const std::string& name) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/../io/python/" + name;
}
inline std::string can_peer_script() {
  return python_script("can_peer.py");
}

/// Quotes `s` for /bin/sh.
inline std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (char c : s) {
    if (c == '\'') {
      out += "'\\''";
    } else {
      out += c;
    }
  }
  return out + "'";
}

/// Why python-can cannot be used, or nullopt when it can.
inline std::optional<std::string> python_can_missing() {
  if (std::system("/usr/bin/python3 -c 'import can, msgpack' >/dev/null 2>&1") != 0) {
    return "python-can needs Debian's python3-can and python3-msgpack (/usr/bin/python3)";
  }
  return std::nullopt;
}

/// can_peer.py (or another script) running with its stdout piped to us. stderr goes to the
/// test's stderr.
class PythonPeer {
 public:
  explicit PythonPeer(const std::vector<std::string>& args) : PythonPeer(can_peer_script(), args) {}
  PythonPeer(const std::string& script, const std::vector<std::string>& args) {
    std::string command = "/usr/bin/python3 " + shell_quote(script);
    for (const auto& a : args) command += " " + shell_quote(a);
    pipe_ = ::popen(command.c_str(), "r");
  }
  ~PythonPeer() { (void)finish(); }
  PythonPeer(const PythonPeer&) = delete;
  PythonPeer& operator=(const PythonPeer&) = delete;

  /// The next line of output without its newline; nullopt at end of output.
  std::optional<std::string> read_line() {
    if (pipe_ == nullptr) return std::nullopt;
    std::string line;
    char buf[512];
    while (std::fgets(buf, sizeof buf, pipe_) != nullptr) {
      line += buf;
      if (!line.empty() && line.back() == '\n') {
        line.pop_back();
        return line;
      }
    }
    if (line.empty()) return std::nullopt;
    return line;
  }
  /// All remaining lines.
  std::vector<std::string> read_all() {
    std::vector<std::string> lines;
    while (auto line = read_line()) lines.push_back(*line);
    return lines;
  }
  /// Waits for the process; its exit code (-1 if it did not exit normally).
  int finish() {
    if (pipe_ == nullptr) return exit_code_;
    const int status = ::pclose(pipe_);
    pipe_ = nullptr;
    exit_code_ = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return exit_code_;
  }

 private:
  std::FILE* pipe_ = nullptr;
  int exit_code_ = -1;
};

/// Runs can_peer.py to the end: its exit code and output lines.
struct PeerRun {
  int exit_code;
  std::vector<std::string> lines;
};
inline PeerRun run_python_peer(const std::vector<std::string>& args) {
  PythonPeer peer(args);
  auto lines = peer.read_all();
  return {peer.finish(), std::move(lines)};
}

}  // namespace test_support
