// The program version of DSP 302 §9 ("days since January 1, 1984", "milliseconds after
// midnight") and our image trailer convention (cfg/program_image.hpp).
#include "cfg/program_image.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace {

using cfg::ProgramVersion;

TEST(ProgramVersion, Dsp302Section9DayZeroIsFirstOfJanuary1984) {
  const auto v = cfg::parse_program_version("1984-01-01");
  ASSERT_TRUE(v.ok()) << v.error().message;
  EXPECT_EQ(*v, (ProgramVersion{0, 0}));
}

TEST(ProgramVersion, CountsLeapDaysFromTheEpoch) {
  // 1984 and 1988 are leap years: 1 January 1989 is 366 + 365 + 365 + 365 + 366 = 1827 days on.
  const auto v = cfg::parse_program_version("1989-01-01");
  ASSERT_TRUE(v.ok());
  EXPECT_EQ(v->date_days, 1827U);
  // 2000-03-01: 16 years (4 leap: 84, 88, 92, 96) = 5844 days, + Jan 31 + Feb 29 (2000 leaps).
  const auto w = cfg::parse_program_version("2000-03-01");
  ASSERT_TRUE(w.ok());
  EXPECT_EQ(w->date_days, 5844U + 31U + 29U);
}

TEST(ProgramVersion, TimeIsMillisecondsAfterMidnight) {
  const auto v = cfg::parse_program_version("1984-01-02T01:02:03.004");
  ASSERT_TRUE(v.ok()) << v.error().message;
  EXPECT_EQ(*v, (ProgramVersion{1, ((1 * 60 + 2) * 60 + 3) * 1000 + 4}));
  const auto w = cfg::parse_program_version("1984-01-02 23:59");
  ASSERT_TRUE(w.ok());
  EXPECT_EQ(w->time_ms, (23U * 60U + 59U) * 60000U);
}

TEST(ProgramVersion, NumbersAsTheObjectsHoldThem) {
  const auto v = cfg::parse_program_version("15671,0x1C4");
  ASSERT_TRUE(v.ok()) << v.error().message;
  EXPECT_EQ(*v, (ProgramVersion{15671, 452}));
}

TEST(ProgramVersion, RejectsWhatNoObjectCanHold) {
  for (const char* text : {"", "1983-12-31", "2026-02-29", "2026-13-01", "2026-11-27T24:00",
                           "2026-11-27T12:60", "2026-11-27T12:00:00.5", "2026-11-27X", "1,86400000",
                           "4294967296,0", "x,1", "12", "2026-11-27T1:00"}) {
    const auto v = cfg::parse_program_version(text);
    EXPECT_FALSE(v.ok()) << text;
    if (!v.ok()) {
      EXPECT_NE(v.error().message.find(text), std::string::npos) << text;
    }
  }
}

TEST(ProgramVersion, PrintsTheDateAndTheNumbers) {
  EXPECT_EQ(cfg::to_string(ProgramVersion{1827, 3723004}),
            "1989-01-01 01:02:03.004 (1F52h 1827, 3723004)");
}

TEST(ProgramImage, TrailerCarriesTheVersionLittleEndianBeforeTheMagic) {
  const std::vector<std::uint8_t> payload{0xAA, 0xBB};
  const auto image = cfg::with_program_trailer(payload, ProgramVersion{0x01020304, 0x0A0B0C0D});
  const std::vector<std::uint8_t> expected{0xAA, 0xBB, 0x04, 0x03, 0x02, 0x01, 0x0D,
                                           0x0C, 0x0B, 0x0A, 'C',  'P',  'V',  '1'};
  EXPECT_EQ(image, expected);
  EXPECT_EQ(cfg::program_image_version(image), (ProgramVersion{0x01020304, 0x0A0B0C0D}));
}

TEST(ProgramImage, AnImageWithoutTrailerHasNoVersion) {
  EXPECT_EQ(cfg::program_image_version(std::vector<std::uint8_t>{}), std::nullopt);
  EXPECT_EQ(cfg::program_image_version(std::vector<std::uint8_t>(11, 0)), std::nullopt);
  std::vector<std::uint8_t> almost(12, 0);
  almost[8] = 'C';
  almost[9] = 'P';
  almost[10] = 'V';
  almost[11] = '2';
  EXPECT_EQ(cfg::program_image_version(almost), std::nullopt);
}

TEST(ProgramImage, RestampingReplacesTheTrailer) {
  const std::vector<std::uint8_t> payload(100, 0x5A);
  const auto first = cfg::with_program_trailer(payload, ProgramVersion{1, 2});
  const auto second = cfg::with_program_trailer(first, ProgramVersion{3, 4});
  EXPECT_EQ(second.size(), payload.size() + cfg::kProgramTrailerSize);
  EXPECT_EQ(cfg::program_image_version(second), (ProgramVersion{3, 4}));
}

}  // namespace
