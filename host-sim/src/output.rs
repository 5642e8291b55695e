//! Output files that are either complete or absent: written to a temporary file beside the
//! target and renamed into place only when everything was written. A command with several
//! outputs puts them in place together ([`commit_all`], [`StagedDir`]), after all of them were
//! written, so that a failure leaves none of them.

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
        self.finish_writing()?;
        std::fs::rename(&self.tmp, &self.path)
            .with_context(|| format!("cannot write {}", self.path.display()))?;
        self.committed = true;
        Ok(())
    }

    /// Flushes and syncs the temporary file.
    fn finish_writing(&mut self) -> Result<()> {
        self.w
            .flush()
            .with_context(|| format!("cannot write {}", self.path.display()))?;
        self.w.get_ref().sync_all().ok();
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
    render_staged(path, draw)?.commit()
}

/// [`render_atomically`] without the rename: the image stays at its temporary path until
/// [`StagedPath::commit`] (or [`commit_all`], with the other outputs of the command), and is
/// removed if dropped before.
///
/// # Errors
/// When `draw` fails (the temporary file is removed then).
pub fn render_staged<F>(path: &Path, draw: F) -> Result<StagedPath>
where
    F: FnOnce(&Path) -> Result<()>,
{
    let staged = StagedPath::new(path, ".png");
    draw(&staged.tmp)?;
    Ok(staged)
}

/// A file that another library writes by its path (a PNG through plotters): written at a
/// temporary path beside `path`, renamed to `path` by [`StagedPath::commit`] and removed if
/// dropped before.
pub struct StagedPath {
    path: PathBuf,
    tmp: PathBuf,
    committed: bool,
}

impl StagedPath {
    /// The temporary path for `path` (ending in `suffix`, e.g. `.png` for a writer that picks
    /// the format by extension); nothing is created.
    #[must_use]
    pub fn new(path: &Path, suffix: &str) -> Self {
        Self {
            path: path.to_path_buf(),
            tmp: temp_path(path, suffix),
            committed: false,
        }
    }

    /// Where to write.
    #[must_use]
    pub fn tmp(&self) -> &Path {
        &self.tmp
    }

    /// The final path.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Renames the file into place.
    ///
    /// # Errors
    /// When it cannot be renamed.
    pub fn commit(mut self) -> Result<()> {
        std::fs::rename(&self.tmp, &self.path)
            .with_context(|| format!("cannot write {}", self.path.display()))?;
        self.committed = true;
        Ok(())
    }
}

impl Drop for StagedPath {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// One output of a command, written but not in place yet.
pub enum Staged {
    /// Written through [`AtomicFile`].
    File(AtomicFile),
    /// Written by path ([`render_staged`]).
    Path(StagedPath),
}

impl From<AtomicFile> for Staged {
    fn from(f: AtomicFile) -> Self {
        Self::File(f)
    }
}

impl From<StagedPath> for Staged {
    fn from(p: StagedPath) -> Self {
        Self::Path(p)
    }
}

/// Puts the outputs of one command in place together, once every one of them was written:
/// the files are flushed first, a target that is a folder is refused before anything moves,
/// and if a rename still fails the outputs already moved are removed again, so that the
/// command leaves all of its outputs or none (and no temporary file).
///
/// # Errors
/// When a file cannot be written or renamed.
pub fn commit_all(mut outputs: Vec<Staged>) -> Result<()> {
    for o in &mut outputs {
        if let Staged::File(f) = o {
            f.finish_writing()?;
        }
    }
    let moves: Vec<(PathBuf, PathBuf)> = outputs
        .iter()
        .map(|o| match o {
            Staged::File(f) => (f.tmp.clone(), f.path.clone()),
            Staged::Path(p) => (p.tmp.clone(), p.path.clone()),
        })
        .collect();
    place_together(&moves)?;
    for o in &mut outputs {
        match o {
            Staged::File(f) => f.committed = true,
            Staged::Path(p) => p.committed = true,
        }
    }
    Ok(())
}

/// Renames each `(from, to)`; refuses a `to` that is a folder before renaming anything, and on
/// a failed rename removes the `to`s renamed before it.
fn place_together(moves: &[(PathBuf, PathBuf)]) -> Result<()> {
    if let Some((_, to)) = moves.iter().find(|(_, to)| to.is_dir()) {
        bail!("cannot write {}: it is a folder", to.display());
    }
    for (i, (from, to)) in moves.iter().enumerate() {
        if let Err(e) = std::fs::rename(from, to) {
            for (_, done) in &moves[..i] {
                let _ = std::fs::remove_file(done);
            }
            return Err(e).with_context(|| format!("cannot write {}", to.display()));
        }
    }
    Ok(())
}

/// A folder of outputs written by functions that take a folder (a scene's files): they are
/// written into a hidden staging folder inside it ([`StagedDir::path`]) and moved into the
/// folder together by [`StagedDir::commit`]; if dropped before, the staging folder is removed
/// (and the folder too when this created it and it is empty).
pub struct StagedDir {
    dir: PathBuf,
    tmp: PathBuf,
    created: bool,
    committed: bool,
}

impl StagedDir {
    /// Creates `dir` (when missing) and the staging folder in it.
    ///
    /// # Errors
    /// When either cannot be created.
    pub fn create(dir: &Path) -> Result<Self> {
        let created = !dir.exists();
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
        let name = dir
            .file_name()
            .map_or_else(|| "out".into(), |n| n.to_string_lossy().into_owned());
        let tmp = dir.join(format!(".{name}.partial-{}", std::process::id()));
        let staged = Self {
            dir: dir.to_path_buf(),
            tmp,
            created,
            committed: false,
        };
        std::fs::create_dir(&staged.tmp)
            .with_context(|| format!("cannot create {}", staged.tmp.display()))?;
        Ok(staged)
    }

    /// The staging folder, to write into.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.tmp
    }

    /// Moves every file of the staging folder into the folder (as [`commit_all`] does) and
    /// removes the staging folder.
    ///
    /// # Errors
    /// When a file cannot be moved (none is left moved then).
    pub fn commit(mut self) -> Result<()> {
        let mut names = Vec::new();
        let entries = std::fs::read_dir(&self.tmp)
            .with_context(|| format!("cannot read {}", self.tmp.display()))?;
        for e in entries {
            let e = e.with_context(|| format!("cannot read {}", self.tmp.display()))?;
            names.push(e.file_name());
        }
        names.sort();
        let moves: Vec<(PathBuf, PathBuf)> = names
            .iter()
            .map(|n| (self.tmp.join(n), self.dir.join(n)))
            .collect();
        place_together(&moves)?;
        self.committed = true;
        let _ = std::fs::remove_dir(&self.tmp);
        Ok(())
    }
}

impl Drop for StagedDir {
    fn drop(&mut self) {
        if !self.committed {
            let _ = std::fs::remove_dir_all(&self.tmp);
            if self.created {
                let _ = std::fs::remove_dir(&self.dir);
            }
        }
    }
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
