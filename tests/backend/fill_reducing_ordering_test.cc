// The fill-reducing orderings' names, as options and flags spell them.
#include "subslam/backend/fill_reducing_ordering.h"

#include <gtest/gtest.h>

#include <string_view>

namespace subslam::backend {
namespace {

TEST(FillReducingOrdering, NamesRoundTripAndOthersAreRejected) {
  for (FillReducingOrdering o : {FillReducingOrdering::kAmd, FillReducingOrdering::kNestedDissection,
                                 FillReducingOrdering::kAmdOrNestedDissection}) {
    absl::StatusOr<FillReducingOrdering> parsed = FillReducingOrderingFromString(ToString(o));
    ASSERT_TRUE(parsed.ok());
    EXPECT_EQ(*parsed, o);
  }
  for (const char* bad : {"", "AMD", "metis", "auto "}) {
    const absl::StatusOr<FillReducingOrdering> parsed = FillReducingOrderingFromString(bad);
    ASSERT_FALSE(parsed.ok()) << bad;
    EXPECT_NE(parsed.status().message().find("expected amd, nested_dissection or auto"), std::string_view::npos);
  }
}

}  // namespace
}  // namespace subslam::backend
