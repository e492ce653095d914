//! Writing outputs as a user can trust them: to a temporary file beside the target, renamed into place when
//! complete, and removed on Ctrl-C (or SIGTERM), so an interrupted or failed run leaves finished files and nothing
//! else.

use anyhow::{Context, Result, anyhow};
use std::io::Write;
use std::path::{Path, PathBuf};

/// The temporary outputs being written at this moment. The Ctrl-C handler ([`remove_partials_on_interrupt`])
/// deletes them, so an interrupted `voxelize`, `render` or `batch` leaves finished files and nothing else.
static PARTIALS: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

fn partials() -> std::sync::MutexGuard<'static, Vec<PathBuf>> {
    // A panic while the lock was held leaves the list as valid as before.
    PARTIALS.lock().unwrap_or_else(|e| e.into_inner())
}

/// On Ctrl-C (or SIGTERM): removes the unfinished outputs and exits with status 130. The lock is held to the
/// end, so an output is either renamed into place whole before it (and stays) or removed; never half of each.
pub fn remove_partials_on_interrupt() {
    let installed = ctrlc::set_handler(|| {
        let partials = partials();
        for path in partials.iter() {
            let _ = std::fs::remove_file(path);
        }
        eprintln!("\ninterrupted: {} unfinished output(s) removed", partials.len());
        std::process::exit(130);
    });
    if let Err(e) = installed {
        eprintln!("warning: cannot handle Ctrl-C ({e}); an interrupted run may leave .partial files");
    }
}

/// A temporary output file, listed in [`PARTIALS`] from its creation until it is renamed into place or
/// dropped (which deletes it).
pub(super) struct Partial(Option<tempfile::NamedTempFile>);

impl Drop for Partial {
    fn drop(&mut self) {
        if let Some(file) = &self.0 {
            partials().retain(|p| p != file.path());
        }
    }
}

/// A temporary file in the directory of `output`, to be renamed onto it once complete.
pub(super) fn temp_beside(output: &Path) -> Result<Partial> {
    let dir = match output.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut list = partials();
    let file = tempfile::Builder::new()
        .prefix(".meshvox-")
        .suffix(".partial")
        .tempfile_in(&dir)
        .with_context(|| format!("{}: cannot write here", output.display()))?;
    list.push(file.path().to_path_buf());
    Ok(Partial(Some(file)))
}

/// Writes through `write` into `temp` and renames it to `path`; on any error the temporary file is removed.
pub(super) fn write_atomically(
    mut temp: Partial,
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<&std::fs::File>) -> Result<()>,
) -> Result<u64> {
    let file = temp.0.as_ref().ok_or_else(|| anyhow!("{}: no temporary file", path.display()))?;
    let mut out = std::io::BufWriter::new(file.as_file());
    write(&mut out).with_context(|| format!("{}: write failed", path.display()))?;
    out.flush().with_context(|| format!("{}: write failed", path.display()))?;
    drop(out);
    let bytes = file.as_file().metadata().map(|m| m.len()).unwrap_or(0);
    // Temporary files are created private (0600); the result should get ordinary file permissions.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let _ = file.as_file().set_permissions(std::fs::Permissions::from_mode(0o644));
    }
    let mut list = partials();
    let file = temp.0.take().ok_or_else(|| anyhow!("{}: no temporary file", path.display()))?;
    let temp_path = file.path().to_path_buf();
    list.retain(|p| *p != temp_path);
    file.persist(path).map_err(|e| anyhow!("{}: cannot create: {}", path.display(), e.error))?;
    Ok(bytes)
}
