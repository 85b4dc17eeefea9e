//! Writing a motion as BVH text: the skeleton's rest offsets (its rest pose is the BVH's
//! zero-rotation pose), a root with six channels and three rotation channels per joint
//! (`Zrotation Yrotation Xrotation`), under any joint names. Used to hand motions to other
//! tools and to make retargeting fixtures in each rig's naming convention.

use std::fmt::Write as _;
use std::path::Path;

use super::IoError;
use crate::geometry::Mat4;
use crate::scene::{Motion, Skeleton};

/// The BVH text of `motion` on `skeleton`, joints named `names` (one per skeleton joint),
/// lengths multiplied by `units_per_metre` (100 for centimetres). The skeleton must have one
/// root (joint 0) hanging from the identity, and identity rest rotations with unit scales (a
/// BVH rest pose has every rotation at zero). `path` only names the output in errors.
pub fn bvh_text(
    skeleton: &Skeleton,
    motion: &Motion,
    names: &[String],
    units_per_metre: f32,
    path: &Path,
) -> Result<String, IoError> {
    let fail = |what: String| IoError::Unsupported {
        what,
        path: path.to_path_buf(),
    };
    let n = skeleton.len();
    if names.len() != n {
        return Err(fail(format!("{} names for {n} joints", names.len())));
    }
    if let Some(bad) = names
        .iter()
        .find(|s| s.is_empty() || s.chars().any(char::is_whitespace))
    {
        return Err(fail(format!(
            "BVH joint name '{bad}' (empty or with spaces)"
        )));
    }
    if skeleton.parents.iter().skip(1).any(Option::is_none)
        || (skeleton.world_from_root_parent[0] - Mat4::identity())
            .abs()
            .max()
            > 1e-6
    {
        return Err(fail("BVH needs one root joint in an identity space".into()));
    }
    let identity_rest = skeleton.rest_local.iter().all(|t| {
        t.rotation.angle() < 1e-6 && (t.scale - crate::geometry::Vec3::repeat(1.0)).norm() < 1e-6
    });
    if !identity_rest {
        return Err(fail(
            "BVH needs identity rest rotations and unit scales".into(),
        ));
    }
    if !(units_per_metre.is_finite() && units_per_metre > 0.0) {
        return Err(fail(format!("unit factor {units_per_metre}")));
    }
    let children = skeleton.children();
    let mut out = String::from("HIERARCHY\n");
    let mut order = Vec::with_capacity(n);
    write_joint(
        &mut out,
        skeleton,
        &children,
        names,
        units_per_metre,
        0,
        0,
        &mut order,
    );
    let _ = write!(
        out,
        "MOTION\nFrames: {}\nFrame Time: {:.8}\n",
        motion.frame_count(),
        1.0 / motion.fps
    );
    for pose in &motion.frames {
        let t = pose.root_translation * units_per_metre;
        let mut line = format!("{:.6} {:.6} {:.6}", t.x, t.y, t.z);
        for &j in &order {
            let q = pose
                .rotations
                .get(j)
                .copied()
                .unwrap_or_else(crate::geometry::Quat::identity);
            let (roll, pitch, yaw) = q.euler_angles();
            let _ = write!(
                line,
                " {:.6} {:.6} {:.6}",
                yaw.to_degrees(),
                pitch.to_degrees(),
                roll.to_degrees()
            );
        }
        out.push_str(&line);
        out.push('\n');
    }
    Ok(out)
}

/// Writes joint `j` and its subtree; `order` collects joints in file order.
#[allow(clippy::too_many_arguments)]
fn write_joint(
    out: &mut String,
    skeleton: &Skeleton,
    children: &[Vec<usize>],
    names: &[String],
    scale: f32,
    j: usize,
    depth: usize,
    order: &mut Vec<usize>,
) {
    let pad = "  ".repeat(depth);
    let o = skeleton.rest_local[j].translation * scale;
    let (keyword, channels) = if j == 0 {
        (
            "ROOT",
            "CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation",
        )
    } else {
        ("JOINT", "CHANNELS 3 Zrotation Yrotation Xrotation")
    };
    let _ = writeln!(out, "{pad}{keyword} {}", names[j]);
    let _ = writeln!(out, "{pad}{{");
    let _ = writeln!(out, "{pad}  OFFSET {:.6} {:.6} {:.6}", o.x, o.y, o.z);
    let _ = writeln!(out, "{pad}  {channels}");
    order.push(j);
    if children[j].is_empty() {
        let _ = writeln!(
            out,
            "{pad}  End Site\n{pad}  {{\n{pad}    OFFSET 0 0 0\n{pad}  }}"
        );
    }
    for &c in &children[j] {
        write_joint(out, skeleton, children, names, scale, c, depth + 1, order);
    }
    let _ = writeln!(out, "{pad}}}");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::Bvh;
    use crate::scene::procedural::{MotionKind, mannequin, motion};

    #[test]
    fn written_bvh_reads_back_as_the_same_motion() {
        let avatar = mannequin().unwrap();
        let sk = &avatar.skeleton;
        let m = motion(MotionKind::Run, 30.0, 1.0).unwrap();
        let names: Vec<String> = sk.names.iter().map(|n| format!("x_{n}")).collect();
        let text = bvh_text(sk, &m, &names, 100.0, Path::new("run.bvh")).unwrap();
        let bvh = Bvh::parse(text.as_bytes(), Path::new("run.bvh")).unwrap();
        assert_eq!(bvh.frame_count(), m.frame_count());
        assert!((bvh.fps() - 30.0).abs() < 1e-3);
        for f in [0, 7, m.frame_count() - 1] {
            let want = sk.joint_positions(&m.frames[f]);
            let got = bvh.world(f);
            for (j, name) in names.iter().enumerate() {
                let b = bvh.joints.iter().position(|x| &x.name == name).unwrap();
                let d = (got[b].1 * 0.01 - want[j]).norm();
                assert!(d < 1e-4, "frame {f} joint {name}: {d} m");
            }
        }
        let mut bad = sk.clone();
        bad.rest_local[3].rotation = crate::geometry::Quat::from_euler_angles(0.1, 0.0, 0.0);
        let err = bvh_text(&bad, &m, &names, 100.0, Path::new("run.bvh")).unwrap_err();
        assert!(err.to_string().ends_with("run.bvh"), "{err}");
    }
}
