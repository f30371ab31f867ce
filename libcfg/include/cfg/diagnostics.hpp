// Diagnostics collected while reading files: file:line, severity and a message a user understands.
// The reader keeps going where it can; the caller decides what is fatal.
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace cfg {

enum class Severity { Note, Warning, Error };

std::string_view to_string(Severity severity);

struct Diagnostic {
  std::string file;  ///< path as the user gave it; may be empty for in-memory input
  int line = 0;      ///< 1-based; 0 when the message is about the whole file
  Severity severity = Severity::Error;
  std::string message;

  /// Compiler style: `file.dcf:42: error: message` (`file.dcf: error: ...` when line is 0).
  /// Control characters in the file name or message are shown as \xNN.
  std::string format() const;
  bool operator==(const Diagnostic&) const = default;
};

/// An ordered list of diagnostics for one or more files.
class Diagnostics {
 public:
  void add(Diagnostic diagnostic) { items_.push_back(std::move(diagnostic)); }
  void add(std::string file, int line, Severity severity, std::string message) {
    items_.push_back({std::move(file), line, severity, std::move(message)});
  }
  void append(const Diagnostics& other) {
    items_.insert(items_.end(), other.items_.begin(), other.items_.end());
  }

  const std::vector<Diagnostic>& items() const { return items_; }
  bool empty() const { return items_.empty(); }
  std::size_t size() const { return items_.size(); }
  std::size_t count(Severity severity) const;
  bool has_errors() const { return count(Severity::Error) > 0; }

  /// All diagnostics, one formatted line each, in the order they were added.
  std::string format() const;

 private:
  std::vector<Diagnostic> items_;
};

}  // namespace cfg
