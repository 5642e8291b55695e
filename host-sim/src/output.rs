//! Output files that are either complete or absent: written to a temporary file beside the
//! target and renamed into place only when everything was written. A command with several
//! outputs puts them in place together ([`commit_all`], [`StagedDir`]), after all of them were
//! written, so that a failure leaves none of them.
//!
//! A target that already exists and is not a regular file (`/dev/null`, `/dev/stdout`, a named
//! pipe: [`is_stream`]) is written in place instead: renaming a file onto it would replace the
//! device or pipe itself (as root, `--out /dev/null` would leave a regular file at
//! `/dev/null`), and a stream cannot be "absent" anyway. `-` names standard output. An output
//! that is a link is followed: the file it points to is replaced, and the link stays.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use anyhow::{bail, Context, Result};

/// A file being written: a temporary file beside `path`, renamed to `path` by
/// [`AtomicFile::commit`] and removed if dropped before.
pub struct AtomicFile {
    path: PathBuf,
    /// The temporary file; `None` for a stream ([`is_stream`]), written in place: nothing to
    /// rename or remove.
    tmp: Option<PathBuf>,
    w: BufWriter<File>,
    committed: bool,
}

impl AtomicFile {
    /// Creates the temporary file for `path`.
    ///
    /// # Errors
    /// When it cannot be created.
    pub fn create(path: &Path) -> Result<Self> {
        let path = output_path(path);
        let tmp = (!is_stream(&path)).then(|| temp_path(&path, ""));
        let (file, opened) = match &tmp {
            Some(tmp) => (File::create(tmp), tmp),
            None => (std::fs::OpenOptions::new().append(true).open(&path), &path),
        };
        let file = file.with_context(|| format!("cannot create {}", opened.display()))?;
        Ok(Self {
            path,
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
        if let Some(tmp) = &self.tmp {
            place(tmp, &self.path)
                .with_context(|| format!("cannot write {}", self.path.display()))?;
        }
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
        if let (false, Some(tmp)) = (self.committed, &self.tmp) {
            let _ = std::fs::remove_file(tmp);
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
        let path = output_path(path);
        Self {
            tmp: temp_path(&path, suffix),
            path,
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
        place(&self.tmp, &self.path)
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
        .filter_map(|o| match o {
            Staged::File(f) => f.tmp.clone().map(|tmp| (tmp, f.path.clone())),
            Staged::Path(p) => Some((p.tmp.clone(), p.path.clone())),
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
        if let Err(e) = place(from, to) {
            for (_, done) in moves[..i].iter().filter(|(_, done)| !is_stream(done)) {
                let _ = std::fs::remove_file(resolved(done));
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

/// Device and inode of an existing regular file (or folder); `None` for a stream
/// ([`is_stream`]), which any number of outputs may share.
fn file_id(path: &Path) -> Option<(u64, u64)> {
    use std::os::unix::fs::MetadataExt;
    let m = std::fs::metadata(path).ok()?;
    if is_stream(path) {
        return None;
    }
    Some((m.dev(), m.ino()))
}

/// The file an output named `path` goes to: `-` is standard output (`/dev/stdout`).
#[must_use]
pub fn output_path(path: &Path) -> PathBuf {
    if path == Path::new("-") {
        PathBuf::from("/dev/stdout")
    } else {
        path.to_path_buf()
    }
}

/// Whether `path` is written in place rather than replaced (opened to append: standard output
/// redirected with `>>` keeps what it holds): it exists and is neither a
/// regular file nor a folder (a character device such as `/dev/null`, a named pipe, a
/// socket), or it names an open descriptor (`/dev/stdout`, `/dev/fd/N`, `/proc/self/fd/N`:
/// what the shell redirected it to is the output, whatever that is).
#[must_use]
pub fn is_stream(path: &Path) -> bool {
    let special = std::fs::metadata(path).is_ok_and(|m| !m.is_file() && !m.is_dir());
    special || names_a_descriptor(path)
}

/// Whether `path` or a link on the way from it lies under `/proc` or `/dev/fd`.
fn names_a_descriptor(path: &Path) -> bool {
    let mut p = path.to_path_buf();
    for _ in 0..8 {
        if p.starts_with("/proc") || p.starts_with("/dev/fd") {
            return true;
        }
        match std::fs::read_link(&p) {
            Ok(next) => p = p.parent().unwrap_or(Path::new("/")).join(next),
            Err(_) => return false,
        }
    }
    false
}

/// The file an output replaces: `path` with its links followed (so that a link to an output
/// stays a link, to the new file), or `path` itself when it does not exist yet.
fn resolved(path: &Path) -> PathBuf {
    std::fs::canonicalize(path).unwrap_or_else(|_| path.to_path_buf())
}

/// The folder for temporary files of the output `path`: the folder of the file it replaces
/// (so that the rename stays on one file system), or the system's temporary folder for a
/// stream (whose folder, `/dev`, is no place for files).
#[must_use]
pub fn scratch_dir(path: &Path) -> PathBuf {
    let path = &output_path(path);
    if is_stream(path) {
        return std::env::temp_dir();
    }
    match resolved(path).parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// Moves the finished temporary file `from` to `to`: a rename onto the file `to` names, or for
/// a stream a copy into it (and `from` removed).
fn place(from: &Path, to: &Path) -> std::io::Result<()> {
    if is_stream(to) {
        let mut src = File::open(from)?;
        let mut dst = std::fs::OpenOptions::new().append(true).open(to)?;
        std::io::copy(&mut src, &mut dst)?;
        std::fs::remove_file(from)
    } else {
        std::fs::rename(from, resolved(to))
    }
}

fn temp_path(path: &Path, suffix: &str) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    scratch_dir(path).join(format!(".{name}.partial-{}{suffix}", std::process::id()))
}
