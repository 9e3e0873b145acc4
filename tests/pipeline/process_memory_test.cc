#include "subslam/pipeline/process_memory.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <cstring>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace subslam::pipeline {
namespace {

// glibc's allocator only: not under AddressSanitizer or ThreadSanitizer, whose allocators
// replace it.
#if defined(__GLIBC__) && __GLIBC_PREREQ(2, 33) && !defined(__SANITIZE_ADDRESS__) && !defined(__SANITIZE_THREAD__)
// Whether a 16 MiB block comes from the heap (not mmapped) and stays in it once freed.
// glibc's own threshold starts at 128 KiB and only rises as mmapped blocks are freed, so
// in a fresh process such a block is mmapped and returned at once.
bool BlockStaysInTheHeap() {
  constexpr size_t kBlock = 16 << 20;
  const struct mallinfo2 before = mallinfo2();
  void* block = std::malloc(kBlock);
  if (block == nullptr) return false;
  std::memset(block, 1, kBlock);
  asm volatile("" : : "r"(block) : "memory");  // the block is used: no elision of the pair
  const struct mallinfo2 held = mallinfo2();
  std::free(block);
  const struct mallinfo2 after = mallinfo2();
  return held.hblkhd == before.hblkhd && after.fordblks >= before.fordblks + kBlock;
}

// Each case runs in a fresh process (the threadsafe death-test style re-executes the
// binary), so no other test's heap history or allocator setting reaches it.
TEST(ProcessMemory, FreedBlocksStayInTheProcess) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(std::exit(KeepFreedMemoryInProcess() && BlockStaysInTheHeap() ? 0 : 1), ::testing::ExitedWithCode(0), "");
}

TEST(ProcessMemory, WithoutItAFreedBlockIsReturned) {
  GTEST_FLAG_SET(death_test_style, "threadsafe");
  EXPECT_EXIT(std::exit(BlockStaysInTheHeap() ? 0 : 1), ::testing::ExitedWithCode(1), "");
}
#endif

}  // namespace
}  // namespace subslam::pipeline
