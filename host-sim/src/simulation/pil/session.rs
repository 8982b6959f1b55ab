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

use nix::fcntl::{fcntl, FcntlArg, OFlag};
use nix::poll::{poll, PollFd, PollFlags};
use nix::sys::signal::Signal;
use nix::sys::stat::Mode;
use nix::unistd::Pid;

use crate::interrupt;

/// QEMU's program.
pub const QEMU: &str = "qemu-system-arm";
/// The defmt decoder's program.
pub const DEFMT_PRINT: &str = "defmt-print";

/// How long without a record from the firmware before the run is given up, s
/// (the firmware's tick takes milliseconds of the host's time; only a hung
/// firmware or QEMU waits this long).
const SILENCE_S: u64 = 60;

/// Microseconds `receive` reads again before it sleeps in `poll`.
const SPIN_US: u64 = 200;

/// Seconds the decoder has to finish after QEMU has stopped (it decodes a few
/// kilobytes in milliseconds).
pub const DECODER_S: u64 = 10;

/// Sessions started by this process (the directory's name).
static SESSIONS: AtomicU32 = AtomicU32::new(0);

/// A tool not on `PATH`: the problem, with the command that installs it.
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
        "--firmware: `{name}` is not on PATH: install it with `{install}` (or `bash scripts/test-all.sh setup`, which installs every tool the gates use)"
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
        // Reads that never wait: `receive` spins, then polls.
        fcntl(
            from_firmware.as_raw_fd(),
            FcntlArg::F_SETFL(OFlag::O_NONBLOCK),
        )
        .map_err(|e| format!("cannot make the pipe pil.out non-blocking: {e}"))?;
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
        stay_on_this_cpu();
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

    /// Read a whole record of `buf.len()` bytes, waiting while QEMU runs: for
    /// `SPIN_US` (200 us) by reading again and yielding the CPU in between (QEMU
    /// answers within tens of microseconds; a sleep and a wake-up per tick
    /// would cost as much), then in `poll` with a timeout, to look at Ctrl-C,
    /// QEMU's end and the firmware's silence in between.
    pub fn receive(&mut self, buf: &mut [u8]) -> Result<(), String> {
        let mut done = 0;
        let mut since = Instant::now();
        while done < buf.len() {
            match self.from_firmware.read(&mut buf[done..]) {
                Ok(n) => {
                    done += n;
                    since = Instant::now();
                    continue;
                }
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {}
                Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                Err(e) => return Err(format!("cannot read the firmware's pipe: {e}")),
            }
            if since.elapsed() < Duration::from_micros(SPIN_US) {
                std::thread::yield_now();
                continue;
            }
            let fd = self.from_firmware.as_raw_fd();
            let mut fds = [PollFd::new(fd, PollFlags::POLLIN)];
            match poll(&mut fds, 100) {
                // A signal (Ctrl-C): its flag is looked at below.
                Ok(_) | Err(nix::errno::Errno::EINTR) => {}
                Err(e) => return Err(format!("poll: {e}")),
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

    /// Stop QEMU, let the decoder finish, and return the firmware's log and
    /// whether it is whole (the decoder ended by itself, not killed).
    pub fn finish(mut self) -> (String, bool) {
        let whole = self.stop();
        let log = fs::read_to_string(self.dir.join("firmware.log")).unwrap_or_default();
        (log, whole)
    }

    /// QEMU's process group killed (QEMU and whatever its command started: a
    /// wrapper script's child would otherwise live on, holding the decoder's
    /// input open), then the decoder given [`DECODER_S`] to decode what is left
    /// and exit once its input has ended, and killed with its group after that.
    /// Whether the decoder ended by itself.
    fn stop(&mut self) -> bool {
        if let Some(mut q) = self.qemu.take() {
            kill_group(&q);
            let _ = q.kill();
            let _ = q.wait();
        }
        let mut whole = true;
        if let Some(mut d) = self.decoder.take() {
            let until = Instant::now() + Duration::from_secs(DECODER_S);
            while matches!(d.try_wait(), Ok(None)) && Instant::now() < until {
                std::thread::sleep(Duration::from_millis(5));
            }
            if matches!(d.try_wait(), Ok(None)) {
                whole = false;
                kill_group(&d);
                let _ = d.kill();
            }
            let _ = d.wait();
        }
        whole
    }
}

impl Drop for Session {
    fn drop(&mut self) {
        let _ = self.stop();
        let _ = fs::remove_dir_all(&self.dir);
    }
}

/// This thread, and so QEMU and the decoder it starts (they inherit it), kept
/// on the CPU it runs on now. In lockstep only one side works at a time, so one
/// CPU loses nothing, and a hand-over there is a switch of tasks where one
/// across CPUs is a wake-up by interrupt: 10 s of the reference machine took
/// about 0.8 s instead of 1.1 to 2 s on a 2-CPU VM (benchmarks/pil.md). Where
/// the CPU cannot be read or set, nothing is changed (the run is the same, only
/// slower).
fn stay_on_this_cpu() {
    use nix::sched::{sched_getcpu, sched_setaffinity, CpuSet};
    let Ok(cpu) = sched_getcpu() else {
        return;
    };
    let mut set = CpuSet::new();
    if set.set(cpu).is_ok() {
        let _ = sched_setaffinity(Pid::from_raw(0), &set);
    }
}

/// SIGKILL to the process group `child` leads (spawned with `process_group(0)`).
fn kill_group(child: &Child) {
    if let Ok(pid) = i32::try_from(child.id()) {
        let _ = nix::sys::signal::killpg(Pid::from_raw(pid), Signal::SIGKILL);
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
