// The fill-reducing ordering of the EIF joiner's sparse factorisations (EifJoinerOptions).
#ifndef SUBSLAM_BACKEND_FILL_REDUCING_ORDERING_H_
#define SUBSLAM_BACKEND_FILL_REDUCING_ORDERING_H_

#include <string>
#include <string_view>

#include "absl/status/statusor.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace subslam::backend {

//  - kAmd ("amd"): approximate minimum degree. Cheap to compute (about 0.1 ms at 1,400
//    variables), but on a map revisited at random its elimination tree is deep: a rank
//    update from an old variable walks a path holding half of L.
//  - kNestedDissection ("nested_dissection"): METIS nested dissection, through CHOLMOD
//    (cholmod_metis, the elimination tree postordered). About three times AMD's time to
//    compute, but its tree is balanced: on the 16 km random world L has 40 % fewer
//    entries and an update's path 60 % fewer (bench/RESULTS.md).
//    subslam builds against a CHOLMOD with its Partition module (Debian's libcholmod3);
//    where that CHOLMOD reports METIS not installed, AMD is used instead. (cholmod_metis
//    returns the identity for a nearly dense matrix, which the EIF's Λ is not.)
//  - kAmdOrNestedDissection ("auto"): AMD until AMD's factor would cost at least
//    SparseCholesky::kNestedDissectionMinFlopsPerEntry flops per entry of the matrix's
//    lower triangle, nested dissection from that factorisation on (the EIF's information
//    matrix grows with every join, and AMD's cost per entry with it; the second analysis
//    is paid once, at the switch, and the switch stays when an undone loop closure
//    shrinks Λ again). On a map whose graph is close to a chain (few
//    revisits) AMD's factor stays cheap and METIS's time would be wasted; on one revisited
//    at random it does not. (Nested dissection's own flops are not compared: where they
//    are a little higher, its balanced tree still shortens the rank updates' paths, which
//    cost more than the factorisations.)
enum class FillReducingOrdering { kAmd, kNestedDissection, kAmdOrNestedDissection };

inline std::string_view ToString(FillReducingOrdering o) {
  switch (o) {
    case FillReducingOrdering::kAmd:
      return "amd";
    case FillReducingOrdering::kNestedDissection:
      return "nested_dissection";
    case FillReducingOrdering::kAmdOrNestedDissection:
      return "auto";
  }
  return "?";
}

inline absl::StatusOr<FillReducingOrdering> FillReducingOrderingFromString(std::string_view name) {
  for (FillReducingOrdering o : {FillReducingOrdering::kAmd, FillReducingOrdering::kNestedDissection,
                                 FillReducingOrdering::kAmdOrNestedDissection}) {
    if (name == ToString(o)) return o;
  }
  return absl::InvalidArgumentError(
      absl::StrCat("unknown fill-reducing ordering '", std::string(name), "' (amd | nested_dissection | auto)"));
}

// Abseil flag hooks (found by argument-dependent lookup): a flag of this type accepts
// the names above and rejects anything else at parse time.
inline bool AbslParseFlag(absl::string_view text, FillReducingOrdering* o, std::string* error) {
  absl::StatusOr<FillReducingOrdering> parsed =
      FillReducingOrderingFromString(std::string_view(text.data(), text.size()));
  if (!parsed.ok()) {
    *error = std::string(parsed.status().message());
    return false;
  }
  *o = *parsed;
  return true;
}
inline std::string AbslUnparseFlag(FillReducingOrdering o) { return std::string(ToString(o)); }

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_FILL_REDUCING_ORDERING_H_
