#include "ini_scanner.hpp"

#include <cstring>

namespace cfg::detail {
namespace {

// Next physical line of `text` from `pos`, without its terminator; false at the end.
bool next_line(std::string_view text, std::size_t& pos, std::string_view& out) {
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
  out = std::string_view(begin, len);
  return true;
}

}  // namespace

void scan_ini(std::string_view text, IniSink& sink) {
  std::size_t pos = 0;
  int line = 0;
  std::string_view raw;
  while (next_line(text, pos, raw)) {
    ++line;
    std::size_t i = 0;
    while (i < raw.size() && is_blank(raw[i])) ++i;
    if (i == raw.size()) continue;  // blank
    const std::string_view l = raw.substr(i);
    const char first = l.front();
    if (first == ';' || first == '#') {
      sink.on_comment(line, first);
      continue;
    }
    if (first == '[') {
      const std::size_t close = l.find(']');
      const bool closed = close != std::string_view::npos;
      sink.on_section(line, trim_blanks(l.substr(1, closed ? close - 1 : std::string_view::npos)),
                      closed ? trim_blanks(l.substr(close + 1)) : std::string_view(), closed);
      continue;
    }
    const std::size_t eq = l.find('=');
    if (eq == std::string_view::npos) {
      sink.on_junk(line, trim_blanks(l));
      continue;
    }
    sink.on_key(line, trim_blanks(l.substr(0, eq)), trim_blanks(l.substr(eq + 1)));
  }
}

}  // namespace cfg::detail
