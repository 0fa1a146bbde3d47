// Process-wide tuning of the C allocator for hmc's per-frame work.
#pragma once

namespace hmc {

// Every frame of footage allocates and frees tens of megabytes of images
// (decoded frames, float copies, box filters, label maps: 1-5 MB each).
// glibc serves such blocks with mmap, or trims them back to the system when
// freed, so each frame touches fresh pages: on `hmc track` the page faults
// took over a third of the time (docs/PERFORMANCE.md). This keeps blocks up
// to 32 MB in the heap and freed memory for reuse (peak memory barely
// moves: 348 -> 358 MB on `hmc track`; what is kept was in use before).
// Idempotent: main() calls it first thing, and RunSynthShot too, so tests
// and benchmarks that render shots get it; a no-op off glibc.
void KeepFreedMemoryForReuse();

// What the process freed goes back to the system now (the heap kept above
// is for reuse within a stage): `hmc run` calls it between stages, so its
// peak is its largest stage's, not that plus what earlier stages left
// (docs/PERFORMANCE.md, "Footage to mesh"). A no-op off glibc.
void ReturnFreedMemory();

}  // namespace hmc
