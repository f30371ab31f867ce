#include "ini_scanner.hpp"

#include <array>
#include <bit>
#include <cstdint>
#include <cstring>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

namespace cfg::detail {

constexpr std::size_t kBlock = 64;
constexpr std::size_t kNone = std::string_view::npos;

// Every byte of a device file is looked at once here, so the whole text is read as bitmaps
// rather than byte by byte or with three memchr calls a line.
BlockMarks block_marks_portable(const char* p) {
  BlockMarks m;
  for (std::size_t i = 0; i < kBlock; ++i) {
    m.ends |= std::uint64_t{p[i] == '\n' || p[i] == '\r'} << i;
    m.equals |= std::uint64_t{p[i] == '='} << i;
  }
  return m;
}

BlockMarks block_marks(const char* p) {
#if defined(__SSE2__)
  BlockMarks m;
  const __m128i lf = _mm_set1_epi8('\n');
  const __m128i cr = _mm_set1_epi8('\r');
  const __m128i eq = _mm_set1_epi8('=');
  for (std::size_t k = 0; k < kBlock / 16; ++k) {
    const __m128i v = _mm_loadu_si128(reinterpret_cast<const __m128i*>(p + 16 * k));
    const auto ends = static_cast<std::uint32_t>(
        _mm_movemask_epi8(_mm_or_si128(_mm_cmpeq_epi8(v, lf), _mm_cmpeq_epi8(v, cr))));
    const auto equals = static_cast<std::uint32_t>(_mm_movemask_epi8(_mm_cmpeq_epi8(v, eq)));
    m.ends |= std::uint64_t{ends} << (16 * k);
    m.equals |= std::uint64_t{equals} << (16 * k);
  }
  return m;
#else
  return block_marks_portable(p);
#endif
}

namespace {

// The physical lines of a text, in order.
class LineFinder {
 public:
  explicit LineFinder(std::string_view text) : text_(text) {}

  struct Line {
    std::size_t end = 0;         // offset of the LF/CR that ends it, or the text's size
    std::size_t equals = kNone;  // offset of its first '=', if it has one
  };

  // The line that starts at `pos` (< the text's size).
  Line line_at(std::size_t pos) {
    Line r;
    std::size_t b = pos / kBlock;
    load(b);
    const std::uint64_t from = ~std::uint64_t{0} << (pos % kBlock);
    std::uint64_t ends = marks_.ends & from;
    std::uint64_t equals = marks_.equals & from;
    while (ends == 0) {
      if (r.equals == kNone && equals != 0) r.equals = b * kBlock + std::countr_zero(equals);
      ++b;
      if (b * kBlock >= text_.size()) {
        r.end = text_.size();
        return r;
      }
      load(b);
      ends = marks_.ends;
      equals = marks_.equals;
    }
    const auto at = static_cast<unsigned>(std::countr_zero(ends));
    r.end = b * kBlock + at;
    if (r.equals == kNone) {
      if (const std::uint64_t before = equals & ((std::uint64_t{1} << at) - 1); before != 0) {
        r.equals = b * kBlock + std::countr_zero(before);
      }
    }
    return r;
  }

 private:
  void load(std::size_t block) {
    if (block == block_) return;
    block_ = block;
    const std::size_t begin = block * kBlock;
    if (begin + kBlock <= text_.size()) {
      marks_ = block_marks(text_.data() + begin);
    } else {  // the last, short block: padded with bytes that mark nothing
      std::array<char, kBlock> tail{};
      std::memcpy(tail.data(), text_.data() + begin, text_.size() - begin);
      marks_ = block_marks(tail.data());
    }
  }

  std::string_view text_;
  std::size_t block_ = kNone;
  BlockMarks marks_;
};

}  // namespace

void scan_ini(std::string_view text, IniSink& sink) {
  const std::size_t n = text.size();
  const char* p = text.data();
  LineFinder lines(text);
  std::size_t pos = 0;
  int line = 0;
  while (pos < n) {
    ++line;
    const LineFinder::Line found = lines.line_at(pos);
    std::size_t i = pos;
    // LF, CRLF, or a lone CR (old Mac files, or mixed endings) ends the line.
    pos = found.end;
    if (pos < n) pos += (p[pos] == '\r' && pos + 1 < n && p[pos + 1] == '\n') ? 2 : 1;

    while (i < found.end && is_blank(p[i])) ++i;
    if (i == found.end) continue;  // blank
    const std::string_view l(p + i, found.end - i);
    const char first = l.front();
    if (first == ';' || first == '#') {
      sink.on_comment(line, first);
      continue;
    }
    if (first == '[') {
      const std::size_t close = l.find(']');
      const bool closed = close != kNone;
      sink.on_section(line, trim_blanks(l.substr(1, closed ? close - 1 : kNone)),
                      closed ? trim_blanks(l.substr(close + 1)) : std::string_view(), closed);
      continue;
    }
    if (found.equals == kNone) {
      sink.on_junk(line, trim_blanks(l));
      continue;
    }
    const std::size_t eq = found.equals - i;
    sink.on_key(line, trim_blanks(l.substr(0, eq)), trim_blanks(l.substr(eq + 1)));
  }
}

}  // namespace cfg::detail
