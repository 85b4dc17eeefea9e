//! Memory measurements: the streaming-read bandwidth floor and the process's peak resident
//! memory (Linux `/proc`).

use std::time::Instant;

use serde::Serialize;

/// Streaming read bandwidth over a buffer.
#[derive(Clone, Debug, Serialize)]
pub struct MemoryBandwidth {
    /// Buffer size in bytes.
    pub bytes: usize,
    /// Threads reading.
    pub threads: usize,
    /// Best (lowest) milliseconds for one full read of the buffer.
    pub ms_per_pass: f64,
    /// Gigabytes per second.
    pub gb_per_sec: f64,
}

/// Sum of `data`, read as fast as this CPU can (AVX2 when available): the floor is only a
/// floor if no code could read the buffer faster.
fn read_all(data: &[f32]) -> f32 {
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        // SAFETY: AVX2 was detected.
        return unsafe { read_all_avx2(data) };
    }
    // Eight independent accumulators let the loop vectorise and pipeline.
    let mut acc = [0f32; 8];
    for block in data.chunks_exact(8) {
        for (a, v) in acc.iter_mut().zip(block) {
            *a += v;
        }
    }
    acc.iter().sum()
}

/// # Safety
/// AVX2 must be available.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
unsafe fn read_all_avx2(data: &[f32]) -> f32 {
    use std::arch::x86_64::*;
    let mut acc = [_mm256_setzero_ps(); 8];
    let mut blocks = data.chunks_exact(64);
    for block in &mut blocks {
        for (j, a) in acc.iter_mut().enumerate() {
            // SAFETY: `block` holds 64 values, lane group `j` is inside it.
            *a = _mm256_add_ps(*a, unsafe { _mm256_loadu_ps(block.as_ptr().add(8 * j)) });
        }
    }
    let mut lanes = [0f32; 8];
    let total = acc
        .iter()
        .fold(_mm256_setzero_ps(), |s, a| _mm256_add_ps(s, *a));
    // SAFETY: `lanes` holds eight floats.
    unsafe { _mm256_storeu_ps(lanes.as_mut_ptr(), total) };
    lanes.iter().sum::<f32>() + blocks.remainder().iter().sum::<f32>()
}

/// A buffer of `bytes` bytes (at least 4 KiB) for [`read_pass_secs`], every page touched.
pub fn floor_buffer(bytes: usize) -> Vec<f32> {
    let n = (bytes / 4).max(1024);
    (0..n).map(|i| (i % 1024) as f32 * 1e-3).collect()
}

/// Seconds for one streaming read of all of `data` by `threads` threads (each reads one
/// contiguous part).
pub fn read_pass_secs(data: &[f32], threads: usize) -> f64 {
    let chunk = data.len().div_ceil(threads.max(1)).max(1);
    let start = Instant::now();
    let total: f32 = std::thread::scope(|s| {
        let handles: Vec<_> = data
            .chunks(chunk)
            .map(|c| s.spawn(move || read_all(c)))
            .collect();
        handles.into_iter().map(|h| h.join().unwrap_or(0.0)).sum()
    });
    std::hint::black_box(total);
    start.elapsed().as_secs_f64()
}

/// Reads a `bytes`-sized `f32` buffer `passes` times (sum of all values) with `threads`
/// threads and keeps the fastest pass: the floor for any code that must stream that much
/// data once per frame.
pub fn measure_bandwidth(bytes: usize, threads: usize, passes: usize) -> MemoryBandwidth {
    let data = floor_buffer(bytes);
    let n = data.len();
    let threads = threads.max(1);
    let mut best = f64::INFINITY;
    for _ in 0..passes.max(1) {
        best = best.min(read_pass_secs(&data, threads));
    }
    MemoryBandwidth {
        bytes: n * 4,
        threads,
        ms_per_pass: best * 1e3,
        gb_per_sec: (n * 4) as f64 / best / 1e9,
    }
}

/// Peak resident set size of this process in bytes (`VmHWM`), 0 when unknown.
pub fn peak_rss_bytes() -> usize {
    status_kb("VmHWM:") * 1024
}

/// Current resident set size of this process in bytes (`VmRSS`), 0 when unknown.
pub fn rss_bytes() -> usize {
    status_kb("VmRSS:") * 1024
}

fn status_kb(key: &str) -> usize {
    status_field(key).unwrap_or(0)
}

/// The number after `key` (e.g. `"VmRSS:"` in kB, `"Threads:"`) in `/proc/self/status`,
/// `None` where that file or the field is missing (not Linux).
pub fn status_field(key: &str) -> Option<usize> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    status
        .lines()
        .find_map(|l| l.strip_prefix(key))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<usize>().ok())
}

/// Resets the peak resident set size to the current one (Linux; no-op elsewhere).
pub fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bandwidth_is_positive_and_counts_the_buffer() {
        let b = measure_bandwidth(1 << 20, 2, 3);
        assert_eq!(b.bytes, 1 << 20);
        assert!(b.gb_per_sec > 0.0 && b.ms_per_pass > 0.0);
    }

    #[test]
    fn read_all_sums_every_value() {
        let data: Vec<f32> = (0..1000).map(|i| (i % 7) as f32).collect();
        let expected: f32 = data.iter().sum();
        assert_eq!(read_all(&data), expected);
    }
}
