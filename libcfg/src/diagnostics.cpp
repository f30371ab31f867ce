#include "cfg/diagnostics.hpp"

#include <algorithm>

namespace cfg {

std::string_view to_string(Severity severity) {
  switch (severity) {
    case Severity::Note:
      return "note";
    case Severity::Warning:
      return "warning";
    case Severity::Error:
      return "error";
  }
  return "error";
}

namespace {

// Messages quote text from the input, which may be any bytes: control characters (ESC starts a
// terminal escape sequence) are shown as \xNN so that printing a diagnostic cannot reprogram the
// user's terminal. Other bytes (UTF-8, Latin-1 names) are kept.
void append_printable(std::string& out, std::string_view text) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  for (char c : text) {
    const auto b = static_cast<unsigned char>(c);
    if (b < 0x20 || b == 0x7F) {
      out += "\\x";
      out += kHex[b >> 4];
      out += kHex[b & 0xF];
    } else {
      out += c;
    }
  }
}

}  // namespace

std::string Diagnostic::format() const {
  std::string out;
  append_printable(out, file.empty() ? std::string_view("<input>") : std::string_view(file));
  if (line > 0) out += ":" + std::to_string(line);
  out += ": ";
  out += to_string(severity);
  out += ": ";
  append_printable(out, message);
  return out;
}

std::size_t Diagnostics::count(Severity severity) const {
  return static_cast<std::size_t>(std::count_if(
      items_.begin(), items_.end(), [&](const Diagnostic& d) { return d.severity == severity; }));
}

std::string Diagnostics::format() const {
  std::string out;
  for (const auto& d : items_) {
    out += d.format();
    out += '\n';
  }
  return out;
}

}  // namespace cfg
