// Private to libcfg: splits EDS/DCF text into lines and classifies each one (section header,
// key=value, comment, other), handing the sink views into the caller's buffer.
//
// Not inih: Debian's inih cuts lines at 200 bytes (long DOMAIN values), strips inline ';'
// comments after whitespace and joins indented lines, with process-global settings a library
// must not touch; real device files break all three. Here no line limit, comment or continuation
// rule touches data, and nothing is allocated per line.
#pragma once

#include <cstdint>
#include <string_view>

namespace cfg::detail {

/// Receives the lines of an INI text in file order. Line numbers are 1-based. Views point into
/// the scanned text and are valid as long as it is.
class IniSink {
 public:
  virtual ~IniSink() = default;
  /// `[name]trailing`: name and trailing text trimmed; `closed` is false when ']' is missing
  /// (then name is the rest of the line).
  virtual void on_section(int line, std::string_view name, std::string_view trailing,
                          bool closed) = 0;
  /// `key=value`, both trimmed of blanks; the value is taken verbatim up to the end of the line
  /// (comments in it are the sink's business, they depend on the key).
  virtual void on_key(int line, std::string_view key, std::string_view value) = 0;
  /// A whole-line comment; `marker` is ';' (CiA 306) or '#'.
  virtual void on_comment(int line, char marker) = 0;
  /// A line that is neither blank, a comment, a section header nor has an '='.
  virtual void on_junk(int line, std::string_view text) = 0;
};

/// Scans `text` (no BOM handling: strip it first). Lines end at LF, CRLF or a lone CR; a
/// missing final line end is fine. Every line is handed to the sink, in order; nothing fails.
void scan_ini(std::string_view text, IniSink& sink);

/// Where the line ends (LF or CR) and the '=' are among 64 bytes: bit i stands for byte i. The
/// scanner reads the whole text this way, 64 bytes at a time.
struct BlockMarks {
  std::uint64_t ends = 0;
  std::uint64_t equals = 0;
  bool operator==(const BlockMarks&) const = default;
};
/// The marks of the 64 bytes at `p`: with SSE2 compares where the target has them, else
/// block_marks_portable.
BlockMarks block_marks(const char* p);
/// The same, byte by byte: what targets without SSE2 run, and what tests hold the SSE2 path to.
BlockMarks block_marks_portable(const char* p);

/// Blank for the purposes of trimming: space, tab, vertical tab, form feed.
constexpr bool is_blank(char c) {
  return c == ' ' || c == '\t' || c == '\v' || c == '\f';
}

constexpr std::string_view trim_blanks(std::string_view s) {
  std::size_t b = 0;
  while (b < s.size() && is_blank(s[b])) ++b;
  std::size_t e = s.size();
  while (e > b && is_blank(s[e - 1])) --e;
  return s.substr(b, e - b);
}

}  // namespace cfg::detail
