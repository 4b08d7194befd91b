//! Safe output: every file and folder a run writes appears complete or not at all.
//!
//! - A regular file (new or existing) is written to a temporary file in its folder and
//!   renamed over the path when complete ([`AtomicFile`]). A new file gets the mode
//!   `0666 & !umask`, as `touch` would give it; an existing one keeps its mode. A symbolic
//!   link is followed: its target is replaced and the link stays.
//! - A path that exists and is not a regular file (`/dev/null`, a FIFO, a terminal) is
//!   written in place: renaming over it would replace the device with a file.
//! - `-` is standard output.
//! - A folder of outputs (PNG frames, a sequence) is written into a hidden temporary folder
//!   beside it and swapped in at the end ([`AtomicDir`]), so no stale or partial frames mix
//!   with the new ones.
//!
//! Temporary paths carry the `.roadtrack-` prefix and a `.partial` or `.tmp` suffix. While
//! a run writes them they are registered, so the command line's SIGINT/SIGTERM handler can
//! remove them ([`remove_pending_outputs`]) before it exits; only SIGKILL can leave one
//! behind, hidden and never under the output's name.

use crate::error::{Error, Result};
use std::collections::BTreeSet;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};

/// Temporary outputs being written, for [`remove_pending_outputs`]. A temporary is made
/// and registered, and committed and unregistered, under this lock, so a signal handler
/// that takes it sees every temporary that exists and no half-committed output.
static PENDING: Mutex<BTreeSet<PathBuf>> = Mutex::new(BTreeSet::new());

fn pending() -> MutexGuard<'static, BTreeSet<PathBuf>> {
    PENDING.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Registers a temporary path while it lives.
#[derive(Debug)]
struct Pending(PathBuf);

impl Pending {
    /// Makes a temporary with `make` and registers the path `path_of` gives, under the
    /// registry's lock.
    fn make<T>(
        make: impl FnOnce() -> Result<T>,
        path_of: impl FnOnce(&T) -> PathBuf,
    ) -> Result<(T, Self)> {
        let mut set = pending();
        let t = make()?;
        let path = path_of(&t);
        set.insert(path.clone());
        Ok((t, Self(path)))
    }

    /// Runs `commit` and unregisters the path, under the registry's lock.
    fn commit<R>(self, commit: impl FnOnce() -> R) -> R {
        let mut set = pending();
        let r = commit();
        set.remove(&self.0);
        drop(set);
        std::mem::forget(self);
        r
    }
}

impl Drop for Pending {
    fn drop(&mut self) {
        pending().remove(&self.0);
    }
}

/// Removes every temporary output still being written (files and folders). For a signal
/// handler that is about to exit the process; returns how many it removed.
pub fn remove_pending_outputs() -> usize {
    remove_pending(&mut pending(), |_| true)
}

/// Removes every temporary output still being written, then exits the process with
/// `code`, holding the registry's lock so that no thread makes a new temporary meanwhile.
pub fn remove_pending_outputs_and_exit(code: i32) -> ! {
    let mut set = pending();
    remove_pending(&mut set, |_| true);
    std::process::exit(code)
}

/// Removes the registered temporaries `select` picks. A folder is first renamed aside, so
/// a thread still writing into it cannot add entries while it is removed.
fn remove_pending(set: &mut BTreeSet<PathBuf>, select: impl Fn(&Path) -> bool) -> usize {
    let paths: Vec<PathBuf> = set.iter().filter(|p| select(p)).cloned().collect();
    let mut removed = 0;
    for p in paths {
        set.remove(&p);
        let ok = if p.is_dir() {
            let gone = p.with_extension("removing");
            let doomed = if std::fs::rename(&p, &gone).is_ok() {
                gone
            } else {
                p
            };
            std::fs::remove_dir_all(&doomed).is_ok()
        } else {
            std::fs::remove_file(&p).is_ok()
        };
        removed += usize::from(ok);
    }
    removed
}

/// Where an output path leads.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Destination {
    /// `-`.
    Stdout,
    /// An existing path that is not a regular file or a folder (a device, a FIFO): written
    /// in place.
    InPlace(PathBuf),
    /// A regular file, existing or not (symbolic links followed to it): replaced whole.
    File(PathBuf),
}

/// Follows symbolic links from `path` to the path they finally name (which may not exist).
///
/// # Errors
/// A link that cannot be read, or more than 40 links in a row (a loop).
pub fn follow_links(path: &Path) -> Result<PathBuf> {
    let mut p = path.to_owned();
    for _ in 0..40 {
        match std::fs::symlink_metadata(&p) {
            Ok(m) if m.file_type().is_symlink() => {
                let target = std::fs::read_link(&p).map_err(|e| Error::io(&p, e))?;
                p = if target.is_absolute() {
                    target
                } else {
                    p.parent().unwrap_or(Path::new(".")).join(target)
                };
            }
            _ => return Ok(p),
        }
    }
    Err(Error::Invalid(format!(
        "{}: too many levels of symbolic links",
        path.display()
    )))
}

/// Decides how `path` is written (see the module documentation).
///
/// # Errors
/// `path` is a folder; a link loop.
pub fn destination(path: &Path) -> Result<Destination> {
    if path.as_os_str() == "-" {
        return Ok(Destination::Stdout);
    }
    let target = follow_links(path)?;
    match std::fs::metadata(&target) {
        Ok(m) if m.is_dir() => Err(Error::Invalid(format!(
            "{} is a folder; give a file name",
            path.display()
        ))),
        Ok(m) if !m.is_file() => Ok(Destination::InPlace(target)),
        _ => Ok(Destination::File(target)),
    }
}

/// A temporary file beside `target`, with `suffix`, made with the mode the finished output
/// should have.
fn temp_beside(target: &Path, suffix: &str) -> Result<tempfile::NamedTempFile> {
    let dir = match target.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
    let mut b = tempfile::Builder::new();
    b.prefix(".roadtrack-").suffix(suffix);
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        // A new file: 0666 less the umask (the kernel applies it at creation); an existing
        // one keeps its mode.
        let mode = std::fs::metadata(target).map_or(0o666, |m| m.permissions().mode() & 0o7777);
        b.permissions(std::fs::Permissions::from_mode(mode));
    }
    b.tempfile_in(dir).map_err(|e| Error::io(dir, e))
}

/// An output file written in pieces and put in place only when complete (see the module
/// documentation for devices, links and `-`). Dropped without [`AtomicFile::commit`] (an
/// error, a panic), the temporary file is removed and the path is untouched.
pub struct AtomicFile {
    path: PathBuf,
    out: Target,
}

enum Target {
    Stdout(BufWriter<std::io::Stdout>),
    InPlace(BufWriter<std::fs::File>),
    Temp {
        target: PathBuf,
        out: BufWriter<tempfile::NamedTempFile>,
        _pending: Pending,
    },
}

impl std::fmt::Debug for AtomicFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("AtomicFile")
            .field("path", &self.path)
            .finish()
    }
}

impl AtomicFile {
    /// Starts the output `path` (`-` = standard output).
    ///
    /// # Errors
    /// `path` is a folder; the folder cannot be created or the temporary file cannot be
    /// made there; a device cannot be opened.
    pub fn create(path: &Path) -> Result<Self> {
        let out = match destination(path)? {
            Destination::Stdout => Target::Stdout(BufWriter::new(std::io::stdout())),
            Destination::InPlace(target) => {
                let f = std::fs::OpenOptions::new()
                    .write(true)
                    .open(&target)
                    .map_err(|e| Error::io(path, e))?;
                Target::InPlace(BufWriter::new(f))
            }
            Destination::File(target) => {
                let (tmp, pending) =
                    Pending::make(|| temp_beside(&target, ".tmp"), |t| t.path().to_owned())?;
                Target::Temp {
                    target,
                    out: BufWriter::new(tmp),
                    _pending: pending,
                }
            }
        };
        Ok(Self {
            path: path.to_owned(),
            out,
        })
    }

    /// The destination path as given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Writes the file by calling `write` on it, then [`AtomicFile::commit`]s: on failure
    /// the temporary file is removed and the destination is untouched.
    ///
    /// # Errors
    /// `write` fails (the error names the destination, `<stdout>` for `-`), or the commit.
    pub fn write_with(
        mut self,
        write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
    ) -> Result<()> {
        let name = if self.path.as_os_str() == "-" {
            PathBuf::from("<stdout>")
        } else {
            self.path.clone()
        };
        write(&mut self).map_err(|e| Error::io(&name, e))?;
        self.commit()
    }

    /// Flushes, syncs and renames the temporary file over the destination (flushes a
    /// device or standard output).
    ///
    /// # Errors
    /// A write, sync or rename fails (the destination is then untouched).
    pub fn commit(self) -> Result<()> {
        let path = self.path;
        match self.out {
            Target::Stdout(mut out) => out.flush().map_err(|e| Error::io("<stdout>", e)),
            Target::InPlace(mut out) => out.flush().map_err(|e| Error::io(&path, e)),
            Target::Temp {
                target,
                out,
                _pending,
            } => {
                let tmp = out
                    .into_inner()
                    .map_err(|e| Error::io(&path, e.into_error()))?;
                tmp.as_file().sync_all().map_err(|e| Error::io(&path, e))?;
                _pending
                    .commit(|| tmp.persist(&target).map(drop))
                    .map_err(|e| Error::io(&path, e.error))
            }
        }
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match &mut self.out {
            Target::Stdout(w) => w.write(buf),
            Target::InPlace(w) => w.write(buf),
            Target::Temp { out, .. } => out.write(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match &mut self.out {
            Target::Stdout(w) => w.flush(),
            Target::InPlace(w) => w.flush(),
            Target::Temp { out, .. } => out.flush(),
        }
    }
}

/// A file that another program writes (ffmpeg's video): a registered temporary path beside
/// the destination, renamed over it by [`TempOutput::commit`], removed when dropped.
#[derive(Debug)]
pub struct TempOutput {
    tmp: tempfile::TempPath,
    target: PathBuf,
    path: PathBuf,
    _pending: Pending,
}

impl TempOutput {
    /// A temporary path for the output `path` (links followed; `suffix` e.g. `.mp4.partial`).
    ///
    /// # Errors
    /// `path` is `-`, a folder or a device; the temporary file cannot be made.
    pub fn create(path: &Path, suffix: &str) -> Result<Self> {
        let target = match destination(path)? {
            Destination::File(t) => t,
            Destination::Stdout => {
                return Err(Error::Invalid(
                    "this output cannot go to standard output; give a file name".into(),
                ));
            }
            Destination::InPlace(_) => {
                return Err(Error::Invalid(format!(
                    "{} is not a regular file; give a file name",
                    path.display()
                )));
            }
        };
        let (tmp, pending) = Pending::make(
            || Ok(temp_beside(&target, suffix)?.into_temp_path()),
            |t| t.to_path_buf(),
        )?;
        Ok(Self {
            tmp,
            target,
            path: path.to_owned(),
            _pending: pending,
        })
    }

    /// Where the other program writes.
    pub fn temp_path(&self) -> &Path {
        &self.tmp
    }

    /// Renames the finished file over the destination.
    ///
    /// # Errors
    /// The rename fails.
    pub fn commit(self) -> Result<()> {
        let Self {
            tmp,
            target,
            path,
            _pending,
        } = self;
        _pending
            .commit(|| tmp.persist(&target))
            .map_err(|e| Error::io(&path, e.error))
    }
}

/// A folder of outputs written in a hidden temporary folder beside it and swapped in by
/// [`AtomicDir::commit`]: the destination never shows a partial run or stale files of an
/// earlier one. Dropped without a commit, the temporary folder is removed.
#[derive(Debug)]
pub struct AtomicDir {
    tmp: Option<tempfile::TempDir>,
    target: PathBuf,
    path: PathBuf,
    _pending: Pending,
}

impl AtomicDir {
    /// Starts the folder `path` (links followed).
    ///
    /// # Errors
    /// `path` is `-` or exists and is not a folder; the temporary folder cannot be made.
    pub fn create(path: &Path) -> Result<Self> {
        if path.as_os_str() == "-" {
            return Err(Error::Invalid(
                "a folder of files cannot go to standard output; give a folder name".into(),
            ));
        }
        let target = follow_links(path)?;
        if target.exists() && !target.is_dir() {
            return Err(Error::Invalid(format!(
                "{} exists and is not a folder",
                path.display()
            )));
        }
        let parent = match target.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_owned(),
            _ => PathBuf::from("."),
        };
        std::fs::create_dir_all(&parent).map_err(|e| Error::io(&parent, e))?;
        let (tmp, pending) = Pending::make(
            || {
                tempfile::Builder::new()
                    .prefix(".roadtrack-")
                    .suffix(".partial")
                    .tempdir_in(&parent)
                    .map_err(|e| Error::io(&parent, e))
            },
            |t| t.path().to_owned(),
        )?;
        #[cfg(unix)]
        {
            // TempDir is made private (0700); a finished folder gets the usual mode.
            use std::os::unix::fs::PermissionsExt;
            let mode =
                std::fs::metadata(&target).map_or(0o755, |m| m.permissions().mode() & 0o7777);
            std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(mode))
                .map_err(|e| Error::io(tmp.path(), e))?;
        }
        Ok(Self {
            tmp: Some(tmp),
            target,
            path: path.to_owned(),
            _pending: pending,
        })
    }

    /// Where the files go while the run lasts.
    pub fn temp_path(&self) -> &Path {
        self.tmp.as_ref().map_or(&self.target, |t| t.path())
    }

    /// The destination as given.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Swaps the finished folder in: an existing destination is moved aside, the new one
    /// renamed into place, then the old one removed.
    ///
    /// # Errors
    /// A rename fails (the old folder is then put back).
    pub fn commit(self) -> Result<()> {
        let Self {
            tmp,
            target,
            path,
            _pending,
        } = self;
        let Some(tmp) = tmp else {
            return Ok(());
        };
        // Choice: the whole swap runs under the registry's lock, so an interrupt waits
        // for it rather than leaving the old folder moved aside.
        _pending.commit(|| {
            let new = tmp.keep();
            let old = if target.exists() {
                let aside = new.with_extension("old");
                std::fs::rename(&target, &aside).map_err(|e| Error::io(&path, e))?;
                Some(aside)
            } else {
                None
            };
            if let Err(e) = std::fs::rename(&new, &target) {
                if let Some(aside) = &old {
                    let _ = std::fs::rename(aside, &target);
                }
                let _ = std::fs::remove_dir_all(&new);
                return Err(Error::io(&path, e));
            }
            if let Some(aside) = old {
                std::fs::remove_dir_all(&aside).map_err(|e| Error::io(&aside, e))?;
            }
            Ok(())
        })
    }
}

/// Writes a file by calling `write` on a buffered writer, atomically ([`AtomicFile`]): on
/// failure the temporary file is removed and `path` is untouched. The path `-` writes to
/// standard output.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    AtomicFile::create(path)?.write_with(write)
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn writes_the_whole_file() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("sub/out.txt");
        write_bytes_atomic(&p, b"hello\n")?;
        assert_eq!(std::fs::read(&p).map_err(|e| Error::io(&p, e))?, b"hello\n");
        Ok(())
    }

    #[cfg(unix)]
    fn mode(p: &Path) -> Result<u32> {
        use std::os::unix::fs::PermissionsExt;
        Ok(std::fs::metadata(p)
            .map_err(|e| Error::io(p, e))?
            .permissions()
            .mode()
            & 0o7777)
    }

    #[cfg(unix)]
    #[test]
    fn new_outputs_get_the_umask_mode_and_existing_ones_keep_theirs() -> Result<()> {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        // What the umask makes of 0666, as for any newly created file.
        let plain = dir.path().join("plain.txt");
        std::fs::File::create(&plain).map_err(|e| Error::io(&plain, e))?;
        let p = dir.path().join("o.txt");
        write_bytes_atomic(&p, b"x")?;
        assert_eq!(mode(&p)?, mode(&plain)?);
        std::fs::set_permissions(&p, std::fs::Permissions::from_mode(0o600))
            .map_err(|e| Error::io(&p, e))?;
        write_bytes_atomic(&p, b"y")?;
        assert_eq!(mode(&p)?, 0o600);
        Ok(())
    }

    #[cfg(unix)]
    #[test]
    fn a_fifo_is_written_in_place_and_stays_a_fifo() -> Result<()> {
        use std::os::unix::fs::FileTypeExt;
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if !made.is_ok_and(|s| s.success()) {
            eprintln!("note: mkfifo unavailable; skipped");
            return Ok(());
        }
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || std::fs::read(fifo))
        };
        write_bytes_atomic(&fifo, b"through the pipe")?;
        let got = reader
            .join()
            .map_err(|_| Error::Invalid("reader panicked".into()))?
            .map_err(|e| Error::io(&fifo, e))?;
        assert_eq!(got, b"through the pipe");
        let ft = std::fs::symlink_metadata(&fifo)
            .map_err(|e| Error::io(&fifo, e))?
            .file_type();
        assert!(ft.is_fifo());
        Ok(())
    }

    #[cfg(unix)]
    #[test]
    fn a_symlink_is_followed_and_kept() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let target = dir.path().join("real.txt");
        let link = dir.path().join("link.txt");
        std::fs::write(&target, b"old").map_err(|e| Error::io(&target, e))?;
        std::os::unix::fs::symlink("real.txt", &link).map_err(|e| Error::io(&link, e))?;
        write_bytes_atomic(&link, b"new")?;
        let meta = std::fs::symlink_metadata(&link).map_err(|e| Error::io(&link, e))?;
        assert!(meta.file_type().is_symlink());
        assert_eq!(
            std::fs::read(&target).map_err(|e| Error::io(&target, e))?,
            b"new"
        );
        // A dangling link: the file it names is created.
        let dangling = dir.path().join("dangling");
        std::os::unix::fs::symlink("made.txt", &dangling).map_err(|e| Error::io(&dangling, e))?;
        write_bytes_atomic(&dangling, b"made")?;
        let made = dir.path().join("made.txt");
        assert_eq!(
            std::fs::read(&made).map_err(|e| Error::io(&made, e))?,
            b"made"
        );
        Ok(())
    }

    #[test]
    fn a_folder_is_not_a_file_destination() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let err = write_bytes_atomic(dir.path(), b"x").expect_err("folder");
        assert!(err.to_string().contains("is a folder"), "{err}");
        Ok(())
    }

    fn names(dir: &Path) -> Result<Vec<String>> {
        let mut v: Vec<String> = std::fs::read_dir(dir)
            .map_err(|e| Error::io(dir, e))?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .collect();
        v.sort();
        Ok(v)
    }

    #[test]
    fn a_folder_output_replaces_the_old_one_whole_or_not_at_all() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let out = dir.path().join("frames");
        std::fs::create_dir(&out).map_err(|e| Error::io(&out, e))?;
        for i in 1..=5 {
            let f = out.join(format!("{i}.png"));
            std::fs::write(&f, b"stale").map_err(|e| Error::io(&f, e))?;
        }
        // An interrupted run (dropped without commit) leaves the old folder as it was.
        {
            let d = AtomicDir::create(&out)?;
            let f = d.temp_path().join("1.png");
            std::fs::write(&f, b"new").map_err(|e| Error::io(&f, e))?;
            assert_eq!(names(&out)?.len(), 5, "nothing visible before the commit");
        }
        assert_eq!(names(dir.path())?, ["frames"]);
        let d = AtomicDir::create(&out)?;
        for i in 1..=2 {
            let f = d.temp_path().join(format!("{i}.png"));
            std::fs::write(&f, b"new").map_err(|e| Error::io(&f, e))?;
        }
        d.commit()?;
        assert_eq!(names(&out)?, ["1.png", "2.png"]);
        assert_eq!(names(dir.path())?, ["frames"]);
        assert!(AtomicDir::create(Path::new("-")).is_err());
        Ok(())
    }

    #[test]
    fn pending_temporaries_are_removed_on_request() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let mut f = AtomicFile::create(&dir.path().join("a.txt"))?;
        f.write_all(b"half").map_err(|e| Error::io("tmp", e))?;
        let d = AtomicDir::create(&dir.path().join("frames"))?;
        assert_eq!(names(dir.path())?.len(), 2);
        // Only this test's temporaries: other tests write outputs at the same time.
        assert_eq!(
            remove_pending(&mut pending(), |p| p.starts_with(dir.path())),
            2
        );
        assert!(names(dir.path())?.is_empty());
        drop((f, d));
        Ok(())
    }

    #[test]
    fn failed_write_leaves_old_file_and_no_temporary() -> Result<()> {
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("out.txt");
        write_bytes_atomic(&p, b"old")?;
        let r = write_atomic(&p, |w| {
            w.write_all(b"partial new content")?;
            Err(std::io::Error::other("interrupted"))
        });
        assert!(r.is_err());
        assert_eq!(std::fs::read(&p).map_err(|e| Error::io(&p, e))?, b"old");
        let names: Vec<_> = std::fs::read_dir(dir.path())
            .map_err(|e| Error::io("tmp", e))?
            .filter_map(|e| e.ok())
            .map(|e| e.file_name())
            .collect();
        assert_eq!(names, vec![std::ffi::OsString::from("out.txt")]);
        Ok(())
    }
}
