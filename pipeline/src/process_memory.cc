#include "subslam/pipeline/process_memory.h"

#include <cstdlib>  // defines __GLIBC__ (through <features.h>) where the C library is glibc

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace subslam::pipeline {

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

}  // namespace subslam::pipeline
