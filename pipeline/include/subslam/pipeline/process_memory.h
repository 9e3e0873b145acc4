// Process-wide allocator settings for subslam's executables (the CLI and the benches,
// through their flag --keep_freed_memory, cli/); the libraries never change
// them, so a program that embeds subslam keeps its own unless it calls this itself.
//
// glibc hands a freed block of at least 128 KiB (a threshold it raises as it goes) back
// to the kernel at once, and gives the memory at the top of its heap back once more than
// twice that is free there; the next allocation of that size then faults in fresh,
// zero-filled pages. The joiners allocate and free blocks of that size on every join
// (the dense EKF its n × n covariance as it grows, the EIF its sparse factor at every
// full factorisation). On a virtual machine where a page fault costs microseconds this
// can dominate a joiner's time (the dense EKF joiner's, ten times over: bench/RESULTS.md).
// Blocks above 32 MiB are still mmapped.
#ifndef SUBSLAM_PIPELINE_PROCESS_MEMORY_H_
#define SUBSLAM_PIPELINE_PROCESS_MEMORY_H_

namespace subslam::pipeline {

// Keeps freed memory in the process for reuse: blocks up to 32 MiB (glibc's largest
// mmap threshold on 64-bit) come from the heap, and the heap's top is given back to the
// kernel only beyond 512 MiB free. What the process holds between peaks stays near its
// peak, and the peak itself grows a little. Returns false where the allocator is not glibc's or refused a
// setting (nothing is then changed for that setting).
bool KeepFreedMemoryInProcess();

}  // namespace subslam::pipeline

#endif  // SUBSLAM_PIPELINE_PROCESS_MEMORY_H_
