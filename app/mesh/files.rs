//! What a load may read, for mesh files from anywhere (docs/untrusted-files.md): the mesh file and the files it
//! refers to (glTF buffers and images, OBJ material libraries, MTL textures), found beside it on disk, among files
//! handed over together, or nowhere.
//!
//! On disk three rules hold, because a file is a program's input and must not choose what else the program reads:
//! - **Only regular files**, checked before opening and again on the opened handle: a device (`/dev/zero`,
//!   `/dev/urandom`) never ends, a FIFO blocks forever, a directory is not data.
//! - **Bounded reads**: every file's size is checked against a limit (the memory budget by default) before it is
//!   read, reads stop at the size that was checked, and all files of one load together stay under the same limit.
//!   A glTF buffer reads exactly its `byteLength`.
//! - **References stay inside the mesh's folder** (or a resource root the caller names): a reference is a relative
//!   path, resolved against the referencing file's folder (after percent-decoding, for glTF's URIs), and the
//!   resolved real path (symlinks followed) must lie inside one of those folders. Absolute paths and URIs with a
//!   scheme (`file:`, `http:`) are refused. Without this, a glTF whose buffer is `/etc/os-release` turns a host's
//!   file into a conversion service's output.
//!
//! Nothing here is a sandbox: a file swapped for a symlink between the check and the read (by someone who can write
//! the folder while meshvox runs) is outside what it guards against.

use super::MeshError;
use crate::names::Setting;
use std::borrow::Cow;
use std::cell::Cell;
use std::io::Read;
use std::path::{Path, PathBuf};

/// How a file writes its references: glTF URIs are percent-encoded relative URI references (RFC 3986, as the glTF
/// specification says); OBJ `mtllib` and MTL `map_*` names are plain paths, in which `%` is a percent sign.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum RefStyle {
    Uri,
    Path,
}

/// Why a referenced file was not read. Each message names the reference; the caller adds what it was for.
#[derive(Clone, Debug, PartialEq, Eq)]
pub(crate) enum ReadError {
    /// The reference breaks one of this module's rules; the message says which.
    Refused(String),
    /// An ordinary failure: a missing file, no permission, not among the files picked.
    Failed(String),
}

impl ReadError {
    /// The error as a line about `what` (`buffers[0] refused: …`, `images[2]: cannot read …`).
    pub(crate) fn about(&self, what: &str) -> String {
        match self {
            ReadError::Refused(_) => format!("{what} {self}"),
            ReadError::Failed(_) => format!("{what}: {self}"),
        }
    }
}

impl std::fmt::Display for ReadError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            ReadError::Refused(m) => write!(f, "refused: {m}"),
            ReadError::Failed(m) => f.write_str(m),
        }
    }
}

/// The bytes one load may take in: the files it reads and the textures it decodes, together. A decoded texture
/// is counted too, since a small image can decode to hundreds of megabytes and a file can name thousands.
#[derive(Debug)]
pub(crate) struct Budget {
    limit: u64,
    spent: Cell<u64>,
}

impl Budget {
    pub(crate) fn new(limit: u64) -> Budget {
        Budget { limit, spent: Cell::new(0) }
    }

    pub(crate) fn limit(&self) -> u64 {
        self.limit
    }

    /// Counts `bytes`, or returns the total they would make when that is over the limit.
    pub(crate) fn spend(&self, bytes: u64) -> Result<(), u64> {
        let total = self.spent.get().saturating_add(bytes);
        if total > self.limit {
            return Err(total);
        }
        self.spent.set(total);
        Ok(())
    }

    /// Why `size` more bytes (`total` in all) are refused.
    pub(crate) fn over(&self, size: u64, total: u64) -> String {
        let human = crate::memory::human;
        match size > self.limit {
            true => {
                format!("is {}, more than the limit of {} ({})", human(size), human(self.limit), Setting::MaxFileSize)
            }
            false => format!(
                "is {}, which would bring what this mesh reads to {}, more than the limit of {} ({})",
                human(size),
                human(total),
                human(self.limit),
                Setting::MaxFileSize
            ),
        }
    }
}

/// The rules one load from disk reads under: the folders references may resolve into and the byte budget.
#[derive(Debug)]
pub(crate) struct Access {
    /// The mesh file's folder (canonical): relative references in the mesh start here.
    base: PathBuf,
    /// Canonical folders a reference's real path may lie in: `base`, then the caller's resource roots.
    roots: Vec<PathBuf>,
    /// The most bytes one file may have, and all files (and decoded textures) of this load together.
    budget: Budget,
}

impl Access {
    /// The rules for loading `mesh`: references inside its real folder or one of `resource_roots`, at most `limit`
    /// bytes. A resource root that does not exist is an error (a typo must not silently narrow what loads).
    pub(crate) fn new(mesh: &Path, resource_roots: &[PathBuf], limit: u64) -> Result<Access, MeshError> {
        let canonical = |path: &Path| {
            std::fs::canonicalize(path).map_err(|source| MeshError::Io { path: path.to_path_buf(), source })
        };
        // The folder of the file itself, when the mesh is reached through a symbolic link (datasets made of links
        // into a master copy keep their textures beside the real files).
        let real = canonical(mesh)?;
        let base = real.parent().map_or_else(|| PathBuf::from("/"), Path::to_path_buf);
        let mut roots = vec![base.clone()];
        for root in resource_roots {
            let root = canonical(root)?;
            if !root.is_dir() {
                let source = std::io::Error::other("a resource root must be a directory");
                return Err(MeshError::Io { path: root, source });
            }
            roots.push(root);
        }
        Ok(Access { base, roots, budget: Budget::new(limit) })
    }

    /// The mesh file's folder, where its own references are resolved.
    pub(crate) fn base(&self) -> &Path {
        &self.base
    }

    /// The mesh file itself: a regular file within the limit. It was named by the user, so no folder rule applies.
    pub(crate) fn read_mesh(&self, path: &Path) -> Result<Vec<u8>, MeshError> {
        self.read_regular(path, None).map_err(|e| refusal_error(path, e, self.budget.limit()))
    }

    /// The file `reference` names, resolved against the folder `from` (canonical; the referencing file's folder),
    /// with its real path. `exact`: read this many bytes (a glTF buffer's `byteLength`; a longer file is read only
    /// that far, a shorter one returns what it has for the caller to refuse), else the whole file.
    pub(crate) fn read_reference(
        &self,
        from: &Path,
        reference: &str,
        style: RefStyle,
        exact: Option<u64>,
    ) -> Result<(Vec<u8>, PathBuf), ReadError> {
        let shown = quote(reference);
        let real = self.resolve(from, reference, style)?;
        let bytes = self.read_regular(&real, exact).map_err(|e| match e {
            Refusal::TooLarge { size, total } => {
                ReadError::Refused(format!("{shown} {}", self.budget.over(size, total)))
            }
            Refusal::Io(e) => ReadError::Failed(format!("cannot read {}: {e}", real.display())),
            Refusal::Rule(m) => ReadError::Refused(format!("{shown} {m}")),
        })?;
        Ok((bytes, real))
    }

    /// The real path of `reference` if it stays inside the roots.
    fn resolve(&self, from: &Path, reference: &str, style: RefStyle) -> Result<PathBuf, ReadError> {
        let shown = quote(reference);
        let name: Cow<str> = match style {
            RefStyle::Uri => {
                if let Some(scheme) = uri_scheme(reference) {
                    return Err(ReadError::Refused(format!(
                        "{shown} is a {scheme}: URI; a file may only refer to relative paths (or embed data: URIs)"
                    )));
                }
                urlencoding::decode(reference).map_err(|e| ReadError::Failed(format!("bad URI {shown}: {e}")))?
            }
            RefStyle::Path => reference.into(),
        };
        if name.contains('\0') {
            return Err(ReadError::Refused(format!("{shown} contains a NUL byte")));
        }
        let relative = Path::new(&*name);
        if relative.has_root() || relative.is_absolute() {
            return Err(ReadError::Refused(format!(
                "{shown} is an absolute path; a file may only refer to paths relative to its folder"
            )));
        }
        let joined = from.join(relative);
        let real = std::fs::canonicalize(&joined)
            .map_err(|e| ReadError::Failed(format!("cannot read {}: {e}", joined.display())))?;
        if !self.roots.iter().any(|root| real.starts_with(root)) {
            let root = Setting::ResourceRoot;
            let also = if self.roots.len() > 1 { format!(" or a {root}") } else { format!(" (or a {root})") };
            return Err(ReadError::Refused(format!(
                "{shown} resolves to {}, outside {}; a file may only refer to files inside its own folder{also}",
                real.display(),
                self.base.display()
            )));
        }
        Ok(real)
    }

    /// Reads `path` if it is a regular file and fits the budget: `exact` bytes (or fewer if the file is shorter),
    /// else the whole file.
    fn read_regular(&self, path: &Path, exact: Option<u64>) -> Result<Vec<u8>, Refusal> {
        read_checked(path, |size| {
            let want = exact.map_or(size, |n| n.min(size));
            self.spend(want)?;
            Ok(want)
        })
    }

    /// Counts `bytes` against the load's budget, or refuses them.
    fn spend(&self, bytes: u64) -> Result<(), Refusal> {
        self.budget.spend(bytes).map_err(|total| Refusal::TooLarge { size: bytes, total })
    }
}

/// Reads `path` if it is a regular file, as many bytes as `admit` allows of its size (or refuses). The checks come
/// before opening, and the type is checked again on the opened handle (opened non-blocking, so even a FIFO
/// slipped in between cannot make the open wait).
fn read_checked(path: &Path, admit: impl FnOnce(u64) -> Result<u64, Refusal>) -> Result<Vec<u8>, Refusal> {
    let size = check_regular(&std::fs::metadata(path).map_err(Refusal::Io)?)?;
    let want = admit(size)?;
    let file = open_nonblocking(path).map_err(Refusal::Io)?;
    let size = check_regular(&file.metadata().map_err(Refusal::Io)?)?;
    let want = want.min(size);
    // Capacity from the checked size, and `take` so that a file growing meanwhile is still read only so far.
    let mut bytes = Vec::with_capacity(usize::try_from(want).unwrap_or(0));
    file.take(want).read_to_end(&mut bytes).map_err(Refusal::Io)?;
    Ok(bytes)
}

/// A file a user named that is streamed rather than read whole (an `.npy` or `.npz` point cloud): it must be a
/// regular file, no larger than `limit` when one is given.
pub(crate) fn check_named(path: &Path, meta: &std::fs::Metadata, limit: Option<u64>) -> Result<(), MeshError> {
    let size = check_regular(meta).map_err(|e| refusal_error(path, e, limit.unwrap_or(u64::MAX)))?;
    match limit {
        Some(limit) if size > limit => Err(MeshError::FileTooLarge { path: path.to_path_buf(), size, limit }),
        _ => Ok(()),
    }
}

/// Reads a file that an option or an argument names (a palette, a block set, a query's points) under the rules
/// mesh files follow: a regular file, at most `limit` bytes (checked before it is read), `what` naming the limit
/// in the message (`--max-file-size`, or why a palette has one).
pub fn read_named(path: &Path, limit: u64, what: &str) -> Result<Vec<u8>, MeshError> {
    read_checked(path, |size| match size > limit {
        true => Err(Refusal::TooLarge { size, total: size }),
        false => Ok(size),
    })
    .map_err(|e| match e {
        Refusal::TooLarge { size, .. } => MeshError::Refused {
            path: path.to_path_buf(),
            message: format!(
                "the file is {}, more than the limit of {} ({what}); it was not read",
                crate::memory::human(size),
                crate::memory::human(limit)
            ),
        },
        e => refusal_error(path, e, limit),
    })
}

/// The most bytes a settings file (a palette, a block set) may have: such files are kilobytes, and a device or a
/// huge file named by mistake must not be read.
pub const SETTING_FILE_LIMIT: u64 = 64 << 20;

/// Reads a settings file an option names (a palette, a block set): [`read_named`] within [`SETTING_FILE_LIMIT`],
/// its errors naming the file as `what` (`--palette x.png`, `palette='x.png'`).
pub fn read_setting_file(path: &Path, what: &str) -> Result<Vec<u8>, MeshError> {
    read_named(path, SETTING_FILE_LIMIT, "palettes and block sets are at most 64 MiB").map_err(|e| match e {
        MeshError::Io { source, .. } => MeshError::Io { path: what.into(), source },
        MeshError::Refused { message, .. } => MeshError::Refused { path: what.into(), message },
        e => e,
    })
}

/// A refusal as the error about the file `path`.
fn refusal_error(path: &Path, refusal: Refusal, limit: u64) -> MeshError {
    match refusal {
        Refusal::TooLarge { size, .. } => MeshError::FileTooLarge { path: path.to_path_buf(), size, limit },
        Refusal::Io(source) => MeshError::Io { path: path.to_path_buf(), source },
        Refusal::Rule(message) => MeshError::Refused { path: path.to_path_buf(), message },
    }
}

/// A failed [`Access::read_regular`], before its caller words it.
enum Refusal {
    /// The file has `size` bytes, which would bring this load's reads to `total`, over the limit.
    TooLarge {
        size: u64,
        total: u64,
    },
    Rule(String),
    Io(std::io::Error),
}

/// The file's size if it is a regular file; otherwise what it is, as a refusal.
fn check_regular(meta: &std::fs::Metadata) -> Result<u64, Refusal> {
    if meta.is_file() {
        return Ok(meta.len());
    }
    Err(Refusal::Rule(format!("is {}, not a regular file (meshvox reads only regular files)", kind(meta))))
}

/// What a file that is not a regular file is, for messages.
fn kind(meta: &std::fs::Metadata) -> &'static str {
    if meta.is_dir() {
        return "a directory";
    }
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        let t = meta.file_type();
        if t.is_char_device() {
            return "a character device";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_fifo() {
            return "a named pipe (FIFO)";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    "a special file"
}

/// Opens for reading without waiting on a FIFO's writer (regular files ignore the flag).
pub(crate) fn open_nonblocking(path: &Path) -> std::io::Result<std::fs::File> {
    let mut options = std::fs::OpenOptions::new();
    options.read(true);
    #[cfg(unix)]
    {
        use std::os::unix::fs::OpenOptionsExt;
        options.custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY);
    }
    options.open(path)
}

/// The scheme of a URI reference that has one (`file`, `http`, …, as RFC 3986 spells schemes: a letter, then
/// letters, digits, `+`, `-` or `.`, then `:` before any `/`, `?` or `#`). A Windows drive (`C:/x.bin`) parses as
/// one too, and is refused as well.
fn uri_scheme(reference: &str) -> Option<&str> {
    let end = reference.find([':', '/', '?', '#'])?;
    let scheme = &reference[..end];
    let valid = reference[end..].starts_with(':')
        && scheme.starts_with(|c: char| c.is_ascii_alphabetic())
        && scheme.chars().all(|c| c.is_ascii_alphanumeric() || matches!(c, '+' | '-' | '.'));
    valid.then_some(scheme)
}

/// A reference from a hostile file as a message shows it: quoted, control characters dropped, cut short.
fn quote(reference: &str) -> String {
    let mut s: String = reference.chars().filter(|c| !c.is_control()).take(80).collect();
    if reference.chars().count() > 80 {
        s.push('…');
    }
    format!("\"{s}\"")
}

/// Where a file's external references are read from: beside it on disk (under [`Access`]'s rules), among files
/// handed over together (found by file name, as a browser hands them over), or nowhere.
#[derive(Clone, Copy)]
pub(crate) enum Externals<'a> {
    None(&'a Budget),
    Dir(&'a Access),
    Files(&'a [(String, Vec<u8>)], &'a Budget),
}

impl<'a> Externals<'a> {
    /// What this load may still take in (decoded textures count against it).
    pub(crate) fn budget(&self) -> &'a Budget {
        match *self {
            Externals::None(budget) | Externals::Files(_, budget) => budget,
            Externals::Dir(access) => &access.budget,
        }
    }

    /// The bytes of `reference`, written in `style`, relative to the folder `from` (the mesh's folder when `None`).
    /// `exact` as in [`Access::read_reference`]. On disk, also the file's real path (its folder resolves the
    /// references inside it, as an MTL's textures).
    pub(crate) fn read(
        &self,
        from: Option<&Path>,
        reference: &str,
        style: RefStyle,
        exact: Option<u64>,
    ) -> Result<(Cow<'a, [u8]>, Option<PathBuf>), ReadError> {
        match *self {
            Externals::None(_) => {
                Err(ReadError::Failed(format!("{} is a separate file, which cannot be read here", quote(reference))))
            }
            Externals::Dir(access) => {
                let (bytes, real) = access.read_reference(from.unwrap_or(access.base()), reference, style, exact)?;
                Ok((bytes.into(), Some(real)))
            }
            Externals::Files(files, _) => {
                let decoded = match style {
                    RefStyle::Uri => urlencoding::decode(reference)
                        .map_err(|e| ReadError::Failed(format!("bad URI {}: {e}", quote(reference))))?,
                    RefStyle::Path => reference.into(),
                };
                let wanted = Path::new(&*decoded).file_name();
                files
                    .iter()
                    .find(|(name, _)| Path::new(name).file_name() == wanted)
                    .map(|(_, bytes)| (bytes.as_slice().into(), None))
                    .ok_or_else(|| {
                        ReadError::Failed(format!("{reference} was not among the files opened together with it"))
                    })
            }
        }
    }
}
