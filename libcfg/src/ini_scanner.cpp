#include "ini_scanner.hpp"

#include <bit>
#include <cstdint>
#include <cstring>

namespace cfg::detail {
namespace {

// The scanner reads every byte of a device file once, so it looks at 8 bytes at a time: each
// byte of the word that equals `c` gets its top bit set. Exact for the lowest such byte (a
// borrow can only mark bytes above a real match), which is the only one read.
constexpr std::uint64_t kOnes = 0x0101010101010101ULL;
constexpr std::uint64_t kTops = 0x8080808080808080ULL;

std::uint64_t bytes_equal_to(std::uint64_t word, char c) {
  const std::uint64_t x = word ^ (kOnes * static_cast<unsigned char>(c));
  return (x - kOnes) & ~x & kTops;
}

// Offset in the word of the first (lowest-addressed) marked byte; `mask` is not 0.
std::size_t first_marked(std::uint64_t mask) {
  return static_cast<std::size_t>(std::countr_zero(mask)) / 8;
}

// Where a physical line ends: at the first LF or CR from `begin`, and the first '=' before it.
struct LineEnd {
  std::size_t end = 0;                          // offset of the terminator (or the text's size)
  std::size_t equals = std::string_view::npos;  // offset of the first '=' before `end`
};

LineEnd find_line_end(std::string_view text, std::size_t begin) {
  const char* p = text.data();
  const std::size_t n = text.size();
  LineEnd r;
  std::size_t i = begin;
  if constexpr (std::endian::native == std::endian::little) {
    for (; i + 8 <= n; i += 8) {
      std::uint64_t w = 0;
      std::memcpy(&w, p + i, sizeof w);
      const std::uint64_t ends = bytes_equal_to(w, '\n') | bytes_equal_to(w, '\r');
      if (r.equals == std::string_view::npos) {
        if (const std::uint64_t eq = bytes_equal_to(w, '=');
            eq != 0 && (ends == 0 || first_marked(eq) < first_marked(ends))) {
          r.equals = i + first_marked(eq);
        }
      }
      if (ends != 0) {
        r.end = i + first_marked(ends);
        return r;
      }
    }
  }
  for (; i < n; ++i) {
    const char c = p[i];
    if (c == '\n' || c == '\r') break;
    if (c == '=' && r.equals == std::string_view::npos) r.equals = i;
  }
  r.end = i;
  return r;
}

}  // namespace

void scan_ini(std::string_view text, IniSink& sink) {
  const std::size_t n = text.size();
  std::size_t pos = 0;
  int line = 0;
  while (pos < n) {
    ++line;
    const LineEnd found = find_line_end(text, pos);
    const std::size_t begin = pos;
    // LF, CRLF, or a lone CR (old Mac files, or mixed endings) ends the line.
    pos = found.end;
    if (pos < n) pos += (text[pos] == '\r' && pos + 1 < n && text[pos + 1] == '\n') ? 2 : 1;

    std::size_t i = begin;
    while (i < found.end && is_blank(text[i])) ++i;
    if (i == found.end) continue;  // blank
    const std::string_view l = text.substr(i, found.end - i);
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
    if (found.equals == std::string_view::npos) {
      sink.on_junk(line, trim_blanks(l));
      continue;
    }
    const std::size_t eq = found.equals - i;
    sink.on_key(line, trim_blanks(l.substr(0, eq)), trim_blanks(l.substr(eq + 1)));
  }
}

}  // namespace cfg::detail
