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
//! `vcvtph2ps`); elsewhere a portable loop computes the same sums. Linear blend skinning
//! ([`skin_into`]) has an AVX2 kernel too: after the weights, it is the largest cost per frame.

use serde::{Deserialize, Serialize};

use neural_cloth_core::geometry::skinning::MAX_INFLUENCES;
use neural_cloth_core::geometry::{SkinWeights, Vec3};

use super::skinning::{MATRIX_FLOATS, skin_positions_into};

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

/// Per-row scaling puts a row's largest weight in `[2^14, 2^15)`, well inside the f16 range
/// (largest finite value 65504) and far above its subnormals (below 2^-14), so every row keeps
/// f16's full 11-bit precision whatever its magnitude.
const F16_ROW_TOP_EXPONENT: i32 = 14;

/// Values converted per step of the in-place f16 conversion.
const CONVERT_BLOCK: usize = 1024;

/// Half-precision values (their bit patterns) packed two per `f32` slot of the buffer the
/// matrix came in, so the conversion needs no second buffer of the matrix's size. Row `r` holds
/// its weights multiplied by a power of two; `row_scale[r]` undoes it (exactly).
#[derive(Clone, Debug, PartialEq)]
struct HalfBuffer {
    words: Vec<f32>,
    len: usize,
    row_scale: Vec<f32>,
}

/// The power of two that brings `max_abs` into `[2^14, 2^15)` (1 for zero or non-finite).
fn row_exponent(max_abs: f32) -> i32 {
    if max_abs > 0.0 && max_abs.is_finite() {
        (F16_ROW_TOP_EXPONENT - max_abs.log2().floor() as i32).clamp(-100, 100)
    } else {
        0
    }
}

impl HalfBuffer {
    /// Converts `data` (rows of `cols` values) to scaled f16 in place (round to nearest even)
    /// and gives the unused half of the allocation back.
    fn from_f32(mut data: Vec<f32>, cols: usize) -> Self {
        use half::slice::{HalfBitsSliceExt, HalfFloatSliceExt};
        let len = data.len();
        let cols = cols.max(1);
        let exponents: Vec<i32> = data
            .chunks(cols)
            .map(|row| row_exponent(row.iter().fold(0f32, |m, v| m.max(v.abs()))))
            .collect();
        {
            let bits: &mut [u16] = bytemuck::cast_slice_mut(&mut data[..]);
            let mut block = [0f32; CONVERT_BLOCK];
            for (r, &e) in exponents.iter().enumerate() {
                let scale = 2f32.powi(e);
                let row_end = ((r + 1) * cols).min(len);
                let mut start = r * cols;
                while start < row_end {
                    let n = CONVERT_BLOCK.min(row_end - start);
                    // Value `i` occupies u16 slots 2i, 2i+1 and its f16 goes to slot i: a block
                    // is read before any of it is written, and writes never pass its end.
                    let Some(src) = bits
                        .get(2 * start..2 * (start + n))
                        .and_then(|s| bytemuck::try_cast_slice::<u16, f32>(s).ok())
                    else {
                        break;
                    };
                    for (b, v) in block.iter_mut().zip(src) {
                        *b = v * scale;
                    }
                    if let Some(out) = bits.get_mut(start..start + n) {
                        out.reinterpret_cast_mut::<half::f16>()
                            .convert_from_f32_slice(&block[..n]);
                    }
                    start += n;
                }
            }
        }
        data.truncate(len.div_ceil(2));
        data.shrink_to_fit();
        Self {
            words: data,
            len,
            row_scale: exponents.iter().map(|&e| 2f32.powi(-e)).collect(),
        }
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
    /// `precision`, converting in place (no second copy). At f16 each row is scaled by a power
    /// of two so that its largest weight uses the top of the f16 range.
    pub fn new(rows: usize, cols: usize, data: Vec<f32>, precision: Precision) -> Self {
        let storage = match precision {
            Precision::F16 => Storage::F16(HalfBuffer::from_f32(data, cols)),
            Precision::F32 => Storage::F32(data),
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

    /// Bytes of weight storage (an f16 matrix also keeps one f32 scale per row, not counted).
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
            Storage::F16(h) => accumulate_f16(h.bits(), &h.row_scale, self.cols, x, col0, y),
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
        unsafe { avx2::accumulate_f32(w, &[], cols, x, col0, y) };
        return;
    }
    accumulate_portable(w, &[], cols, x, col0, y, |v| v);
}

/// As `accumulate_f32` for f16 bit patterns whose row `r` is scaled by `1 / row_scale[r]`.
fn accumulate_f16(
    w: &[u16],
    row_scale: &[f32],
    cols: usize,
    x: &[f32],
    col0: usize,
    y: &mut [f32],
) {
    debug_assert!(w.len() >= x.len() * cols && col0 + y.len() <= cols);
    #[cfg(target_arch = "x86_64")]
    if simd_available() && w.len() >= x.len() * cols && col0 + y.len() <= cols {
        // SAFETY: as in `accumulate_f32`.
        unsafe { avx2::accumulate_f16(w, row_scale, cols, x, col0, y) };
        return;
    }
    accumulate_portable(w, row_scale, cols, x, col0, y, |v| {
        half::f16::from_bits(v).to_f32()
    });
}

/// The kernel without SIMD intrinsics: row by row, skipping zero inputs; row `r`'s input is
/// multiplied by `row_scale[r]` when there is one.
fn accumulate_portable<T: Copy>(
    w: &[T],
    row_scale: &[f32],
    cols: usize,
    x: &[f32],
    col0: usize,
    y: &mut [f32],
    to_f32: impl Fn(T) -> f32,
) {
    for (r, &xi) in x.iter().enumerate() {
        let start = r * cols + col0;
        if xi != 0.0
            && let Some(row) = w.get(start..start + y.len())
        {
            let c = row_scale.get(r).map_or(xi, |s| xi * s);
            for (yo, &wo) in y.iter_mut().zip(row) {
                *yo += c * to_f32(wo);
            }
        }
    }
}

/// Linear blend skinning of flat rest positions `[V * 3]` with 3x4 row-major joint matrices
/// (`MATRIX_FLOATS` per joint) into `out`: [`super::skinning::skin_positions_into`] with the
/// AVX2 kernel when available. Influences with weight 0 or a joint outside `matrices` add
/// nothing.
pub fn skin_into(
    rest: &[f32],
    joint_index: &[[u16; MAX_INFLUENCES]],
    weights: &[[f32; MAX_INFLUENCES]],
    matrices: &[f32],
    out: &mut [Vec3],
) {
    #[cfg(target_arch = "x86_64")]
    if simd_available() {
        // SAFETY: the features were detected; the kernel bounds-checks joint indices.
        unsafe { avx2::skin(rest, joint_index, weights, matrices, out) };
        return;
    }
    skin_positions_into(rest, joint_index, weights, matrices, out);
}

/// What every chunk of the fused garment pass reads.
pub struct GarmentChunk<'a> {
    /// The basis `[decoder width, V * 3]`.
    pub basis: &'a Matrix,
    /// Basis coefficients (decoder output).
    pub h: &'a [f32],
    /// Bias of the basis `[V * 3]`, if any.
    pub bias: Option<&'a [f32]>,
    /// Template `[V * 3]`, rest space.
    pub template: &'a [f32],
    /// Garment skin weights.
    pub skin: &'a SkinWeights,
    /// Skinning matrices, 3x4 row-major per joint.
    pub mats: &'a [f32],
}

impl GarmentChunk<'_> {
    /// Offsets, rest positions and posed positions of the vertices from `v0` on (as many as
    /// `posed` holds; `offsets` and `rest` hold three values per vertex).
    pub fn run(&self, v0: usize, offsets: &mut [f32], rest: &mut [f32], posed: &mut [Vec3]) {
        let n = posed.len();
        match self
            .bias
            .and_then(|b| b.get(3 * v0..3 * v0 + offsets.len()))
        {
            Some(bias) => offsets.copy_from_slice(bias),
            None => offsets.fill(0.0),
        }
        self.basis.accumulate(self.h, 3 * v0, offsets);
        let template = self.template.get(3 * v0..3 * (v0 + n)).unwrap_or(&[]);
        for ((r, t), o) in rest.iter_mut().zip(template).zip(offsets.iter()) {
            *r = t + o;
        }
        let joints = self.skin.joints.get(v0..v0 + n).unwrap_or(&[]);
        let weights = self.skin.weights.get(v0..v0 + n).unwrap_or(&[]);
        skin_into(rest, joints, weights, self.mats, posed);
    }
}

#[cfg(target_arch = "x86_64")]
mod avx2 {
    //! The AVX2 kernels: nonzero inputs are gathered four at a time and their rows fused into
    //! one pass over `y` (one load and one store of `y` per four weight rows).

    use std::arch::x86_64::*;

    use super::{MATRIX_FLOATS, MAX_INFLUENCES, Vec3};

    /// Skinning, one vertex per iteration: the blended 3x4 matrix lives in one 8-lane and one
    /// 4-lane register; the four influences are blended without branches (an unused or
    /// out-of-range influence blends joint 0 with weight 0, which adds exactly zero).
    ///
    /// # Safety
    /// AVX2 and FMA must be available.
    #[target_feature(enable = "avx2,fma")]
    pub unsafe fn skin(
        rest: &[f32],
        joint_index: &[[u16; MAX_INFLUENCES]],
        weights: &[[f32; MAX_INFLUENCES]],
        matrices: &[f32],
        out: &mut [Vec3],
    ) {
        let joints = matrices.len() / MATRIX_FLOATS;
        if joints == 0 {
            out.iter_mut()
                .zip(rest.chunks_exact(3))
                .for_each(|(o, _)| *o = Vec3::zeros());
            return;
        }
        let m = matrices.as_ptr();
        for (((p, js), ws), o) in rest
            .chunks_exact(3)
            .zip(joint_index)
            .zip(weights)
            .zip(out.iter_mut())
        {
            // Two partial sums (influences 0, 2 and 1, 3) halve the dependency chain.
            let mut rows01 = [_mm256_setzero_ps(); 2];
            let mut row2 = [_mm_setzero_ps(); 2];
            for (k, (&j, &w)) in js.iter().zip(ws).enumerate() {
                let used = w != 0.0 && (j as usize) < joints;
                let j = if used { j as usize } else { 0 };
                let wv = _mm256_set1_ps(if used { w } else { 0.0 });
                // SAFETY: `j < joints`, so the 12 floats of matrix `j` are inside `matrices`.
                unsafe {
                    let mj = m.add(j * MATRIX_FLOATS);
                    rows01[k % 2] = _mm256_fmadd_ps(wv, _mm256_loadu_ps(mj), rows01[k % 2]);
                    row2[k % 2] = _mm_fmadd_ps(
                        _mm256_castps256_ps128(wv),
                        _mm_loadu_ps(mj.add(8)),
                        row2[k % 2],
                    );
                }
            }
            let rows01 = _mm256_add_ps(rows01[0], rows01[1]);
            let row2 = _mm_add_ps(row2[0], row2[1]);
            let p1 = _mm_setr_ps(p[0], p[1], p[2], 1.0);
            let prod01 = _mm256_mul_ps(rows01, _mm256_set_m128(p1, p1));
            let prod2 = _mm_mul_ps(row2, p1);
            let pairs = _mm_hadd_ps(
                _mm256_castps256_ps128(prod01),
                _mm256_extractf128_ps(prod01, 1),
            );
            let xyz = _mm_hadd_ps(pairs, _mm_hadd_ps(prod2, prod2));
            let mut lanes = [0f32; 4];
            // SAFETY: `lanes` holds four floats.
            unsafe { _mm_storeu_ps(lanes.as_mut_ptr(), xyz) };
            *o = Vec3::new(lanes[0], lanes[1], lanes[2]);
        }
    }

    /// Stamps out `accumulate_<type>` for a storage type and its 8-lane load.
    macro_rules! accumulate_kernel {
        ($name:ident, $t:ty, $load8:expr, $to_f32:expr) => {
            /// `y += x W[:, col0..col0 + y.len()]` over the rows with nonzero `x`, row `r`'s
            /// input multiplied by `row_scale[r]` when there is one.
            ///
            /// # Safety
            /// AVX2, FMA and F16C must be available, and `w` must hold `x.len()` rows of `cols`
            /// values with `col0 + y.len() <= cols`.
            #[target_feature(enable = "avx2,fma,f16c")]
            pub unsafe fn $name(
                w: &[$t],
                row_scale: &[f32],
                cols: usize,
                x: &[f32],
                col0: usize,
                y: &mut [f32],
            ) {
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
                    coef[pending] = row_scale.get(r).map_or(xi, |s| xi * s);
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
                            let acc =
                                _mm256_fmadd_ps(a, load8(p.add(k)), _mm256_loadu_ps(yp.add(k)));
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
#[path = "kernels_tests.rs"]
mod tests;
