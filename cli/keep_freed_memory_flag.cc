#include "keep_freed_memory_flag.h"

#include <cstdio>

#include "absl/flags/flag.h"
#include "subslam/pipeline/process_memory.h"

ABSL_FLAG(bool, keep_freed_memory, true,
          "keep freed memory in the process for reuse (glibc: mmap threshold 32 MiB, trim "
          "threshold 512 MiB; see subslam/pipeline/process_memory.h) instead of returning it to "
          "the kernel and faulting it in again");

namespace subslam::pipeline {

void ApplyKeepFreedMemoryFlag() {
  if (absl::GetFlag(FLAGS_keep_freed_memory) && !KeepFreedMemoryInProcess()) {
    std::fprintf(stderr, "note: the allocator settings of --keep_freed_memory are not available here\n");
  }
}

}  // namespace subslam::pipeline
