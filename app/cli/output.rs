//! The CLI's side of writing outputs as a user can trust them (the library's [`AtomicFile`]: a temporary file
//! beside the target, renamed into place when complete): messages naming the file, and removing the unfinished
//! ones on Ctrl-C (or SIGTERM), so an interrupted or failed run leaves finished files and nothing else.

use anyhow::{Context, Result};
use meshvox::formats::atomic::{self, AtomicFile};
use std::path::Path;

/// On Ctrl-C (or SIGTERM): removes the unfinished outputs and exits with status 130.
pub fn remove_partials_on_interrupt() {
    let installed = ctrlc::set_handler(|| {
        let removed = atomic::remove_partials();
        eprintln!("\ninterrupted: {removed} unfinished output(s) removed");
        std::process::exit(130);
    });
    if let Err(e) = installed {
        eprintln!("warning: cannot handle Ctrl-C ({e}); an interrupted run may leave .partial files");
    }
}

/// A temporary file in the directory of `output`, to be renamed onto it once complete: made before the work, so
/// that a folder that cannot be written fails at once.
pub(super) fn temp_beside(output: &Path) -> Result<AtomicFile> {
    AtomicFile::beside(output).with_context(|| format!("{}: cannot write here", output.display()))
}

/// Writes through `write` into `temp` and renames it to `path`; on any error the temporary file is removed.
pub(super) fn write_atomically(
    temp: AtomicFile,
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<&std::fs::File>) -> Result<()>,
) -> Result<u64> {
    temp.commit(write).with_context(|| format!("{}: write failed", path.display()))
}
