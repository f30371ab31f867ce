// Diagnostics print like a compiler's (DEVELOPERS.md: `file.dcf:42: error: ...`).
#include "cfg/diagnostics.hpp"

#include <gtest/gtest.h>

namespace cfg {
namespace {

TEST(Diagnostics, FormatsAsFileLineSeverityMessage) {
  EXPECT_EQ((Diagnostic{"pilz.eds", 212, Severity::Warning, "[1A00sub3] DataType"}.format()),
            "pilz.eds:212: warning: [1A00sub3] DataType");
  EXPECT_EQ((Diagnostic{"a.dcf", 0, Severity::Error, "empty file"}.format()),
            "a.dcf: error: empty file");
  EXPECT_EQ((Diagnostic{"", 3, Severity::Note, "x"}.format()), "<input>:3: note: x");
}

// A message quoting bytes of a hostile file must not carry a terminal escape sequence (ESC [ ...)
// or a carriage return that hides the start of the line.
TEST(Diagnostics, ControlCharactersAreShownEscaped) {
  const Diagnostic d{"x.eds", 7, Severity::Warning, "line \"\x1b[31mred\rX\x7f\" is not a key"};
  EXPECT_EQ(d.format(), "x.eds:7: warning: line \"\\x1B[31mred\\x0DX\\x7F\" is not a key");
}

TEST(Diagnostics, Utf8AndLatin1BytesAreKept) {
  const Diagnostic d{"m.eds", 1, Severity::Note, "Drehzahl \xC3\xBC \xFC"};
  EXPECT_EQ(d.format(), "m.eds:1: note: Drehzahl \xC3\xBC \xFC");
}

TEST(Diagnostics, CountsBySeverity) {
  Diagnostics all;
  all.add("a", 1, Severity::Warning, "w");
  all.add("a", 2, Severity::Error, "e");
  all.add("a", 3, Severity::Warning, "w2");
  EXPECT_EQ(all.count(Severity::Warning), 2u);
  EXPECT_TRUE(all.has_errors());
  EXPECT_EQ(all.format(), "a:1: warning: w\na:2: error: e\na:3: warning: w2\n");
}

}  // namespace
}  // namespace cfg
