//! Joint names across the common rigs: one table of synonyms per canonical joint for each
//! naming convention (Mixamo, CMU "3ds Max friendly" / MakeHuman / ASF, Blender Rigify and
//! metarig, Unreal mannequin and 3ds Max Biped, SMPL, Daz), name normalisation (namespaces,
//! rig prefixes, case, separators, side markers) and the classification of a whole joint list.
//!
//! The canonical joints are the 22 Mixamo names of [`CANONICAL_JOINTS`]. The same word means
//! different bones in different rigs (a 3ds Max friendly CMU `LeftShoulder` is the upper arm, a
//! Mixamo `LeftShoulder` the clavicle; SMPL's `Spine1` is Mixamo's `Spine`), so names are not
//! looked up one by one: [`classify`] picks the convention that recognises most of a rig's
//! joints, then falls back to a generic table for the names it does not know.

/// The canonical joints (Mixamo names), in the order of the built-in mannequin.
pub use crate::scene::procedural::body::JOINT_NAMES as CANONICAL_JOINTS;

/// Canonical names every avatar must map when it has them: hips, spine, upper legs, legs,
/// arms and forearms.
pub const CORE_JOINTS: [&str; 10] = [
    "Hips",
    "Spine",
    "LeftUpLeg",
    "RightUpLeg",
    "LeftLeg",
    "RightLeg",
    "LeftArm",
    "RightArm",
    "LeftForeArm",
    "RightForeArm",
];

use super::joint_tables::{CONVENTIONS, Convention, Entry, GENERIC};

/// Rig prefixes removed before matching (compared in lower case, after the namespace).
const PREFIXES: [&str; 9] = [
    "mixamorig",
    "def-",
    "org-",
    "def_",
    "bip001",
    "bip01",
    "cc_base_",
    "m_avg_",
    "f_avg_",
];

/// Which side of the body a joint name says it is on.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Side {
    /// The character's left.
    Left,
    /// The character's right.
    Right,
}

/// A joint name reduced to its side and a lower-case alphanumeric base.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct NormalisedName {
    /// Side marker found in the name (`l`, `left`, `.L`, `_r`, `Right...`), if any.
    pub side: Option<Side>,
    /// What is left: lower-case letters and digits only.
    pub base: String,
}

/// True when `base` is a sided synonym in some table (lets `lhip` read as left `hip`).
fn is_sided_word(base: &str) -> bool {
    CONVENTIONS
        .iter()
        .chain(std::iter::once(&GENERIC))
        .flat_map(|c| c.table.iter())
        .any(|e| e.sided && e.names.contains(&base))
}

fn side_word(token: &str) -> Option<Side> {
    match token.to_ascii_lowercase().as_str() {
        "l" | "left" => Some(Side::Left),
        "r" | "right" => Some(Side::Right),
        _ => None,
    }
}

fn lower_alnum(s: &str) -> String {
    s.chars()
        .filter(char::is_ascii_alphanumeric)
        .map(|c| c.to_ascii_lowercase())
        .collect()
}

/// Strips the namespace (after the last `:` or `|`) and known rig prefixes (`mixamorig`,
/// `DEF-`, `Bip01`, `CC_Base_`, ...), case-insensitively.
fn strip_prefixes(name: &str) -> &str {
    let mut tail = name.rsplit([':', '|']).next().unwrap_or(name).trim();
    loop {
        let lower = tail.to_ascii_lowercase();
        let Some(p) = PREFIXES.iter().find(|p| lower.starts_with(*p)) else {
            return tail;
        };
        let rest = tail.get(p.len()..).unwrap_or("");
        let rest = rest.trim_start_matches(|c: char| !c.is_ascii_alphanumeric());
        if rest.is_empty() {
            return tail;
        }
        tail = rest;
    }
}

/// Normalises a joint name: namespace and rig prefixes removed, a side found from a separate
/// `l`/`r`/`left`/`right` token (`L_Hip`, `thigh.L`, `Bip01 L Thigh`, `upper_arm.R.001`), a
/// `Left`/`Right` prefix or suffix, a capital-led `l`/`r` prefix (`lThigh`, `RShldr`) or a
/// lower-case `l`/`r` before a known sided word (`lhip`, `relbow`), the rest lower-case
/// alphanumerics.
pub fn normalise_joint_name(name: &str) -> NormalisedName {
    let tail = strip_prefixes(name);
    let mut tokens: Vec<&str> = tail
        .split(|c: char| !c.is_ascii_alphanumeric())
        .filter(|t| !t.is_empty())
        .collect();
    if tokens.len() > 1
        && let Some(k) = tokens.iter().position(|t| side_word(t).is_some())
    {
        let side = side_word(tokens[k]);
        tokens.remove(k);
        return NormalisedName {
            side,
            base: lower_alnum(&tokens.concat()),
        };
    }
    let joined = tokens.concat();
    let lower = joined.to_ascii_lowercase();
    for (word, side) in [("left", Side::Left), ("right", Side::Right)] {
        if lower.len() > word.len() {
            if let Some(rest) = lower.strip_prefix(word) {
                return sided(side, rest);
            }
            if let Some(rest) = lower.strip_suffix(word) {
                return sided(side, rest);
            }
        }
    }
    let chars: Vec<char> = joined.chars().collect();
    if chars.len() > 1 {
        let side = match chars[0] {
            'l' | 'L' => Some(Side::Left),
            'r' | 'R' => Some(Side::Right),
            _ => None,
        };
        if let Some(side) = side
            && (chars[1].is_ascii_uppercase() || is_sided_word(&lower[1..]))
        {
            return sided(side, &lower[1..]);
        }
    }
    NormalisedName {
        side: None,
        base: lower,
    }
}

fn sided(side: Side, base: &str) -> NormalisedName {
    NormalisedName {
        side: Some(side),
        base: lower_alnum(base),
    }
}

fn canonical_index(name: &str) -> Option<usize> {
    CANONICAL_JOINTS.iter().position(|c| *c == name)
}

/// The canonical index of `entry` on `side` (`None` for a centre entry).
fn entry_index(entry: &Entry, side: Option<Side>) -> Option<usize> {
    match (entry.sided, side) {
        (false, None) => canonical_index(entry.joint),
        (true, Some(Side::Left)) => canonical_index(&format!("Left{}", entry.joint)),
        (true, Some(Side::Right)) => canonical_index(&format!("Right{}", entry.joint)),
        _ => None,
    }
}

/// Assigns joints to canonical joints with `convention`, skipping joints and canonical
/// joints already taken in `joint_of` / `canon_of`.
fn assign(
    convention: &Convention,
    names: &[NormalisedName],
    canon_of: &mut [Option<usize>],
    joint_of: &mut [Option<usize>; 22],
) {
    for entry in convention.table {
        let sides: &[Option<Side>] = if entry.sided {
            &[Some(Side::Left), Some(Side::Right)]
        } else {
            &[None]
        };
        for &side in sides {
            let Some(k) = entry_index(entry, side) else {
                continue;
            };
            if joint_of[k].is_some() {
                continue;
            }
            let found = entry.names.iter().find_map(|word| {
                (0..names.len()).find(|&j| {
                    canon_of[j].is_none() && names[j].side == side && names[j].base == *word
                })
            });
            if let Some(j) = found {
                joint_of[k] = Some(j);
                canon_of[j] = Some(k);
            }
        }
    }
}

/// Per joint its canonical index, per canonical joint its joint.
type Assignment = (Vec<Option<usize>>, [Option<usize>; 22]);

/// The canonical joints of a whole rig's joint list.
#[derive(Clone, Debug, PartialEq)]
pub struct Classified {
    /// The convention that recognised most joints (`"none"` when none recognised any).
    pub convention: &'static str,
    /// For each joint, its canonical name.
    pub canonical: Vec<Option<&'static str>>,
}

impl Classified {
    /// The joint whose canonical name is `canonical`.
    pub fn joint_of(&self, canonical: &str) -> Option<usize> {
        self.canonical.iter().position(|c| *c == Some(canonical))
    }
}

/// Classifies a rig's joint names: the convention recognising most of them, then the generic
/// table for the rest. Each canonical joint goes to one joint at most.
pub fn classify<S: AsRef<str>>(names: &[S]) -> Classified {
    let parsed: Vec<NormalisedName> = names
        .iter()
        .map(|n| normalise_joint_name(n.as_ref()))
        .collect();
    let mut best: Option<(usize, &Convention, Assignment)> = None;
    for convention in &CONVENTIONS {
        let mut canon_of = vec![None; names.len()];
        let mut joint_of = [None; 22];
        assign(convention, &parsed, &mut canon_of, &mut joint_of);
        let score = joint_of.iter().flatten().count();
        if best.as_ref().is_none_or(|b| score > b.0) {
            best = Some((score, convention, (canon_of, joint_of)));
        }
    }
    let (score, convention, mut canon_of, mut joint_of) = match best {
        Some((score, c, (canon_of, joint_of))) => (score, c.name, canon_of, joint_of),
        None => (0, "none", vec![None; names.len()], [None; 22]),
    };
    assign(&GENERIC, &parsed, &mut canon_of, &mut joint_of);
    Classified {
        convention: if score == 0 { "none" } else { convention },
        canonical: canon_of
            .iter()
            .map(|k| k.map(|k| CANONICAL_JOINTS[k]))
            .collect(),
    }
}

/// The canonical (Mixamo) name of a single joint name through the generic table, or `None`.
/// Names whose meaning depends on the rig (`LeftShoulder`, `Spine1`, `LowerBack`) are read
/// as Mixamo's; use [`classify`] for a whole rig.
///
/// Examples: `mixamorig:LeftUpLeg`, `lThigh`, `thigh_l`, `thigh.L`, `Bip01 L Thigh` and `L_Hip`
/// all give `LeftUpLeg`; `hip`, `pelvis` give `Hips`; `abdomen` gives `Spine`; `chest` gives
/// `Spine2`; CMU helper joints such as `LHipJoint` give `None`.
pub fn canonical_joint_name(name: &str) -> Option<&'static str> {
    classify_with(&GENERIC, &[name])
}

fn classify_with(convention: &Convention, names: &[&str]) -> Option<&'static str> {
    let parsed: Vec<NormalisedName> = names.iter().map(|n| normalise_joint_name(n)).collect();
    let mut canon_of = vec![None; names.len()];
    let mut joint_of = [None; 22];
    assign(convention, &parsed, &mut canon_of, &mut joint_of);
    canon_of
        .first()
        .copied()
        .flatten()
        .map(|k| CANONICAL_JOINTS[k])
}

/// Edit distance between two strings (characters), for suggesting close names.
pub fn edit_distance(a: &str, b: &str) -> usize {
    let b: Vec<char> = b.chars().collect();
    let mut row: Vec<usize> = (0..=b.len()).collect();
    for (i, ca) in a.chars().enumerate() {
        let mut prev = row[0];
        row[0] = i + 1;
        for (j, cb) in b.iter().enumerate() {
            let cur = row[j + 1];
            row[j + 1] = (prev + usize::from(ca != *cb)).min(row[j] + 1).min(cur + 1);
            prev = cur;
        }
    }
    row[b.len()]
}

/// Up to `max` of `candidates` closest to `name` (normalised names, edit distance; ties keep
/// the candidates' order).
pub fn closest_names<'a>(name: &str, candidates: &[&'a str], max: usize) -> Vec<&'a str> {
    let key = lower_alnum(strip_prefixes(name));
    let mut scored: Vec<(usize, usize, &str)> = candidates
        .iter()
        .enumerate()
        .map(|(k, c)| (edit_distance(&key, &lower_alnum(strip_prefixes(c))), k, *c))
        .collect();
    scored.sort_unstable();
    scored.into_iter().take(max).map(|(_, _, c)| c).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_normalise_with_sides() {
        let cases = [
            ("mixamorig:LeftUpLeg", Some(Side::Left), "upleg"),
            ("DEF-upper_arm.R.001", Some(Side::Right), "upperarm001"),
            ("thigh_l", Some(Side::Left), "thigh"),
            ("Bip01 L Thigh", Some(Side::Left), "thigh"),
            ("L_Hip", Some(Side::Left), "hip"),
            ("lThigh", Some(Side::Left), "thigh"),
            ("lhip", Some(Side::Left), "hip"),
            ("relbow", Some(Side::Right), "elbow"),
            ("ArmLeft", Some(Side::Left), "arm"),
            ("lowerback", None, "lowerback"),
            ("leg", None, "leg"),
            ("spine_01", None, "spine01"),
            ("m_avg_Pelvis", None, "pelvis"),
            ("Hips", None, "hips"),
        ];
        for (name, side, base) in cases {
            let n = normalise_joint_name(name);
            assert_eq!((n.side, n.base.as_str()), (side, base), "{name}");
        }
    }

    #[test]
    fn canonical_names_of_single_joints() {
        let cases = [
            ("mixamorig:LeftUpLeg", Some("LeftUpLeg")),
            ("lThigh", Some("LeftUpLeg")),
            ("thigh_l", Some("LeftUpLeg")),
            ("thigh.L", Some("LeftUpLeg")),
            ("Bip01 L Thigh", Some("LeftUpLeg")),
            ("L_Hip", Some("LeftUpLeg")),
            ("rShldr", Some("RightArm")),
            ("upperarm_r", Some("RightArm")),
            ("hip", Some("Hips")),
            ("abdomen", Some("Spine")),
            ("chest", Some("Spine2")),
            ("rCollar", Some("RightShoulder")),
            ("LHipJoint", None),
            ("LowerBack", None),
            ("LeftHandIndex1", None),
            ("Root", None),
            ("Leg", None),
        ];
        for (name, want) in cases {
            assert_eq!(canonical_joint_name(name), want, "{name}");
        }
    }

    /// (convention, names in CANONICAL_JOINTS order) for the conventions whose words clash
    /// with Mixamo's (`tests/io/rigs.rs` retargets all seven namings by joint positions).
    fn rigs() -> Vec<(&'static str, Vec<String>)> {
        let sided = |l: &str, r: &str, parts: [&str; 8]| -> Vec<String> {
            let mut v = Vec::new();
            for side in [l, r] {
                for p in &parts[..4] {
                    v.push(p.replace('#', side));
                }
            }
            for side in [l, r] {
                for p in &parts[4..] {
                    v.push(p.replace('#', side));
                }
            }
            v
        };
        let rig = |centre: [&str; 6], rest: Vec<String>| -> Vec<String> {
            centre.iter().map(|s| s.to_string()).chain(rest).collect()
        };
        vec![
            (
                "CMU 3ds Max friendly / MakeHuman / ASF",
                rig(
                    ["Hips", "lowerback", "upperback", "thorax", "Neck", "Head"],
                    sided(
                        "Left",
                        "Right",
                        [
                            "#Collar",
                            "#Shoulder",
                            "#Elbow",
                            "#Wrist",
                            "#Hip",
                            "#Knee",
                            "#Ankle",
                            "#Toe",
                        ],
                    ),
                ),
            ),
            (
                "CMU 3ds Max friendly / MakeHuman / ASF",
                rig(
                    ["hips", "lowerback", "upperback", "thorax", "neck", "head"],
                    sided(
                        "l",
                        "r",
                        [
                            "#clavicle",
                            "#shoulder",
                            "#elbow",
                            "#wrist",
                            "#hip",
                            "#knee",
                            "#ankle",
                            "#toe",
                        ],
                    ),
                ),
            ),
            (
                "Blender Rigify / metarig",
                rig(
                    [
                        "DEF-spine",
                        "DEF-spine.001",
                        "DEF-spine.002",
                        "DEF-spine.003",
                        "DEF-spine.004",
                        "DEF-spine.006",
                    ],
                    sided(
                        "L",
                        "R",
                        [
                            "DEF-shoulder.#",
                            "DEF-upper_arm.#",
                            "DEF-forearm.#",
                            "DEF-hand.#",
                            "DEF-thigh.#",
                            "DEF-shin.#",
                            "DEF-foot.#",
                            "DEF-toe.#",
                        ],
                    ),
                ),
            ),
            (
                "SMPL",
                rig(
                    ["Pelvis", "Spine1", "Spine2", "Spine3", "Neck", "Head"],
                    sided(
                        "L",
                        "R",
                        [
                            "#_Collar",
                            "#_Shoulder",
                            "#_Elbow",
                            "#_Wrist",
                            "#_Hip",
                            "#_Knee",
                            "#_Ankle",
                            "#_Foot",
                        ],
                    ),
                ),
            ),
        ]
    }

    #[test]
    fn every_convention_is_recognised_whole() {
        for (convention, names) in rigs() {
            assert_eq!(names.len(), 22);
            let c = classify(&names);
            assert_eq!(c.convention, convention, "{names:?}");
            for (k, name) in names.iter().enumerate() {
                assert_eq!(
                    c.canonical[k],
                    Some(CANONICAL_JOINTS[k]),
                    "{convention}: {name}"
                );
            }
        }
    }

    #[test]
    fn unreal_five_spines_and_extra_joints() {
        let names = [
            "root",
            "pelvis",
            "spine_01",
            "spine_02",
            "spine_03",
            "spine_04",
            "spine_05",
            "neck_01",
            "head",
            "thigh_l",
            "calf_l",
            "ik_foot_root",
            "index_01_l",
        ];
        let c = classify(&names);
        assert_eq!(c.convention, "Unreal mannequin / 3ds Max Biped");
        assert_eq!(c.joint_of("Hips"), Some(1));
        assert_eq!(c.joint_of("Spine1"), Some(3));
        assert_eq!(c.joint_of("Spine2"), Some(6));
        assert_eq!(c.canonical[0], None);
        assert_eq!(c.canonical[11], None);
        assert_eq!(c.canonical[12], None);
    }

    #[test]
    fn closest_names_rank_by_edit_distance() {
        assert_eq!(edit_distance("kitten", "sitting"), 3);
        let names = ["LeftElbow", "LArm", "Head", "LeftArmX"];
        assert_eq!(
            closest_names("LeftArm", &names, 2),
            vec!["LeftArmX", "LArm"]
        );
    }
}
