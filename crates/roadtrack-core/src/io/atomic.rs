//! Atomic file output: write to a temporary file in the same folder, then rename.

use crate::error::{Error, Result};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// An output file written in pieces and put in place only when complete.
///
/// The data go to a temporary file in the destination's folder (created if missing); on
/// [`AtomicFile::commit`] it is flushed, synced and renamed over the path. Dropped without
/// a commit (an error, a panic), the temporary file is removed and the path is untouched.
/// The path `-` writes to standard output as the data come.
pub struct AtomicFile {
    path: PathBuf,
    out: Target,
}

enum Target {
    Stdout(BufWriter<std::io::Stdout>),
    Temp(BufWriter<tempfile::NamedTempFile>),
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
    /// The folder cannot be created or the temporary file cannot be made there.
    pub fn create(path: &Path) -> Result<Self> {
        if path.as_os_str() == "-" {
            return Ok(Self {
                path: path.to_owned(),
                out: Target::Stdout(BufWriter::new(std::io::stdout())),
            });
        }
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        std::fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let tmp = tempfile::Builder::new()
            .prefix(".roadtrack-")
            .suffix(".tmp")
            .tempfile_in(dir)
            .map_err(|e| Error::io(dir, e))?;
        Ok(Self {
            path: path.to_owned(),
            out: Target::Temp(BufWriter::new(tmp)),
        })
    }

    /// The destination path.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes, syncs and renames the temporary file over the destination.
    ///
    /// # Errors
    /// A write, sync or rename fails (the destination is then untouched).
    pub fn commit(self) -> Result<()> {
        let path = self.path;
        match self.out {
            Target::Stdout(mut out) => out.flush().map_err(|e| Error::io("<stdout>", e)),
            Target::Temp(out) => {
                let tmp = out
                    .into_inner()
                    .map_err(|e| Error::io(&path, e.into_error()))?;
                tmp.as_file().sync_all().map_err(|e| Error::io(&path, e))?;
                // Temporary files are created private (0600); a finished output gets the
                // usual mode.
                #[cfg(unix)]
                {
                    use std::os::unix::fs::PermissionsExt;
                    std::fs::set_permissions(tmp.path(), std::fs::Permissions::from_mode(0o644))
                        .map_err(|e| Error::io(&path, e))?;
                }
                tmp.persist(&path).map_err(|e| Error::io(&path, e.error))?;
                Ok(())
            }
        }
    }
}

impl Write for AtomicFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        match &mut self.out {
            Target::Stdout(w) => w.write(buf),
            Target::Temp(w) => w.write(buf),
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        match &mut self.out {
            Target::Stdout(w) => w.flush(),
            Target::Temp(w) => w.flush(),
        }
    }
}

/// Writes a file by calling `write` on a buffered writer, atomically ([`AtomicFile`]): on
/// failure the temporary file is removed and `path` is untouched. The path `-` writes to
/// standard output.
pub fn write_atomic(
    path: &Path,
    write: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<()> {
    let mut file = AtomicFile::create(path)?;
    let name = if path.as_os_str() == "-" {
        Path::new("<stdout>")
    } else {
        path
    };
    write(&mut file).map_err(|e| Error::io(name, e))?;
    file.commit()
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
    #[test]
    fn outputs_are_readable_by_others() -> Result<()> {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().map_err(|e| Error::io("tmp", e))?;
        let p = dir.path().join("o.txt");
        write_bytes_atomic(&p, b"x")?;
        let mode = std::fs::metadata(&p)
            .map_err(|e| Error::io(&p, e))?
            .permissions()
            .mode();
        assert_eq!(mode & 0o777, 0o644);
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
