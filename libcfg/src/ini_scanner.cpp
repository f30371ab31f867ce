#include "ini_scanner.hpp"

#include <ini.h>

#include <charconv>
#include <cstring>

namespace cfg::detail {
namespace {

// The open marker follows every section token, so that sections without keys reach the
// handler too (inih only calls it for name=value lines). Key lines are handed over as the
// shortest line inih reads as a key: inih's per-line work (strlen, strchr per character) grows
// with the token, and the handler knows which line it stands for.
constexpr char kOpenMarker[] = "@=\n";
constexpr char kKeyToken[] = "k=\n";

struct Scanner {
  std::string_view text;
  std::size_t pos = 0;
  int line = 0;
  IniSink* sink = nullptr;

  // The line whose token inih is processing; the handler reads it (inih calls the handler
  // for a line before it reads the next one).
  enum class Pending { None, Section, Key } pending = Pending::None;
  int pending_line = 0;
  std::string_view name, value;
  bool closed = true;
  bool marker_due = false;
  bool in_sync = true;
  const char* current_section = nullptr;  // inih's section text at the last open marker

  // Writes `[<line>]\n` (section) or `k=\n` (key) into inih's buffer.
  bool write_token(char* buf, int size, bool section) const {
    char tmp[32];
    char* p = tmp;
    if (section) {
      *p++ = '[';
      p = std::to_chars(p, tmp + sizeof(tmp) - 4, pending_line).ptr;
      *p++ = ']';
      *p++ = '\n';
    } else {
      std::memcpy(p, kKeyToken, sizeof(kKeyToken) - 1);
      p += sizeof(kKeyToken) - 1;
    }
    const auto n = static_cast<std::size_t>(p - tmp);
    if (size < 0 || static_cast<std::size_t>(size) < n + 1) return false;
    std::memcpy(buf, tmp, n);
    buf[n] = '\0';
    return true;
  }

  // Next physical line, without its terminator; false at the end of the text.
  bool next_line(std::string_view& out) {
    if (pos >= text.size()) return false;
    const char* begin = text.data() + pos;
    const std::size_t rest = text.size() - pos;
    const auto* nl = static_cast<const char*>(std::memchr(begin, '\n', rest));
    std::size_t len = nl ? static_cast<std::size_t>(nl - begin) : rest;
    std::size_t advance = nl ? len + 1 : len;
    // CRLF, or a lone CR (old Mac files, or mixed endings) that ends the line early.
    if (const auto* cr = static_cast<const char*>(std::memchr(begin, '\r', len))) {
      const auto at = static_cast<std::size_t>(cr - begin);
      advance = (at + 1 == len && nl) ? len + 1 : at + 1;
      len = at;
    }
    pos += advance;
    ++line;
    out = std::string_view(begin, len);
    return true;
  }

  // Classifies lines until one has to go through inih; false at the end of the text.
  bool advance() {
    std::string_view raw;
    while (next_line(raw)) {
      std::size_t i = 0;
      while (i < raw.size() && is_blank(raw[i])) ++i;
      if (i == raw.size()) continue;  // blank
      const std::string_view l = raw.substr(i);
      const char first = l.front();
      if (first == ';' || first == '#') {
        sink->on_comment(line, first);
        continue;
      }
      pending_line = line;
      if (first == '[') {
        const std::size_t close = l.find(']');
        closed = close != std::string_view::npos;
        name = trim_blanks(l.substr(1, closed ? close - 1 : std::string_view::npos));
        value = closed ? trim_blanks(l.substr(close + 1)) : std::string_view();
        pending = Pending::Section;
        return true;
      }
      const std::size_t eq = l.find('=');
      if (eq == std::string_view::npos) {
        sink->on_junk(line, trim_blanks(l));
        continue;
      }
      name = trim_blanks(l.substr(0, eq));
      value = trim_blanks(l.substr(eq + 1));
      pending = Pending::Key;
      return true;
    }
    pending = Pending::None;
    return false;
  }

  static char* read(char* buf, int size, void* stream) {
    auto* self = static_cast<Scanner*>(stream);
    if (self->marker_due) {
      self->marker_due = false;
      if (size < static_cast<int>(sizeof(kOpenMarker))) return nullptr;
      std::memcpy(buf, kOpenMarker, sizeof(kOpenMarker));
      return buf;
    }
    if (!self->advance()) return nullptr;
    const bool section = self->pending == Pending::Section;
    if (!self->write_token(buf, size, section)) {
      self->in_sync = false;
      return nullptr;
    }
    self->marker_due = section;
    return buf;
  }

  static bool token_is_line(const char* token, int line) {
    int n = 0;
    const char* end = token + std::strlen(token);
    auto [p, ec] = std::from_chars(token, end, n);
    return ec == std::errc{} && p == end && n == line;
  }

  static int handle(void* user, const char* section, const char* key, const char* /*value*/) {
    auto* self = static_cast<Scanner*>(user);
    if (key[0] == '@' && key[1] == '\0') {
      if (self->pending != Pending::Section || !token_is_line(section, self->pending_line)) {
        self->in_sync = false;
        return 1;
      }
      self->current_section = section;
      self->sink->on_section(self->pending_line, self->name, self->value, self->closed);
      return 1;
    }
    // A key line: inih must have read our key token, in the section we opened last (its section
    // text was checked at the open marker; inih keeps it in one buffer).
    const bool in_section =
        self->current_section == nullptr ? section[0] == '\0' : section == self->current_section;
    if (self->pending != Pending::Key || key[0] != 'k' || key[1] != '\0' || !in_section) {
      self->in_sync = false;
      return 1;
    }
    self->sink->on_key(self->pending_line, self->name, self->value);
    return 1;
  }
};

}  // namespace

bool scan_ini(std::string_view text, IniSink& sink) {
  Scanner scanner;
  scanner.text = text;
  scanner.sink = &sink;
  const int rc = ini_parse_stream(&Scanner::read, &scanner, &Scanner::handle, &scanner);
  return rc == 0 && scanner.in_sync;
}

}  // namespace cfg::detail
