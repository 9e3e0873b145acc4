// The fill-reducing ordering of the EIF joiner's sparse factorisations (EifJoinerOptions).
#ifndef SUBSLAM_BACKEND_FILL_REDUCING_ORDERING_H_
#define SUBSLAM_BACKEND_FILL_REDUCING_ORDERING_H_

#include <string>
#include <string_view>

#include "absl/status/statusor.h"

namespace subslam::backend {

//  - kAmd ("amd"): approximate minimum degree. Cheap to compute (about 0.1 ms at 1,400
//    variables), but on a map revisited at random its elimination tree is deep: a rank
//    update from an old variable walks a path holding half of L.
//  - kNestedDissection ("nested_dissection"): METIS nested dissection, through CHOLMOD
//    (cholmod_metis, the elimination tree postordered). About three times AMD's time to
//    compute, but its tree is balanced: on a map revisited at random L has fewer entries
//    and an update's path is much shorter (docs/design/eif.md).
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

const char* ToString(FillReducingOrdering o);  // amd, nested_dissection, auto
absl::StatusOr<FillReducingOrdering> FillReducingOrderingFromString(const std::string& name);

}  // namespace subslam::backend

#endif  // SUBSLAM_BACKEND_FILL_REDUCING_ORDERING_H_
