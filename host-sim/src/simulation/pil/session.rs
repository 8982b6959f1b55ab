//! The firmware's run on QEMU for the processor in the loop: a temporary
//! directory with the two named pipes the firmware opens through semihosting
//! (`pil.in`, `pil.out`), QEMU started in it on a copy of the ELF, its standard
//! output (the firmware's defmt frames) decoded by `defmt-print` into a log file
//! there; records written and read whole. Dropping the session stops QEMU
//! (killed, waited for), waits for `defmt-print` and removes the directory, on
//! every path out of a run.

use std::fs::{self, File, OpenOptions};
use std::io::{Read, Write};
use std::os::fd::AsRawFd;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicU32, Ordering};
use std::time::{Duration, Instant};

use nix::poll::{poll, PollFd, PollFlags};
use nix::sys::stat::Mode;

use crate::interrupt;

/// QEMU's program.
pub const QEMU: &str = "qemu-system-arm";
/// The defmt decoder's program.
pub const DEFMT_PRINT: &str = "defmt-print";

/// How long without a record from the firmware before the run is given up, s
/// (the firmware's tick takes milliseconds of the host's time; only a hung
/// firmware or QEMU waits this long).
const SILENCE_S: u64 = 60;

/// Sessions started by this process (the directory's name).
static SESSIONS: AtomicU32 = AtomicU32::new(0);

/// A tool not on `PATH`: the error with the command that installs it.
pub fn missing_tool(name: &str) -> Option<String> {
    let on_path = std::env::var_os("PATH")
        .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(name).is_file()));
    if on_path {
        return None;
    }
    let install = match name {
        QEMU => "apt-get install -y qemu-system-arm",
        _ => "cargo install --locked defmt-print",
    };
    Some(format!(
        "error: --firmware: `{name}` is not on PATH: install it with `{install}` (or `bash scripts/test-all.sh setup`, which installs every tool the gates use)"
    ))
}

/// The firmware running on QEMU.
pub struct Session {
    dir: PathBuf,
    qemu: Option<Child>,
    decoder: Option<Child>,
    /// The host's ends of the pipes, both opened read-write (an open that never
    /// blocks, whether QEMU has opened its end yet or not).
    to_firmware: File,
    from_firmware: File,
}

impl Session {
    /// QEMU started on a copy of `elf` in a new temporary directory, with the
    /// pipes open.
    pub fn start(elf: &Path) -> Result<Session, String> {
        let n = SESSIONS.fetch_add(1, Ordering::Relaxed);
        let dir = std::env::temp_dir().join(format!("host-sim-pil-{}-{n}", std::process::id()));
        fs::create_dir(&dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
        // From here on, a failure removes the directory (the guard's drop).
        let mut guard = Dir(Some(dir.clone()));
        let fifo = |name: &str| -> Result<File, String> {
            let path = dir.join(name);
            nix::unistd::mkfifo(&path, Mode::S_IRUSR | Mode::S_IWUSR)
                .map_err(|e| format!("cannot make the pipe {}: {e}", path.display()))?;
            OpenOptions::new()
                .read(true)
                .write(true)
                .open(&path)
                .map_err(|e| format!("cannot open {}: {e}", path.display()))
        };
        let to_firmware = fifo("pil.in")?;
        let from_firmware = fifo("pil.out")?;
        // A copy, so that a build meanwhile cannot swap the ELF under QEMU or the
        // decoder.
        let copy = dir.join("firmware.elf");
        fs::copy(elf, &copy).map_err(|e| format!("cannot copy {}: {e}", elf.display()))?;
        let log = File::create(dir.join("firmware.log"))
            .map_err(|e| format!("cannot create the firmware's log: {e}"))?;
        let errors = |name: &str| {
            File::create(dir.join(name))
                .map(Stdio::from)
                .map_err(|e| format!("cannot create {name}: {e}"))
        };
        // -icount shift=0,sleep=off: one instruction is one nanosecond of virtual
        // time, and the core's sleep jumps to the next timer event: the firmware's
        // clock is its own instructions, never the host's (docs/firmware-qemu.md).
        // Its own process group: a Ctrl-C at the terminal reaches host-sim, which
        // stops QEMU itself.
        let mut qemu = Command::new(QEMU)
            .args([
                "-machine",
                "netduinoplus2",
                "-display",
                "none",
                "-serial",
                "null",
                "-monitor",
                "none",
                "-semihosting-config",
                "enable=on,target=native",
                "-icount",
                "shift=0,sleep=off",
                "-kernel",
                "firmware.elf",
            ])
            .current_dir(&dir)
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(errors("qemu.stderr")?)
            .process_group(0)
            .spawn()
            .map_err(|e| format!("cannot start {QEMU}: {e}"))?;
        let frames = qemu.stdout.take().map(Stdio::from).unwrap_or(Stdio::null());
        let decoder = Command::new(DEFMT_PRINT)
            .args(["-e", "firmware.elf", "--log-format", "{t} {L} {s}"])
            .current_dir(&dir)
            .stdin(frames)
            .stdout(log)
            .stderr(errors("defmt-print.stderr")?)
            .process_group(0)
            .spawn();
        let mut session = Session {
            dir: guard.0.take().unwrap_or_default(),
            qemu: Some(qemu),
            decoder: None,
            to_firmware,
            from_firmware,
        };
        session.decoder = Some(decoder.map_err(|e| format!("cannot start {DEFMT_PRINT}: {e}"))?);
        Ok(session)
    }

    /// Write a whole record.
    pub fn send(&mut self, record: &[u8]) -> Result<(), String> {
        self.to_firmware
            .write_all(record)
            .map_err(|e| format!("cannot write to the firmware's pipe: {e}"))
    }

    /// Read a whole record of `buf.len()` bytes, waiting while QEMU runs.
    pub fn receive(&mut self, buf: &mut [u8]) -> Result<(), String> {
        let mut done = 0;
        let mut since = Instant::now();
        while done < buf.len() {
            let fd = self.from_firmware.as_raw_fd();
            let mut fds = [PollFd::new(fd, PollFlags::POLLIN)];
            let ready = match poll(&mut fds, 100) {
                Ok(n) => n,
                // A signal (Ctrl-C): its flag is looked at below.
                Err(nix::errno::Errno::EINTR) => 0,
                Err(e) => return Err(format!("poll: {e}")),
            };
            if ready > 0 {
                let n = self
                    .from_firmware
                    .read(&mut buf[done..])
                    .map_err(|e| format!("cannot read the firmware's pipe: {e}"))?;
                done += n;
                since = Instant::now();
                continue;
            }
            if interrupt::interrupted() {
                return Err(interrupt::interruption());
            }
            if let Some(status) = self.qemu.as_mut().and_then(|q| q.try_wait().ok().flatten()) {
                return Err(format!("QEMU ended ({status}){}", self.log_tail()));
            }
            if since.elapsed() > Duration::from_secs(SILENCE_S) {
                return Err(format!(
                    "no record from the firmware for {SILENCE_S} s{}",
                    self.log_tail()
                ));
            }
        }
        Ok(())
    }

    /// The firmware's log so far, for an error: its last lines.
    fn log_tail(&self) -> String {
        let log = fs::read_to_string(self.dir.join("firmware.log")).unwrap_or_default();
        let lines: Vec<&str> = log.lines().collect();
        let tail = lines[lines.len().saturating_sub(5)..].join("\n  ");
        if tail.is_empty() {
            "; the firmware's log is empty".to_string()
        } else {
            format!("; the firmware's log ends:\n  {tail}")
        }
    }

    /// Stop QEMU, let the decoder finish, and return the firmware's log.
    pub fn finish(mut self) -> String {
        self.stop();
        fs::read_to_string(self.dir.join("firmware.log")).unwrap_or_default()
    }

    fn stop(&mut self) {
        if let Some(mut q) = self.qemu.take() {
            let _ = q.kill();
            let _ = q.wait();
        }
        // Its input ended with QEMU: it decodes what is left and exits.
        if let Some(mut d) = self.decoder.take() {
            let _ = d.wait();
        }
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        self.stop();
        let _ = fs::remove_dir_all(&self.dir);
    }
}

/// A directory removed when dropped, unless taken.
struct Dir(Option<PathBuf>);

impl Drop for Dir {
    fn drop(&mut self) {
        if let Some(d) = &self.0 {
            let _ = fs::remove_dir_all(d);
        }
    }
}
