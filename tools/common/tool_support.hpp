// What the command-line tools share: exit codes, compiler-style diagnostics on stderr, JSON
// output, and writing an output file so that no partial file is ever left behind.
// Header-only: tools are thin, this is output formatting, not protocol logic.
#pragma once

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "cfg/device_file.hpp"
#include "cfg/diagnostics.hpp"
#include "cfg/integer_literal.hpp"
#include "cfg/node_id.hpp"
#include "cfg/result.hpp"

namespace tools {

/// Exit codes of every tool (documented in each --help).
enum ExitCode : int {
  kExitOk = 0,           ///< done; warnings may have been printed
  kExitInputErrors = 1,  ///< the input has errors (diagnostics say which)
  kExitUsage = 2,        ///< bad command line
  kExitIo = 3,           ///< a file could not be read or written
};

inline constexpr std::string_view kExitCodesHelp =
    "Exit codes:\n"
    "  0  success (warnings may have been printed)\n"
    "  1  the input has errors (printed as FILE:LINE: error: ...)\n"
    "  2  usage error (bad command line)\n"
    "  3  I/O error (a file could not be read or written)\n";

/// The project version (CMake PROJECT_VERSION, passed by tools/CMakeLists.txt).
#ifndef CANOPEN_VERSION
#error "tools/CMakeLists.txt defines CANOPEN_VERSION"
#endif
inline constexpr std::string_view kProjectVersion = CANOPEN_VERSION;

/// What `TOOL --version` prints: "cfgmgr 0.1.0".
inline std::string version_text(std::string_view tool) {
  return std::string(tool) + " " + std::string(kProjectVersion);
}

/// Keeps `value` until the process exits, never destroying it: for a large model a tool is done
/// with just before it exits. Its memory goes back to the system with the process in one piece;
/// destroying it first walks every map node only to free it (2-6 M instructions, 2-4 % of a
/// run on a 3 MB DCF, BENCHMARKS.md), which is what clang's -disable-free avoids too. Tool boundary
/// only, and only for values that own nothing but memory (no open files, nothing to flush). The
/// values stay reachable, so LeakSanitizer does not report them.
template <class T>
void keep_until_exit(T&& value) {
  using Kept = std::remove_cvref_t<T>;
  static auto* kept = new std::vector<std::unique_ptr<Kept>>();  // never destroyed, on purpose
  kept->push_back(std::make_unique<Kept>(std::forward<T>(value)));
}

/// What a node-ID argument says, before its range is checked: an integer literal as CiA 306
/// §4.6.3 writes them (decimal, 0x hex, leading-0 octal), or, where `unconfigured_ok` (the
/// arguments of LSS and of simulated devices that wait for it), the word "unconfigured" for
/// CiA 305's FFh "not configured". nullopt when it is neither. parse_node_id_argument() is this
/// with the range of CiA 301; `cfgmgr lss` and `cfgmgr simulate` check their own ranges (255).
inline std::optional<std::uint64_t> node_id_argument_value(std::string_view text,
                                                           bool unconfigured_ok = false) {
  if (unconfigured_ok && text == "unconfigured") return 0xFF;
  const auto parsed = cfg::parse_integer_literal(text);
  if (!parsed.literal) return std::nullopt;
  return parsed.literal->value;
}

/// A node-ID argument of a tool (NODE, --node-id, --master, NODE=FILE): node_id_argument_value()
/// in 1..127 (CiA 301 §7.2.8.3.1); nullopt for anything else, which the caller reports with
/// node_id_argument_error().
inline std::optional<cfg::NodeId> parse_node_id_argument(std::string_view text) {
  const auto value = node_id_argument_value(text);
  if (!value) return std::nullopt;
  return cfg::NodeId::from(*value);
}

/// What every tool says of a node-ID argument that is none: "WHAT TEXT: expected a node-ID
/// 1..127" (WHAT names the argument: "NODE", "--node-id").
inline std::string node_id_argument_error(std::string_view what, std::string_view text) {
  return std::string(what) + " " + std::string(text) + ": expected a node-ID 1..127";
}

/// A count with its noun in the right number: plural(1, "error") is "1 error", plural(2,
/// "error") is "2 errors". Nouns here take a plain "s".
inline std::string plural(std::size_t count, std::string_view noun) {
  std::string out = std::to_string(count) + " " + std::string(noun);
  if (count != 1) out += 's';
  return out;
}

/// Prints diagnostics compiler-style (`file.dcf:42: error: ...`) on stderr, one a line.
inline void print_diagnostics(const cfg::Diagnostics& diagnostics) {
  // One write for all: std::cerr is unbuffered, so each << was a system call of its own (two a
  // line: a file with 260 warnings made 520 writes).
  std::string text;
  for (const auto& d : diagnostics.items()) {
    text += d.format();
    text += '\n';
  }
  std::cerr.write(text.data(), static_cast<std::streamsize>(text.size()));
  std::cerr.flush();
}

/// --strict: warnings count as errors (like -Werror); returns the promoted copy.
inline cfg::Diagnostics promote_warnings(const cfg::Diagnostics& diagnostics) {
  cfg::Diagnostics out;
  for (auto d : diagnostics.items()) {
    if (d.severity == cfg::Severity::Warning) d.severity = cfg::Severity::Error;
    out.add(std::move(d));
  }
  return out;
}

/// A JSON string literal (RFC 8259) for arbitrary bytes. Bytes that are not valid UTF-8 are
/// written as \u00XX of their Latin-1 reading, so the output is always valid JSON.
inline std::string json_string(std::string_view text) {
  std::string out = "\"";
  auto escape = [&out](unsigned code) {
    char buf[8];
    std::snprintf(buf, sizeof buf, "\\u%04X", code);
    out += buf;
  };
  for (std::size_t i = 0; i < text.size(); ++i) {
    const auto c = static_cast<unsigned char>(text[i]);
    if (c == '"') {
      out += "\\\"";
    } else if (c == '\\') {
      out += "\\\\";
    } else if (c == '\n') {
      out += "\\n";
    } else if (c == '\r') {
      out += "\\r";
    } else if (c == '\t') {
      out += "\\t";
    } else if (c < 0x20 || c == 0x7F) {
      escape(c);
    } else if (c < 0x80) {
      out += static_cast<char>(c);
    } else {
      // Copy a well-formed UTF-8 sequence; escape anything else byte by byte.
      std::size_t len = c >= 0xF0 && c <= 0xF4 ? 4 : c >= 0xE0 ? 3 : c >= 0xC2 && c < 0xE0 ? 2 : 0;
      bool valid = len != 0 && i + len <= text.size();
      for (std::size_t k = 1; valid && k < len; ++k) {
        valid = (static_cast<unsigned char>(text[i + k]) & 0xC0) == 0x80;
      }
      if (valid) {
        out.append(text.substr(i, len));
        i += len - 1;
      } else {
        escape(c);
      }
    }
  }
  out += '"';
  return out;
}

/// `[{"file": ..., "line": 42, "severity": "error", "message": ...}, ...]`
inline std::string json_diagnostics(const cfg::Diagnostics& diagnostics) {
  std::string out = "[";
  bool first = true;
  for (const auto& d : diagnostics.items()) {
    if (!first) out += ", ";
    first = false;
    out += "{\"file\": " + json_string(d.file) + ", \"line\": " + std::to_string(d.line) +
           ", \"severity\": " + json_string(cfg::to_string(d.severity)) +
           ", \"message\": " + json_string(d.message) + "}";
  }
  return out + "]";
}

/// Lower-case hex pairs without separators ("e803"), as JSON carries data.
inline std::string hex_string(std::span<const std::uint8_t> bytes) {
  static constexpr char kDigits[] = "0123456789abcdef";
  std::string out;
  out.reserve(bytes.size() * 2);
  for (std::uint8_t b : bytes) {
    out += kDigits[b >> 4];
    out += kDigits[b & 0xF];
  }
  return out;
}

/// The exit code for an error: kExitIo when a file could not be read or written, else
/// kExitInputErrors. The category is set where the error arises, so no tool checks its files
/// beforehand (each file is opened once).
inline int exit_code_for(const cfg::Error& error) {
  return error.category == cfg::ErrorCategory::Io ? kExitIo : kExitInputErrors;
}

/// An I/O error (exit code 3) about `path`: "PATH: error: WHAT".
inline cfg::Error io_error(const std::string& path, const std::string& what) {
  return cfg::Error{path + ": error: " + what, cfg::ErrorCategory::Io};
}

/// Reads a whole file in one piece (cfg::read_file: mapped when it can be), or "-" for stdin.
/// Fails (category Io) with a message naming the path.
inline cfg::Result<cfg::FileText> read_input(const std::string& path) {
  const bool from_stdin = path == "-";
  auto text = from_stdin ? cfg::read_file(STDIN_FILENO) : cfg::read_file(path);
  if (!text) return io_error(from_stdin ? std::string("<stdin>") : path, text.error().message);
  return text;
}

/// Writes all of `bytes` to `fd`; errno-based message on failure.
inline cfg::Status write_all(int fd, std::string_view bytes, const std::string& path) {
  std::size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) {
      std::string what = "write error: ";
      what += n == 0 ? "nothing written" : std::strerror(errno);
      return io_error(path, what);
    }
    written += static_cast<std::size_t>(n);
  }
  return {};
}

/// An output named on the command line ("-": stdout), written in pieces and committed at the
/// end. A regular file (new or existing) appears complete or not at all: the pieces go to a
/// temporary file beside it, which commit() renames over it (rename(2)), keeping an existing
/// file's permission bits; an output never committed (an error on the way) is removed and the
/// old file is untouched. A symbolic link is followed (the link stays, its target is replaced).
/// Anything else that exists (a device such as /dev/null, a FIFO) is opened and written in
/// place, never replaced. Failures are category Io, naming the path.
class OutputFile {
 public:
  static cfg::Result<OutputFile> open(const std::string& path) {
    OutputFile out;
    out.path_ = path;
    if (path == "-") {
      out.stdout_ = true;
      return out;
    }
    namespace fs = std::filesystem;
    std::error_code ec;
    fs::path target(path);
    if (fs::is_symlink(fs::symlink_status(target, ec))) {
      const fs::path resolved = fs::weakly_canonical(target, ec);
      if (ec) return io_error(path, "cannot follow the link: " + ec.message());
      target = resolved;
    }
    const fs::file_status status = fs::status(target, ec);
    if (fs::is_directory(status)) return io_error(path, "is a directory");
    mode_t mode = 0;
    if (fs::exists(status)) {
      if (!fs::is_regular_file(status)) {
        // A device or FIFO: write into it, as a shell redirection would.
        out.fd_ = ::open(target.c_str(), O_WRONLY | O_TRUNC | O_CLOEXEC);
        if (out.fd_ < 0)
          return io_error(path, std::string("cannot open for writing: ") + std::strerror(errno));
        return out;
      }
      struct stat st {};
      if (::stat(target.c_str(), &st) == 0) mode = st.st_mode & 07777;
    } else {
      // A new file gets the mode a plain create would (0666 & ~umask).
      const mode_t mask = ::umask(0);
      ::umask(mask);
      mode = 0666 & ~mask;
    }
    const fs::path dir = target.has_parent_path() ? target.parent_path() : fs::path(".");
    // Hidden temporary beside the target: ".NAME.tmpXXXXXX" (built by append: GCC 12 -O2 reports
    // a false -Wrestrict on `"." + std::string`, GCC bug 105329).
    std::string temp_name = ".";
    temp_name += target.filename().string();
    temp_name += ".tmpXXXXXX";
    out.temp_ = (dir / temp_name).string();
    out.fd_ = ::mkstemp(out.temp_.data());
    if (out.fd_ < 0) {
      out.temp_.clear();
      return io_error(path, std::string("cannot create: ") + std::strerror(errno));
    }
    ::fchmod(out.fd_, mode);
    out.target_ = target.string();
    return out;
  }

  OutputFile(OutputFile&& other) noexcept { *this = std::move(other); }
  OutputFile& operator=(OutputFile&& other) noexcept {
    std::swap(path_, other.path_);
    std::swap(target_, other.target_);
    std::swap(temp_, other.temp_);
    std::swap(fd_, other.fd_);
    std::swap(stdout_, other.stdout_);
    return *this;
  }
  OutputFile(const OutputFile&) = delete;
  OutputFile& operator=(const OutputFile&) = delete;
  ~OutputFile() { abandon(); }

  /// Appends `bytes`.
  cfg::Status write(std::string_view bytes) {
    if (!stdout_) return write_all(fd_, bytes, path_);
    std::cout.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    if (!std::cout) return io_error("<stdout>", "write error");
    return {};
  }

  /// Closes the output; a regular file replaces the old one now. Call once, after the last write.
  cfg::Status commit() {
    if (stdout_) {
      std::cout.flush();
      if (!std::cout) return io_error("<stdout>", "write error");
      return {};
    }
    const int fd = std::exchange(fd_, -1);
    if (::close(fd) != 0) {
      const std::string why = std::strerror(errno);
      abandon();
      return io_error(path_, "write error: " + why);
    }
    if (temp_.empty()) return {};
    if (std::rename(temp_.c_str(), target_.c_str()) != 0) {
      const std::string why = std::strerror(errno);
      abandon();
      return io_error(path_, "cannot write: " + why);
    }
    temp_.clear();
    return {};
  }

 private:
  OutputFile() = default;
  // Not committed: close and remove the temporary file, if any.
  void abandon() {
    if (fd_ >= 0) ::close(fd_);
    fd_ = -1;
    if (!temp_.empty()) ::unlink(temp_.c_str());
    temp_.clear();
  }

  std::string path_;    // as given, for messages
  std::string target_;  // the file a temporary replaces
  std::string temp_;    // the temporary file, until committed
  int fd_ = -1;
  bool stdout_ = false;  // "-": through std::cout, in order with what else the tool prints
};

/// Writes `bytes` to `path` ("-": stdout) in one piece, as OutputFile does.
inline cfg::Status write_output(const std::string& path, std::string_view bytes) {
  auto out = OutputFile::open(path);
  if (!out) return out.error();
  if (auto written = out->write(bytes); !written) return written;
  return out->commit();
}

/// A report file named on the command line (`--json FILE`, `--json-events FILE`): opened (and
/// truncated) when the command starts, so that a bad path fails before any bus work, written
/// during or at the end of the run, and flushed at the end, where a write error (a full disk)
/// is reported. Unlike write_output it is not atomic: event lines appear as they happen.
class ReportFile {
 public:
  /// No file: stream() is nullptr and finish() succeeds.
  ReportFile() = default;
  /// Opens `path` for writing ("" means no file). Fails (category Io, exit code 3) with
  /// "PATH: error: cannot open for writing: REASON".
  static cfg::Result<ReportFile> open(const std::string& path) {
    ReportFile file;
    if (path.empty()) return file;
    file.path_ = path;
    file.out_ = std::make_unique<std::ofstream>(path, std::ios::binary | std::ios::trunc);
    if (!*file.out_) {
      return io_error(path, std::string("cannot open for writing: ") + std::strerror(errno));
    }
    return file;
  }
  /// The stream to write to, or nullptr when no file was named. Owned by this object.
  std::ostream* stream() const { return out_.get(); }
  /// Writes `text` (when a file was named), then flushes; fails (category Io) on a write error.
  cfg::Status finish(std::string_view text = {}) {
    if (!out_) return {};
    out_->write(text.data(), static_cast<std::streamsize>(text.size()));
    out_->flush();
    if (!*out_) return io_error(path_, "write error");
    return {};
  }

 private:
  std::string path_;
  std::unique_ptr<std::ofstream> out_;
};

}  // namespace tools
