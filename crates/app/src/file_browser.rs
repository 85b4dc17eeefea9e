//! The in-app file browser, for desktops without a file-dialog service: a folder listing
//! (folders first), the parent folder, a filter by extension (with "all files"), and a typed
//! path that may name a folder to show, a file to open, or a name to save under.
//!
//! No maintained egui file-dialog crate fits egui 0.37 as it is: egui-file-dialog 0.15 needs
//! egui 0.36, and egui_file 0.29 draws emoji that egui 0.37's default fonts do not have.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::error::AppError;

/// What the browser chooses.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Choose {
    /// An existing file.
    OpenFile,
    /// A file to write (new or existing).
    SaveFile,
    /// A folder.
    Folder,
}

/// One entry of the listing.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Entry {
    /// File or folder name.
    pub name: String,
    /// True for a folder.
    pub is_dir: bool,
}

/// What happened in the browser this frame.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum BrowserAnswer {
    /// Still choosing.
    Open,
    /// The chosen path.
    Chosen(PathBuf),
    /// Closed without a choice.
    Cancelled,
}

/// The browser's state.
#[derive(Clone, Debug)]
pub struct FileBrowser {
    title: &'static str,
    choose: Choose,
    extensions: &'static [&'static str],
    /// The folder shown.
    pub folder: PathBuf,
    /// The typed path (absolute, or relative to the folder shown).
    pub typed: String,
    /// List every file, not only those with the wanted extensions.
    pub all_files: bool,
    /// The folder's entries, or why it could not be listed (shared: the browser is cloned).
    entries: Result<Vec<Entry>, Arc<AppError>>,
    /// Why the last choice was refused.
    pub problem: Option<String>,
}

/// The entries of `folder`, folders first, each group by name; hidden entries left out.
pub fn list_folder(folder: &Path) -> Result<Vec<Entry>, AppError> {
    let read = std::fs::read_dir(folder).map_err(|source| AppError::ReadFolder {
        source,
        path: folder.to_path_buf(),
    })?;
    let mut entries: Vec<Entry> = read
        .filter_map(|e| e.ok())
        .map(|e| Entry {
            name: e.file_name().to_string_lossy().into_owned(),
            is_dir: e.path().is_dir(),
        })
        .filter(|e| !e.name.starts_with('.'))
        .collect();
    entries.sort_by(|a, b| b.is_dir.cmp(&a.is_dir).then(a.name.cmp(&b.name)));
    Ok(entries)
}

impl FileBrowser {
    /// A browser titled `title` choosing `choose`, offering files of `extensions` (none: any),
    /// showing `folder`, with `typed` in the path field.
    pub fn new(
        title: &'static str,
        choose: Choose,
        extensions: &'static [&'static str],
        folder: PathBuf,
        typed: String,
    ) -> Self {
        let mut browser = Self {
            title,
            choose,
            extensions,
            folder: PathBuf::new(),
            typed,
            all_files: false,
            entries: Ok(Vec::new()),
            problem: None,
        };
        browser.show_folder(folder);
        browser
    }

    /// Shows `folder`.
    pub fn show_folder(&mut self, folder: PathBuf) {
        self.entries = list_folder(&folder).map_err(Arc::new);
        self.folder = folder;
        self.problem = None;
    }

    /// The entries shown: folders, and the files the filter lets through.
    pub fn shown(&self) -> Vec<Entry> {
        let wanted = |e: &Entry| {
            e.is_dir
                || self.all_files
                || self.extensions.is_empty()
                || self.extensions.iter().any(|x| {
                    neural_cloth_core::io::scene_loader::extension(Path::new(&e.name)) == *x
                })
        };
        match &self.entries {
            Ok(entries) if self.choose == Choose::Folder => {
                entries.iter().filter(|e| e.is_dir).cloned().collect()
            }
            Ok(entries) => entries.iter().filter(|e| wanted(e)).cloned().collect(),
            Err(_) => Vec::new(),
        }
    }

    /// The typed path resolved against the folder shown (the folder itself when empty), with
    /// `.` and `..` taken out.
    pub fn typed_path(&self) -> PathBuf {
        let typed = self.typed.trim();
        let joined = match typed.is_empty() {
            true => self.folder.clone(),
            false => self.folder.join(typed),
        };
        let mut clean = PathBuf::new();
        for part in joined.components() {
            match part {
                std::path::Component::CurDir => {}
                std::path::Component::ParentDir => {
                    clean.pop();
                }
                other => clean.push(other),
            }
        }
        clean
    }

    /// Acts on the typed path (Enter, or the main button): when choosing a folder, a folder is
    /// chosen; otherwise a folder is shown and a file is chosen when it fits.
    pub fn confirm(&mut self) -> BrowserAnswer {
        let path = self.typed_path();
        if path.is_dir() && self.choose != Choose::Folder {
            self.typed.clear();
            self.show_folder(path);
            return BrowserAnswer::Open;
        }
        let refuse = |me: &mut Self, why: String| {
            me.problem = Some(why);
            BrowserAnswer::Open
        };
        match self.choose {
            Choose::Folder if path.is_dir() => BrowserAnswer::Chosen(path),
            Choose::Folder => refuse(self, format!("no such folder: {}", path.display())),
            Choose::OpenFile if path.is_file() => BrowserAnswer::Chosen(path),
            Choose::OpenFile => refuse(self, format!("no such file: {}", path.display())),
            Choose::SaveFile if path.parent().is_some_and(Path::is_dir) => {
                BrowserAnswer::Chosen(path)
            }
            Choose::SaveFile => refuse(
                self,
                format!("the folder does not exist: {}", path.display()),
            ),
        }
    }

    /// Clicks on entry `entry`: a single click puts it in the path field, a double click opens
    /// a folder or chooses a file.
    fn entry_clicked(&mut self, entry: &Entry, double: bool) -> BrowserAnswer {
        match (double, entry.is_dir) {
            (true, true) => {
                self.typed.clear();
                self.show_folder(self.folder.join(&entry.name));
                BrowserAnswer::Open
            }
            (true, false) => {
                self.typed = entry.name.clone();
                self.confirm()
            }
            (false, _) => {
                self.typed = entry.name.clone();
                BrowserAnswer::Open
            }
        }
    }

    /// The browser window; returns what happened.
    pub fn ui(&mut self, ctx: &egui::Context) -> BrowserAnswer {
        let mut answer = BrowserAnswer::Open;
        let mut open = true;
        egui::Window::new(self.title)
            .id(egui::Id::unique("neural-cloth file browser"))
            .open(&mut open)
            .collapsible(false)
            .default_size(egui::vec2(520.0, 380.0))
            .show(ctx, |ui| answer = self.contents_ui(ui));
        if !open || ctx.input(|i| i.key_pressed(egui::Key::Escape)) {
            answer = BrowserAnswer::Cancelled;
        }
        answer
    }

    fn contents_ui(&mut self, ui: &mut egui::Ui) -> BrowserAnswer {
        let mut answer = BrowserAnswer::Open;
        ui.horizontal(|ui| {
            let parent = self.folder.parent().map(Path::to_path_buf);
            if ui
                .add_enabled(parent.is_some(), egui::Button::new("Up"))
                .on_hover_text("the parent folder")
                .clicked()
                && let Some(parent) = parent
            {
                self.show_folder(parent);
            }
            ui.monospace(self.folder.display().to_string());
        });
        ui.horizontal(|ui| {
            let label = ui.label("Path:");
            let edit = egui::TextEdit::singleline(&mut self.typed)
                .hint_text("a folder, a file, or a name")
                .desired_width(300.0);
            let response = ui.add(edit).labelled_by(label.id);
            if response.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
                answer = self.confirm();
            }
        });
        if !self.extensions.is_empty() && self.choose != Choose::Folder {
            let filter = self.extensions.join(", ");
            ui.checkbox(
                &mut self.all_files,
                format!("all files (not only {filter})"),
            );
        }
        if let Err(e) = &self.entries {
            ui.colored_label(ui.visuals().error_fg_color, e.to_string());
        }
        egui::ScrollArea::vertical()
            .id_salt("file browser entries")
            .max_height(220.0)
            .auto_shrink([false, true])
            .show(ui, |ui| {
                for entry in self.shown() {
                    let text = match entry.is_dir {
                        true => format!("{}/", entry.name),
                        false => entry.name.clone(),
                    };
                    let selected = self.typed.trim() == entry.name;
                    let response = ui.selectable_label(selected, text);
                    if response.double_clicked() {
                        answer = self.entry_clicked(&entry, true);
                    } else if response.clicked() {
                        answer = self.entry_clicked(&entry, false);
                    }
                }
            });
        if let Some(problem) = &self.problem {
            ui.colored_label(ui.visuals().error_fg_color, problem);
        }
        ui.horizontal(|ui| {
            let main = match self.choose {
                Choose::OpenFile => "Open",
                Choose::SaveFile => "Save",
                Choose::Folder => "Use this folder",
            };
            if ui.button(main).clicked() {
                answer = self.confirm();
            }
            if ui.button("Cancel").clicked() {
                answer = BrowserAnswer::Cancelled;
            }
        });
        answer
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tree() -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir(dir.path().join("runs")).unwrap();
        std::fs::create_dir(dir.path().join(".hidden")).unwrap();
        std::fs::write(dir.path().join("b.toml"), b"").unwrap();
        std::fs::write(dir.path().join("a.obj"), b"").unwrap();
        dir
    }

    #[test]
    fn folders_come_first_and_the_filter_hides_other_files() {
        let dir = tree();
        let mut b = FileBrowser::new(
            "t",
            Choose::OpenFile,
            &["toml"],
            dir.path().into(),
            String::new(),
        );
        let names: Vec<String> = b.shown().into_iter().map(|e| e.name).collect();
        assert_eq!(names, vec!["runs", "b.toml"]);
        b.all_files = true;
        assert_eq!(b.shown().len(), 3);
    }

    #[test]
    fn typed_paths_open_folders_and_choose_files() {
        let dir = tree();
        let mut b = FileBrowser::new(
            "t",
            Choose::OpenFile,
            &["toml"],
            dir.path().join("runs"),
            String::new(),
        );
        b.typed = "..".into();
        assert_eq!(b.confirm(), BrowserAnswer::Open);
        assert_eq!(b.folder, dir.path());
        b.typed = dir.path().join("b.toml").display().to_string();
        assert_eq!(
            b.confirm(),
            BrowserAnswer::Chosen(dir.path().join("b.toml"))
        );
        b.typed = "missing.toml".into();
        assert_eq!(b.confirm(), BrowserAnswer::Open);
        assert!(b.problem.as_deref().unwrap_or("").contains("no such file"));
        // Saving: a new name in the folder shown; folders: the folder shown.
        let mut s = FileBrowser::new(
            "t",
            Choose::SaveFile,
            &[],
            dir.path().into(),
            "new.toml".into(),
        );
        assert_eq!(
            s.confirm(),
            BrowserAnswer::Chosen(dir.path().join("new.toml"))
        );
        let mut f = FileBrowser::new("t", Choose::Folder, &[], dir.path().into(), "runs".into());
        assert_eq!(f.confirm(), BrowserAnswer::Chosen(dir.path().join("runs")));
        f.typed.clear();
        assert_eq!(f.confirm(), BrowserAnswer::Chosen(dir.path().to_path_buf()));
    }
}
