//! The bridge between the fused kernels and burn: positions are read from the (possibly
//! autodiff) tensor once, and each kernel's result comes back as the `[B]` tensor
//!
//! `s + e - sg(s)` with `s_b = Σ_{v,k} x_{bvk} G_{bvk}` (`G` a constant),
//!
//! whose value is `e` (`s - sg(s)` is exactly zero) and whose gradient with respect to `x` is
//! exactly `G`. Whatever produced `x` (network, decoder basis, skinning) keeps its autodiff; only
//! the physics below `x` is replaced by the hand-written gradient.

use burn::tensor::{DType, Element, Tensor, TensorData};

use crate::PhysicsError;

use super::{Evaluation, Real};

/// Positions of a `[B, V, 3]` tensor on the host, in the tensor's float type (`f64` stays
/// `f64`; every other float type is read as `f32`).
#[derive(Clone, Debug)]
pub enum HostPositions {
    /// Single precision values, `B·V·3`, sample-major.
    F32(Vec<f32>),
    /// Double precision values, `B·V·3`, sample-major.
    F64(Vec<f64>),
}

impl HostPositions {
    /// Reads `x` back once (no gradient is recorded).
    pub fn read(x: &Tensor<3>) -> Result<Self, PhysicsError> {
        let x = x.clone().detach();
        let backend = |e: burn::tensor::TensorReadError| PhysicsError::Backend(e.to_string());
        Ok(match x.dtype() {
            DType::F64 => Self::F64(x.try_into_vec_as::<f64>().map_err(backend)?),
            _ => Self::F32(x.try_into_vec_as::<f32>().map_err(backend)?),
        })
    }

    /// Number of values.
    pub fn len(&self) -> usize {
        match self {
            Self::F32(v) => v.len(),
            Self::F64(v) => v.len(),
        }
    }

    /// True when empty.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// The `[B]` tensor with value `evaluation.energies` and gradient `evaluation.gradient` with
/// respect to `x` (`[B, V, 3]`), in `dtype` on `x`'s device.
pub fn surrogate<T: Real + Element>(
    x: &Tensor<3>,
    evaluation: Evaluation<T>,
    dtype: DType,
) -> Result<Tensor<1>, PhysicsError> {
    let [b, v, c] = x.dims();
    if evaluation.energies.len() != b || evaluation.gradient.len() != b * v * c {
        return Err(PhysicsError::ShapeMismatch {
            what: "fused physics result".into(),
            expected: format!("{b} energies and {} gradient values", b * v * c),
            found: format!(
                "{} energies and {} gradient values",
                evaluation.energies.len(),
                evaluation.gradient.len()
            ),
        });
    }
    let device = x.device();
    let gradient = Tensor::<3>::from_data(
        TensorData::new(evaluation.gradient, [b, v, c]),
        (&device, dtype),
    );
    let energy =
        Tensor::<1>::from_data(TensorData::new(evaluation.energies, [b]), (&device, dtype));
    let s = (x.clone() * gradient)
        .reshape([b, v * c])
        .sum_dim(1)
        .reshape([b]);
    Ok(s.clone() - s.detach() + energy)
}
