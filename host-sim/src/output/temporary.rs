//! The temporary file an output is written to until its set is committed
//! ([`super::file::Staged`]), in the target's directory so that putting it in place
//! never crosses file systems.
//!
//! - On Linux, where the file system supports it, a file without a name
//!   (`open(2)` with `O_TMPFILE` in the target's directory): nothing of it is ever
//!   visible beside the target while it is written, and a process that ends
//!   without committing, however it ends (SIGKILL, a crash, a power cut), leaves
//!   nothing behind. At the commit it is linked in by its descriptor (`linkat(2)`
//!   of `/proc/self/fd/N`, following that link): straight under the target's name
//!   when the target does not exist; otherwise under a hidden name beside it,
//!   then renamed over the target (a link cannot replace a file, a rename can,
//!   atomically). A SIGKILL in the moment between those two calls (two system
//!   calls, microseconds) leaves the whole file under the hidden name
//!   `.NAME.PID.tmp`; that moment is the only one.
//!   ext2/3/4, XFS, Btrfs, F2FS, tmpfs and UBIFS support it (`open(2)`).
//! - Elsewhere (another system; a file system that refuses `O_TMPFILE`, such as
//!   NFS or FAT: `EOPNOTSUPP`, or `EISDIR` on a kernel without it; or no `/proc`
//!   to link it through): the hidden named file `.NAME.PID.tmp` beside the
//!   target, renamed over it at the commit, removed when the set is dropped
//!   uncommitted. A SIGKILL while it is written leaves it behind.

use std::fs::{self, File, OpenOptions};
use std::io;
use std::path::{Path, PathBuf};

/// A temporary file being written for one target.
pub struct Temporary {
    file: File,
    /// Its name while it has one and is not yet in place (removed on drop).
    named: Option<PathBuf>,
}

impl Temporary {
    /// A new empty temporary file for `target` (a regular file's path, its links
    /// resolved), without a name where the platform allows it and `unnamed` asks.
    pub fn beside(target: &Path, unnamed: bool) -> io::Result<Temporary> {
        if unnamed {
            if let Some(file) = open_unnamed(&directory(target))? {
                return Ok(Temporary { file, named: None });
            }
        }
        let name = hidden_name(target)?;
        let file = OpenOptions::new()
            .write(true)
            .create(true)
            .truncate(true)
            .open(&name)?;
        Ok(Temporary {
            file,
            named: Some(name),
        })
    }

    /// The file, to write to, set permissions on and sync.
    pub fn file(&self) -> &File {
        &self.file
    }

    /// Whether the file has no name ([module doc](self)), before it is in place.
    #[cfg(test)]
    pub fn is_unnamed(&self) -> bool {
        self.named.is_none()
    }

    /// Puts the file in place of `target` (written and synced before).
    pub fn persist(&mut self, target: &Path) -> io::Result<()> {
        if let Some(name) = &self.named {
            fs::rename(name, target)?;
            self.named = None;
            return Ok(());
        }
        link_unnamed(&self.file, target)
    }
}

impl Drop for Temporary {
    /// A named file not put in place is removed (an unnamed one goes with its
    /// descriptor).
    fn drop(&mut self) {
        if let Some(name) = &self.named {
            let _ = fs::remove_file(name);
        }
    }
}

/// The directory `path` is in (`.` for a bare name).
fn directory(path: &Path) -> PathBuf {
    match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    }
}

/// The hidden name beside `path`: `.NAME.PID.tmp` in the same directory.
fn hidden_name(path: &Path) -> io::Result<PathBuf> {
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::new(io::ErrorKind::InvalidInput, "not a file name"))?
        .to_string_lossy();
    Ok(directory(path).join(format!(".{name}.{}.tmp", std::process::id())))
}

/// A file without a name in `dir`, or `None` where this system or `dir`'s file
/// system has none (then a named one is used); other errors (no such directory,
/// no permission) are the caller's.
#[cfg(target_os = "linux")]
fn open_unnamed(dir: &Path) -> io::Result<Option<File>> {
    use nix::libc;
    use std::os::unix::fs::OpenOptionsExt;
    // `O_TMPFILE` needs write access; the mode is a new file's (0666 less the
    // umask), as for the named file.
    match OpenOptions::new()
        .write(true)
        .custom_flags(libc::O_TMPFILE)
        .open(dir)
    {
        // Linked in through `/proc`: without it mounted, the named file.
        Ok(file) => Ok(fs::metadata(descriptor_path(&file)).is_ok().then_some(file)),
        Err(e)
            if matches!(
                e.raw_os_error(),
                Some(libc::EOPNOTSUPP | libc::EISDIR | libc::EINVAL)
            ) =>
        {
            Ok(None)
        }
        Err(e) => Err(e),
    }
}

/// No file without a name on this system.
#[cfg(not(target_os = "linux"))]
fn open_unnamed(_dir: &Path) -> io::Result<Option<File>> {
    Ok(None)
}

/// `/proc/self/fd/N`: the link to `file`'s open file.
#[cfg(target_os = "linux")]
fn descriptor_path(file: &File) -> PathBuf {
    use std::os::fd::AsRawFd;
    PathBuf::from(format!("/proc/self/fd/{}", file.as_raw_fd()))
}

/// Gives the unnamed `file` the name `target`, replacing what is there
/// ([module doc](self)).
#[cfg(target_os = "linux")]
fn link_unnamed(file: &File, target: &Path) -> io::Result<()> {
    use nix::errno::Errno;
    use nix::unistd::{linkat, LinkatFlags};
    let link = |to: &Path| {
        linkat(
            None,
            descriptor_path(file).as_path(),
            None,
            to,
            LinkatFlags::SymlinkFollow,
        )
    };
    match link(target) {
        Err(Errno::EEXIST) => {}
        r => return r.map_err(io::Error::from),
    }
    // The target exists: a hidden name, then the rename over it. A hidden name
    // left by an earlier process with this id (killed between these two calls)
    // is taken over.
    let hidden = hidden_name(target)?;
    let _ = fs::remove_file(&hidden);
    link(&hidden).map_err(io::Error::from)?;
    fs::rename(&hidden, target).inspect_err(|_| {
        let _ = fs::remove_file(&hidden);
    })
}

/// Never called: without [`open_unnamed`] no file is unnamed.
#[cfg(not(target_os = "linux"))]
fn link_unnamed(_file: &File, _target: &Path) -> io::Result<()> {
    Err(io::Error::from(io::ErrorKind::Unsupported))
}
