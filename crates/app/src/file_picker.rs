//! Choosing files and folders: the desktop's file dialog (rfd) where the desktop has a
//! file-dialog service, and the in-app file browser ([`super::file_browser`]: folder listing,
//! parent folder, filter by extension, a typed path) where it has none, e.g. a Linux machine
//! without an XDG desktop portal, on which rfd returns nothing at once.
//!
//! A request names its [`PickPurpose`]; the chosen path comes back from
//! [`FilePicker::take_picked`] (at once from the desktop dialog, or on a later frame from the
//! in-app browser) and the app dispatches it.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::export::ExportFormat;
use super::file_browser::{BrowserAnswer, Choose, FileBrowser};
use super::scene_edit::LoadKind;

/// A desktop dialog that returns nothing faster than this never opened (no person cancels a
/// dialog this fast): the in-app browser takes over, now and for the rest of the session.
pub const NO_DIALOG_SECS: f64 = 0.3;

/// Which file dialog the app uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DialogMode {
    /// The desktop's dialog where a dialog service seems to exist, else the in-app browser.
    #[default]
    Auto,
    /// Always the in-app browser (tests; a desktop whose dialog misbehaves).
    InApp,
}

/// What a chosen path is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PickPurpose {
    /// A scene part to load.
    Load(LoadKind),
    /// A project file to open.
    OpenProject,
    /// Where to save the project.
    SaveProject,
    /// A run folder whose trained model to load.
    OpenRun,
    /// The folder new runs are written under.
    RunsFolder,
    /// Where the export dialog writes a bake of this format: a file of its extension, or a
    /// folder for the OBJ sequence.
    ExportPath(ExportFormat),
}

impl PickPurpose {
    /// The dialog's title.
    pub fn title(self) -> &'static str {
        match self {
            Self::Load(kind) => kind.title(),
            Self::OpenProject => "Open project",
            Self::SaveProject => "Save project as",
            Self::OpenRun => "Open run folder",
            Self::RunsFolder => "Folder for new runs",
            Self::ExportPath(_) => "Export to",
        }
    }

    /// File extensions offered (empty: folders, or any file).
    pub fn extensions(self) -> &'static [&'static str] {
        match self {
            Self::Load(kind) => kind.extensions(),
            Self::OpenProject | Self::SaveProject => &[super::project::PROJECT_EXTENSION],
            Self::OpenRun | Self::RunsFolder => &[],
            Self::ExportPath(ExportFormat::ObjSequence) => &[],
            Self::ExportPath(format) => format.extensions(),
        }
    }

    /// The file name a save starts with when none is given.
    pub fn default_name(self) -> String {
        match self {
            Self::ExportPath(format) => format.with_extension("export"),
            _ => format!("project.{}", super::project::PROJECT_EXTENSION),
        }
    }

    fn choose(self) -> Choose {
        match self {
            Self::Load(_) | Self::OpenProject => Choose::OpenFile,
            Self::ExportPath(ExportFormat::ObjSequence) => Choose::Folder,
            Self::SaveProject | Self::ExportPath(_) => Choose::SaveFile,
            Self::OpenRun | Self::RunsFolder => Choose::Folder,
        }
    }
}

/// True when `path` is a folder or has one of `extensions` (any file when there are none).
pub fn matches_extension(path: &Path, extensions: &[&str]) -> bool {
    path.is_dir()
        || extensions.is_empty()
        || extensions
            .iter()
            .any(|e| neural_cloth_core::io::scene_loader::extension(path) == *e)
}

/// True when this session may have a desktop file-dialog service: on Linux and the BSDs rfd
/// talks to the XDG desktop portal over the session bus, so without a bus there is none.
pub fn desktop_dialog_possible() -> bool {
    if cfg!(any(target_os = "windows", target_os = "macos")) {
        return true;
    }
    std::env::var_os("DBUS_SESSION_BUS_ADDRESS").is_some_and(|v| !v.is_empty())
}

/// The file dialogs of the app: the desktop's, or the in-app browser.
#[derive(Default)]
pub struct FilePicker {
    /// Which dialog to use.
    pub mode: DialogMode,
    /// Set once the desktop dialog gave nothing at once: the in-app browser is used from then.
    pub desktop_failed: bool,
    browser: Option<(PickPurpose, FileBrowser)>,
    picked: Option<(PickPurpose, PathBuf)>,
}

impl std::fmt::Debug for FilePicker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FilePicker")
            .field("mode", &self.mode)
            .field("desktop_failed", &self.desktop_failed)
            .field("browsing", &self.browser.as_ref().map(|(p, _)| *p))
            .finish()
    }
}

impl FilePicker {
    /// A picker using `mode`.
    pub fn new(mode: DialogMode) -> Self {
        Self {
            mode,
            ..Default::default()
        }
    }

    /// True while the in-app browser is open.
    pub fn is_browsing(&self) -> bool {
        self.browser.is_some()
    }

    /// Whether a request would try the desktop dialog first.
    pub fn uses_desktop(&self) -> bool {
        self.mode == DialogMode::Auto && !self.desktop_failed && desktop_dialog_possible()
    }

    /// Asks for a path for `purpose`, starting in `start` (a folder or a file). The desktop
    /// dialog blocks until the person chooses; the in-app browser opens and answers on a later
    /// frame. Either way the answer comes from [`Self::take_picked`].
    pub fn request(&mut self, purpose: PickPurpose, start: Option<&Path>) {
        if self.uses_desktop() {
            let asked = Instant::now();
            let answer = desktop_dialog(purpose, start);
            if self.desktop_answered(purpose, answer, asked.elapsed()) {
                return;
            }
        }
        self.open_browser(purpose, start);
    }

    /// Takes the desktop dialog's answer, given after `took` (a save path gets the purpose's
    /// extension when it has none, as in the in-app browser); false when no dialog opened and
    /// the in-app browser should be used instead.
    fn desktop_answered(
        &mut self,
        purpose: PickPurpose,
        answer: Option<PathBuf>,
        took: Duration,
    ) -> bool {
        match answer {
            Some(path) => {
                self.picked = Some((purpose, with_extension(path, purpose)));
                true
            }
            None if took > Duration::from_secs_f64(NO_DIALOG_SECS) => true,
            None => {
                self.desktop_failed = true;
                false
            }
        }
    }

    fn open_browser(&mut self, purpose: PickPurpose, start: Option<&Path>) {
        let folder = start
            .map(|p| match p.is_dir() {
                true => p.to_path_buf(),
                false => p.parent().map(Path::to_path_buf).unwrap_or_default(),
            })
            .filter(|p| p.is_dir())
            .or_else(|| std::env::current_dir().ok())
            .unwrap_or_default();
        let folder = std::path::absolute(&folder).unwrap_or(folder);
        let typed = match purpose.choose() {
            Choose::SaveFile => start
                .filter(|p| !p.is_dir())
                .and_then(|p| p.file_name())
                .map(|n| n.to_string_lossy().into_owned())
                .unwrap_or_else(|| purpose.default_name()),
            Choose::OpenFile | Choose::Folder => String::new(),
        };
        let browser = FileBrowser::new(
            purpose.title(),
            purpose.choose(),
            purpose.extensions(),
            folder,
            typed,
        );
        self.browser = Some((purpose, browser));
    }

    /// Shows `folder` in the open in-app browser (what typing its path does).
    pub fn browse_to(&mut self, folder: &Path) {
        if let Some((_, browser)) = &mut self.browser {
            browser.show_folder(folder.to_path_buf());
        }
    }

    /// Closes the in-app browser without a choice.
    pub fn cancel(&mut self) {
        self.browser = None;
    }

    /// Shows the in-app browser while it is open; a confirmed choice becomes the answer of
    /// [`Self::take_picked`] (a save path gets the purpose's extension when it has none).
    pub fn browser_ui(&mut self, ctx: &egui::Context) {
        let Some((purpose, browser)) = &mut self.browser else {
            return;
        };
        let purpose = *purpose;
        match browser.ui(ctx) {
            BrowserAnswer::Open => {}
            BrowserAnswer::Chosen(path) => {
                self.browser = None;
                self.picked = Some((purpose, with_extension(path, purpose)));
            }
            BrowserAnswer::Cancelled => self.browser = None,
        }
    }

    /// The path chosen since the last call, with what it is for.
    pub fn take_picked(&mut self) -> Option<(PickPurpose, PathBuf)> {
        self.picked.take()
    }
}

/// `path` with the purpose's extension added when saving a file that has none.
fn with_extension(path: PathBuf, purpose: PickPurpose) -> PathBuf {
    match (purpose.choose(), purpose.extensions().first()) {
        (Choose::SaveFile, Some(ext)) if path.extension().is_none() => path.with_extension(ext),
        _ => path,
    }
}

/// The desktop's dialog (blocks until it closes; None when cancelled or when none opened).
fn desktop_dialog(purpose: PickPurpose, start: Option<&Path>) -> Option<PathBuf> {
    let mut dialog = rfd::FileDialog::new().set_title(purpose.title());
    if !purpose.extensions().is_empty() {
        dialog = dialog.add_filter(purpose.title(), purpose.extensions());
    }
    if let Some(start) = start {
        match start.is_dir() {
            true => dialog = dialog.set_directory(start),
            false => {
                if let Some(dir) = start.parent().filter(|d| d.is_dir()) {
                    dialog = dialog.set_directory(dir);
                }
                if let Some(name) = start.file_name() {
                    dialog = dialog.set_file_name(name.to_string_lossy());
                }
            }
        }
    }
    match purpose.choose() {
        Choose::OpenFile => dialog.pick_file(),
        Choose::SaveFile => dialog.save_file(),
        Choose::Folder => dialog.pick_folder(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn filters_keep_folders_and_matching_files() {
        let dir = tempfile::tempdir().unwrap();
        let obj = dir.path().join("shirt.OBJ");
        std::fs::write(&obj, b"").unwrap();
        let exts = PickPurpose::Load(LoadKind::Garment).extensions();
        assert!(matches_extension(&obj, exts));
        assert!(matches_extension(dir.path(), exts));
        assert!(!matches_extension(&dir.path().join("walk.bvh"), exts));
        assert!(matches_extension(&dir.path().join("x.any"), &[]));
    }

    #[test]
    fn an_export_path_follows_its_format_and_the_obj_sequence_is_a_folder() {
        let obj = PickPurpose::ExportPath(ExportFormat::ObjSequence);
        assert_eq!(obj.choose(), Choose::Folder);
        assert!(obj.extensions().is_empty());
        assert_eq!(obj.default_name(), "export");
        assert_eq!(
            with_extension(PathBuf::from("/tmp/frames"), obj),
            PathBuf::from("/tmp/frames")
        );
        let usd = PickPurpose::ExportPath(ExportFormat::Usd);
        assert_eq!(usd.choose(), Choose::SaveFile);
        assert_eq!(usd.extensions(), ["usda"]);
        assert_eq!(usd.default_name(), "export.usda");
        // The desktop dialog's answer gets the extension too.
        let mut picker = FilePicker::default();
        let glb = PickPurpose::ExportPath(ExportFormat::Glb);
        assert!(picker.desktop_answered(glb, Some("/tmp/walk".into()), Duration::ZERO));
        assert_eq!(
            picker.take_picked(),
            Some((glb, PathBuf::from("/tmp/walk.glb")))
        );
        // A dialog that never opened hands over to the in-app browser.
        assert!(!picker.desktop_answered(glb, None, Duration::ZERO));
        assert!(picker.desktop_failed);
    }

    #[test]
    fn a_saved_project_gets_its_extension() {
        let p = with_extension(PathBuf::from("/tmp/mine"), PickPurpose::SaveProject);
        assert_eq!(p, PathBuf::from("/tmp/mine.toml"));
        let p = with_extension(PathBuf::from("/tmp/run"), PickPurpose::OpenRun);
        assert_eq!(p, PathBuf::from("/tmp/run"));
    }
}
