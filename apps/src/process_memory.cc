#include "subslam/app/process_memory.h"

#include <cstdio>

#include "absl/flags/flag.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

ABSL_FLAG(bool, keep_freed_memory, true,
          "keep freed memory in the process for reuse (glibc: mmap threshold 32 MiB, trim "
          "threshold 512 MiB; see subslam/app/process_memory.h) instead of returning it to "
          "the kernel and faulting it in again");

namespace subslam::app {

bool KeepFreedMemoryInProcess() {
#if defined(__GLIBC__)
  constexpr int kMmapThreshold = 32 << 20;   // bytes; glibc's maximum on 64-bit
  constexpr int kTrimThreshold = 512 << 20;  // bytes
  const bool mmap_set = mallopt(M_MMAP_THRESHOLD, kMmapThreshold) == 1;
  const bool trim_set = mallopt(M_TRIM_THRESHOLD, kTrimThreshold) == 1;
  return mmap_set && trim_set;
#else
  return false;
#endif
}

void ApplyKeepFreedMemoryFlag() {
  if (absl::GetFlag(FLAGS_keep_freed_memory) && !KeepFreedMemoryInProcess()) {
    std::fprintf(stderr, "note: the allocator settings of --keep_freed_memory are not available here\n");
  }
}

}  // namespace subslam::app
