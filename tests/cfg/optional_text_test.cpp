// OptionalText: the optional attribute text of the model (CiA 306 DefaultValue, ParameterValue,
// LowLimit, ...), one pointer when absent. It must behave as std::optional<std::string> does.
#include "cfg/optional_text.hpp"

#include <gtest/gtest.h>

#include <optional>
#include <string>
#include <utility>

#include "cfg/object_dictionary.hpp"

namespace cfg {
namespace {

TEST(OptionalText, AbsentByDefaultAndEqualToNullopt) {
  OptionalText t;
  EXPECT_FALSE(t.has_value());
  EXPECT_TRUE(t == std::nullopt);
  EXPECT_FALSE(t == "");  // absent differs from an empty text (an empty key in a file)
  EXPECT_EQ(t.value_or("x"), "x");
  EXPECT_THROW((void)t.value(), std::bad_optional_access);
}

TEST(OptionalText, HoldsTextAndComparesLikeOptional) {
  OptionalText t = "0x1F";
  ASSERT_TRUE(t);
  EXPECT_EQ(*t, "0x1F");
  EXPECT_EQ(t->size(), 4u);
  EXPECT_TRUE(t == "0x1F");
  EXPECT_TRUE(t == std::string("0x1F"));
  EXPECT_TRUE(t == std::optional<std::string>("0x1F"));
  EXPECT_FALSE(t == std::optional<std::string>());
  EXPECT_TRUE(t != OptionalText("0x20"));
  t = std::nullopt;
  EXPECT_FALSE(t.has_value());
  t.emplace("");
  EXPECT_TRUE(t.has_value());
  EXPECT_EQ(*t, "");
}

TEST(OptionalText, CopiesAreDeepAndMovesLeaveTheSourceAbsent) {
  OptionalText a = "$NODEID+0x180";
  OptionalText b = a;
  *b += "0";
  EXPECT_EQ(*a, "$NODEID+0x180");  // the copy has its own text
  OptionalText c = std::move(b);
  EXPECT_EQ(*c, "$NODEID+0x1800");
  EXPECT_FALSE(b.has_value());  // NOLINT(bugprone-use-after-move): moved-from is empty by design
}

// The point of the type: the model's per-entry size (memory within 3x the file size).
TEST(OptionalText, IsOnePointerSoASubObjectStaysSmall) {
  EXPECT_EQ(sizeof(OptionalText), sizeof(void*));
  EXPECT_LE(sizeof(SubObject), 128u);
}

}  // namespace
}  // namespace cfg
