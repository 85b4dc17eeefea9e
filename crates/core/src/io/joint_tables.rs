//! The tables of [`super::joint_names`]: per naming convention, the synonyms of each
//! canonical (Mixamo) joint in order of preference, as normalised names (lower-case
//! alphanumerics, side markers removed).

/// One row of a convention's table: a centre joint (full canonical name) or a sided part
/// (canonical name without `Left`/`Right`) and its synonyms in order of preference.
pub(super) struct Entry {
    pub(super) joint: &'static str,
    pub(super) sided: bool,
    pub(super) names: &'static [&'static str],
}

const fn c(joint: &'static str, names: &'static [&'static str]) -> Entry {
    Entry {
        joint,
        sided: false,
        names,
    }
}

const fn s(joint: &'static str, names: &'static [&'static str]) -> Entry {
    Entry {
        joint,
        sided: true,
        names,
    }
}

/// A naming convention: its display name and table.
pub(super) struct Convention {
    pub(super) name: &'static str,
    pub(super) table: &'static [Entry],
}

/// The conventions, in order of preference when two recognise as many joints.
pub(super) const CONVENTIONS: [Convention; 6] = [
    Convention {
        name: "Mixamo",
        table: &[
            c("Hips", &["hips", "hip"]),
            c("Spine", &["spine"]),
            c("Spine1", &["spine1"]),
            c("Spine2", &["spine2"]),
            c("Neck", &["neck"]),
            c("Head", &["head"]),
            s("Shoulder", &["shoulder"]),
            s("Arm", &["arm"]),
            s("ForeArm", &["forearm"]),
            s("Hand", &["hand"]),
            s("UpLeg", &["upleg"]),
            s("Leg", &["leg"]),
            s("Foot", &["foot"]),
            s("ToeBase", &["toebase", "toe"]),
        ],
    },
    Convention {
        name: "Unreal mannequin / 3ds Max Biped",
        table: &[
            c("Hips", &["pelvis"]),
            c("Spine", &["spine01", "spine"]),
            c("Spine1", &["spine02", "spine1"]),
            c("Spine2", &["spine05", "spine04", "spine03", "spine2"]),
            c("Neck", &["neck01", "neck"]),
            c("Head", &["head"]),
            s("Shoulder", &["clavicle"]),
            s("Arm", &["upperarm"]),
            s("ForeArm", &["lowerarm", "forearm"]),
            s("Hand", &["hand"]),
            s("UpLeg", &["thigh"]),
            s("Leg", &["calf"]),
            s("Foot", &["foot"]),
            s("ToeBase", &["ball", "toe0", "toe"]),
        ],
    },
    Convention {
        name: "Blender Rigify / metarig",
        table: &[
            c("Hips", &["spine", "hips", "pelvis"]),
            c("Spine", &["spine001"]),
            c("Spine1", &["spine002"]),
            c("Spine2", &["spine003", "chest"]),
            c("Neck", &["spine004", "neck"]),
            c("Head", &["spine006", "head"]),
            s("Shoulder", &["shoulder"]),
            s("Arm", &["upperarm"]),
            s("ForeArm", &["forearm"]),
            s("Hand", &["hand"]),
            s("UpLeg", &["thigh"]),
            s("Leg", &["shin"]),
            s("Foot", &["foot"]),
            s("ToeBase", &["toe"]),
        ],
    },
    Convention {
        name: "CMU 3ds Max friendly / MakeHuman / ASF",
        table: &[
            c("Hips", &["hips", "hip", "pelvis", "root"]),
            c("Spine", &["lowerback", "abdomen"]),
            c("Spine1", &["upperback"]),
            c("Spine2", &["thorax", "chest"]),
            c("Neck", &["neck", "lowerneck"]),
            c("Head", &["head"]),
            s("Shoulder", &["collar", "clavicle"]),
            s("Arm", &["shoulder", "humerus"]),
            s("ForeArm", &["elbow", "radius"]),
            s("Hand", &["wrist", "hand"]),
            s("UpLeg", &["hip", "femur"]),
            s("Leg", &["knee", "tibia"]),
            s("Foot", &["ankle", "foot"]),
            s("ToeBase", &["toe", "toes"]),
        ],
    },
    Convention {
        name: "SMPL",
        table: &[
            c("Hips", &["pelvis"]),
            c("Spine", &["spine1"]),
            c("Spine1", &["spine2"]),
            c("Spine2", &["spine3"]),
            c("Neck", &["neck"]),
            c("Head", &["head"]),
            s("Shoulder", &["collar"]),
            s("Arm", &["shoulder"]),
            s("ForeArm", &["elbow"]),
            s("Hand", &["wrist"]),
            s("UpLeg", &["hip"]),
            s("Leg", &["knee"]),
            s("Foot", &["ankle"]),
            s("ToeBase", &["foot"]),
        ],
    },
    Convention {
        name: "Daz",
        table: &[
            c("Hips", &["hip", "pelvis"]),
            c("Spine", &["abdomen", "abdomenlower"]),
            c("Spine1", &["abdomen2", "abdomenupper"]),
            c("Spine2", &["chest", "chestupper", "chestlower"]),
            c("Neck", &["neck", "necklower"]),
            c("Head", &["head"]),
            s("Shoulder", &["collar"]),
            s("Arm", &["shldr", "shldrbend"]),
            s("ForeArm", &["forearm", "forearmbend"]),
            s("Hand", &["hand"]),
            s("UpLeg", &["thigh", "thighbend"]),
            s("Leg", &["shin"]),
            s("Foot", &["foot"]),
            s("ToeBase", &["toe"]),
        ],
    },
];

/// Unambiguous spellings of any convention, for names the detected convention does not know
/// and for single names ([`canonical_joint_name`]).
pub(super) const GENERIC: Convention = Convention {
    name: "generic",
    table: &[
        c("Hips", &["hips", "hip", "pelvis"]),
        c("Spine", &["spine", "abdomen", "spine01"]),
        c("Spine1", &["spine1", "spine02", "abdomen2"]),
        c("Spine2", &["spine2", "chest", "spine03", "upperchest"]),
        c("Neck", &["neck", "neck01"]),
        c("Head", &["head"]),
        s("Shoulder", &["shoulder", "collar", "clavicle"]),
        s("Arm", &["arm", "upperarm", "uparm", "shldr"]),
        s("ForeArm", &["forearm", "lowerarm", "elbow"]),
        s("Hand", &["hand", "wrist"]),
        s("UpLeg", &["upleg", "thigh", "upperleg", "hip"]),
        s("Leg", &["leg", "shin", "calf", "lowerleg", "knee"]),
        s("Foot", &["foot", "ankle"]),
        s("ToeBase", &["toebase", "toe", "toes", "ball"]),
    ],
};
