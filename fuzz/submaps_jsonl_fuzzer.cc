// libFuzzer target for the local-maps exchange reader (io/submaps_jsonl.h): whatever the
// text, ParseSubmapsJsonl must return local maps or an error (never crash or read out of
// bounds), and every local map it returns must pass LocalSubmap::Validate() — the
// invariants the back-ends rely on — with ids increasing and time spans in order.
// Built and run by scripts/fuzz.sh (clang, -fsanitize=fuzzer,address,undefined).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <string>

#include "subslam/io/submaps_jsonl.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  auto maps = subslam::io::ParseSubmapsJsonl(text, "fuzz");
  if (!maps.ok()) {
    if (maps.status().message().empty()) std::abort();
    return 0;
  }
  for (size_t k = 0; k < maps->size(); ++k) {
    const subslam::LocalSubmap& s = (*maps)[k];
    if (!s.Validate().ok()) std::abort();
    if (k > 0 && !(s.id > (*maps)[k - 1].id)) std::abort();
  }
  return 0;
}
