//! Side-panel sections: scene (avatar, garment and motion loading through file dialogs or
//! typed paths), fabric (preset, stiffness, density, bending, collision threshold) and
//! effects/overlay toggles. They only edit [`super::AppState`] through its methods.

use std::path::PathBuf;

use neural_cloth_physics::fabric::PRESET_NAMES;

use super::NeuralClothApp;
use super::file_picker::PickPurpose;
use super::state::Level;

/// Which scene part a load targets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LoadKind {
    /// Avatar (glTF/GLB).
    Avatar,
    /// Garment (OBJ/glTF).
    Garment,
    /// Motion (BVH).
    Motion,
}

impl LoadKind {
    /// Dialog title.
    pub fn title(self) -> &'static str {
        match self {
            Self::Avatar => "Load avatar (glTF/GLB)",
            Self::Garment => "Load garment (OBJ/glTF)",
            Self::Motion => "Load motion (BVH)",
        }
    }

    /// Extensions the dialog offers.
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            Self::Avatar => &["glb", "gltf"],
            Self::Garment => &["obj", "glb", "gltf"],
            Self::Motion => &["bvh"],
        }
    }
}

/// The split's name as the motion list shows it.
pub fn split_name(split: neural_cloth_core::scene::Split) -> &'static str {
    match split {
        neural_cloth_core::scene::Split::Train => "train",
        neural_cloth_core::scene::Split::Validation => "validation",
        neural_cloth_core::scene::Split::Test => "test",
    }
}

impl NeuralClothApp {
    /// Loads `path` as `kind`: the single path used by the dialog, the typed field and tests.
    pub fn load_file(&mut self, kind: LoadKind, path: &std::path::Path) -> bool {
        match kind {
            LoadKind::Avatar => self.state.load_avatar(path),
            LoadKind::Garment => self.state.load_garment(path),
            LoadKind::Motion => {
                let map = self.state.typed.joint_map.trim().to_string();
                let map = (!map.is_empty()).then(|| PathBuf::from(map));
                self.state.load_motion_mapped(path, map.as_deref())
            }
        }
    }

    /// The "Joint map" row: a typed path to a joint map (TOML: `[joints] AvatarJoint =
    /// "MotionJoint"`) that motions loaded next are retargeted with; checked when the field
    /// is left, its error shown under it.
    fn joint_map_row(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let label = ui.label("Joint map");
            let typed = &mut self.state.typed;
            let response = ui
                .add(
                    egui::TextEdit::singleline(&mut typed.joint_map)
                        .hint_text("optional .toml, for motions")
                        .desired_width(150.0),
                )
                .labelled_by(label.id)
                .on_hover_text(
                    "[joints] AvatarJoint = \"MotionJoint\": overrides the automatic joint \
                     mapping of the motions loaded next",
                );
            if response.lost_focus() {
                let text = typed.joint_map.trim();
                typed.joint_map_error = match text.is_empty() {
                    true => None,
                    false => neural_cloth_core::io::JointMap::load(std::path::Path::new(text))
                        .err()
                        .map(|e| e.to_string()),
                };
            }
        });
        if let Some(e) = &self.state.typed.joint_map_error {
            ui.colored_label(egui::Color32::from_rgb(255, 100, 90), e);
        }
    }

    /// The "Up axis" row: auto, Y or Z for the files loaded next (a Z-up file is turned Y up).
    fn up_axis_row(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let label = ui.label("Up axis");
            let up = &mut self.state.typed.up;
            egui::ComboBox::from_id_salt("up_axis")
                .selected_text(up.label())
                .show_ui(ui, |ui| {
                    for choice in neural_cloth_core::scene::UpAxis::ALL {
                        ui.selectable_value(up, choice, choice.label());
                    }
                })
                .response
                .labelled_by(label.id)
                .on_hover_text(
                    "Which axis of the files loaded next points up: auto detects it (from a \
                     skeleton, or an OBJ's shape), Z turns a Z-up file Y up",
                );
        });
    }

    /// One "label, typed path, Load, Browse…" row.
    fn load_row(&mut self, ui: &mut egui::Ui, kind: LoadKind) {
        let (label, hint) = match kind {
            LoadKind::Avatar => ("Avatar", "avatar .glb/.gltf path"),
            LoadKind::Garment => ("Garment", "garment .obj/.glb path"),
            LoadKind::Motion => ("Motion", "motion .bvh path"),
        };
        ui.horizontal(|ui| {
            let typed = match kind {
                LoadKind::Avatar => &mut self.state.typed.avatar,
                LoadKind::Garment => &mut self.state.typed.garment,
                LoadKind::Motion => &mut self.state.typed.motion,
            };
            let edit = egui::TextEdit::singleline(typed)
                .hint_text(hint)
                .desired_width(120.0);
            let response = ui.add(edit);
            let enter = response.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter));
            let typed = typed.trim().to_string();
            if (ui
                .button(format!("Load {}", label.to_lowercase()))
                .clicked()
                || enter)
                && !typed.is_empty()
            {
                self.load_file(kind, &PathBuf::from(typed));
            }
            if ui.button("...").on_hover_text(kind.title()).clicked() {
                let start = self.state.scene_file(kind);
                self.picker
                    .request(PickPurpose::Load(kind), start.as_deref());
            }
        });
    }

    /// Scene section: what is loaded and the load rows; the last load error, if any.
    pub fn scene_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Scene")
            .default_open(true)
            .show(ui, |ui| {
                let avatar = self.state.scene.avatar.clone();
                let garment_text = match &self.state.scene.garment {
                    Some(g) => format!("{} ({} vertices)", g.name, g.vertex_count()),
                    None => "none".into(),
                };
                ui.label(format!(
                    "Avatar: {} ({} joints), garment: {garment_text}",
                    avatar.name,
                    avatar.skeleton.len()
                ));
                self.up_axis_row(ui);
                self.load_row(ui, LoadKind::Avatar);
                self.load_row(ui, LoadKind::Garment);
                self.fit_ui(ui);
                self.load_row(ui, LoadKind::Motion);
                self.joint_map_row(ui);
                // (A joint map's error is shown under its field, not twice.)
                let map_error = self.state.typed.joint_map_error.as_ref();
                if let Some(m) = self
                    .state
                    .messages
                    .last()
                    .filter(|m| m.level == Level::Error && Some(&m.text) != map_error)
                {
                    ui.colored_label(egui::Color32::from_rgb(255, 100, 90), &m.text);
                }
            });
    }

    /// The motion list: every motion with its split (train, validation, test), all rows
    /// visible (the side panel scrolls, the list does not hide rows); click one to show it.
    pub fn motions_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Motions")
            .default_open(true)
            .show(ui, |ui| {
                let avatar = self.state.scene.avatar.clone();
                let mut chosen = None;
                for (k, m) in avatar.motions.iter().enumerate() {
                    let split = self
                        .state
                        .scene
                        .splits
                        .get(k)
                        .copied()
                        .unwrap_or(neural_cloth_core::scene::Split::Train);
                    let selected = k == self.state.playback.motion;
                    let text = format!(
                        "{} ({:.1} s) · {}",
                        m.name,
                        m.duration_secs(),
                        split_name(split)
                    );
                    if ui.selectable_label(selected, text).clicked() {
                        chosen = Some(k);
                    }
                }
                if avatar.motions.is_empty() {
                    ui.weak("no motions: load a BVH file");
                }
                if let Some(k) = chosen {
                    self.state.playback.select_motion(k, avatar.motions.len());
                }
            });
    }

    /// Fabric section: preset and the main material parameters.
    pub fn fabric_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Fabric")
            .default_open(true)
            .show(ui, |ui| {
                let mut preset = None;
                let current = self.state.fabric_preset();
                egui::ComboBox::from_label("preset")
                    .selected_text(current)
                    .show_ui(ui, |ui| {
                        for name in PRESET_NAMES {
                            if ui.selectable_label(current == name, name).clicked() {
                                preset = Some(name);
                            }
                        }
                    });
                if let Some(name) = preset {
                    self.state.apply_preset(name);
                }
                let f = &mut self.state.scene.config.fabric;
                let mut changed = false;
                changed |= ui
                    .add(
                        egui::Slider::new(&mut f.stretch_stiffness, 0.1..=100.0)
                            .logarithmic(true)
                            .text("stretch (N/m)"),
                    )
                    .changed();
                changed |= ui
                    .add(egui::Slider::new(&mut f.shear_stiffness, 0.0..=50.0).text("shear (N/m)"))
                    .changed();
                changed |= ui
                    .add(
                        egui::Slider::new(&mut f.density_kg_per_m2, 0.01..=1.0)
                            .logarithmic(true)
                            .text("density (kg/m²)"),
                    )
                    .changed();
                changed |= ui
                    .add(
                        egui::Slider::new(&mut f.bending_stiffness, 1e-7..=1e-2)
                            .logarithmic(true)
                            .text("bending (N·m)")
                            .custom_formatter(|v, _| format!("{v:.1e}")),
                    )
                    .changed();
                let mut eps_mm = f.collision_threshold_m * 1000.0;
                if ui
                    .add(egui::Slider::new(&mut eps_mm, 0.0..=20.0).text("collision ε (mm)"))
                    .changed()
                {
                    f.collision_threshold_m = eps_mm / 1000.0;
                    changed = true;
                }
                changed |= ui
                    .add(
                        egui::Slider::new(&mut f.friction_coefficient, 0.0..=2.0)
                            .text("friction μ (with the friction effect)"),
                    )
                    .changed();
                if changed {
                    self.state.fabric_changed();
                }
            });
    }

    /// Effects and viewport overlay toggles.
    pub fn effects_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Effects & view")
            .default_open(false)
            .show(ui, |ui| {
                let active = self.state.training.state().is_active();
                ui.add_enabled_ui(!active, |ui| {
                    let e = &mut self.state.scene.config.effects;
                    let mut changed = false;
                    changed |= ui.checkbox(&mut e.gravity, "gravity").changed();
                    changed |= ui.checkbox(&mut e.bending, "bending").changed();
                    changed |= ui.checkbox(&mut e.collision, "collision").changed();
                    changed |= ui.checkbox(&mut e.dynamics, "dynamics (inertia)").changed();
                    changed |= ui.checkbox(&mut e.pinning, "pinning").changed();
                    let can_rub = e.collision && e.dynamics;
                    changed |= ui
                        .add_enabled(can_rub, egui::Checkbox::new(&mut e.friction, "friction"))
                        .on_disabled_hover_text("friction needs collision and dynamics")
                        .changed();
                    e.drop_unmet_needs();
                    if changed {
                        // Dynamics changes the network layout of the preview.
                        self.state.preview.reset_scene();
                        self.state.scene.revision += 1;
                    }
                });
                ui.separator();
                let d = &mut self.state.draw;
                ui.checkbox(&mut d.heat_map, "strain heat-map");
                ui.checkbox(&mut d.collision_points, "collision points");
                ui.checkbox(&mut d.wireframe, "wireframe");
                ui.checkbox(&mut d.show_body, "body");
                ui.checkbox(&mut d.show_garment, "garment");
                ui.checkbox(&mut d.grid, "ground grid");
                ui.checkbox(&mut self.viewport.follow, "camera follows body");
                ui.checkbox(&mut self.viewport.show_timing, "frame time");
                if ui.button("Reset camera").clicked() {
                    self.viewport.reset_camera();
                }
            });
    }

    /// The status line: the latest message, coloured by severity.
    pub fn status_ui(&mut self, ui: &mut egui::Ui) {
        let animating = self.state.playback.playing || self.state.training.state().is_active();
        let frame_time = match animating {
            true => self.viewport.frame_time_text(),
            false => Some("viewport idle (paused)".to_owned()),
        };
        ui.horizontal(|ui| {
            match self.state.messages.last() {
                Some(m) => {
                    let color = match m.level {
                        Level::Info => ui.visuals().text_color(),
                        Level::Warning => egui::Color32::from_rgb(230, 180, 60),
                        Level::Error => egui::Color32::from_rgb(255, 100, 90),
                    };
                    ui.colored_label(color, &m.text);
                }
                None => {
                    ui.weak("ready");
                }
            }
            if let Some(text) = frame_time {
                ui.with_layout(egui::Layout::right_to_left(egui::Align::Center), |ui| {
                    ui.weak(text)
                        .on_hover_text("time between viewport frames while it redraws");
                });
            }
        });
    }
}
