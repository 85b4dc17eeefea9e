//! Simulated frames of a motion's mirrored copy without simulating it again: when the garment
//! and the body are left/right symmetric, the simulation of the mirrored motion is the mirror
//! image of the motion's own simulation, with each vertex moved to its counterpart, up to the
//! order of floating-point operations (the built-in garments and bodies are symmetric by
//! construction; asymmetric scenes are detected here and simulated instead).
//!
//! Used by the experimental [`crate::TrainConfig::warm_start_mirror_frames`]
//! (docs/TRAINING.md round 23): the warm start's mirrored copies, which otherwise have no
//! frames, fitted to the mirror images. Measured worse than leaving them without frames (the
//! t-shirt's spin alone: 26.8 mm from the simulator against 17.8), hence off by default. On
//! that spin the mirror image parts from a simulation of the mirrored spin by 9.9 mm on
//! average (0.0 mm at the start, up to 26 mm while the shirt whirls): the spin's sensitivity
//! to a micrometre (round 21: 4.7 mm), not an error of either.

use std::collections::HashSet;

use neural_cloth_core::geometry::{KdTree, TriMesh, Vec3};
use neural_cloth_core::scene::{Avatar, Garment, Motion};

/// Largest distance, in metres, from a rest-pose vertex's mirror image to its counterpart.
const REST_TOLERANCE_M: f32 = 1e-4;
/// Largest distance, in metres, between a posed vertex of the mirrored motion and the mirror
/// image of its counterpart posed by the motion itself (checked on a few frames).
const POSED_TOLERANCE_M: f32 = 5e-4;

/// The mirror image across the world YZ plane (the plane [`Motion::mirrored`] reflects in).
fn reflect(p: &Vec3) -> Vec3 {
    Vec3::new(-p.x, p.y, p.z)
}

/// A garment's vertex correspondence under the left/right mirror, valid for one scene.
#[derive(Clone, Debug, PartialEq)]
pub struct MirrorMap {
    /// For each garment vertex, the vertex at its mirror image.
    garment: Vec<u32>,
}

impl MirrorMap {
    /// The correspondence when the scene's simulation of `mirrored` (the mirrored copy of
    /// `motion`) is the mirror image of the simulation of `motion`: the garment and the body
    /// are symmetric at rest (vertices and faces), the pinned and collision-exempt vertices
    /// are too, and the skinned garment and posed body of `mirrored` are the mirror images of
    /// those of `motion` on its first, middle and last frames. `Err` says which is not.
    pub fn for_scene(
        avatar: &Avatar,
        garment: &Garment,
        motion: &Motion,
        mirrored: &Motion,
    ) -> Result<Self, String> {
        let garment_map = symmetric_mesh(&garment.mesh).ok_or("the garment is not symmetric")?;
        let body_map = symmetric_mesh(&avatar.rest_mesh).ok_or("the body is not symmetric")?;
        for (what, set) in [
            ("pinned", &garment.pinned),
            ("collision-exempt", &garment.no_collide),
        ] {
            let members: HashSet<u32> = set.iter().copied().collect();
            if !set.iter().all(|v| {
                garment_map
                    .get(*v as usize)
                    .is_some_and(|m| members.contains(m))
            }) {
                return Err(format!("the {what} vertices are not symmetric"));
            }
        }
        let frames = motion.frames.len().min(mirrored.frames.len());
        if frames == 0 {
            return Err("the motion has no frames".into());
        }
        for f in [0, frames / 2, frames - 1] {
            let (pose, image) = (&motion.frames[f], &mirrored.frames[f]);
            let worn = garment.pose_vertices(avatar, pose);
            let worn_image = garment.pose_vertices(avatar, image);
            if !mirror_images(&worn, &worn_image, &garment_map, POSED_TOLERANCE_M) {
                return Err(format!("the skinned garment does not mirror at frame {f}"));
            }
            let body = avatar.pose_vertices(pose);
            let body_image = avatar.pose_vertices(image);
            if !mirror_images(&body, &body_image, &body_map, POSED_TOLERANCE_M) {
                return Err(format!("the posed body does not mirror at frame {f}"));
            }
        }
        Ok(Self {
            garment: garment_map,
        })
    }

    /// The mirrored copy's frames from `frames`: each vertex's mirror image moved to its
    /// counterpart.
    pub fn reflect_frames(&self, frames: &[Vec<Vec3>]) -> Vec<Vec<Vec3>> {
        frames
            .iter()
            .map(|frame| {
                let mut out = vec![Vec3::zeros(); frame.len()];
                for (p, m) in frame.iter().zip(&self.garment) {
                    if let Some(o) = out.get_mut(*m as usize) {
                        *o = reflect(p);
                    }
                }
                out
            })
            .collect()
    }
}

/// For each vertex of `mesh`, the vertex within [`REST_TOLERANCE_M`] of its mirror image, when
/// every vertex has one, the correspondence is its own inverse and it maps faces onto faces.
fn symmetric_mesh(mesh: &TriMesh) -> Option<Vec<u32>> {
    let tree = KdTree::new(&mesh.positions);
    let tolerance_sq = REST_TOLERANCE_M * REST_TOLERANCE_M;
    let map: Vec<u32> = mesh
        .positions
        .iter()
        .map(|p| {
            tree.nearest(&reflect(p))
                .filter(|(_, d2)| *d2 <= tolerance_sq)
                .map(|(i, _)| i)
        })
        .collect::<Option<_>>()?;
    let involution = map
        .iter()
        .enumerate()
        .all(|(i, m)| map.get(*m as usize) == Some(&(i as u32)));
    let sorted = |f: [u32; 3]| {
        let mut f = f;
        f.sort_unstable();
        f
    };
    let faces: HashSet<[u32; 3]> = mesh.faces.iter().map(|f| sorted(*f)).collect();
    let faces_map = mesh.faces.iter().all(|f| {
        faces.contains(&sorted([
            map[f[0] as usize],
            map[f[1] as usize],
            map[f[2] as usize],
        ]))
    });
    (involution && faces_map).then_some(map)
}

/// True when `image[map[i]]` is within `tolerance` of the mirror image of `points[i]`, for all i.
fn mirror_images(points: &[Vec3], image: &[Vec3], map: &[u32], tolerance: f32) -> bool {
    points.len() == image.len()
        && points.iter().zip(map).all(|(p, m)| {
            image
                .get(*m as usize)
                .is_some_and(|q| (reflect(p) - q).norm() <= tolerance)
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A strip of two quads across x = 0 (vertices at x = -1, 0, 1), both split along the
    /// same diagonal direction.
    fn strip(shift_x: f32) -> TriMesh {
        let positions = [-1.0, 0.0, 1.0]
            .iter()
            .flat_map(|x| {
                [
                    Vec3::new(x + shift_x, 0.0, 0.0),
                    Vec3::new(x + shift_x, 1.0, 0.0),
                ]
            })
            .collect();
        TriMesh {
            positions,
            faces: vec![[0, 2, 3], [0, 3, 1], [2, 4, 5], [2, 5, 3]],
            uvs: None,
        }
    }

    #[test]
    fn a_symmetric_mesh_maps_each_vertex_to_its_mirror_image() {
        let mut mesh = strip(0.0);
        mesh.faces = vec![[0, 2, 3], [0, 3, 1], [4, 5, 3], [4, 3, 2]];
        assert_eq!(symmetric_mesh(&mesh), Some(vec![4, 5, 2, 3, 0, 1]));
    }

    #[test]
    fn a_shifted_mesh_or_unmirrored_triangulation_is_not_symmetric() {
        assert_eq!(symmetric_mesh(&strip(0.01)), None);
        // Both quads split along the same diagonal direction: the vertices mirror, the
        // faces do not (and the simulation of the mirror would differ).
        assert_eq!(symmetric_mesh(&strip(0.0)), None);
    }

    #[test]
    fn reflected_frames_move_each_vertex_to_its_counterpart() {
        let map = MirrorMap {
            garment: vec![1, 0, 2],
        };
        let frame = vec![
            Vec3::new(-1.0, 2.0, 3.0),
            Vec3::new(1.5, 2.0, 3.0),
            Vec3::new(0.25, 0.0, 1.0),
        ];
        let out = map.reflect_frames(&[frame]);
        assert_eq!(
            out[0],
            vec![
                Vec3::new(-1.5, 2.0, 3.0),
                Vec3::new(1.0, 2.0, 3.0),
                Vec3::new(-0.25, 0.0, 1.0)
            ]
        );
    }
}
