// The executables' flag --keep_freed_memory (default true), for subslam's own programs
// (the CLI and the benches) only: this target is not installed, so a program that links
// the libraries gets no flag of this name.
#ifndef SUBSLAM_CLI_KEEP_FREED_MEMORY_FLAG_H_
#define SUBSLAM_CLI_KEEP_FREED_MEMORY_FLAG_H_

namespace subslam::pipeline {

// Calls KeepFreedMemoryInProcess() (subslam/pipeline/process_memory.h) when
// --keep_freed_memory is set, with a note on stderr if that failed. Call it after
// absl::ParseCommandLine.
void ApplyKeepFreedMemoryFlag();

}  // namespace subslam::pipeline

#endif  // SUBSLAM_CLI_KEEP_FREED_MEMORY_FLAG_H_
