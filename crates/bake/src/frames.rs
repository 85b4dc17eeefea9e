//! Frame sources for baking: the neural model's inference engine or the reference simulator,
//! stepped at their own rate along a motion and resampled to the output rate.

use std::sync::Arc;

use neural_cloth_core::geometry::{Mat4, Vec3};
use neural_cloth_core::scene::{Avatar, Garment, Motion, Pose};
use neural_cloth_model::InferenceEngine;
use neural_cloth_physics::PosedBody;
use neural_cloth_physics::simulator::{StepInput, Stepper};

use super::BakeError;

/// Something that turns poses into garment frames, one native time step at a time.
pub trait FrameSource {
    /// The rate this source must be stepped at, in frames per second.
    fn native_fps(&self) -> f32;
    /// Forgets all state (start of a sequence).
    fn reset(&mut self);
    /// Advances one native step to `pose`.
    fn step(&mut self, pose: &Pose, w: f32) -> Result<(), BakeError>;
    /// Posed garment of the last step.
    fn garment(&self) -> Vec<Vec3>;
    /// Rest-space garment (template + offsets) of the last step.
    fn rest(&self) -> Vec<Vec3>;
}

/// The trained network through the fast inference engine, stepped at the engine's own rate
/// (the model's training rate, [`InferenceEngine::fps`]).
pub struct ModelSource {
    engine: InferenceEngine,
}

impl ModelSource {
    /// Wraps an engine (built from a [`neural_cloth_model::ModelArtifact`], at its training rate).
    pub fn new(engine: InferenceEngine) -> Self {
        Self { engine }
    }
}

impl FrameSource for ModelSource {
    fn native_fps(&self) -> f32 {
        self.engine.fps()
    }

    fn reset(&mut self) {
        self.engine.reset();
    }

    fn step(&mut self, pose: &Pose, w: f32) -> Result<(), BakeError> {
        self.engine
            .step(pose, w)
            .map_err(|e| BakeError::Source(e.to_string()))
    }

    fn garment(&self) -> Vec<Vec3> {
        self.engine.garment_positions().to_vec()
    }

    fn rest(&self) -> Vec<Vec3> {
        self.engine
            .rest_positions()
            .chunks_exact(3)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect()
    }
}

/// The reference simulator (paper Eq. 8) stepping the garment against the moving body.
pub struct SimulatorSource<'a> {
    stepper: Stepper,
    avatar: &'a Avatar,
    garment: &'a Garment,
    fps: f32,
    positions: Vec<Vec3>,
    pose: Option<Pose>,
    collision: bool,
}

impl<'a> SimulatorSource<'a> {
    /// Wraps a stepper whose time step is `1 / fps`.
    pub fn new(
        stepper: Stepper,
        avatar: &'a Avatar,
        garment: &'a Garment,
        fps: f32,
        collision: bool,
    ) -> Self {
        let positions = stepper.positions();
        Self {
            stepper,
            avatar,
            garment,
            fps,
            positions,
            pose: None,
            collision,
        }
    }
}

impl FrameSource for SimulatorSource<'_> {
    fn native_fps(&self) -> f32 {
        self.fps
    }

    fn reset(&mut self) {}

    fn step(&mut self, pose: &Pose, _w: f32) -> Result<(), BakeError> {
        let body = match self.collision {
            true => Some(Arc::new(
                PosedBody::from_avatar(self.avatar, pose)
                    .map_err(|e| BakeError::Source(e.to_string()))?,
            )),
            false => None,
        };
        let quasi_static = !self.stepper.terms().effects().dynamics;
        let skinned = (quasi_static || !self.garment.pinned.is_empty())
            .then(|| self.garment.pose_vertices(self.avatar, pose));
        let pin_targets = if self.garment.pinned.is_empty() {
            None
        } else {
            skinned.clone()
        };
        let (x, _) = self
            .stepper
            .step(&StepInput {
                body,
                pin_targets,
                skinned: if quasi_static { skinned } else { None },
                body_before: None,
            })
            .map_err(|e| BakeError::Source(e.to_string()))?;
        self.positions = x;
        self.pose = Some(pose.clone());
        Ok(())
    }

    fn garment(&self) -> Vec<Vec3> {
        self.positions.clone()
    }

    fn rest(&self) -> Vec<Vec3> {
        let Some(pose) = &self.pose else {
            return self.garment.mesh.positions.clone();
        };
        unskin(self.avatar, self.garment, pose, &self.positions)
    }
}

/// Inverse linear blend skinning: the rest-space positions that `pose` skins onto `posed`.
/// Vertices whose blended matrix is singular keep their template position.
pub fn unskin(avatar: &Avatar, garment: &Garment, pose: &Pose, posed: &[Vec3]) -> Vec<Vec3> {
    let sk = &avatar.skeleton;
    let rest = sk.world_from_joint(&sk.rest_pose());
    let mats: Vec<Mat4> = sk
        .world_from_joint(pose)
        .iter()
        .zip(&rest)
        .map(|(p, r)| p * r.try_inverse().unwrap_or_else(Mat4::identity))
        .collect();
    posed
        .iter()
        .enumerate()
        .map(|(v, x)| {
            let mut m = Mat4::zeros();
            for k in 0..4 {
                let w = garment.skin.weights[v][k];
                if w != 0.0
                    && let Some(j) = mats.get(garment.skin.joints[v][k] as usize)
                {
                    m += j * w;
                }
            }
            m.try_inverse()
                .map(|inv| inv.transform_point(&nalgebra::Point3::from(*x)).coords)
                .unwrap_or(garment.mesh.positions[v])
        })
        .collect()
}

/// One output frame.
pub struct Frame {
    /// Posed garment.
    pub garment: Vec<Vec3>,
    /// Rest-space garment.
    pub rest: Vec<Vec3>,
}

/// Steps a source along a motion at its native rate and interpolates output times.
pub struct Resampler<'a> {
    motion: &'a Motion,
    source: &'a mut dyn FrameSource,
    w: f32,
    /// Native step index of `current`.
    index: usize,
    previous: Option<Frame>,
    current: Option<Frame>,
}

impl<'a> Resampler<'a> {
    /// Starts at the beginning of `motion`.
    pub fn new(
        motion: &'a Motion,
        source: &'a mut dyn FrameSource,
        w: f32,
    ) -> Result<Self, BakeError> {
        let fps = source.native_fps();
        if !(fps.is_finite() && fps > 0.0) {
            return Err(BakeError::Invalid(format!(
                "source frame rate {fps} is not positive"
            )));
        }
        source.reset();
        Ok(Self {
            motion,
            source,
            w,
            index: 0,
            previous: None,
            current: None,
        })
    }

    fn advance(&mut self) -> Result<(), BakeError> {
        let next_index = if self.current.is_some() {
            self.index + 1
        } else {
            0
        };
        let pose = self
            .motion
            .sample(next_index as f32 / self.source.native_fps());
        self.source.step(&pose, self.w)?;
        let frame = Frame {
            garment: self.source.garment(),
            rest: self.source.rest(),
        };
        self.previous = self.current.replace(frame);
        self.index = next_index;
        Ok(())
    }

    /// The frame at `time_secs` (non-decreasing across calls).
    pub fn at(&mut self, time_secs: f32) -> Result<Frame, BakeError> {
        let x = time_secs.max(0.0) * self.source.native_fps();
        while self.current.is_none() || (self.index as f32) < x - 1e-4 {
            self.advance()?;
        }
        let (Some(cur), prev) = (&self.current, &self.previous) else {
            return Err(BakeError::Source("no frame".into()));
        };
        let t = (self.index as f32 - x).clamp(0.0, 1.0);
        match prev {
            Some(p) if t > 1e-4 => Ok(Frame {
                garment: cur
                    .garment
                    .iter()
                    .zip(&p.garment)
                    .map(|(c, q)| c.lerp(q, t))
                    .collect(),
                rest: cur
                    .rest
                    .iter()
                    .zip(&p.rest)
                    .map(|(c, q)| c.lerp(q, t))
                    .collect(),
            }),
            _ => Ok(Frame {
                garment: cur.garment.clone(),
                rest: cur.rest.clone(),
            }),
        }
    }
}
