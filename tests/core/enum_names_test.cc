#include "subslam/core/enum_names.h"

#include <gtest/gtest.h>

namespace subslam {
namespace {

enum class Colour { kRed, kGreen, kBlue };
constexpr EnumName<Colour> kColourNames[] = {{Colour::kRed, "red"}, {Colour::kGreen, "green"}, {Colour::kBlue, "blue"}};

TEST(EnumNames, NamesAndParsesEveryValue) {
  for (const EnumName<Colour>& entry : kColourNames) {
    EXPECT_STREQ(NameOf(kColourNames, entry.value), entry.name);
    absl::StatusOr<Colour> parsed = ParseEnum(kColourNames, entry.name, "colour");
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, entry.value);
  }
}

TEST(EnumNames, AnUnknownNameListsTheExpectedOnes) {
  const absl::StatusOr<Colour> parsed = ParseEnum(kColourNames, "Red", "colour");
  ASSERT_FALSE(parsed.ok());
  EXPECT_EQ(parsed.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(parsed.status().message(), "unknown colour \"Red\" (expected red, green or blue)");
  EXPECT_STREQ(NameOf(kColourNames, static_cast<Colour>(7)), "?");
}

}  // namespace
}  // namespace subslam
