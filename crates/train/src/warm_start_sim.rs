//! The dynamic warm start ([`TrainConfig::warm_start_steps`]): our own simulator's frames of
//! every training motion, simulated once before the first step and fitted for the run's first
//! steps, alongside the paper's loss.
//!
//! Why (docs/TRAINING.md rounds 21 and 22): on a motion whose simulation does not fork, the
//! paper's loss holds a network that starts near the simulator's dynamics there (the t-shirt
//! on the spin: 5.0 mm from the simulator after 800 steps of the paper's loss alone, as close
//! as the simulator is to itself), but from the template it settles on a damped solution that
//! is a resting point of the same loss (27.7 mm). A short fit (150 steps) is enough to put
//! the descent in the swinging basin. The simulations are cached in the run's `reference/`
//! folder under the key `compare` uses, so that checking the run against the simulator reads
//! them again instead of simulating. With [`TrainConfig::warm_start_mirror_frames`]
//! (experimental, round 23) the mirrored copies of the motions get frames too: reflected when
//! the scene is symmetric ([`crate::warm_start_mirror`]), else simulated.

use std::path::Path;
use std::time::Instant;

use neural_cloth_core::geometry::Vec3;
use neural_cloth_core::scene::{Motion, Split};
use neural_cloth_model::ModelError;

use super::compare::{CompareOptions, ComparePhase, SimulatedScene, simulation_in};
use super::data::Dataset;
use super::fit_reference::FitReference;
use super::handle::{PrepareProgress, Preparing};
use super::warm_start_mirror::MirrorMap;
use super::{TrainConfig, TrainError};

/// The warm start's reference and what it cost.
pub struct WarmStart {
    /// Simulated frames per motion of the training dataset (its mirrored copies included with
    /// [`TrainConfig::warm_start_mirror_frames`], else none for them).
    pub reference: FitReference,
    /// Motions simulated now (the others were read from the run's cache or reflected).
    pub simulated: usize,
    /// Motions read from the cache.
    pub cached: usize,
    /// Mirrored copies whose frames are the reflection of their motion's simulation.
    pub reflected: usize,
    /// Why mirrored copies were simulated rather than reflected, when they were.
    pub not_reflected: Option<String>,
    /// Seconds spent simulating now.
    pub simulate_secs: f64,
}

/// Simulates (or reads from `run_root/reference/`) every train-split motion of `motions` at
/// `fps` with [`TrainConfig::warm_start_iterations`], and lines the frames up with the
/// motions of `dataset` (the training dataset built from the same motions: each motion
/// followed by its mirrored copy when [`TrainConfig::mirror_poses`]: without frames, or with
/// [`TrainConfig::warm_start_mirror_frames`] the reflection of the motion's when the scene is
/// symmetric, else simulated too).
pub fn warm_start_reference(
    scene: SimulatedScene<'_>,
    run_root: &Path,
    motions: &[(Motion, Split)],
    dataset: &Dataset,
    fps: f32,
    config: &TrainConfig,
    progress: PrepareProgress<'_>,
) -> Result<WarmStart, TrainError> {
    let options = CompareOptions {
        iterations: config.warm_start_iterations,
        ..CompareOptions::default()
    };
    let mut training: Vec<Motion> = Vec::new();
    for (motion, _) in motions.iter().filter(|(_, split)| *split == Split::Train) {
        training.push(motion.resample(fps).map_err(ModelError::from)?);
    }
    let started = Instant::now();
    let (mut simulated, mut cached, mut reflected) = (0, 0, 0);
    let mut not_reflected = None;
    let mut frames: Vec<(String, Vec<Vec<Vec3>>)> = Vec::with_capacity(2 * training.len());
    let mut simulate = |motion: &Motion, label: String| {
        let stage = format!(
            "simulating {} for the warm start ({label}, {} iterations per frame)",
            motion.name, options.iterations
        );
        let mut say = |_: ComparePhase, done: usize, total: usize| {
            progress(Preparing {
                stage: stage.clone(),
                done,
                total,
            })
        };
        let (sim, _, was_cached) = simulation_in(scene, run_root, motion, &options, &mut say)?;
        match was_cached {
            true => cached += 1,
            false => simulated += 1,
        }
        Ok::<_, TrainError>(sim)
    };
    let count = training.len();
    for (index, motion) in training.iter().enumerate() {
        let label = format!("{} of {count}", index + 1);
        let sim = simulate(motion, label.clone())?;
        let mut copy = None;
        if config.mirror_poses && config.warm_start_mirror_frames {
            let mirrored = motion.mirrored(&scene.avatar.skeleton);
            let copy_frames =
                match MirrorMap::for_scene(scene.avatar, scene.garment, motion, &mirrored) {
                    Ok(map) => {
                        reflected += 1;
                        map.reflect_frames(&sim)
                    }
                    Err(why) => {
                        not_reflected = Some(why);
                        simulate(&mirrored, format!("{label}, mirrored copy"))?
                    }
                };
            copy = Some((mirrored.name, copy_frames));
        }
        frames.push((motion.name.clone(), sim));
        frames.extend(copy);
    }
    let reference = FitReference::from_frames(
        line_up(&dataset_names(dataset), frames),
        scene.garment.vertex_count(),
    )?;
    Ok(WarmStart {
        reference,
        simulated,
        cached,
        reflected,
        not_reflected,
        simulate_secs: match simulated > 0 {
            true => started.elapsed().as_secs_f64(),
            false => 0.0,
        },
    })
}

/// The names of `dataset`'s motions, in order.
fn dataset_names(dataset: &Dataset) -> Vec<&str> {
    dataset.motions.iter().map(|m| m.name.as_str()).collect()
}

/// Per name of `names` (the dataset's motions: each training motion, then perhaps its
/// mirrored copy), the next simulated motion's frames when it has that name, else None (a
/// dataset built with other motions than the ones simulated).
fn line_up<T>(names: &[&str], simulated: Vec<(String, T)>) -> Vec<Option<T>> {
    let mut next = simulated.into_iter().peekable();
    names
        .iter()
        .map(|name| match next.peek() {
            Some((sim_name, _)) if sim_name == name => next.next().map(|(_, f)| f),
            _ => None,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn simulated_motions_line_up_with_the_dataset_and_mirrors_get_none() {
        let sims = vec![("walk".to_string(), 1), ("walk".to_string(), 2)];
        // Two motions of the same name, each followed by its mirrored copy.
        let names = ["walk", "walk (mirrored)", "walk", "walk (mirrored)"];
        assert_eq!(line_up(&names, sims), vec![Some(1), None, Some(2), None]);
        let sims = vec![("idle".to_string(), 1), ("spin".to_string(), 2)];
        assert_eq!(line_up(&["idle", "spin"], sims), vec![Some(1), Some(2)]);
    }
}
