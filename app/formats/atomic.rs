//! Writing an output as users can trust it, for every client (the CLI's `voxelize`, `render` and `batch`, and
//! Python's `VoxelGrid.save`): into a temporary file beside the target, renamed into place when complete, so a
//! failed or interrupted write leaves no file that looks whole. Temporary files are listed while they exist, so
//! an interrupt handler can remove them ([`remove_partials`]).

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard};

/// The temporary outputs being written at this moment.
static PARTIALS: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn partials() -> MutexGuard<'static, Vec<PathBuf>> {
    // A panic while the lock was held leaves the list as valid as before.
    PARTIALS.lock().unwrap_or_else(|e| e.into_inner())
}

/// Removes every unfinished output and returns how many there were; for a Ctrl-C handler that then exits. The
/// list stays locked until the process ends, so an output is either renamed into place whole before this (and
/// stays) or removed, never half of each.
pub fn remove_partials() -> usize {
    let list = partials();
    for path in list.iter() {
        let _ = std::fs::remove_file(path);
    }
    let count = list.len();
    // Held to the end: the caller exits next.
    std::mem::forget(list);
    count
}

/// A temporary file beside `path`, to be renamed onto it by [`AtomicFile::commit`]; dropped before that, it is
/// deleted.
pub struct AtomicFile {
    temp: Option<tempfile::NamedTempFile>,
    path: PathBuf,
}

impl AtomicFile {
    /// Creates the temporary file (`.meshvox-*.partial`, private until committed) in `path`'s folder: a folder
    /// that cannot be written fails here, before any work is done for it.
    pub fn beside(path: &Path) -> io::Result<AtomicFile> {
        let dir = match path.parent() {
            Some(p) if !p.as_os_str().is_empty() => p,
            _ => Path::new("."),
        };
        let mut list = partials();
        let temp = tempfile::Builder::new().prefix(".meshvox-").suffix(".partial").tempfile_in(dir);
        // The error names the folder, not the hidden temporary file nobody asked for.
        let temp = temp.map_err(|e| match e.kind() {
            io::ErrorKind::NotFound => io::Error::new(e.kind(), format!("no such folder: {}", dir.display())),
            kind => {
                io::Error::new(kind, format!("cannot create a file in {}: {}", dir.display(), io::Error::from(kind)))
            }
        })?;
        list.push(temp.path().to_path_buf());
        Ok(AtomicFile { temp: Some(temp), path: path.to_path_buf() })
    }

    /// Writes the whole output through `write` (buffered), then renames it onto the target with ordinary
    /// permissions. Returns the bytes written. On any error the temporary file is removed.
    pub fn commit<E: From<io::Error>>(
        mut self,
        write: impl FnOnce(&mut BufWriter<&File>) -> Result<(), E>,
    ) -> Result<u64, E> {
        // Left in `self` while writing, so that Drop deletes it if writing fails.
        let gone = || io::Error::other("the temporary file is gone");
        let temp = self.temp.as_ref().ok_or_else(gone)?;
        let mut out = BufWriter::new(temp.as_file());
        write(&mut out)?;
        out.flush()?;
        drop(out);
        let bytes = temp.as_file().metadata()?.len();
        // Temporary files are created private (0600); the result gets ordinary file permissions.
        #[cfg(unix)]
        {
            use std::os::unix::fs::PermissionsExt;
            let _ = temp.as_file().set_permissions(std::fs::Permissions::from_mode(0o644));
        }
        let mut list = partials();
        let temp = self.temp.take().ok_or_else(gone)?;
        let temp_path = temp.path().to_path_buf();
        list.retain(|p| *p != temp_path);
        temp.persist(&self.path).map_err(|e| e.error)?;
        Ok(bytes)
    }
}

impl Drop for AtomicFile {
    fn drop(&mut self) {
        // Deleted under the lock, so that an interrupt handler never misses a file still on disk.
        let mut list = partials();
        if let Some(temp) = self.temp.take() {
            let path = temp.path().to_path_buf();
            drop(temp);
            list.retain(|p| *p != path);
        }
    }
}

/// [`AtomicFile::beside`] and [`AtomicFile::commit`] in one step.
pub fn write_atomically<E: From<io::Error>>(
    path: &Path,
    write: impl FnOnce(&mut BufWriter<&File>) -> Result<(), E>,
) -> Result<u64, E> {
    AtomicFile::beside(path)?.commit(write)
}
