//! Unit activity of a [`ClothNet`]: which ReLU units are dead (zero for every input of a
//! batch), and the function-preserving remedy that brings them back.
//!
//! A ReLU unit whose pre-activation is negative for every input gets no gradient, so nothing
//! can bring it back once it is there. When every unit of the last decoder layer is dead the
//! basis receives zero input: the network outputs the bare template for ever (the "dead
//! skirt" of issue 11). [`unit_activity`] measures it per layer; [`revive_dead_units`]
//! re-initialises the incoming weights of dead units (fresh random weights, zero bias) and
//! zeroes their outgoing weights, so the network's output is unchanged at the moment of the
//! repair while the units receive gradients again.

use burn::nn::Linear;
use burn::tensor::activation::relu;
use burn::tensor::{Distribution, Tensor, TensorData};

use super::ModelError;
use super::network::{ClothNet, Mlp};

/// Activity of one ReLU layer over a batch.
#[derive(Clone, Debug, PartialEq)]
pub struct LayerActivity {
    /// Layer name, e.g. `decoder.2` or `static.0`.
    pub name: String,
    /// Units in the layer.
    pub units: usize,
    /// Units whose output was zero for every input of the batch.
    pub dead: usize,
    /// True for the layers on the path from the pose to the garment (static encoder and
    /// decoder); the dynamic encoder's bias-free units are legitimately silent on still poses.
    pub on_static_path: bool,
    /// True when [`revive_dead_units`] can revive this layer's units without changing the
    /// output: every decoder layer and every static-encoder layer but the last (the static
    /// latent `z_S`, whose outgoing weights also carry `z_D`).
    pub revivable: bool,
}

impl LayerActivity {
    /// Dead units in percent, 0..=100.
    pub fn dead_pct(&self) -> f64 {
        100.0 * self.dead as f64 / self.units.max(1) as f64
    }
}

/// Per-layer activity of all layers, input first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Activity {
    /// The layers.
    pub layers: Vec<LayerActivity>,
}

impl Activity {
    /// The largest dead percentage among the static-path layers (0 when there are none).
    pub fn worst_static_path_pct(&self) -> f64 {
        self.layers
            .iter()
            .filter(|l| l.on_static_path)
            .map(LayerActivity::dead_pct)
            .fold(0.0, f64::max)
    }

    /// The largest dead percentage among the layers the remedy can revive (0 when none): the
    /// measure the stall detector acts on.
    pub fn worst_revivable_pct(&self) -> f64 {
        self.layers
            .iter()
            .filter(|l| l.revivable)
            .map(LayerActivity::dead_pct)
            .fold(0.0, f64::max)
    }

    /// Dead percentage of the last decoder layer (the basis input); 100 means the network
    /// outputs the template whatever the pose.
    pub fn basis_input_dead_pct(&self) -> f64 {
        self.layers
            .iter()
            .rev()
            .find(|l| l.name.starts_with("decoder."))
            .map(LayerActivity::dead_pct)
            .unwrap_or(0.0)
    }

    /// One line per layer, for logs.
    pub fn summary(&self) -> String {
        self.layers
            .iter()
            .map(|l| format!("{} {}/{}", l.name, l.dead, l.units))
            .collect::<Vec<_>>()
            .join(", ")
    }
}

/// Per unit of `x` (`[.., units]`), the largest value over every leading index.
fn unit_max<const D: usize>(x: &Tensor<D>) -> Result<Vec<f32>, ModelError> {
    let dims = x.dims();
    let units = dims[D - 1];
    let rows = dims[..D - 1].iter().product::<usize>().max(1);
    x.clone()
        .detach()
        .reshape([rows, units])
        .max_dim(0)
        .try_into_vec_as::<f32>()
        .map_err(|e| ModelError::TensorRead {
            what: "activations".into(),
            reason: e.to_string(),
        })
}

/// Counts the units of `x` (`[.., units]`) that are zero for every leading index.
fn dead_units<const D: usize>(x: &Tensor<D>) -> Result<(usize, usize), ModelError> {
    let max = unit_max(x)?;
    Ok((max.iter().filter(|v| **v <= 0.0).count(), max.len()))
}

/// Applies `mlp` to `x` and records each layer's activity under `prefix.k`.
fn probe_mlp<const D: usize>(
    mlp: &Mlp,
    mut x: Tensor<D>,
    prefix: &str,
    on_static_path: bool,
    revivable_last: bool,
    out: &mut Vec<LayerActivity>,
) -> Result<Tensor<D>, ModelError> {
    let n = mlp.layers.len();
    for (k, layer) in mlp.layers.iter().enumerate() {
        x = relu(layer.forward(x));
        let (dead, units) = dead_units(&x)?;
        out.push(LayerActivity {
            name: format!("{prefix}.{k}"),
            units,
            dead,
            on_static_path,
            revivable: on_static_path && (k + 1 < n || revivable_last),
        });
    }
    Ok(x)
}

/// Activity of every ReLU layer of `net` on descriptors `[B, T, J, 9]` and `[B, T, J, 12]`
/// (dynamic optional), at `w = 1`.
pub fn unit_activity(
    net: &ClothNet,
    static_desc: Tensor<4>,
    dynamic_desc: Option<Tensor<4>>,
) -> Result<Activity, ModelError> {
    let static_desc = static_desc.detach();
    let dynamic_desc = dynamic_desc.map(|d| d.detach());
    let mut layers = Vec::new();
    let [b, t, j, c] = static_desc.dims();
    if let Some(enc) = &net.static_encoder {
        let flat = static_desc.clone().reshape([b, t, j * c]);
        probe_mlp(enc, flat, "static", true, false, &mut layers)?;
    }
    if let (Some(enc), Some(d)) = (&net.dynamic_encoder, &dynamic_desc) {
        let x = probe_mlp(
            &enc.joint_mlp,
            d.clone(),
            "dynamic.joint",
            false,
            false,
            &mut layers,
        )?;
        let [b, t, j, c] = x.dims();
        probe_mlp(
            &enc.mlp,
            x.reshape([b, t, j * c]),
            "dynamic.fc",
            false,
            false,
            &mut layers,
        )?;
    }
    let z = net.latent_code(static_desc, dynamic_desc, 1.0).detach();
    probe_mlp(&net.decoder.mlp, z, "decoder", true, true, &mut layers)?;
    Ok(Activity { layers })
}

/// Which units of `x` (`[N, units]`, ReLU outputs) are zero on every row.
fn dead_mask(x: &Tensor<2>) -> Result<Vec<bool>, ModelError> {
    Ok(unit_max(x)?.iter().map(|v| *v <= 0.0).collect())
}

/// Replaces the columns of `layer` (its units) marked in `mask` by fresh `N(0, std²)`
/// weights and a zero bias; parameter ids (and so the optimiser's state) are kept.
fn reinit_incoming(layer: &mut Linear, mask: &[bool], std: f64) {
    let weight = layer.weight.clone().map(|w| {
        let w = w.detach();
        let [d_in, d_out] = w.dims();
        let device = w.device();
        let keep = column_mask(mask, d_in, &device);
        let fresh = Tensor::<2>::random([d_in, d_out], Distribution::Normal(0.0, std), &device);
        leaf(w * keep.clone() + fresh * keep.neg().add_scalar(1.0))
    });
    layer.weight = weight;
    layer.bias = layer.bias.clone().map(|bias| {
        bias.map(|b| {
            let b = b.detach();
            let [d_out] = b.dims();
            let keep = column_mask(mask, 1, &b.device()).reshape([d_out]);
            leaf(b * keep)
        })
    });
}

/// Zeroes the rows of `layer`'s weight (its inputs) marked in `mask`.
fn zero_outgoing(layer: &mut Linear, mask: &[bool]) {
    layer.weight = layer.weight.clone().map(|w| {
        let w = w.detach();
        let [d_in, d_out] = w.dims();
        let keep = Tensor::<2>::from_data(
            TensorData::new(
                mask.iter()
                    .map(|dead| if *dead { 0.0f32 } else { 1.0 })
                    .collect::<Vec<_>>(),
                [d_in, 1],
            ),
            &w.device(),
        )
        .repeat_dim(1, d_out);
        leaf(w * keep)
    });
}

/// `x` as a fresh leaf tensor (a parameter value) on its device.
fn leaf<const D: usize>(x: Tensor<D>) -> Tensor<D> {
    let device = x.device();
    let t = Tensor::from_data(x.into_data(), &device);
    if device.is_autodiff() {
        t.require_grad()
    } else {
        t
    }
}

/// `[rows, units]` of ones with zero columns where `mask` is true.
fn column_mask(mask: &[bool], rows: usize, device: &burn::tensor::Device) -> Tensor<2> {
    let units = mask.len();
    Tensor::<2>::from_data(
        TensorData::new(
            mask.iter()
                .map(|dead| if *dead { 0.0f32 } else { 1.0 })
                .collect::<Vec<_>>(),
            [1, units],
        ),
        device,
    )
    .repeat_dim(0, rows)
}

/// Re-initialises every dead unit of the static encoder's hidden layers (dead over the flat
/// static descriptors `statics`, `[N, J * 9]`) and of the decoder MLP (dead over the codes
/// `z`, `[N, latent]`) with fresh incoming weights (`N(0, std²)`, zero bias) and zero outgoing
/// weights (the next layer's, or the basis rows for the last decoder layer). The output of the
/// network on any input is unchanged by the repair; the revived units get gradients again.
/// The static latent layer is left alone: its outgoing weights also carry `z_D`. Returns the
/// number of units revived per layer, static encoder first.
pub fn revive_dead_units(
    net: &mut ClothNet,
    statics: Tensor<2>,
    z: Tensor<2>,
    std: f64,
) -> Result<Vec<usize>, ModelError> {
    let mut revived = Vec::new();
    if let Some(enc) = net.static_encoder.as_mut() {
        revived.extend(revive_mlp(&mut enc.layers, None, statics, std)?);
    }
    let decoder = &mut net.decoder;
    revived.extend(revive_mlp(
        &mut decoder.mlp.layers,
        Some(&mut decoder.basis),
        z,
        std,
    )?);
    Ok(revived)
}

/// Revives the dead units of `layers` on the inputs `x`; the last layer's units are revived
/// only when `after` (the layer they feed) is given.
fn revive_mlp(
    layers: &mut [Linear],
    mut after: Option<&mut Linear>,
    x: Tensor<2>,
    std: f64,
) -> Result<Vec<usize>, ModelError> {
    let mut revived = Vec::new();
    let mut x = x.detach();
    let n = layers.len();
    for k in 0..n {
        let h = relu(layers[k].forward(x.clone()));
        let mut mask = dead_mask(&h)?;
        if k + 1 == n && after.is_none() {
            mask.fill(false);
        }
        let count = mask.iter().filter(|d| **d).count();
        revived.push(count);
        if count > 0 {
            reinit_incoming(&mut layers[k], &mask, std);
            match (layers.get_mut(k + 1), after.as_deref_mut()) {
                (Some(next), _) => zero_outgoing(next, &mask),
                (None, Some(next)) => zero_outgoing(next, &mask),
                (None, None) => {}
            }
        }
        x = relu(layers[k].forward(x)).detach();
    }
    Ok(revived)
}

/// Data-dependent initialisation: sets the bias of every layer of the static encoder and of
/// the decoder MLP so that each unit's pre-activation has zero mean over the probe
/// descriptors (`[B, T, J, 9]`, `[B, T, J, 12]`). With zero biases and inputs that are far
/// from centred (static descriptors vary little around their mean, ReLU outputs are all
/// positive), about half of every layer is dead for *every* pose from the first step (measured:
/// 31 of 64 units of the first static layer, 294 of 512 of the fourth on the skirt scene);
/// centred, each unit is active on about half of the poses. The network's function changes,
/// so call it before training (and before a warm start of the basis bias).
pub fn centre_biases(
    net: &mut ClothNet,
    static_desc: Tensor<4>,
    dynamic_desc: Option<Tensor<4>>,
) -> Result<(), ModelError> {
    let static_desc = static_desc.detach();
    let dynamic_desc = dynamic_desc.map(|d| d.detach());
    let [b, t, j, c] = static_desc.dims();
    if let Some(enc) = net.static_encoder.as_mut() {
        centre_mlp(enc, static_desc.clone().reshape([b * t, j * c]))?;
    }
    let z = net.latent_code(static_desc, dynamic_desc, 1.0).detach();
    let latent = z.dims()[2];
    centre_mlp(&mut net.decoder.mlp, z.reshape([b * t, latent]))
}

/// Centres the pre-activations of each layer of `mlp` on the rows of `x` (`[N, d_in]`).
fn centre_mlp(mlp: &mut Mlp, mut x: Tensor<2>) -> Result<(), ModelError> {
    for layer in &mut mlp.layers {
        let Some(bias) = layer.bias.take() else {
            x = relu(layer.forward(x)).detach();
            continue;
        };
        let w = layer.weight.val().detach();
        let mean = x.clone().matmul(w).mean_dim(0);
        let d_out = mean.dims()[1];
        layer.bias = Some(bias.map(|_| leaf(mean.reshape([d_out]).neg())));
        x = relu(layer.forward(x)).detach();
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use burn::module::Param;
    use burn::tensor::Device;

    use super::*;
    use crate::ClothNetConfig;

    fn small(vertices: usize) -> ClothNet {
        ClothNetConfig {
            static_hidden: vec![8],
            joint_hidden: vec![4],
            dynamic_hidden: vec![6],
            latent: 6,
            decoder_hidden: vec![10, 12],
            init_std: 0.3,
            ..Default::default()
        }
        .init(3, vertices, &Device::flex())
        .unwrap()
    }

    fn descriptors(device: &Device) -> (Tensor<4>, Tensor<4>) {
        let s = Tensor::<4>::random([4, 5, 3, 9], Distribution::Normal(0.0, 1.0), device);
        let d = Tensor::<4>::random([4, 5, 3, 12], Distribution::Normal(0.0, 1.0), device);
        (s, d)
    }

    /// Sets every bias of the last decoder layer to -1e3: all its units die.
    fn kill_decoder(net: &mut ClothNet) {
        let last = net.decoder.mlp.layers.last_mut().unwrap();
        let b = last.bias.as_ref().unwrap().val();
        last.bias = Some(Param::from_tensor(b.zeros_like().add_scalar(-1e3)));
    }

    #[test]
    fn network_with_all_decoder_units_dead_is_detected() {
        let device = Device::flex();
        let mut net = small(5);
        let (s, d) = descriptors(&device);
        let alive = unit_activity(&net, s.clone(), Some(d.clone())).unwrap();
        assert!(alive.basis_input_dead_pct() < 100.0, "{}", alive.summary());
        kill_decoder(&mut net);
        let dead = unit_activity(&net, s.clone(), Some(d.clone())).unwrap();
        assert_eq!(dead.basis_input_dead_pct(), 100.0, "{}", dead.summary());
        assert_eq!(dead.worst_static_path_pct(), 100.0);
        // Its output is the template: zero offsets whatever the pose.
        let offsets = net.forward(s, Some(d), 1.0);
        let max = offsets.abs().max().into_scalar::<f32>();
        assert_eq!(max, 0.0);
    }

    #[test]
    fn revive_keeps_the_output_and_brings_units_back() {
        let device = Device::flex();
        let mut net = small(5);
        let (s, d) = descriptors(&device);
        // Kill half of the last decoder layer's units.
        let last = net.decoder.mlp.layers.last_mut().unwrap();
        let b = last.bias.as_ref().unwrap().val();
        let half: Vec<f32> = (0..12).map(|i| if i < 6 { -1e3 } else { 0.0 }).collect();
        last.bias = Some(Param::from_tensor(
            b + Tensor::<1>::from_data(TensorData::new(half, [12]), &device),
        ));
        let before = net.forward(s.clone(), Some(d.clone()), 1.0);
        let activity = unit_activity(&net, s.clone(), Some(d.clone())).unwrap();
        assert!(activity.basis_input_dead_pct() >= 50.0);
        let z = net
            .latent_code(s.clone(), Some(d.clone()), 1.0)
            .reshape([20, 6]);
        let statics = s.clone().reshape([20, 27]);
        let revived = revive_dead_units(&mut net, statics, z, 0.3).unwrap();
        // Static encoder (hidden, then the latent: never revived), decoder layers 0 and 1.
        assert_eq!(revived.len(), 4, "{revived:?}");
        assert_eq!(revived[1], 0);
        assert!(revived[3] >= 6, "{revived:?}");
        let after = net.forward(s.clone(), Some(d.clone()), 1.0);
        let diff = (after - before).abs().max().into_scalar::<f32>();
        assert!(diff < 1e-5, "output changed by {diff}");
        let activity = unit_activity(&net, s, Some(d)).unwrap();
        assert!(
            activity.basis_input_dead_pct() < 50.0,
            "{}",
            activity.summary()
        );
    }

    #[test]
    fn centred_biases_leave_no_unit_dead_on_uncentred_inputs() {
        let device = Device::flex();
        let mut net = small(5);
        // Inputs far from centred: a large constant plus a little variation.
        let noise = Tensor::<4>::random([8, 5, 3, 9], Distribution::Normal(0.0, 0.05), &device);
        let s = noise.add_scalar(1.0);
        let before = unit_activity(&net, s.clone(), None).unwrap();
        centre_biases(&mut net, s.clone(), None).unwrap();
        let after = unit_activity(&net, s, None).unwrap();
        assert!(
            after.worst_static_path_pct() < before.worst_static_path_pct()
                || before.worst_static_path_pct() == 0.0,
            "before {} after {}",
            before.summary(),
            after.summary()
        );
        assert!(
            after.worst_static_path_pct() <= 20.0,
            "after centring: {}",
            after.summary()
        );
    }
}
