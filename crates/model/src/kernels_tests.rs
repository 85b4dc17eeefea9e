//! Tests of the inference kernels (kept apart so the kernels read as one file).

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
fn f16_conversion_in_place_scales_rows_rounds_to_nearest_and_frees_half() {
    let mut s = 3;
    for (len, cols) in [
        (0, 1),
        (1, 1),
        (2, 2),
        (7, 3),
        (1023, 1023),
        (3000, 1500),
        (5000, 7),
    ] {
        // Rows of very different magnitudes: each must keep f16's relative precision.
        let data: Vec<f32> = (0..len)
            .map(|i| lcg(&mut s) * 10f32.powi((i / cols) as i32 % 9 - 6))
            .collect();
        let h = HalfBuffer::from_f32(data.clone(), cols);
        assert_eq!(h.bits().len(), len);
        assert_eq!(h.row_scale.len(), len.div_ceil(cols));
        assert!(h.words.capacity() <= len.div_ceil(2) + 1);
        for (i, (b, v)) in h.bits().iter().zip(&data).enumerate() {
            let scale = h.row_scale[i / cols];
            assert_eq!(*b, half::f16::from_f32(v / scale).to_bits(), "len {len}");
            let back = half::f16::from_bits(*b).to_f32() * scale;
            let row_max = data[i / cols * cols..((i / cols + 1) * cols).min(len)]
                .iter()
                .fold(0f32, |m, v| m.max(v.abs()));
            assert!(
                (back - v).abs() <= row_max * 2f32.powi(-11),
                "{back} vs {v}"
            );
        }
    }
}

#[test]
fn kernels_match_a_double_precision_reference() {
    let mut s = 11;
    for (rows, cols, col0, n) in [
        (13, 40, 0, 40),
        (64, 100, 7, 61),
        (5, 9, 8, 1),
        (9, 33, 0, 33),
    ] {
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
        let rounded: Vec<f32> = w
            .chunks(cols)
            .flat_map(|row| {
                let e = row_exponent(row.iter().fold(0f32, |m, v| m.max(v.abs())));
                row.iter()
                    .map(move |v| half::f16::from_f32(v * 2f32.powi(e)).to_f32() * 2f32.powi(-e))
            })
            .collect();
        let expected16 = reference(&rounded, cols, &x, col0, n);
        let m16 = Matrix::new(rows, cols, w, Precision::F16);
        assert_eq!(m16.precision(), Precision::F16);
        assert_eq!(m16.bytes(), rows * cols * 2);
        let mut y = vec![1.0; n];
        m16.accumulate(&x, col0, &mut y);
        for (a, b) in y.iter().zip(&expected16) {
            assert!(
                (a - 1.0 - b).abs() < 1e-5,
                "f16 {rows}x{cols}: {a} vs 1 + {b}"
            );
        }
    }
}

#[test]
fn portable_and_simd_kernels_agree() {
    let mut s = 17;
    let (rows, cols) = (23, 45);
    let w: Vec<f32> = (0..rows * cols).map(|_| lcg(&mut s)).collect();
    let x: Vec<f32> = (0..rows)
        .map(|r| if r % 4 == 0 { 0.0 } else { lcg(&mut s) })
        .collect();
    let h: Vec<u16> = w
        .iter()
        .map(|v| half::f16::from_f32(*v).to_bits())
        .collect();
    for col0 in [0, 3, 20] {
        let n = cols - col0;
        let (mut a, mut b) = (vec![0.5; n], vec![0.5; n]);
        accumulate_portable(&w, &[], cols, &x, col0, &mut a, |v| v);
        accumulate_f32(&w, cols, &x, col0, &mut b);
        assert!(a.iter().zip(&b).all(|(p, q)| (p - q).abs() < 1e-5));
        let (mut a, mut b) = (vec![0.5; n], vec![0.5; n]);
        let scale: Vec<f32> = (0..rows).map(|r| 0.5 + r as f32).collect();
        accumulate_portable(&h, &scale, cols, &x, col0, &mut a, |v| {
            half::f16::from_bits(v).to_f32()
        });
        accumulate_f16(&h, &scale, cols, &x, col0, &mut b);
        assert!(a.iter().zip(&b).all(|(p, q)| (p - q).abs() < 1e-5));
    }
}

#[test]
fn simd_skinning_matches_the_reference() {
    let mut s = 5;
    let joints = 7;
    let mats: Vec<f32> = (0..joints * MATRIX_FLOATS).map(|_| lcg(&mut s)).collect();
    let n = 37;
    let rest: Vec<f32> = (0..3 * n).map(|_| lcg(&mut s)).collect();
    // Unused slots (weight 0) and a joint index past the matrices must add nothing.
    let idx: Vec<[u16; 4]> = (0..n as u16)
        .map(|v| [v % 7, (v + 3) % 7, 9, v % 5])
        .collect();
    let w: Vec<[f32; 4]> = (0..n)
        .map(|v| [0.5, 0.25, 0.25, if v % 2 == 0 { 0.0 } else { 0.1 }])
        .collect();
    let mut expected = vec![Vec3::zeros(); n];
    skin_positions_into(&rest, &idx, &w, &mats, &mut expected);
    let mut got = vec![Vec3::zeros(); n];
    skin_into(&rest, &idx, &w, &mats, &mut got);
    for (a, b) in got.iter().zip(&expected) {
        assert!((a - b).norm() < 1e-5, "{a:?} vs {b:?}");
    }
}

#[test]
fn large_and_tiny_weights_survive_f16_and_bad_sizes_do_not_overrun() {
    let m = Matrix::new(2, 2, vec![1.0, 1e6, 3e-7, -1e-7], Precision::F16);
    assert_eq!(m.precision(), Precision::F16);
    let mut y = vec![0.0; 5];
    m.accumulate(&[2.0, 3.0], 1, &mut y);
    assert!((y[0] - (2e6 - 3e-7)).abs() < 2e6 * 1e-3, "{}", y[0]);
    assert_eq!(&y[1..], [0.0; 4]);
    let mut y = vec![0.0; 2];
    m.accumulate(&[0.0, 1.0], 0, &mut y);
    assert!(
        (y[0] - 3e-7).abs() < 3e-10 && (y[1] + 1e-7).abs() < 1e-10,
        "{y:?}"
    );
    m.accumulate(&[1.0], 3, &mut y);
    assert!((y[0] - 3e-7).abs() < 3e-10);
}

/// The patched burn-flex computes products of few rows with a transposed right-hand side
/// (a small batch's `dG · Wᵀ`) column-major and transposes them back: every row count around
/// its limit (64), both operand layouts, against a product in f64.
#[test]
fn products_of_few_rows_with_a_transposed_rhs_match_a_reference() {
    use burn::tensor::{Tensor, TensorData};
    let device = burn::tensor::Device::flex();
    let mut s = 11;
    for (m, k, n) in [
        (1, 7, 5),
        (3, 33, 17),
        (8, 96, 40),
        (64, 40, 70),
        (65, 40, 70),
    ] {
        let a: Vec<f32> = (0..m * k).map(|_| lcg(&mut s)).collect();
        // W is stored [n, k] and used transposed: the right-hand side [k, n] has unit stride
        // along k.
        let w: Vec<f32> = (0..n * k).map(|_| lcg(&mut s)).collect();
        let lhs = Tensor::<2>::from_data(TensorData::new(a.clone(), [m, k]), &device);
        let rhs = Tensor::<2>::from_data(TensorData::new(w.clone(), [n, k]), &device);
        let out: Vec<f32> = lhs
            .matmul(rhs.transpose())
            .into_data()
            .try_to_vec::<f32>()
            .unwrap();
        assert_eq!(out.len(), m * n);
        for i in 0..m {
            for j in 0..n {
                let want: f64 = (0..k)
                    .map(|l| f64::from(a[i * k + l]) * f64::from(w[j * k + l]))
                    .sum();
                let got = f64::from(out[i * n + j]);
                assert!(
                    (got - want).abs() <= 1e-5 * (1.0 + want.abs()),
                    "[{m}, {k}] x [{k}, {n}] at ({i}, {j}): {got} against {want}"
                );
            }
        }
    }
}
