#include "subslam/app/process_memory.h"

#include <gtest/gtest.h>

#if defined(__GLIBC__)
#include <malloc.h>
#endif

#include <cstdlib>
#include <cstring>

namespace subslam::app {
namespace {

#if defined(__GLIBC__)
TEST(ProcessMemory, FreedBlocksStayInTheProcess) {
  ASSERT_TRUE(KeepFreedMemoryInProcess());
  // A 4 MiB block (above glibc's default 128 KiB mmap threshold) now comes from the heap,
  // and freeing it keeps the memory: the heap's free bytes grow by about its size.
  constexpr size_t kBlock = 4 << 20;
  const struct mallinfo2 before = mallinfo2();
  void* block = std::malloc(kBlock);
  ASSERT_NE(block, nullptr);
  std::memset(block, 1, kBlock);
  const struct mallinfo2 held = mallinfo2();
  EXPECT_EQ(held.hblkhd, before.hblkhd);  // not mmapped
  std::free(block);
  const struct mallinfo2 after = mallinfo2();
  EXPECT_GE(after.fordblks, before.fordblks + kBlock);  // kept, free for reuse
  EXPECT_GE(after.arena, before.arena + kBlock);
}
#endif

}  // namespace
}  // namespace subslam::app
