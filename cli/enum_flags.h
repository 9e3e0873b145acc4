// Abseil flag hooks for the enums that are flags of their own type (found by
// argument-dependent lookup): a flag of such a type accepts the names of the enum's table
// (its FromString) and rejects anything else at parse time.
#ifndef SUBSLAM_CLI_ENUM_FLAGS_H_
#define SUBSLAM_CLI_ENUM_FLAGS_H_

#include <string>

#include "absl/strings/string_view.h"
#include "subslam/backend/fill_reducing_ordering.h"

namespace subslam::backend {

inline bool AbslParseFlag(absl::string_view text, FillReducingOrdering* o, std::string* error) {
  absl::StatusOr<FillReducingOrdering> parsed = FillReducingOrderingFromString(std::string(text));
  if (!parsed.ok()) {
    *error = std::string(parsed.status().message());
    return false;
  }
  *o = *parsed;
  return true;
}

inline std::string AbslUnparseFlag(FillReducingOrdering o) { return ToString(o); }

}  // namespace subslam::backend

#endif  // SUBSLAM_CLI_ENUM_FLAGS_H_
