// The program image version convention of program_image.hpp (DSP 302 §9 dates).
#include "cfg/program_image.hpp"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <limits>

#include "cfg/bytes.hpp"
#include "cfg/integer_literal.hpp"

namespace cfg {
namespace {

// DSP 302 §9: day 0 is 1 January 1984.
constexpr std::chrono::sys_days kEpoch = std::chrono::year{1984} / std::chrono::January / 1;
constexpr std::uint32_t kMsPerDay = 24U * 60U * 60U * 1000U;

bool ends_in_trailer(std::span<const std::uint8_t> image) {
  if (image.size() < kProgramTrailerSize) return false;
  const auto magic = image.last(kProgramTrailerMagic.size());
  return std::equal(magic.begin(), magic.end(), kProgramTrailerMagic.begin(),
                    [](std::uint8_t b, char c) { return b == static_cast<std::uint8_t>(c); });
}

// Exactly `digits` decimal digits at `text[pos]`.
std::optional<unsigned> digits_at(std::string_view text, std::size_t pos, std::size_t digits) {
  if (pos + digits > text.size()) return std::nullopt;
  unsigned v = 0;
  for (std::size_t i = pos; i < pos + digits; ++i) {
    if (text[i] < '0' || text[i] > '9') return std::nullopt;
    v = v * 10 + static_cast<unsigned>(text[i] - '0');
  }
  return v;
}

Error bad(std::string_view text, std::string_view why) {
  return Error{"program version '" + std::string(text) + "': " + std::string(why) +
               " (expected YYYY-MM-DD[THH:MM[:SS[.mmm]]] or DAYS,MS)"};
}

Result<ProgramVersion> parse_calendar(std::string_view text) {
  const auto y = digits_at(text, 0, 4);
  const auto m = digits_at(text, 5, 2);
  const auto d = digits_at(text, 8, 2);
  if (!y || !m || !d || text[4] != '-' || text[7] != '-') return bad(text, "not a date");
  const std::chrono::year_month_day date{std::chrono::year{static_cast<int>(*y)},
                                         std::chrono::month{*m}, std::chrono::day{*d}};
  if (!date.ok()) return bad(text, "no such day");
  const auto days = (std::chrono::sys_days{date} - kEpoch).count();
  if (days < 0) return bad(text, "before 1984-01-01, day 0 of DSP 302 §9");
  ProgramVersion v{static_cast<std::uint32_t>(days), 0};
  if (text.size() == 10) return v;
  if (text[10] != 'T' && text[10] != ' ') return bad(text, "not a date and time");
  const auto hh = digits_at(text, 11, 2);
  const auto mm = digits_at(text, 14, 2);
  if (!hh || !mm || text.size() < 16 || text[13] != ':') return bad(text, "not a time");
  std::optional<unsigned> ss = 0;
  std::optional<unsigned> ms = 0;
  std::size_t end = 16;
  if (text.size() > 16) {
    ss = text[16] == ':' ? digits_at(text, 17, 2) : std::nullopt;
    end = 19;
    if (ss && text.size() > 19) {
      ms = text[19] == '.' ? digits_at(text, 20, 3) : std::nullopt;
      end = 23;
    }
  }
  if (!ss || !ms || end != text.size()) return bad(text, "not a time");
  if (*hh > 23 || *mm > 59 || *ss > 59) return bad(text, "no such time of day");
  v.time_ms = ((*hh * 60 + *mm) * 60 + *ss) * 1000 + *ms;
  return v;
}

}  // namespace

std::optional<ProgramVersion> program_image_version(std::span<const std::uint8_t> image) {
  if (!ends_in_trailer(image)) return std::nullopt;
  const auto trailer = image.last(kProgramTrailerSize);
  return ProgramVersion{load_le32(trailer.first(4)), load_le32(trailer.subspan(4, 4))};
}

std::vector<std::uint8_t> with_program_trailer(std::span<const std::uint8_t> payload,
                                               ProgramVersion version) {
  const auto body =
      ends_in_trailer(payload) ? payload.first(payload.size() - kProgramTrailerSize) : payload;
  std::vector<std::uint8_t> image(body.begin(), body.end());
  image.reserve(body.size() + kProgramTrailerSize);
  append_le(image, version.date_days, 4);
  append_le(image, version.time_ms, 4);
  image.insert(image.end(), kProgramTrailerMagic.begin(), kProgramTrailerMagic.end());
  return image;
}

Result<ProgramVersion> parse_program_version(std::string_view text) {
  if (const auto comma = text.find(','); comma != std::string_view::npos) {
    const auto days = parse_integer_literal(text.substr(0, comma)).literal;
    const auto ms = parse_integer_literal(text.substr(comma + 1)).literal;
    if (!days || !ms) return bad(text, "DAYS and MS must be numbers");
    if (days->value > std::numeric_limits<std::uint32_t>::max()) {
      return bad(text, "DAYS does not fit UNSIGNED32");
    }
    if (ms->value >= kMsPerDay) return bad(text, "MS is 24 h or more");
    return ProgramVersion{static_cast<std::uint32_t>(days->value),
                          static_cast<std::uint32_t>(ms->value)};
  }
  return parse_calendar(text);
}

std::string to_string(ProgramVersion version) {
  const std::chrono::year_month_day date{kEpoch + std::chrono::days{version.date_days}};
  const std::uint32_t t = version.time_ms;
  char text[96];
  std::snprintf(text, sizeof text, "%04d-%02u-%02u %02u:%02u:%02u.%03u (1F52h %u, %u)",
                static_cast<int>(date.year()), static_cast<unsigned>(date.month()),
                static_cast<unsigned>(date.day()), t / 3600000U, t / 60000U % 60U, t / 1000U % 60U,
                t % 1000U, version.date_days, version.time_ms);
  return text;
}

}  // namespace cfg
