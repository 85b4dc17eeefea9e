//! Matrix storage and the vector-matrix kernels of the inference engine.
//!
//! Every layer of the engine computes `y += x W` for one input vector `x` and a row-major
//! weight matrix `W = [rows, cols]`, skipping the rows whose input is exactly zero (after a
//! ReLU about half of them). The product is memory-bound: per frame the weights stream once
//! from memory, so the engine can keep them in half precision ([`Precision::F16`], IEEE
//! binary16, accumulated in f32), which halves the bytes read per frame.
//!
//! Kernels: with AVX2, FMA and F16C (checked at run time) four active rows are fused per pass
//! over an output block that stays in L1 (eight lanes per instruction, f16 converted by
//! `vcvtph2ps`); elsewhere a portable loop computes the same sums.

use serde::{Deserialize, Serialize};

/// Storage precision of a weight matrix. Arithmetic is always f32.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Precision {
    /// 32-bit floats: the trained weights bit for bit.
    #[default]
    F32,
    /// 16-bit IEEE floats (relative rounding error ≤ 2⁻¹¹), half the bytes per frame.
    F16,
}

impl Precision {
    /// Bytes per stored weight.
    pub fn bytes(self) -> usize {
        match self {
            Precision::F32 => 4,
            Precision::F16 => 2,
        }
    }

    /// Lower-case name (`f32`, `f16`).
    pub fn name(self) -> &'static str {
        match self {
            Precision::F32 => "f32",
            Precision::F16 => "f16",
        }
    }
}

/// Largest finite f16 value; matrices with larger weights stay in f32.
const F16_MAX: f32 = 65504.0;

/// Values converted per step of the in-place f16 conversion.
const CONVERT_BLOCK: usize = 1024;

/// Half-precision values (their bit patterns) packed two per `f32` slot of the buffer the
/// matrix came in, so the conversion needs no second buffer of the matrix's size.
#[derive(Clone, Debug, PartialEq)]
struct HalfBuffer {
    words: Vec<f32>,
    len: usize,
}

impl HalfBuffer {
    /// Converts `data` to f16 in place (round to nearest even) and gives the unused half of
    /// the allocation back.
    fn from_f32(mut data: Vec<f32>) -> Self {
        use half::slice::{HalfBitsSliceExt, HalfFloatSliceExt};
        let len = data.len();
        {
            let bits: &mut [u16] = bytemuck::cast_slice_mut(&mut data[..]);
            let mut block = [0f32; CONVERT_BLOCK];
            let mut start = 0;
            while start < len {
                let n = CONVERT_BLOCK.min(len - start);
                // Value `i` occupies u16 slots 2i, 2i+1 and its f16 goes to slot i: a whole block
                // is read before any of it is written, and writes never pass the block's end.
                let Some(src) = bits
                    .get(2 * start..2 * (start + n))
                    .and_then(|s| bytemuck::try_cast_slice::<u16, f32>(s).ok())
                else {
                    break;
                };
                block[..n].copy_from_slice(src);
                if let Some(out) = bits.get_mut(start..start + n) {
                    out.reinterpret_cast_mut::<half::f16>()
                        .convert_from_f32_slice(&block[..n]);
                }
                start += n;
            }
        }
        data.truncate(len.div_ceil(2));
        data.shrink_to_fit();
        Self { words: data, len }
    }

    fn bits(&self) -> &[u16] {
        let all: &[u16] = bytemuck::cast_slice(&self.words);
        all.get(..self.len).unwrap_or(all)
    }
}

#[derive(Clone, Debug, PartialEq)]
enum Storage {
    F32(Vec<f32>),
    F16(HalfBuffer),
}

/// A row-major `[rows, cols]` weight matrix in f32 or f16.
#[derive(Clone, Debug, PartialEq)]
pub struct Matrix {
    rows: usize,
    cols: usize,
    storage: Storage,
}

impl Matrix {
    /// Takes ownership of `data` (`rows * cols` values, row-major) and stores it at
    /// `precision`, converting in place (no second copy). A matrix with a weight beyond the
    /// f16 range stays in f32.
    pub fn new(rows: usize, cols: usize, data: Vec<f32>, precision: Precision) -> Self {
        let fits_f16 = || data.iter().all(|v| v.abs() <= F16_MAX);
        let storage = match precision {
            Precision::F16 if fits_f16() => Storage::F16(HalfBuffer::from_f32(data)),
            _ => Storage::F32(data),
        };
        Self {
            rows,
            cols,
            storage,
        }
    }

    /// Number of rows (input width).
    pub fn rows(&self) -> usize {
        self.rows
    }

    /// Number of columns (output width).
    pub fn cols(&self) -> usize {
        self.cols
    }

    /// Precision the weights are stored at.
    pub fn precision(&self) -> Precision {
        match self.storage {
            Storage::F32(_) => Precision::F32,
            Storage::F16(_) => Precision::F16,
        }
    }

    /// Bytes of weight storage.
    pub fn bytes(&self) -> usize {
        self.rows * self.cols * self.precision().bytes()
    }

    /// `y += x W[:, col0 .. col0 + y.len()]`, skipping rows whose `x` is zero. Extra values of
    /// `x` and columns past the matrix are ignored.
    pub fn accumulate(&self, x: &[f32], col0: usize, y: &mut [f32]) {
        let rows = x.len().min(self.rows);
        let n = y.len().min(self.cols.saturating_sub(col0));
        let (x, y) = (&x[..rows], &mut y[..n]);
        match &self.storage {
            Storage::F32(w) => accumulate_f32(w, self.cols, x, col0, y),
            Storage::F16(h) => accumulate_f16(h.bits(), self.cols, x, col0, y),
        }
    }
}

/// True when the AVX2 + FMA + F16C kernels can run on this CPU.
pub fn simd_available() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
            && std::arch::is_x86_feature_detected!("fma")
            && std::arch::is_x86_feature_detected!("f16c")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

fn accumulate_f32(w: &[f32], cols: usize, x: &[f32], col0: usize, y: &mut [f32]) {
    debug_assert!(w.len() >= x.len() * cols && col0 + y.len() <= cols);
    #[cfg(target_arch = "x86_64")]
    if simd_available() && w.len() >= x.len() * cols && col0 + y.len() <= cols {
        // SAFETY: the features were detected and every row slice `[r*cols + col0, +y.len())`
        // with `r < x.len()` lies inside `w` (checked just above).
        unsafe { avx2::accumulate_f32(w, cols, x, col0, y) };
        return;
    }
    for (r, &xi) in x.iter().enumerate() {
        let start = r * cols + col0;
        if xi != 0.0
            && let Some(row) = w.get(start..start + y.len())
        {
            for (yo, &wo) in y.iter_mut().zip(row) {
                *yo += xi * wo;
            }
        }
    }
}

fn accumulate_f16(w: &[u16], cols: usize, x: &[f32], col0: usize, y: &mut [f32]) {
    debug_assert!(w.len() >= x.len() * cols && col0 + y.len() <= cols);
    #[cfg(target_arch = "x86_64")]
    if simd_available() && w.len() >= x.len() * cols && col0 + y.len() <= cols {
        // SAFETY: as in `accumulate_f32`.
        unsafe { avx2::accumulate_f16(w, cols, x, col0, y) };
        return;
    }
    for (r, &xi) in x.iter().enumerate() {
        let start = r * cols + col0;
        if xi != 0.0
            && let Some(row) = w.get(start..start + y.len())
        {
            for (yo, &wo) in y.iter_mut().zip(row) {
                *yo += xi * half::f16::from_bits(wo).to_f32();
            }
        }
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    //! The AVX2 kernels: nonzero inputs are gathered four at a time and their rows fused into
    //! one pass over `y` (one load and one store of `y` per four weight rows).

    use std::arch::x86_64::*;

    /// Stamps out `accumulate_<type>` for a storage type and its 8-lane load.
    macro_rules! accumulate_kernel {
        ($name:ident, $t:ty, $load8:expr, $to_f32:expr) => {
            /// `y += x W[:, col0..col0 + y.len()]` over the rows with nonzero `x`.
            ///
            /// # Safety
            /// AVX2, FMA and F16C must be available, and `w` must hold `x.len()` rows of `cols`
            /// values with `col0 + y.len() <= cols`.
            #[target_feature(enable = "avx2,fma,f16c")]
            pub unsafe fn $name(w: &[$t], cols: usize, x: &[f32], col0: usize, y: &mut [f32]) {
                let n = y.len();
                let load8 = $load8;
                let to_f32 = $to_f32;
                let base = w.as_ptr();
                let yp = y.as_mut_ptr();
                let mut rows = [base; 4];
                let mut coef = [0f32; 4];
                let mut pending = 0;
                for (r, &xi) in x.iter().enumerate() {
                    if xi == 0.0 {
                        continue;
                    }
                    // SAFETY: row `r` starts at `r * cols` inside `w` (caller's contract).
                    rows[pending] = unsafe { base.add(r * cols + col0) };
                    coef[pending] = xi;
                    pending += 1;
                    if pending < 4 {
                        continue;
                    }
                    pending = 0;
                    let a = [
                        _mm256_set1_ps(coef[0]),
                        _mm256_set1_ps(coef[1]),
                        _mm256_set1_ps(coef[2]),
                        _mm256_set1_ps(coef[3]),
                    ];
                    let mut k = 0;
                    // SAFETY: every access is below `n` values from a row start or from `yp`.
                    unsafe {
                        while k + 8 <= n {
                            let mut acc = _mm256_loadu_ps(yp.add(k));
                            acc = _mm256_fmadd_ps(a[0], load8(rows[0].add(k)), acc);
                            acc = _mm256_fmadd_ps(a[1], load8(rows[1].add(k)), acc);
                            acc = _mm256_fmadd_ps(a[2], load8(rows[2].add(k)), acc);
                            acc = _mm256_fmadd_ps(a[3], load8(rows[3].add(k)), acc);
                            _mm256_storeu_ps(yp.add(k), acc);
                            k += 8;
                        }
                        while k < n {
                            let mut v = *yp.add(k);
                            for (p, c) in rows.iter().zip(coef) {
                                v = c.mul_add(to_f32(*p.add(k)), v);
                            }
                            *yp.add(k) = v;
                            k += 1;
                        }
                    }
                }
                for (p, &c) in rows.iter().zip(&coef).take(pending) {
                    let a = _mm256_set1_ps(c);
                    let mut k = 0;
                    // SAFETY: as above.
                    unsafe {
                        while k + 8 <= n {
                            let acc = _mm256_fmadd_ps(a, load8(p.add(k)), _mm256_loadu_ps(yp.add(k)));
                            _mm256_storeu_ps(yp.add(k), acc);
                            k += 8;
                        }
                        while k < n {
                            *yp.add(k) = c.mul_add(to_f32(*p.add(k)), *yp.add(k));
                            k += 1;
                        }
                    }
                }
            }
        };
    }

    accumulate_kernel!(
        accumulate_f32,
        f32,
        |p: *const f32| unsafe { _mm256_loadu_ps(p) },
        |v: f32| v
    );
    accumulate_kernel!(
        accumulate_f16,
        u16,
        |p: *const u16| unsafe { _mm256_cvtph_ps(_mm_loadu_si128(p.cast::<__m128i>())) },
        |v: u16| half::f16::from_bits(v).to_f32()
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lcg(s: &mut u64) -> f32 {
        *s = s
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((*s >> 40) as f32 / (1u64 << 24) as f32) * 2.0 - 1.0
    }

    fn reference(w: &[f32], cols: usize, x: &[f32], col0: usize, n: usize) -> Vec<f32> {
        (0..n)
            .map(|c| {
                x.iter()
                    .enumerate()
                    .map(|(r, xi)| (*xi as f64) * (w[r * cols + col0 + c] as f64))
                    .sum::<f64>() as f32
            })
            .collect()
    }

    #[test]
    fn f16_conversion_in_place_rounds_to_nearest_and_frees_half() {
        let mut s = 3;
        for len in [0, 1, 2, 7, 1023, 1024, 1025, 5000] {
            let data: Vec<f32> = (0..len).map(|_| lcg(&mut s) * 3.0).collect();
            let h = HalfBuffer::from_f32(data.clone());
            assert_eq!(h.bits().len(), len);
            assert!(h.words.capacity() <= len.div_ceil(2) + 1);
            for (b, v) in h.bits().iter().zip(&data) {
                assert_eq!(*b, half::f16::from_f32(*v).to_bits(), "len {len}");
            }
        }
    }

    #[test]
    fn kernels_match_a_double_precision_reference() {
        let mut s = 11;
        for (rows, cols, col0, n) in [(13, 40, 0, 40), (64, 100, 7, 61), (5, 9, 8, 1), (9, 33, 0, 33)] {
            let w: Vec<f32> = (0..rows * cols).map(|_| lcg(&mut s)).collect();
            // Every third input is zero: those rows must be skipped without effect.
            let x: Vec<f32> = (0..rows)
                .map(|r| if r % 3 == 1 { 0.0 } else { lcg(&mut s) })
                .collect();
            let expected = reference(&w, cols, &x, col0, n);
            let m32 = Matrix::new(rows, cols, w.clone(), Precision::F32);
            let mut y = vec![0.0; n];
            m32.accumulate(&x, col0, &mut y);
            for (a, b) in y.iter().zip(&expected) {
                assert!((a - b).abs() < 1e-5, "f32 {rows}x{cols}: {a} vs {b}");
            }
            let rounded: Vec<f32> = w.iter().map(|v| half::f16::from_f32(*v).to_f32()).collect();
            let expected16 = reference(&rounded, cols, &x, col0, n);
            let m16 = Matrix::new(rows, cols, w, Precision::F16);
            assert_eq!(m16.precision(), Precision::F16);
            assert_eq!(m16.bytes(), rows * cols * 2);
            let mut y = vec![1.0; n];
            m16.accumulate(&x, col0, &mut y);
            for (a, b) in y.iter().zip(&expected16) {
                assert!((a - 1.0 - b).abs() < 1e-5, "f16 {rows}x{cols}: {a} vs 1 + {b}");
            }
        }
    }

    #[test]
    fn out_of_range_weights_stay_f32_and_bad_sizes_do_not_overrun() {
        let m = Matrix::new(1, 2, vec![1.0, 1e6], Precision::F16);
        assert_eq!(m.precision(), Precision::F32);
        let mut y = vec![0.0; 5];
        m.accumulate(&[2.0, 3.0], 1, &mut y);
        assert_eq!(y, [2e6, 0.0, 0.0, 0.0, 0.0]);
        m.accumulate(&[1.0], 3, &mut y);
        assert_eq!(y[0], 2e6);
    }
}
