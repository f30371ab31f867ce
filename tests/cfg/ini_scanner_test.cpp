// The INI scanner under the reader (libcfg/src/ini_scanner.hpp): its line rules (LF, CRLF or a
// lone CR ends a line; the first '=' splits key and value) hold wherever a line falls among the
// 64-byte blocks it reads, and the SSE2 step reads the same marks as the byte-by-byte one that
// targets without SSE2 run.
#include "ini_scanner.hpp"

#include <gtest/gtest.h>

#include <array>
#include <random>
#include <string>
#include <vector>

namespace {

using cfg::detail::BlockMarks;

// Every call of the sink as one line of text: "3 key a=b", "5 section x", "7 junk y", ...
class Recorder final : public cfg::detail::IniSink {
 public:
  std::vector<std::string> calls;
  void on_section(int line, std::string_view name, std::string_view, bool) override {
    calls.push_back(std::to_string(line) + " section " + std::string(name));
  }
  void on_key(int line, std::string_view key, std::string_view value) override {
    calls.push_back(std::to_string(line) + " key " + std::string(key) + "=" + std::string(value));
  }
  void on_comment(int line, char) override { calls.push_back(std::to_string(line) + " comment"); }
  void on_junk(int line, std::string_view text) override {
    calls.push_back(std::to_string(line) + " junk " + std::string(text));
  }
};

std::vector<std::string> scanned(const std::string& text) {
  Recorder r;
  cfg::detail::scan_ini(text, r);
  return r.calls;
}

TEST(IniScanner, SseMarksAreTheBytewiseMarks) {
  // Bytes drawn mostly from the marked ones, so that every bit position sees both values; and
  // one block of each byte value.
  std::mt19937 random(306);
  const std::string alphabet = "\n\r=a [;\x80\xff";
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1);
  std::array<char, 64> block{};
  for (int round = 0; round < 2000; ++round) {
    for (char& c : block) c = alphabet[pick(random)];
    ASSERT_EQ(cfg::detail::block_marks(block.data()),
              cfg::detail::block_marks_portable(block.data()))
        << "round " << round;
  }
  for (int value = 0; value < 256; ++value) {
    block.fill(static_cast<char>(value));
    const BlockMarks m = cfg::detail::block_marks_portable(block.data());
    EXPECT_EQ(m.ends, value == '\n' || value == '\r' ? ~std::uint64_t{0} : 0U) << value;
    EXPECT_EQ(m.equals, value == '=' ? ~std::uint64_t{0} : 0U) << value;
    EXPECT_EQ(cfg::detail::block_marks(block.data()), m) << value;
  }
}

TEST(IniScanner, AnEqualsSignInALaterBlockSplitsTheKeyThere) {
  const std::string key(100, 'k');  // the '=' is in the second block
  EXPECT_EQ(scanned(key + "=v\r\nx=y"),
            (std::vector<std::string>{"1 key " + key + "=v", "2 key x=y"}));
}

TEST(IniScanner, CrLfAcrossABlockBoundaryIsOneLineEnd) {
  const std::string first = "a=" + std::string(61, 'v');  // 63 bytes: '\r' is byte 63
  ASSERT_EQ(first.size(), 63U);
  EXPECT_EQ(scanned(first + "\r\nb=2\r\n"),
            (std::vector<std::string>{"1 key a=" + std::string(61, 'v'), "2 key b=2"}));
}

TEST(IniScanner, LoneCrEndsALineAndTheLastLineNeedsNoEnd) {
  EXPECT_EQ(scanned("[S]\ra=1\n\nb=2"),
            (std::vector<std::string>{"1 section S", "2 key a=1", "4 key b=2"}));
}

TEST(IniScanner, AnEqualsSignOnTheNextLineIsNotThisLinesKey) {
  // The '=' of line 2 is in the same block as line 1, which has none.
  EXPECT_EQ(scanned("no equals here\na=b=c\n; x=y\n"),
            (std::vector<std::string>{"1 junk no equals here", "2 key a=b=c", "3 comment"}));
}

TEST(IniScanner, ALineOfManyBlocksWithoutAnEndIsOneLine) {
  const std::string value(300, 'x');
  EXPECT_EQ(scanned("  k = " + value), (std::vector<std::string>{"1 key k=" + value}));
}

}  // namespace
