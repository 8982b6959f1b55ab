//! Output files written whole or not at all, and a command's several outputs as one
//! set: either every regular file is replaced, or none is.
//!
//! What a path names decides how it is written ([`Target::of`]):
//! - `-`: the process's stdout, written through; so is a path naming the file or
//!   pipe stdout already writes to (`/dev/stdout`, or `--out t.csv > t.csv`), and
//!   likewise stderr's, so that what goes there stays in order;
//! - a regular file, or a name not yet taken: a temporary file in the same
//!   directory ([`super::temporary`]: on Linux one without a name, so that even a
//!   process killed with SIGKILL leaves nothing; elsewhere a hidden
//!   `.NAME.PID.tmp`), flushed to disk, then put in its place. A symbolic link is
//!   followed: the file it points to is replaced, the link stays a link. An
//!   existing file keeps its permissions;
//! - anything else that exists and is not a directory (`/dev/null`, `/dev/full`, a
//!   FIFO, a terminal), and any existing path under `/dev` or `/proc`
//!   (`/dev/stdout` redirected to a file): opened for writing and written through,
//!   never replaced;
//! - a directory: refused.
//!
//! [`Staged`] holds a set of outputs while a run writes them (a trace streamed row
//! by row, say): every target is checked and every temporary file created before the
//! run starts, so an unwritable path is reported at once and nothing is left
//! behind; [`Staged::commit`] puts them all in place at the end; dropping a set
//! that was not committed removes its temporary files.

use std::fs::{self, File, OpenOptions};
use std::io::{self, BufWriter, Write};
use std::path::{Path, PathBuf};

use super::temporary::Temporary;
use crate::failure::Failure;

/// Where an output path's bytes go.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    /// `-`, or a path naming the file or pipe the process's stdout already
    /// writes to (`/dev/stdout`, `> t.csv` with `--out t.csv`): the stdout stream,
    /// so that the file holds what is written to it in order.
    Stdout,
    /// A path naming what the process's stderr writes to (`/dev/stderr`).
    Stderr,
    /// A regular file (the symbolic links resolved): replaced whole.
    Regular(PathBuf),
    /// A device, FIFO or socket: written through.
    Special(PathBuf),
}

impl Target {
    /// What `path` names, following symbolic links. A directory is refused.
    pub fn of(path: &Path) -> Result<Target, String> {
        if path.as_os_str() == "-" {
            return Ok(Target::Stdout);
        }
        let metadata = fs::metadata(path);
        // `/dev/stdout`, `/dev/fd/N`, `/proc/self/fd/N` name a stream the process
        // already has open, even when it is redirected to a regular file: written
        // through, never renamed over (that would cut the file from the stream).
        let stream = path.starts_with("/dev") || path.starts_with("/proc");
        match metadata {
            Ok(m) if m.is_dir() => Err("is a directory".to_string()),
            Ok(m) if same_file(&m, "/proc/self/fd/1") => Ok(Target::Stdout),
            Ok(m) if same_file(&m, "/proc/self/fd/2") => Ok(Target::Stderr),
            Ok(_) if stream => Ok(Target::Special(path.to_path_buf())),
            Ok(m) if m.is_file() => Ok(Target::Regular(resolve_links(path))),
            Ok(_) => Ok(Target::Special(path.to_path_buf())),
            // No new files among the devices: `/dev/stdot` is a typo, not a file
            // to create (as root it would be).
            Err(e) if e.kind() == io::ErrorKind::NotFound && stream => {
                Err("no such device or stream (nothing is created under /dev or /proc)".to_string())
            }
            // Not there (or a link to nothing): a new regular file where the
            // links lead.
            Err(e) if e.kind() == io::ErrorKind::NotFound => {
                Ok(Target::Regular(resolve_links(path)))
            }
            Err(e) => Err(e.to_string()),
        }
    }
}

/// Whether `m` is the file behind `other` (same device and inode): a pipe, a
/// terminal or a regular file. `false` where `other` cannot be read.
fn same_file(m: &fs::Metadata, other: &str) -> bool {
    use std::os::unix::fs::MetadataExt;
    fs::metadata(other).is_ok_and(|o| o.dev() == m.dev() && o.ino() == m.ino())
}

/// `path` with its symbolic links followed as far as they lead (at most 40, as
/// the kernel does), even to a name that does not exist yet.
fn resolve_links(path: &Path) -> PathBuf {
    let mut p = path.to_path_buf();
    for _ in 0..40 {
        match fs::read_link(&p) {
            Ok(next) => {
                p = match p.parent() {
                    Some(dir) if next.is_relative() => dir.join(next),
                    _ => next,
                };
            }
            Err(_) => break,
        }
    }
    p
}

/// `path` with its folder made absolute and its links resolved (the file itself
/// need not exist yet), so that two spellings of one file compare equal.
fn canonical(path: &Path) -> PathBuf {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    match (fs::canonicalize(dir), path.file_name()) {
        (Ok(d), Some(name)) => d.join(name),
        _ => path.to_path_buf(),
    }
}

/// One output being written.
struct Pending {
    /// The option that named it (`--out`), for messages.
    option: String,
    /// The path as the user named it (for messages).
    named: PathBuf,
    target: Target,
    /// The temporary file of a regular target.
    temporary: Option<Temporary>,
    writer: BufWriter<Box<dyn Write>>,
    /// A stream whose reader has gone (`host-sim ... --out - | head`): what
    /// follows is dropped without a word, as for any output to a closed pipe.
    closed: bool,
}

impl Pending {
    /// A write error, or `Ok` for a closed pipe on stdout or stderr.
    fn check(&mut self, r: io::Result<()>) -> Result<(), Failure> {
        match r {
            Err(e)
                if e.kind() == io::ErrorKind::BrokenPipe
                    && matches!(self.target, Target::Stdout | Target::Stderr) =>
            {
                self.closed = true;
                Ok(())
            }
            r => r.map_err(|e| cannot_write(&self.option, &self.named, e)),
        }
    }
}

/// A set of outputs written together ([module doc](self)).
pub struct Staged {
    pending: Vec<Pending>,
    /// Temporary files without a name where the platform has them (the tests
    /// also try the named ones).
    unnamed: bool,
}

impl Default for Staged {
    fn default() -> Self {
        Staged {
            pending: Vec::new(),
            unnamed: true,
        }
    }
}

/// "OPTION: cannot write PATH: why", a user mistake (the path is the user's to fix).
fn cannot_write(option: &str, path: &Path, why: impl std::fmt::Display) -> Failure {
    Failure::usage(format!("{option}: cannot write {}: {why}", path.display()))
}

impl Staged {
    /// An empty set.
    pub fn new() -> Self {
        Staged::default()
    }

    /// Adds `path`, given as `option` (`--out`, which every message about it
    /// names), to the set: checks it and opens its temporary file (or the special
    /// file). Returns its index for [`Staged::write`].
    pub fn add(&mut self, option: &str, path: &Path) -> Result<usize, Failure> {
        let refuse = |why: &dyn std::fmt::Display| cannot_write(option, path, why);
        let target = Target::of(path).map_err(|why| refuse(&why))?;
        // Two outputs into one file would share its temporary file and replace it
        // with a mix of both; two into stdout (or stderr), streamed as the run
        // goes, would interleave their lines.
        let here = match &target {
            Target::Regular(p) => Some(canonical(p)),
            _ => None,
        };
        if let Some(other) = self.pending.iter().find(|o| match (&o.target, &target) {
            (Target::Regular(q), Target::Regular(_)) => Some(canonical(q)) == here,
            (Target::Stdout, Target::Stdout) | (Target::Stderr, Target::Stderr) => true,
            _ => false,
        }) {
            let what = if here.is_some() { "file" } else { "stream" };
            return Err(refuse(&format!(
                "`{} {}` writes to that {what} already: give each output its own {what}",
                other.option,
                other.named.display()
            )));
        }
        let (temporary, sink): (Option<Temporary>, Box<dyn Write>) = match &target {
            Target::Stdout => (None, Box::new(io::stdout())),
            Target::Stderr => (None, Box::new(io::stderr())),
            Target::Special(p) => {
                let f = OpenOptions::new()
                    .write(true)
                    .open(p)
                    .map_err(|e| refuse(&e))?;
                (None, Box::new(f))
            }
            Target::Regular(p) => {
                let tmp = Temporary::beside(p, self.unnamed).map_err(|e| refuse(&e))?;
                // An existing file keeps its permissions.
                if let Ok(m) = fs::metadata(p) {
                    let _ = tmp.file().set_permissions(m.permissions());
                }
                let f = tmp.file().try_clone().map_err(|e| refuse(&e))?;
                (Some(tmp), Box::new(f))
            }
        };
        self.pending.push(Pending {
            option: option.to_string(),
            named: path.to_path_buf(),
            target,
            temporary,
            writer: BufWriter::with_capacity(1 << 16, sink),
            closed: false,
        });
        Ok(self.pending.len() - 1)
    }

    /// [`Staged::add`] for an option that may be absent: `None` when it is.
    pub fn add_optional(
        &mut self,
        option: &str,
        path: Option<&Path>,
    ) -> Result<Option<usize>, Failure> {
        path.map(|p| self.add(option, p)).transpose()
    }

    /// Writes `contents` to output `index`.
    pub fn write(&mut self, index: usize, contents: &str) -> Result<(), Failure> {
        let p = &mut self.pending[index];
        if p.closed {
            return Ok(());
        }
        let r = p.writer.write_all(contents.as_bytes());
        p.check(r)
    }

    /// Flushes every output, then puts every temporary file in its target's place.
    /// On an error before the first is in place nothing is replaced.
    pub fn commit(mut self) -> Result<(), Failure> {
        for p in &mut self.pending {
            if !p.closed {
                let r = p.writer.flush();
                p.check(r)?;
            }
        }
        // Durable before any is put in place.
        for p in &self.pending {
            if let Some(tmp) = &p.temporary {
                tmp.file()
                    .sync_all()
                    .map_err(|e| cannot_write(&p.option, &p.named, e))?;
            }
        }
        for p in &mut self.pending {
            if let (Some(tmp), Target::Regular(target)) = (&mut p.temporary, &p.target) {
                tmp.persist(target)
                    .map_err(|e| cannot_write(&p.option, &p.named, e))?;
                // Make the new name durable where directories can be synced (best
                // effort: the file is complete either way).
                if let Some(dir) = target.parent().filter(|d| !d.as_os_str().is_empty()) {
                    if let Ok(d) = File::open(dir) {
                        let _ = d.sync_all();
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::cell::Cell;

    thread_local! {
        /// Whether this test's sets use unnamed temporary files ([`both`]).
        static UNNAMED: Cell<bool> = const { Cell::new(true) };
    }

    /// Runs `test` twice: with temporary files without a name (where the file
    /// system has them) and with the named ones used elsewhere.
    fn both(test: impl Fn()) {
        for unnamed in [true, false] {
            UNNAMED.set(unnamed);
            test();
        }
    }

    /// An empty set in this test's way ([`both`]).
    fn staged() -> Staged {
        Staged {
            pending: Vec::new(),
            unnamed: UNNAMED.get(),
        }
    }

    /// Writes every `(path, contents)` as one set ([`Staged`]): all regular files
    /// replaced, or none.
    fn write_files(files: &[(&Path, String)]) -> Result<(), Failure> {
        let mut staged = staged();
        let indices = files
            .iter()
            .map(|(path, _)| staged.add("--out", path))
            .collect::<Result<Vec<_>, _>>()?;
        for (i, (_, contents)) in indices.into_iter().zip(files) {
            staged.write(i, contents)?;
        }
        staged.commit()
    }

    /// Writes `contents` to `path` whole or not at all ([`write_files`] with one file);
    /// the message names `path` and the reason.
    fn write_whole(path: &Path, contents: &str) -> Result<(), String> {
        write_files(&[(path, contents.to_string())]).map_err(|f| f.text())
    }

    /// A fresh directory for one test.
    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!(
            "host-sim-output-file-{name}-{}",
            std::process::id()
        ));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn names(dir: &Path) -> Vec<String> {
        let mut n: Vec<String> = fs::read_dir(dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().into_string().unwrap())
            .collect();
        n.sort();
        n
    }

    #[test]
    fn write_whole_replaces_the_file_and_leaves_no_temporary() {
        both(|| {
            let dir = scratch("replace");
            let path = dir.join("out.csv");
            fs::write(&path, "old contents, longer than the new").unwrap();
            write_whole(&path, "new\n").unwrap();
            assert_eq!(fs::read_to_string(&path).unwrap(), "new\n");
            assert_eq!(names(&dir), ["out.csv"]);
            fs::remove_dir_all(&dir).unwrap();
        });
    }

    #[test]
    fn write_whole_failure_names_the_path_and_keeps_the_old_file() {
        both(|| {
            let dir = scratch("fail");
            // A missing directory: the temporary file cannot be created.
            let missing = dir.join("no-such-dir").join("out.csv");
            let e = write_whole(&missing, "x").unwrap_err();
            assert!(e.starts_with("--out: cannot write "), "{e}");
            assert!(e.contains("out.csv"), "{e}");
            // The target is a directory: refused, the directory untouched.
            let target = dir.join("taken");
            fs::create_dir(&target).unwrap();
            fs::write(target.join("keep"), "k").unwrap();
            let e = write_whole(&target, "x").unwrap_err();
            assert!(e.contains("taken") && e.contains("is a directory"), "{e}");
            assert_eq!(names(&dir), ["taken"]);
            assert_eq!(fs::read_to_string(target.join("keep")).unwrap(), "k");
            fs::remove_dir_all(&dir).unwrap();
        });
    }

    #[test]
    fn a_symbolic_link_is_followed_and_stays_a_link() {
        both(|| {
            let dir = scratch("symlink");
            let real = dir.join("real.csv");
            fs::write(&real, "old").unwrap();
            let link = dir.join("link.csv");
            std::os::unix::fs::symlink("real.csv", &link).unwrap();
            write_whole(&link, "new").unwrap();
            assert!(fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink());
            assert_eq!(fs::read_to_string(&real).unwrap(), "new");
            // A link to a name not yet taken creates that file.
            let dangling = dir.join("dangling.csv");
            std::os::unix::fs::symlink("later.csv", &dangling).unwrap();
            write_whole(&dangling, "made").unwrap();
            assert!(fs::symlink_metadata(&dangling)
                .unwrap()
                .file_type()
                .is_symlink());
            assert_eq!(fs::read_to_string(dir.join("later.csv")).unwrap(), "made");
            assert_eq!(
                names(&dir),
                ["dangling.csv", "later.csv", "link.csv", "real.csv"]
            );
            fs::remove_dir_all(&dir).unwrap();
        });
    }

    #[test]
    fn special_files_are_written_through_not_replaced() {
        both(|| {
            write_whole(Path::new("/dev/null"), "discarded").unwrap();
            assert!(!fs::metadata("/dev/null").unwrap().is_file());
            let e = write_whole(Path::new("/dev/no-such-device"), "x").unwrap_err();
            assert!(e.contains("no such device"), "{e}");
            assert!(!Path::new("/dev/no-such-device").exists());
            if Path::new("/dev/full").exists() {
                let e = write_whole(Path::new("/dev/full"), &"x".repeat(1 << 17)).unwrap_err();
                assert!(e.contains("/dev/full"), "{e}");
                assert!(!fs::metadata("/dev/full").unwrap().is_file());
            }
        });
    }

    #[test]
    fn a_set_with_one_bad_path_writes_none() {
        both(|| {
            let dir = scratch("set");
            let a = dir.join("a.csv");
            fs::write(&a, "old a").unwrap();
            let b = dir.join("b.csv");
            let bad = dir.join("missing").join("p.svg");
            let e = write_files(&[
                (a.as_path(), "new a".into()),
                (b.as_path(), "new b".into()),
                (bad.as_path(), "svg".into()),
            ])
            .unwrap_err();
            assert_eq!(e.status(), crate::failure::EXIT_USAGE);
            assert!(e.message().contains("p.svg"), "{e:?}");
            assert_eq!(fs::read_to_string(&a).unwrap(), "old a");
            assert_eq!(names(&dir), ["a.csv"]);
            fs::remove_dir_all(&dir).unwrap();
        });
    }

    #[test]
    fn one_file_named_twice_in_a_set_is_refused() {
        both(|| {
            let dir = scratch("twice");
            let a = dir.join("a.csv");
            fs::write(&a, "old").unwrap();
            let again = dir.join(".").join("a.csv");
            let e = write_files(&[(a.as_path(), "one".into()), (again.as_path(), "two".into())])
                .unwrap_err();
            assert!(
                e.message().contains("give each output its own file"),
                "{e:?}"
            );
            assert_eq!(fs::read_to_string(&a).unwrap(), "old");
            assert_eq!(names(&dir), ["a.csv"]);
            fs::remove_dir_all(&dir).unwrap();
        });
    }

    #[test]
    fn permissions_of_a_replaced_file_are_kept() {
        both(|| {
            use std::os::unix::fs::PermissionsExt;
            let dir = scratch("perm");
            let path = dir.join("out.csv");
            fs::write(&path, "old").unwrap();
            fs::set_permissions(&path, fs::Permissions::from_mode(0o640)).unwrap();
            write_whole(&path, "new").unwrap();
            let mode = fs::metadata(&path).unwrap().permissions().mode() & 0o777;
            assert_eq!(mode, 0o640);
            fs::remove_dir_all(&dir).unwrap();
        });
    }

    /// Whether `dir`'s file system gives files without a name (`O_TMPFILE`),
    /// asked of the kernel directly.
    fn has_unnamed_files(dir: &Path) -> bool {
        #[cfg(target_os = "linux")]
        {
            use std::os::unix::fs::OpenOptionsExt;
            OpenOptions::new()
                .write(true)
                .custom_flags(nix::libc::O_TMPFILE)
                .open(dir)
                .is_ok()
        }
        #[cfg(not(target_os = "linux"))]
        {
            let _ = dir;
            false
        }
    }

    /// A process that dies while writing a set (its drop never runs, as under
    /// SIGKILL) leaves no file beside the targets where the file system has
    /// unnamed files; elsewhere, the hidden named files, which a set dropped
    /// uncommitted removes.
    #[test]
    fn a_set_never_committed_nor_dropped_leaves_nothing_where_files_can_be_unnamed() {
        both(|| {
            let dir = scratch("killed");
            let a = dir.join("a.csv");
            fs::write(&a, "old a").unwrap();
            let unnamed = UNNAMED.get() && has_unnamed_files(&dir);
            let hidden = |n: &str| format!(".{n}.{}.tmp", std::process::id());
            for die in [false, true] {
                let mut set = staged();
                for (path, text) in [(&a, "new a"), (&dir.join("b.csv"), "new b")] {
                    let i = set.add("--out", path).unwrap();
                    set.write(i, &text.repeat(1 << 14)).unwrap();
                    set.pending[i].writer.flush().unwrap();
                    let tmp = set.pending[i].temporary.as_ref().unwrap();
                    assert_eq!(tmp.is_unnamed(), unnamed);
                }
                let during = names(&dir);
                if die {
                    std::mem::forget(set);
                } else {
                    drop(set);
                }
                if unnamed {
                    assert_eq!(during, ["a.csv"]);
                    assert_eq!(names(&dir), ["a.csv"]);
                } else {
                    assert_eq!(during, [hidden("a.csv"), hidden("b.csv"), "a.csv".into()]);
                    if die {
                        assert_eq!(names(&dir).len(), 3);
                        fs::remove_file(dir.join(hidden("a.csv"))).unwrap();
                        fs::remove_file(dir.join(hidden("b.csv"))).unwrap();
                    }
                    assert_eq!(names(&dir), ["a.csv"]);
                }
                assert_eq!(fs::read_to_string(&a).unwrap(), "old a");
            }
            fs::remove_dir_all(&dir).unwrap();
        });
    }

    /// A hidden name left by an earlier process with this id is taken over: the
    /// file is replaced and no hidden name stays.
    #[test]
    fn a_stale_hidden_name_is_taken_over() {
        both(|| {
            let dir = scratch("stale");
            let path = dir.join("out.csv");
            fs::write(&path, "old").unwrap();
            let stale = dir.join(format!(".out.csv.{}.tmp", std::process::id()));
            fs::write(&stale, "left by a killed run").unwrap();
            write_whole(&path, "new").unwrap();
            assert_eq!(fs::read_to_string(&path).unwrap(), "new");
            assert_eq!(names(&dir), ["out.csv"]);
            fs::remove_dir_all(&dir).unwrap();
        });
    }
}
