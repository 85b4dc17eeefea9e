//! Allocator settings for training (glibc).
//!
//! A training step allocates and frees the same large buffers every step: the gradients of the
//! two bases (`[512, V·3]`, 21 MB each on the default garment), the matrix products of the
//! batch, the physics buffers. glibc serves buffers above its mmap threshold with fresh
//! `mmap`s and returns freed memory at the top of its heap to the system, so each step paid
//! for zeroing tens of megabytes of new pages again (page faults were about a tenth of the
//! step's profile). [`keep_freed_buffers`] raises the mmap threshold to 32 MiB (the largest
//! value older glibc allows on 64-bit) and the trim threshold to 1 GiB: freed buffers stay in
//! the heap and the next step reuses them. Measured on the default scene at batch 16: 10 to
//! 15% less time per step, about 4% more peak memory (docs/BENCHMARKS.md). The setting is
//! process-wide and only changes when memory goes back to the system, not how much a step uses.
//!
//! The top pad: threads other than the main one (the second half of a split batch, the rayon
//! workers) allocate from their own arenas, chains of 64 MiB heaps. glibc unmaps such a heap
//! as soon as it is empty, whatever the trim threshold, unless the arena would then keep
//! less free memory than the pad (128 KiB by default; `heap_trim` in glibc's arena.c). A step
//! in halves then faulted in fresh pages for its buffers every step. A pad of 64 MiB, the
//! size of such a heap, keeps them: at batch 16 in halves each step is 1.09-1.12x faster, for 1
//! to 7 % more peak memory; with the batch whole no faster and 15 to 24 % more peak memory (the
//! rayon workers' arenas keep their buffers too; docs/BENCHMARKS.md, 2026-11-29). The main
//! arena grows by the pad at a time, as address space; only written pages count as memory.

use std::sync::Once;

/// 32 MiB: the largest `M_MMAP_THRESHOLD` older glibc accepts on 64-bit targets
/// (`HEAP_MAX_SIZE / 2`). glibc 2.36's `mallopt` also accepts larger values (checked); what a
/// larger threshold would do to a step is not measured.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD_BYTES: libc::c_int = 32 << 20;
/// Free memory at the top of the heap kept before glibc trims it.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const TRIM_THRESHOLD_BYTES: libc::c_int = 1 << 30;
/// Free memory an arena keeps when it grows or shrinks: the size of a thread arena's heap
/// (glibc's `HEAP_MAX_SIZE` on 64-bit), so that an emptied heap is kept, not unmapped.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const TOP_PAD_BYTES: libc::c_int = 64 << 20;

static TUNED: Once = Once::new();

/// Keeps freed training buffers in the process for reuse (see the module doc); once per
/// process, a no-op outside Linux with glibc. Returns whether glibc took all three settings.
pub fn keep_freed_buffers() -> bool {
    let mut accepted = false;
    TUNED.call_once(|| accepted = apply());
    accepted
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn apply() -> bool {
    // SAFETY: `mallopt` only changes the allocator's tuning parameters; it is thread-safe
    // and these values are within glibc's documented ranges.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES) == 1
            && libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD_BYTES) == 1
            && libc::mallopt(libc::M_TOP_PAD, TOP_PAD_BYTES) == 1
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn apply() -> bool {
    false
}

/// Returns the freed buffers kept by [`keep_freed_buffers`] to the system (`malloc_trim`),
/// e.g. before measuring the peak memory of the next run in the same process, or when
/// training ends.
pub fn release_freed_buffers() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `malloc_trim` only returns free heap memory to the system; thread-safe.
    unsafe {
        libc::malloc_trim(0);
    }
}

#[cfg(test)]
mod tests {
    #[test]
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    fn glibc_takes_the_settings_once() {
        // The first call applies them (unless another test of this binary did already).
        let _ = super::keep_freed_buffers();
        assert!(!super::keep_freed_buffers(), "applied twice");
        let v: Vec<u8> = vec![1; 40 << 20];
        assert_eq!(v[v.len() - 1], 1);
    }
}
