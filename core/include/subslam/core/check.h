// Invariant checks that fail loudly, shared by every module (Abseil 20220623 on Debian 12 has no
// logging library). A failed check prints file, line, the condition and an optional
// streamed message to stderr, then aborts. Checks stay on in Release builds: they
// guard contracts (a non-positive-definite covariance, an out-of-range index), not
// user input, which is answered with absl::Status instead.
#ifndef SUBSLAM_CORE_CHECK_H_
#define SUBSLAM_CORE_CHECK_H_

#include <sstream>

namespace subslam::internal {

class CheckFailure {
 public:
  CheckFailure(const char* file, int line, const char* condition);
  [[noreturn]] ~CheckFailure();
  template <typename T>
  CheckFailure& operator<<(const T& value) {
    stream_ << value;
    return *this;
  }

 private:
  std::ostringstream stream_;
};

}  // namespace subslam::internal

#define SUBSLAM_CHECK(condition) \
  if (condition) {               \
  } else /* NOLINT */            \
    ::subslam::internal::CheckFailure(__FILE__, __LINE__, #condition)

#endif  // SUBSLAM_CORE_CHECK_H_
