//! Output files that are either complete or absent: written to a temporary file beside the
//! target and renamed into place only when everything was written.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

/// A file being written: a temporary file beside `path`, renamed to `path` by
/// [`AtomicFile::commit`] and removed if dropped before.
pub struct AtomicFile {
    path: PathBuf,
    tmp: PathBuf,
    w: BufWriter<File>,
    committed: bool,
}

impl AtomicFile {
    /// Creates the temporary file for `path`.
    ///
    /// # Errors
    /// When it cannot be created.
    pub fn create(path: &Path) -> Result<Self> {
        let tmp = temp_path(path, "");
        let file =
            File::create(&tmp).with_context(|| format!("cannot create {}", tmp.display()))?;
        Ok(Self {
            path: path.to_path_buf(),
            tmp,
            w: BufWriter::with_capacity(1 << 16, file),
            committed: false,
        })
    }

    /// The writer.
    pub fn writer(&mut self) -> &mut BufWriter<File> {
        &mut self.w
    }

    /// The final path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes, syncs and renames the file into place.
    ///
    /// # Errors
    /// When the data cannot be written or the file cannot be renamed.
    pub fn commit(mut self) -> Result<()> {
        self.w
            .flush()
            .with_context(|| format!("cannot write {}", self.path.display()))?;
        self.w.get_ref().sync_all().ok();
        std::fs::rename(&self.tmp, &self.path)
            .with_context(|| format!("cannot write {}", self.path.display()))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes `path` through `fill`. On any error the partial file is removed and `path` is left as
/// it was, so that no half-written output can pass for a complete one.
pub fn write_atomically<F>(path: &Path, fill: F) -> Result<()>
where
    F: FnOnce(&mut BufWriter<File>) -> Result<()>,
{
    let mut f = AtomicFile::create(path)?;
    fill(f.writer())?;
    f.commit()
}

/// Renders a PNG at `path` through `draw`, which writes the image to the path it is given (a
/// temporary `.png` beside `path`); the result is renamed into place, and removed on error.
pub fn render_atomically<F>(path: &Path, draw: F) -> Result<()>
where
    F: FnOnce(&Path) -> Result<()>,
{
    let tmp = temp_path(path, ".png");
    let result = draw(&tmp).and_then(|()| {
        std::fs::rename(&tmp, path).with_context(|| format!("cannot write {}", path.display()))
    });
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Refuses an output that is one of the inputs (or another output): writing it would destroy
/// the data being read. Paths are compared as files (device and inode), so links and different
/// spellings of one file are caught.
///
/// # Errors
/// When two of the paths name the same existing file.
pub fn check_distinct(inputs: &[&Path], outputs: &[(&str, &Path)]) -> Result<()> {
    for (i, (flag, out)) in outputs.iter().enumerate() {
        let Some(id) = file_id(out) else { continue };
        if let Some(input) = inputs.iter().find(|p| file_id(p) == Some(id)) {
            bail!(
                "{flag} {} is the input {}: refusing to overwrite it",
                out.display(),
                input.display()
            );
        }
        if let Some((other, _)) = outputs.iter().take(i).find(|(_, p)| file_id(p) == Some(id)) {
            bail!("{flag} {} is also given to {other}", out.display());
        }
    }
    Ok(())
}

/// Device and inode of an existing file.
fn file_id(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::metadata(path).ok()?;
    Some((m.dev(), m.ino()))
}

fn temp_path(path: &Path, suffix: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    path.with_file_name(format!(".{name}.partial-{}{suffix}", std::process::id()))
}
