//! Atomic file and folder writes: data goes to a hidden temporary next to the target and is
//! renamed into place only when complete, so a failed export never leaves a partial file.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::ExportError;

/// A buffered file that becomes visible at its final path only on [`AtomicFile::commit`].
/// Dropping it uncommitted deletes the temporary.
pub struct AtomicFile {
    final_path: PathBuf,
    temp_path: PathBuf,
    writer: Option<BufWriter<File>>,
}

/// The hidden temporary path used for `path` (same folder, so the rename is atomic).
pub fn temp_path_for(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

impl AtomicFile {
    /// Creates the temporary file for `path`. The folder must exist and be writable.
    pub fn create(path: &Path) -> Result<Self, ExportError> {
        let temp_path = temp_path_for(path);
        let file = File::create(&temp_path).map_err(|e| ExportError::io(e, path))?;
        Ok(Self {
            final_path: path.to_path_buf(),
            temp_path,
            writer: Some(BufWriter::with_capacity(1 << 20, file)),
        })
    }

    /// The buffered writer of the temporary file.
    pub fn writer(&mut self) -> Result<&mut BufWriter<File>, ExportError> {
        let path = &self.final_path;
        self.writer.as_mut().ok_or_else(|| ExportError::Format {
            reason: "file already committed".into(),
            path: path.clone(),
        })
    }

    /// The path the file will have once committed.
    pub fn path(&self) -> &Path {
        &self.final_path
    }

    /// Flushes, syncs and renames the temporary onto the final path.
    pub fn commit(mut self) -> Result<PathBuf, ExportError> {
        let Some(writer) = self.writer.take() else {
            return Ok(self.final_path.clone());
        };
        let file = writer
            .into_inner()
            .map_err(|e| ExportError::io(e.into_error(), &self.final_path))?;
        file.sync_all()
            .map_err(|e| ExportError::io(e, &self.final_path))?;
        drop(file);
        std::fs::rename(&self.temp_path, &self.final_path)
            .map_err(|e| ExportError::io(e, &self.final_path))?;
        Ok(self.final_path.clone())
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match self.writer.as_mut() {
            Some(w) => w.write(buf),
            None => Err(std::io::Error::other("file already committed")),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match self.writer.as_mut() {
            Some(w) => w.flush(),
            None => Ok(()),
        }
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if self.writer.take().is_some() {
            let _ = std::fs::remove_file(&self.temp_path);
        }
    }
}

/// Writes a whole file atomically.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    let mut f = AtomicFile::create(path)?;
    f.write_all(bytes).map_err(|e| ExportError::io(e, path))?;
    f.commit()?;
    Ok(())
}

/// A folder built under a hidden temporary name and renamed into place on commit; removed with
/// its contents when dropped uncommitted. The final folder must not exist yet (or be empty).
pub struct AtomicDir {
    final_path: PathBuf,
    temp_path: PathBuf,
    committed: bool,
}

impl AtomicDir {
    /// Creates the temporary folder for `path`.
    pub fn create(path: &Path) -> Result<Self, ExportError> {
        let temp_path = temp_path_for(path);
        let _ = std::fs::remove_dir_all(&temp_path);
        std::fs::create_dir(&temp_path).map_err(|e| ExportError::io(e, path))?;
        Ok(Self {
            final_path: path.to_path_buf(),
            temp_path,
            committed: false,
        })
    }

    /// Where files are written until commit.
    pub fn temp_path(&self) -> &Path {
        &self.temp_path
    }

    /// Renames the folder into place (replacing an empty existing folder).
    pub fn commit(mut self) -> Result<PathBuf, ExportError> {
        if self.final_path.is_dir() {
            std::fs::remove_dir(&self.final_path)
                .map_err(|e| ExportError::io(e, &self.final_path))?;
        }
        std::fs::rename(&self.temp_path, &self.final_path)
            .map_err(|e| ExportError::io(e, &self.final_path))?;
        self.committed = true;
        Ok(self.final_path.clone())
    }
}

impl Drop for AtomicDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.temp_path);
        }
    }
}
