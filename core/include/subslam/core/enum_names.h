// One table of names per enum, and the two lookups every enum of the project uses: a
// value's name (for reports and flags) and the value of a name (for flags and files),
// the latter with an error that lists the names it expected. An enum's table is the only
// place its names are written.
//
//   inline constexpr EnumName<Colour> kColourNames[] = {{Colour::kRed, "red"}, …};
//   NameOf(kColourNames, Colour::kRed)            → "red"
//   ParseEnum(kColourNames, "blue", "colour")     → Colour::kBlue, or an InvalidArgument
//                                                   error "unknown colour "…" (expected red or blue)"
#ifndef SUBSLAM_CORE_ENUM_NAMES_H_
#define SUBSLAM_CORE_ENUM_NAMES_H_

#include <cstddef>
#include <string>
#include <string_view>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

namespace subslam {

template <typename E>
struct EnumName {
  E value;
  const char* name;
};

// The name of `value` in `table` ("?" for a value the table does not list).
template <typename E, size_t N>
const char* NameOf(const EnumName<E> (&table)[N], E value) {
  for (const EnumName<E>& entry : table) {
    if (entry.value == value) return entry.name;
  }
  return "?";
}

// The value named `name` in `table`; `what` names the enum in the error.
template <typename E, size_t N>
absl::StatusOr<E> ParseEnum(const EnumName<E> (&table)[N], std::string_view name, std::string_view what) {
  for (const EnumName<E>& entry : table) {
    if (name == entry.name) return entry.value;
  }
  std::string expected;
  for (size_t i = 0; i < N; ++i) {
    if (i > 0) expected += i + 1 == N ? " or " : ", ";
    expected += table[i].name;
  }
  return absl::InvalidArgumentError(std::string("unknown ") + std::string(what) + " \"" + std::string(name) +
                                    "\" (expected " + expected + ")");
}

}  // namespace subslam

#endif  // SUBSLAM_CORE_ENUM_NAMES_H_
