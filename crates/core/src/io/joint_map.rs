//! Mapping an avatar's joints onto a motion's: a user joint map (TOML) first, then the rigs'
//! canonical joints ([`classify`]), then equal names, then, when essential joints are still
//! left over, the skeletons' structure ([`label_by_structure`]); a clear error, with the
//! closest names of the motion, when an essential joint is left over after all that.
//!
//! A joint map file:
//! ```toml
//! [joints]
//! Hips = "root_jnt"        # avatar joint = motion joint
//! LeftArm = "upperarm_L"
//! ```

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::gltf_avatar::short_list;
use super::joint_names::{CORE_JOINTS, classify, closest_names};
use super::joint_structure::{RigShape, label_by_structure};
use super::{IoError, file_stem, read_bytes};

/// A user's joint map: avatar joint names to motion joint names, read from TOML.
#[derive(Clone, Debug, PartialEq)]
pub struct JointMap {
    /// The map file (for messages).
    pub path: PathBuf,
    /// (avatar joint, motion joint) pairs, sorted by avatar joint.
    pub joints: Vec<(String, String)>,
}

#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMap {
    joints: BTreeMap<String, String>,
}

impl JointMap {
    /// Reads a joint map file (`[joints] AvatarJoint = "MotionJoint"`).
    pub fn load(path: &Path) -> Result<Self, IoError> {
        let bytes = read_bytes(path)?;
        let text = String::from_utf8_lossy(&bytes);
        Self::from_toml_str(&text, path)
    }

    /// Parses the text of a joint map file; `path` ends error messages.
    pub fn from_toml_str(text: &str, path: &Path) -> Result<Self, IoError> {
        let raw: RawMap = toml::from_str(text).map_err(|e| IoError::JointMap {
            reason: format!(
                "expected a [joints] table of AvatarJoint = \"MotionJoint\" ({})",
                e.message()
            ),
            path: path.to_path_buf(),
        })?;
        Ok(Self {
            path: path.to_path_buf(),
            joints: raw.joints.into_iter().collect(),
        })
    }
}

/// How an avatar joint found its motion joint.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MatchKind {
    /// Given in the user's joint map.
    UserMap,
    /// Both names mean the same canonical joint in their rigs' conventions.
    Rig,
    /// Same name (ignoring case, separators, namespaces and rig prefixes).
    Name,
    /// Same place in both skeletons' structure (legs, spine, arms), names not recognised.
    Structure,
}

/// For each avatar joint, the motion joint that drives it and how it was found.
#[derive(Clone, Debug, PartialEq)]
pub struct JointMapping {
    /// Per avatar joint: the motion joint, or `None` (it keeps its rest rotation).
    pub source: Vec<Option<usize>>,
    /// Per avatar joint: how its motion joint was found.
    pub how: Vec<Option<MatchKind>>,
    /// Per avatar joint: its canonical (Mixamo) name, when recognised.
    pub canonical: Vec<Option<&'static str>>,
    /// Naming convention recognised in the avatar's joint names.
    pub avatar_convention: &'static str,
    /// Naming convention recognised in the motion's joint names.
    pub motion_convention: &'static str,
    /// Per motion joint: its canonical (Mixamo) name, when recognised.
    pub motion_canonical: Vec<Option<&'static str>>,
    /// What mapping by structure did, when names left essential joints unmapped (see
    /// [`JointMapping::fill_by_structure`]).
    pub structure: Option<String>,
}

/// Finds `name` among `names`: exactly, else ignoring ASCII case.
fn find_name(names: &[String], name: &str) -> Option<usize> {
    names
        .iter()
        .position(|n| n == name)
        .or_else(|| names.iter().position(|n| n.eq_ignore_ascii_case(name)))
}

/// Lower-case alphanumerics after the namespace and `mixamorig`/`Bip01` prefixes.
fn plain_name(name: &str) -> String {
    let n = super::joint_names::normalise_joint_name(name);
    let side = match n.side {
        Some(super::joint_names::Side::Left) => "left",
        Some(super::joint_names::Side::Right) => "right",
        None => "",
    };
    format!("{side}{}", n.base)
}

/// Maps `avatar` joint names onto `motion` joint names (the motion read from `motion_file`):
/// the user's `map` first, then canonical joints, then equal names. Each motion joint drives
/// one avatar joint at most, except when the user's map says otherwise. Errors (naming the
/// map file) when the map names a joint that the avatar or the motion lacks.
pub fn map_joints(
    avatar: &[String],
    motion: &[String],
    map: Option<&JointMap>,
    motion_file: &Path,
) -> Result<JointMapping, IoError> {
    let n = avatar.len();
    let mut source = vec![None; n];
    let mut how = vec![None; n];
    let mut used = vec![false; motion.len()];
    if let Some(map) = map {
        for (a_name, m_name) in &map.joints {
            let fail = |reason: String| IoError::JointMap {
                reason,
                path: map.path.clone(),
            };
            let Some(a) = find_name(avatar, a_name) else {
                let names: Vec<&str> = avatar.iter().map(String::as_str).collect();
                return Err(fail(format!(
                    "the avatar has no joint '{a_name}' (closest: {})",
                    closest_names(a_name, &names, 3).join(", ")
                )));
            };
            let Some(m) = find_name(motion, m_name) else {
                let names: Vec<&str> = motion.iter().map(String::as_str).collect();
                return Err(fail(format!(
                    "avatar joint '{}' is mapped to '{m_name}', which the motion {} does not \
                     have (closest: {})",
                    avatar[a],
                    file_stem(motion_file),
                    closest_names(m_name, &names, 3).join(", ")
                )));
            };
            source[a] = Some(m);
            how[a] = Some(MatchKind::UserMap);
            used[m] = true;
        }
    }
    let a_rig = classify(avatar);
    let m_rig = classify(motion);
    for a in 0..n {
        if source[a].is_some() {
            continue;
        }
        if let Some(canon) = a_rig.canonical[a]
            && let Some(m) = m_rig.joint_of(canon)
            && !used[m]
        {
            source[a] = Some(m);
            how[a] = Some(MatchKind::Rig);
            used[m] = true;
        }
    }
    let plain: Vec<String> = motion.iter().map(|m| plain_name(m)).collect();
    for a in 0..n {
        if source[a].is_some() {
            continue;
        }
        let key = plain_name(&avatar[a]);
        if key.is_empty() {
            continue;
        }
        if let Some(m) = (0..motion.len()).find(|&m| !used[m] && plain[m] == key) {
            source[a] = Some(m);
            how[a] = Some(MatchKind::Name);
            used[m] = true;
        }
    }
    Ok(JointMapping {
        source,
        how,
        canonical: a_rig.canonical,
        avatar_convention: a_rig.convention,
        motion_convention: m_rig.convention,
        motion_canonical: m_rig.canonical,
        structure: None,
    })
}

impl JointMapping {
    /// True when an essential joint (see [`CORE_JOINTS`]) is unmapped or not recognised in
    /// the avatar's names at all.
    pub fn needs_structure(&self) -> bool {
        CORE_JOINTS.iter().any(|c| {
            self.canonical
                .iter()
                .position(|x| *x == Some(*c))
                .is_none_or(|a| self.source[a].is_none())
        })
    }

    /// Maps by the skeletons' structure what the names left unmapped: avatar joints whose
    /// names are not recognised take the canonical joint their place in the avatar's skeleton
    /// gives, then each unmapped avatar joint takes the unused motion joint of that canonical
    /// name (recognised by its name, else by its place in the motion's skeleton). Does nothing unless [`Self::needs_structure`]; records what
    /// it did, or why a skeleton was not recognised, in [`Self::structure`].
    pub fn fill_by_structure(&mut self, avatar: &RigShape<'_>, motion: &RigShape<'_>) {
        if !self.needs_structure() {
            return;
        }
        let labels = label_by_structure(avatar)
            .map_err(|why| format!("the avatar's skeleton is not recognised ({why})"))
            .and_then(|a| {
                label_by_structure(motion)
                    .map(|m| (a, m))
                    .map_err(|why| format!("the motion's skeleton is not recognised ({why})"))
            });
        let (a_labels, m_labels) = match labels {
            Ok(l) => l,
            Err(why) => {
                self.structure = Some(why);
                return;
            }
        };
        for (a, label) in a_labels.iter().enumerate() {
            if self.canonical[a].is_none()
                && let Some(c) = label
                && !self.canonical.contains(&Some(*c))
            {
                self.canonical[a] = Some(*c);
            }
        }
        let mut used = vec![false; m_labels.len()];
        for m in self.source.iter().flatten() {
            if let Some(u) = used.get_mut(*m) {
                *u = true;
            }
        }
        let mut count = 0;
        for a in 0..self.source.len() {
            let Some(c) = self.canonical[a] else { continue };
            if self.source[a].is_some() {
                continue;
            }
            let named = self.motion_canonical.iter().position(|l| *l == Some(c));
            let placed = m_labels.iter().position(|l| *l == Some(c));
            let Some(m) = named.filter(|&m| !used[m]).or(placed) else {
                continue;
            };
            if !used[m] {
                self.source[a] = Some(m);
                self.how[a] = Some(MatchKind::Structure);
                used[m] = true;
                count += 1;
            }
        }
        self.structure = Some(format!(
            "{count} joints mapped by the skeletons' structure (names not recognised)"
        ));
    }

    /// Checks that every essential avatar joint (see [`CORE_JOINTS`]) is mapped, and that
    /// some joint is: else an [`IoError::UnmappedJoints`] naming the motion file, listing the
    /// joints and the closest unused names of the motion.
    pub fn check_essential(
        &self,
        avatar: &[String],
        motion: &[String],
        motion_file: &Path,
    ) -> Result<(), IoError> {
        let missing: Vec<usize> = (0..avatar.len())
            .filter(|&a| {
                self.source[a].is_none()
                    && self.canonical[a].is_some_and(|c| CORE_JOINTS.contains(&c))
            })
            .collect();
        let none_mapped = self.source.iter().all(Option::is_none);
        if missing.is_empty() && !none_mapped {
            return Ok(());
        }
        let missing = if missing.is_empty() {
            (0..avatar.len().min(12)).collect()
        } else {
            missing
        };
        let unused: Vec<&str> = (0..motion.len())
            .filter(|m| !self.source.contains(&Some(*m)))
            .map(|m| motion[m].as_str())
            .collect();
        let closest = missing
            .iter()
            .map(|&a| {
                let near = closest_names(&avatar[a], &unused, 3);
                format!(
                    "{} ~ {}",
                    avatar[a],
                    if near.is_empty() {
                        "-".to_string()
                    } else {
                        near.join(", ")
                    }
                )
            })
            .collect::<Vec<_>>()
            .join("; ");
        Err(IoError::UnmappedJoints {
            joints: missing.iter().map(|&a| avatar[a].clone()).collect(),
            closest,
            note: self
                .structure
                .as_ref()
                .map(|s| format!("; by structure: {s}"))
                .unwrap_or_default(),
            path: motion_file.to_path_buf(),
        })
    }

    /// Avatar joints without a motion joint.
    pub fn unmapped<'a>(&self, avatar: &'a [String]) -> Vec<&'a str> {
        (0..avatar.len())
            .filter(|&a| self.source[a].is_none())
            .map(|a| avatar[a].as_str())
            .collect()
    }

    /// A readable table: one line per avatar joint (`Avatar <- Motion (how)`), then the
    /// unmapped avatar joints and the unused motion joints.
    pub fn report(&self, avatar: &[String], motion: &[String]) -> String {
        let mut out = String::new();
        let _ = writeln!(
            out,
            "naming: avatar {}, motion {}",
            self.avatar_convention, self.motion_convention
        );
        let _ = writeln!(
            out,
            "mapped: {} of {} avatar joints",
            self.source.iter().flatten().count(),
            avatar.len()
        );
        for (a, name) in avatar.iter().enumerate() {
            if let (Some(m), Some(how)) = (self.source[a], self.how[a]) {
                let how = match how {
                    MatchKind::UserMap => "joint map",
                    MatchKind::Rig => "rig names",
                    MatchKind::Name => "same name",
                    MatchKind::Structure => "structure",
                };
                let _ = writeln!(out, "  {name} <- {} ({how})", motion[m]);
            }
        }
        if let Some(note) = &self.structure {
            let _ = writeln!(out, "structure: {note}");
        }
        let unmapped = self.unmapped(avatar);
        let _ = writeln!(
            out,
            "unmapped avatar joints (keep their rest rotation): {}",
            if unmapped.is_empty() {
                "none".to_string()
            } else {
                short_list(&unmapped, 40)
            }
        );
        let unused: Vec<&str> = (0..motion.len())
            .filter(|m| !self.source.contains(&Some(*m)))
            .map(|m| motion[m].as_str())
            .collect();
        let _ = writeln!(
            out,
            "unused motion joints: {}",
            if unused.is_empty() {
                "none".to_string()
            } else {
                short_list(&unused, 40)
            }
        );
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn names(v: &[&str]) -> Vec<String> {
        v.iter().map(|s| s.to_string()).collect()
    }

    #[test]
    fn mixamo_avatar_takes_a_3ds_max_friendly_cmu_clip() {
        let avatar = names(&[
            "Hips",
            "Spine",
            "LeftShoulder",
            "LeftArm",
            "LeftForeArm",
            "LeftUpLeg",
            "LeftLeg",
        ]);
        let motion = names(&[
            "Hips",
            "lowerback",
            "LeftCollar",
            "LeftShoulder",
            "LeftElbow",
            "LeftHip",
            "LeftKnee",
        ]);
        let m = map_joints(&avatar, &motion, None, Path::new("clip.bvh")).unwrap();
        // LeftShoulder (clavicle) must come from LeftCollar, LeftArm from LeftShoulder.
        assert_eq!(
            m.source,
            vec![
                Some(0),
                Some(1),
                Some(2),
                Some(3),
                Some(4),
                Some(5),
                Some(6)
            ]
        );
        assert!(m.how.iter().all(|h| *h == Some(MatchKind::Rig)));
        assert_eq!(
            m.motion_convention,
            "CMU 3ds Max friendly / MakeHuman / ASF"
        );
    }

    #[test]
    fn user_map_overrides_and_names_missing_joints() {
        let avatar = names(&["Hips", "Spine"]);
        let motion = names(&["Hips", "Spine", "Chest"]);
        let map = JointMap::from_toml_str("[joints]\nSpine = \"chest\"\n", Path::new("map.toml"))
            .unwrap();
        let m = map_joints(&avatar, &motion, Some(&map), Path::new("m.bvh")).unwrap();
        assert_eq!(m.source, vec![Some(0), Some(2)]);
        assert_eq!(m.how[1], Some(MatchKind::UserMap));
        let bad = JointMap::from_toml_str("[joints]\nSpine = \"Chset\"\n", Path::new("map.toml"))
            .unwrap();
        let err = map_joints(&avatar, &motion, Some(&bad), Path::new("m.bvh")).unwrap_err();
        let text = err.to_string();
        assert!(text.contains("'Chset'") && text.contains("Chest"), "{text}");
        assert!(text.ends_with("map.toml"), "{text}");
        let bad =
            JointMap::from_toml_str("[joints]\nSpin = \"Chest\"\n", Path::new("map.toml")).unwrap();
        let err = map_joints(&avatar, &motion, Some(&bad), Path::new("m.bvh")).unwrap_err();
        assert!(
            err.to_string().contains("no joint 'Spin' (closest: Spine"),
            "{err}"
        );
        let err =
            JointMap::from_toml_str("Spine = \"Chest\"\n", Path::new("map.toml")).unwrap_err();
        assert!(err.to_string().contains("[joints]"), "{err}");
    }

    #[test]
    fn missing_essentials_list_close_names() {
        let avatar = names(&["Hips", "Spine", "LeftArm"]);
        let motion = names(&["Hips", "Spine", "LArmX", "Head"]);
        let m = map_joints(&avatar, &motion, None, Path::new("m.bvh")).unwrap();
        let err = m
            .check_essential(&avatar, &motion, Path::new("m.bvh"))
            .unwrap_err();
        match &err {
            IoError::UnmappedJoints {
                joints, closest, ..
            } => {
                assert_eq!(joints, &names(&["LeftArm"]));
                assert!(closest.starts_with("LeftArm ~ LArmX"), "{closest}");
            }
            other => panic!("{other}"),
        }
        assert!(err.to_string().ends_with("m.bvh"));
        let report = m.report(&avatar, &motion);
        assert!(report.contains("Hips <- Hips (rig names)"), "{report}");
        assert!(report.contains("unmapped avatar joints (keep their rest rotation): LeftArm"));
        assert!(
            report.contains("unused motion joints: LArmX, Head"),
            "{report}"
        );
    }
}
