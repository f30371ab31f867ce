// End-to-end test helpers: run a built tool with arguments and capture exit code, stdout and
// stderr; a scratch directory per test; a small strict JSON parser to check --json output.
#pragma once

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>

#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <thread>
#include <utility>
#include <vector>

#include "prerequisite.hpp"
#include "scratch_dir.hpp"
#include "test_paths.hpp"

namespace tool_test {

inline std::string tool_path(const std::string& name) {
  return std::string(CANOPEN_TOOLS_DIR) + "/" + name;
}
inline std::string data_path(const std::string& relative) {
  return std::string(CANOPEN_TEST_DATA_DIR) + "/" + relative;
}

inline std::string slurp(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/// Single-quoted for /bin/sh.
inline std::string shell_quote(const std::string& arg) {
  std::string out = "'";
  for (char c : arg) {
    if (c == '\'') {
      out += "'\\''";
    } else {
      out += c;
    }
  }
  return out + "'";
}

struct RunResult {
  int exit_code = -1;
  std::string out;  ///< stdout, bytes as written
  std::string err;  ///< stderr
};

using test_support::ScratchDir;

/// Runs `tool` (cfgmgr, dcf2concise) with `args`, in `cwd` when given, stdin from `stdin_file`
/// when given (else /dev/null).
inline RunResult run(const std::string& tool, const std::vector<std::string>& args,
                     const std::string& scratch, const std::string& cwd = "",
                     const std::string& stdin_file = "") {
  const std::string out_file = scratch + "/.stdout";
  const std::string err_file = scratch + "/.stderr";
  std::string command;
  if (!cwd.empty()) command += "cd " + shell_quote(cwd) + " && ";
  command += shell_quote(tool_path(tool));
  for (const auto& a : args) command += " " + shell_quote(a);
  command += " <" + shell_quote(stdin_file.empty() ? "/dev/null" : stdin_file);
  command += " >" + shell_quote(out_file) + " 2>" + shell_quote(err_file);
  const int status = std::system(command.c_str());
  RunResult r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out_file);
  r.err = slurp(err_file);
  std::filesystem::remove(out_file);
  std::filesystem::remove(err_file);
  return r;
}

/// `cfgmgr ARGS` run in the test's scratch directory.
inline RunResult cfgmgr(const ScratchDir& dir, const std::vector<std::string>& args) {
  return run("cfgmgr", args, dir.path().string());
}

/// A file of the sample network shipped with the project (samples/network/NAME).
inline std::string sample_network(const std::string& name) {
  return std::string(CANOPEN_SAMPLES_DIR) + "/network/" + name;
}
/// A file of the tests' own network (tests/data/network/NAME).
inline std::string test_network(const std::string& name) {
  return data_path("network/" + name);
}

/// A folder of tests/data: `const DataDir data("diff"); data("a.dcf")` is tests/data/diff/a.dcf.
class DataDir {
 public:
  explicit DataDir(std::string folder) : folder_(std::move(folder)) {}
  std::string operator()(const std::string& name) const { return data_path(folder_ + "/" + name); }

 private:
  std::string folder_;
};

/// Writes `bytes` to `path` (binary, replacing it).
template <class Bytes>
inline void write_file(const std::string& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

// ---------------------------------------------------------------------------------------------
// JSON (RFC 8259), strict: enough to check that --json output parses and has its shape.

struct Json {
  enum class Kind { Null, Bool, Number, String, Array, Object } kind = Kind::Null;
  bool boolean = false;
  double number = 0;
  std::string string;
  std::vector<Json> array;
  std::map<std::string, Json> object;

  const Json* get(const std::string& key) const {
    auto it = object.find(key);
    return it == object.end() ? nullptr : &it->second;
  }
  bool is(Kind k) const { return kind == k; }
};

class JsonParser {
 public:
  explicit JsonParser(std::string_view text) : text_(text) {}

  /// The value, or nullopt (with `error()`) when the text is not exactly one JSON value.
  std::optional<Json> parse() {
    auto v = value();
    skip_ws();
    if (v && pos_ != text_.size()) return fail("trailing characters");
    return v;
  }
  const std::string& error() const { return error_; }

 private:
  std::optional<Json> fail(const std::string& why) {
    if (error_.empty()) error_ = why + " at offset " + std::to_string(pos_);
    return std::nullopt;
  }
  void skip_ws() {
    while (pos_ < text_.size() && (text_[pos_] == ' ' || text_[pos_] == '\n' ||
                                   text_[pos_] == '\r' || text_[pos_] == '\t')) {
      ++pos_;
    }
  }
  bool literal(std::string_view word) {
    if (text_.substr(pos_, word.size()) != word) return false;
    pos_ += word.size();
    return true;
  }
  std::optional<Json> value() {
    if (++depth_ > 64) return fail("too deep");
    skip_ws();
    if (pos_ >= text_.size()) return fail("unexpected end");
    Json j;
    const char c = text_[pos_];
    if (c == '{') {
      j.kind = Json::Kind::Object;
      ++pos_;
      skip_ws();
      if (pos_ < text_.size() && text_[pos_] == '}') {
        ++pos_;
      } else {
        while (true) {
          skip_ws();
          auto key = string();
          if (!key) return std::nullopt;
          skip_ws();
          if (pos_ >= text_.size() || text_[pos_] != ':') return fail("expected ':'");
          ++pos_;
          auto v = value();
          if (!v) return std::nullopt;
          if (!j.object.emplace(*key, std::move(*v)).second) return fail("duplicate key " + *key);
          skip_ws();
          if (pos_ < text_.size() && text_[pos_] == ',') {
            ++pos_;
            continue;
          }
          if (pos_ < text_.size() && text_[pos_] == '}') {
            ++pos_;
            break;
          }
          return fail("expected ',' or '}'");
        }
      }
    } else if (c == '[') {
      j.kind = Json::Kind::Array;
      ++pos_;
      skip_ws();
      if (pos_ < text_.size() && text_[pos_] == ']') {
        ++pos_;
      } else {
        while (true) {
          auto v = value();
          if (!v) return std::nullopt;
          j.array.push_back(std::move(*v));
          skip_ws();
          if (pos_ < text_.size() && text_[pos_] == ',') {
            ++pos_;
            continue;
          }
          if (pos_ < text_.size() && text_[pos_] == ']') {
            ++pos_;
            break;
          }
          return fail("expected ',' or ']'");
        }
      }
    } else if (c == '"') {
      auto s = string();
      if (!s) return std::nullopt;
      j.kind = Json::Kind::String;
      j.string = std::move(*s);
    } else if (literal("true")) {
      j.kind = Json::Kind::Bool;
      j.boolean = true;
    } else if (literal("false")) {
      j.kind = Json::Kind::Bool;
    } else if (literal("null")) {
      j.kind = Json::Kind::Null;
    } else if (c == '-' || (c >= '0' && c <= '9')) {
      const std::size_t start = pos_;
      if (text_[pos_] == '-') ++pos_;
      while (pos_ < text_.size() &&
             (std::isdigit(static_cast<unsigned char>(text_[pos_])) || text_[pos_] == '.' ||
              text_[pos_] == 'e' || text_[pos_] == 'E' || text_[pos_] == '+' ||
              text_[pos_] == '-')) {
        ++pos_;
      }
      j.kind = Json::Kind::Number;
      j.number = std::strtod(std::string(text_.substr(start, pos_ - start)).c_str(), nullptr);
    } else {
      return fail(std::string("unexpected '") + c + "'");
    }
    --depth_;
    return j;
  }
  std::optional<std::string> string() {
    if (pos_ >= text_.size() || text_[pos_] != '"') {
      fail("expected string");
      return std::nullopt;
    }
    ++pos_;
    std::string out;
    while (pos_ < text_.size() && text_[pos_] != '"') {
      const auto c = static_cast<unsigned char>(text_[pos_]);
      if (c < 0x20) {
        fail("control character in string");
        return std::nullopt;
      }
      if (c == '\\') {
        if (++pos_ >= text_.size()) break;
        const char e = text_[pos_];
        if (e == 'u') {
          if (pos_ + 4 >= text_.size()) break;
          out += '?';  // code point not needed by the tests
          pos_ += 4;
        } else if (std::string_view("\"\\/bfnrt").find(e) == std::string_view::npos) {
          fail("bad escape");
          return std::nullopt;
        } else {
          out += e == 'n' ? '\n' : e == 't' ? '\t' : e == 'r' ? '\r' : e;
        }
      } else {
        out += static_cast<char>(c);
      }
      ++pos_;
    }
    if (pos_ >= text_.size()) {
      fail("unterminated string");
      return std::nullopt;
    }
    ++pos_;
    return out;
  }

  std::string_view text_;
  std::size_t pos_ = 0;
  int depth_ = 0;
  std::string error_;
};

/// The JSON value in file `path`; nullopt (and a test failure naming the parse error) when the
/// file does not hold exactly one JSON value.
inline std::optional<Json> parse_json_file(const std::string& path) {
  const std::string text = slurp(path);  // the parser keeps a view of it
  JsonParser parser(text);
  auto json = parser.parse();
  EXPECT_TRUE(json) << path << ": " << parser.error() << ": " << text;
  return json;
}

/// The JSON object a command printed (its --json output); an empty Json and a test failure
/// naming the parse error when `text` holds no object.
inline Json json_object_of(const std::string& text) {
  JsonParser parser(text);
  auto json = parser.parse();
  EXPECT_TRUE(json && json->is(Json::Kind::Object)) << parser.error() << ": " << text;
  return json ? *json : Json{};
}

/// The lines of a JSON-lines file (--json-events); every line must be one JSON object ending
/// with a line end (a test failure says which is not).
inline std::vector<Json> json_lines(const std::string& path) {
  std::vector<Json> out;
  const std::string text = slurp(path);
  std::size_t begin = 0;
  while (begin < text.size()) {
    const auto end = text.find('\n', begin);
    EXPECT_NE(end, std::string::npos) << "the last line has no line end";
    const std::string line = text.substr(begin, end - begin);
    JsonParser parser(line);
    auto value = parser.parse();
    EXPECT_TRUE(value && value->is(Json::Kind::Object)) << parser.error() << ": " << line;
    if (value) out.push_back(std::move(*value));
    if (end == std::string::npos) break;
    begin = end + 1;
  }
  return out;
}

/// The events of --json-events lines whose "event" is `name`, in file order.
inline std::vector<const Json*> events_of(const std::vector<Json>& events,
                                          const std::string& name) {
  std::vector<const Json*> out;
  for (const auto& e : events) {
    const Json* kind = e.get("event");
    if (kind != nullptr && kind->string == name) out.push_back(&e);
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Tests over UDP multicast run inside a private network namespace whose only interface is lo
// (tests/support/run_in_netns.sh), so that no datagram leaves the machine; inside, they check
// that with REQUIRE_ISOLATED_MULTICAST() (tests/support/multicast_netns.hpp).

/// Runs this test program's tests matching `filter` inside a private network namespace, as the
/// current test; skips it when no namespace can be made (unshare -n needs root). Fails when
/// `filter` matches no test (tests/support/require_tests_ran.sh), so that renaming the inner
/// suite cannot drop the tier unnoticed.
inline void run_in_private_netns(const std::string& filter) {
  const std::string support = std::string(CANOPEN_TEST_DATA_DIR) + "/../support/";
  const auto self = std::filesystem::read_symlink("/proc/self/exe").string();
  const std::string command = "sh " + shell_quote(support + "run_in_netns.sh") + " sh " +
                              shell_quote(support + "require_tests_ran.sh") + " " +
                              shell_quote(self) + " --gtest_filter=" + shell_quote(filter) +
                              " --gtest_brief=1";
  const int status = std::system(command.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  // run_in_netns.sh exits 77 only when CI is not "true" (tests/support/prerequisite.sh).
  if (WEXITSTATUS(status) == 77)
    PREREQUISITE_MISSING("no network namespace (unshare -n needs root)");
  EXPECT_EQ(WEXITSTATUS(status), 0) << filter << " failed or matched no test; output above";
}

/// A tool started in the background with posix_spawn, stdout and stderr to files, so that a
/// test can signal it. Killed (SIGKILL) at the end of its scope if still running.
class SpawnedTool {
 public:
  SpawnedTool(const std::string& tool, const std::vector<std::string>& args, const std::string& out,
              const std::string& err)
      : out_(out), err_(err) {
    std::vector<std::string> argv_storage{tool_path(tool)};
    argv_storage.insert(argv_storage.end(), args.begin(), args.end());
    std::vector<char*> argv;
    argv.reserve(argv_storage.size() + 1);
    for (auto& a : argv_storage) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, out.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, 2, err.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    if (posix_spawn(&pid_, argv[0], &actions, nullptr, argv.data(), environ) != 0) pid_ = -1;
    posix_spawn_file_actions_destroy(&actions);
  }
  ~SpawnedTool() {
    if (pid_ > 0) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  SpawnedTool(const SpawnedTool&) = delete;
  SpawnedTool& operator=(const SpawnedTool&) = delete;

  bool started() const { return pid_ > 0; }
  /// Waits up to `limit` until the tool's standard output or error has `text`; false when it
  /// did not come (the tool failed to start, or ended, or is stuck).
  bool wait_for_output(std::string_view text,
                       std::chrono::milliseconds limit = std::chrono::seconds(10)) const {
    const auto end = std::chrono::steady_clock::now() + limit;
    for (;;) {
      if (slurp(out_).find(text) != std::string::npos) return true;
      if (slurp(err_).find(text) != std::string::npos) return true;
      if (std::chrono::steady_clock::now() >= end) return false;
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
  }
  /// `cfgmgr simulate` is up: it prints "simulating N devices on BUS" once its bus is open and
  /// its devices are added to the loop (cfgmgr simulate --help), so a frame sent from now on
  /// reaches them. Up to `limit`.
  bool wait_until_simulating(std::chrono::milliseconds limit = std::chrono::seconds(10)) const {
    return wait_for_output("simulating ", limit);
  }
  /// Both output files, for a failure message.
  std::string output() const { return slurp(out_) + slurp(err_); }
  /// Sends `signal` (e.g. SIGSTOP, SIGCONT) without waiting for anything.
  void signal(int signal) const {
    if (pid_ > 0) ::kill(pid_, signal);
  }
  /// Sends `signal` and waits up to `limit` for the exit; the exit code, or nullopt.
  std::optional<int> stop(int signal, std::chrono::milliseconds limit) {
    ::kill(pid_, signal);
    const auto end = std::chrono::steady_clock::now() + limit;
    while (std::chrono::steady_clock::now() < end) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return WIFEXITED(status) ? std::optional<int>(WEXITSTATUS(status)) : std::nullopt;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    return std::nullopt;
  }

 private:
  std::string out_;
  std::string err_;
  pid_t pid_ = -1;
};

/// The devices of a test on a bus: `cfgmgr simulate --bus BUS --for 120 OPTIONS... DEVICES...`,
/// restartable with other devices (a replaced drive, a power cycle). Each simulate() stops the
/// earlier one with SIGINT (it must exit 0), starts the new one and waits until it is simulating
/// (SpawnedTool::wait_until_simulating); stdout and stderr go to DIR/sim.out and DIR/sim.err.
/// Stopped with SIGINT at the end of its scope.
class SimulatedDevices {
 public:
  SimulatedDevices(std::filesystem::path dir, std::string bus,
                   std::vector<std::string> options = {})
      : dir_(std::move(dir)), bus_(std::move(bus)), options_(std::move(options)) {}
  ~SimulatedDevices() { (void)stop(); }
  SimulatedDevices(const SimulatedDevices&) = delete;
  SimulatedDevices& operator=(const SimulatedDevices&) = delete;

  /// Fails the test (fatally, in this function) when the earlier simulate did not exit 0 on
  /// SIGINT or the new one does not come up.
  void simulate(const std::vector<std::string>& devices) {
    if (tool_) {
      const auto code = stop();
      ASSERT_TRUE(code && *code == 0) << "the earlier simulate stops on SIGINT";
    }
    std::vector<std::string> args{"simulate", "--bus", bus_, "--for", "120"};
    args.insert(args.end(), options_.begin(), options_.end());
    args.insert(args.end(), devices.begin(), devices.end());
    tool_.emplace("cfgmgr", args, dir_ / "sim.out", dir_ / "sim.err");
    ASSERT_TRUE(tool_->started());
    // Up once it says so (it opens the bus before it prints this line).
    ASSERT_TRUE(tool_->wait_until_simulating()) << tool_->output();
  }
  /// Stops the running simulate with SIGINT; its exit code, or nullopt (none running, or it did
  /// not end within 3 s).
  std::optional<int> stop() {
    if (!tool_) return std::nullopt;
    const auto code = tool_->stop(SIGINT, std::chrono::milliseconds(3000));
    tool_.reset();
    return code;
  }
  /// What the devices printed on standard output so far.
  std::string out() const { return slurp(dir_ / "sim.out"); }
  /// Both output files, for a failure message.
  std::string output() const { return tool_ ? tool_->output() : out() + slurp(dir_ / "sim.err"); }

 private:
  std::filesystem::path dir_;
  std::string bus_;
  std::vector<std::string> options_;
  std::optional<SpawnedTool> tool_;
};

}  // namespace tool_test
