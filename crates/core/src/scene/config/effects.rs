//! The physical effects a scene declares ([`Effects`]): only declared effects are built,
//! trained, simulated and measured.

use serde::{Deserialize, Serialize};

/// Physical effects a scene needs; only declared effects are built and evaluated.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Effects {
    /// Gravity pulls the cloth down (gravity energy term). Default true.
    pub gravity: bool,
    /// Resistance to folding (bending energy on dihedral angles). Default true.
    pub bending: bool,
    /// The cloth stays outside the body (collision term, body distance queries). Default true.
    pub collision: bool,
    /// Inertia and the dynamic branch of the model; false gives a static, PBNS-like model.
    /// Default true.
    pub dynamics: bool,
    /// Pinned vertices follow the skinned garment exactly (e.g. a waistband). Default false.
    pub pinning: bool,
    /// Coulomb friction between cloth and body: vertices at the body resist sliding over it
    /// (a dissipation term on their motion relative to the body, see
    /// `neural_cloth_physics::friction`). Needs `collision` and `dynamics`. Default false (the
    /// paper's cloth is frictionless).
    pub friction: bool,
}

impl Effects {
    /// Switches off the effects whose needs are off: friction acts at body contacts between
    /// frames, so it goes with collision or dynamics (what an editor or a sweep that turns
    /// one of those off must call before the scene is validated).
    pub fn drop_unmet_needs(&mut self) {
        if !(self.collision && self.dynamics) {
            self.friction = false;
        }
    }
}

impl Default for Effects {
    fn default() -> Self {
        Self {
            gravity: true,
            bending: true,
            collision: true,
            dynamics: true,
            pinning: false,
            friction: false,
        }
    }
}
