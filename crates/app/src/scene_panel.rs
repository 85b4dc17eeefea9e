//! The Scene panel: what is loaded, the up axis of the files loaded next, the avatar, garment
//! and motion load rows (typed path or file dialog), "Fit garment" ([`super::fit_panel`]),
//! the joint map field and the last load error. Loading itself is
//! [`super::state::AppState::load_file`] ([`super::scene_edit`]).

use std::path::PathBuf;

use super::NeuralClothApp;
use super::file_picker::PickPurpose;
use super::scene_edit::LoadKind;
use super::state::Level;

impl NeuralClothApp {
    /// The "Joint map" row: a typed path to a joint map (TOML: `[joints] AvatarJoint =
    /// "MotionJoint"`) that motions loaded next are retargeted with; checked when the field
    /// is left, its error shown under it.
    fn joint_map_row(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let label = ui.label("Joint map");
            let response = ui
                .add(
                    egui::TextEdit::singleline(&mut self.state.typed.joint_map)
                        .hint_text("optional .toml, for motions")
                        .desired_width(150.0),
                )
                .labelled_by(label.id)
                .on_hover_text(
                    "[joints] AvatarJoint = \"MotionJoint\": overrides the automatic joint \
                     mapping of the motions loaded next",
                );
            if response.lost_focus() {
                self.state.check_joint_map();
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
                self.state.load_file(kind, &PathBuf::from(typed));
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
}
