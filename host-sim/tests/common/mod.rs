//! What the command-line tests share: the repository's paths, scratch files, and
//! running the `host-sim` binary with the check that no run ever panics.
// Each test file uses its own subset of these.
#![allow(dead_code)]

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use serde_json::Value;

pub mod device_sim;
pub mod docs;
pub mod fake_device;
pub mod parts;
pub mod truth;

/// The repository root.
pub fn root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// The reference machine file.
pub fn machine() -> PathBuf {
    root().join("examples/vibro-driver.toml")
}

/// The telemetry CSV's header, as docs/cli-device.md documents it
/// (`telemetry_csv_header_is_the_documented_one` checks the document).
pub const TELEMETRY_CSV_HEADER: &str = "uptime_ms,state,faults,speed1_rpm,speed2_rpm,speed_ref1_rpm,speed_ref2_rpm,phase_valid,phase_loop_closed,phase_offset_deg,commanded_offset_deg,target_offset_deg,phase_error_deg,current1_a,current2_a,supply_voltage_v,duty1,duty2,command_rejected,tick_late_us,tick_busy_us,overruns,rx_dropped";

/// The tuning tests' tiny grid: 2 speeds x 4 offsets (0, 90, 180, 270; 360 is 0
/// and runs once). 4 s: the offset reference ramps at 180 deg/s along the shorter
/// arc, holding 180 degrees, the farthest, from 1.18 s on (docs/tuning.md,
/// "Defaults and why"), and `mean_velocity` is over the second half (from 2 s).
pub const TINY_GRID: [&str; 6] = [
    "--speeds",
    "2750:3000:250",
    "--offsets",
    "0:360:90",
    "--t-end",
    "4",
];

/// The reference machine's text without its own `[uncertainty]` (the file's last
/// section), its tuning table named by its absolute path (`examples/`), so that
/// the text may be written anywhere.
pub fn reference_without_uncertainty() -> String {
    let text = std::fs::read_to_string(machine()).unwrap();
    let (machine, ranges) = text
        .split_once("\n[uncertainty]\n")
        .expect("the reference machine's [uncertainty]");
    assert!(!ranges.contains("\n["), "[uncertainty] is the last section");
    machine.replace(
        "tuning_table = \"vibro-driver.tuning.toml\"",
        &format!(
            "tuning_table = {:?}",
            root().join("examples/vibro-driver.tuning.toml")
        ),
    )
}

/// The reference machine with `ranges` as its `[uncertainty]` (its tuning table
/// from `examples/`), written as `uncertain.toml` in the scratch directory `tag`;
/// with `ranges` empty, a machine without `[uncertainty]`.
pub fn uncertain_machine(tag: &str, ranges: &str) -> PathBuf {
    let text = reference_without_uncertainty();
    let path = scratch(tag, "uncertain.toml");
    let section = if ranges.is_empty() {
        String::new()
    } else {
        format!("\n[uncertainty]\n{ranges}")
    };
    std::fs::write(&path, text + &section).unwrap();
    path
}

/// A path `name` in a scratch directory of this test binary (`tag` names it),
/// removed when the binary ends if no test failed ([`remove_scratch_at_exit`]).
pub fn scratch(tag: &str, name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("host-sim-{tag}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("scratch directory");
    remove_scratch_at_exit(&dir);
    dir.join(name)
}

/// The scratch directories this test binary made.
static SCRATCH: std::sync::Mutex<Vec<PathBuf>> = std::sync::Mutex::new(Vec::new());

/// Whether a test of this binary panicked (failed) since the first scratch
/// directory was made.
static FAILED: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Removes `dir` when the test binary ends, unless a test failed: then every
/// scratch directory is kept for a look, and their names are printed. The test
/// harness ends through the C library's `exit` whether its tests pass or fail, so
/// a handler registered with `atexit` runs after the last test; a panic hook that
/// keeps the harness's own notes whether one failed.
pub fn remove_scratch_at_exit(dir: &Path) {
    use std::sync::atomic::Ordering;
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            FAILED.store(true, Ordering::SeqCst);
            previous(info);
        }));
        #[cfg(unix)]
        // SAFETY: `atexit` takes a plain function of no arguments, called once at
        // exit; `remove_scratch` touches only this module's statics.
        unsafe {
            nix::libc::atexit(remove_scratch);
        }
    });
    let mut made = SCRATCH.lock().unwrap_or_else(|e| e.into_inner());
    if !made.iter().any(|d| d == dir) {
        made.push(dir.to_path_buf());
    }
}

/// At exit: every scratch directory removed, or all kept when a test failed.
extern "C" fn remove_scratch() {
    use std::sync::atomic::Ordering;
    let made = SCRATCH.lock().unwrap_or_else(|e| e.into_inner());
    if FAILED.load(Ordering::SeqCst) {
        for dir in made.iter().filter(|d| d.exists()) {
            eprintln!(
                "a test failed: its scratch directory {} is kept",
                dir.display()
            );
        }
        return;
    }
    for dir in made.iter() {
        let _ = std::fs::remove_dir_all(dir);
    }
}

/// A copy of the directory `from` (its files and folders) at `to`.
pub fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).expect("a scratch directory");
    for entry in std::fs::read_dir(from).expect("a directory") {
        let entry = entry.expect("an entry");
        let target = to.join(entry.file_name());
        if entry.file_type().expect("a type").is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), target).expect("a copy");
        }
    }
}

/// The rows of a CSV written whole (a header, then rows of its columns, the last
/// ended), each split into its cells; a cut or ragged file fails the test.
pub fn whole_csv(path: &Path) -> Vec<Vec<String>> {
    let text = std::fs::read_to_string(path).unwrap();
    assert!(text.ends_with('\n'), "{}: its last row cut", path.display());
    let mut lines = text.lines();
    let columns = lines.next().unwrap().split(',').count();
    lines
        .map(|l| {
            let cells: Vec<String> = l.split(',').map(str::to_string).collect();
            assert_eq!(cells.len(), columns, "{}: {l}", path.display());
            cells
        })
        .collect()
}

/// What a run of the binary gave.
pub struct Run {
    /// Exit status (-1 when killed by a signal).
    pub status: i32,
    pub stdout: String,
    pub stderr: String,
    /// Wall-clock time of the run.
    pub took: Duration,
}

impl Run {
    /// Asserts a refusal of the user's mistake: exit 2 and `needle` in stderr.
    pub fn refused(&self, needle: &str) {
        assert_eq!(self.status, 2, "exit {}: {}", self.status, self.stderr);
        assert!(
            self.stderr.contains(needle),
            "{needle:?} not in: {}",
            self.stderr
        );
    }

    /// Asserts a result printed (`printed` on stdout), then the error of
    /// `option` written to Linux's `/dev/full` (every write fails), exit 2.
    pub fn printed_then_full(&self, option: &str, printed: &str) {
        assert_eq!(self.status, 2, "{}{}", self.stdout, self.stderr);
        assert!(self.stdout.contains(printed), "{option}: {}", self.stdout);
        let error = format!("error: {option}: cannot write /dev/full: No space left on device");
        assert!(self.stderr.contains(&error), "{}", self.stderr);
    }
}

/// The `host-sim` binary, to add arguments and environment to.
pub fn host_sim() -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_host-sim"));
    // No progress lines: off a terminal they come every 5 s, so on a busy
    // machine a run that passes 5 s would put one in front of the output a test
    // reads. A test of the progress sets its own interval (a later `env` wins).
    cmd.env("VIBRO_PROGRESS_EVERY", "1e9");
    cmd
}

/// Run `cmd` to the end. Whatever happened, never a panic nor a backtrace.
pub fn finish(mut cmd: Command) -> Run {
    let start = Instant::now();
    let out = cmd.output().expect("host-sim runs");
    let run = Run {
        status: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        took: start.elapsed(),
    };
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    assert!(
        !run.stderr.to_lowercase().contains("backtrace"),
        "{}",
        run.stderr
    );
    run
}

/// Run `cmd` and wait at most `limit` for it to end; a run still going then is
/// killed and the test fails (a defect that runs forever fails instead of hanging
/// the suite).
pub fn finish_within(cmd: Command, limit: Duration) -> Run {
    finish_within_with(cmd, limit, |_| {})
}

/// [`finish_within`], telling `started` the child's process id once it runs.
pub fn finish_within_with(mut cmd: Command, limit: Duration, started: impl FnOnce(u32)) -> Run {
    use std::process::Stdio;
    let start = Instant::now();
    let mut child = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("host-sim runs");
    started(child.id());
    wait_within(&mut child, start, limit)
}

/// Waits for `child` (started at `start`, its stdout and stderr piped) to end, at
/// most until `limit` after `start`; one still going then is killed and the test
/// fails. Never a panic in its stderr.
pub fn wait_within(child: &mut std::process::Child, start: Instant, limit: Duration) -> Run {
    use std::io::Read;
    // Drain both pipes on threads so a chatty run cannot block on a full pipe.
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut s = String::new();
            let _ = r.read_to_string(&mut s);
            s
        })
    };
    let out = drain(Box::new(child.stdout.take().expect("piped")));
    let err = drain(Box::new(child.stderr.take().expect("piped")));
    let status = loop {
        if let Some(s) = child.try_wait().expect("wait") {
            break s;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("host-sim did not end within {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let run = Run {
        status: status.code().unwrap_or(-1),
        stdout: out.join().expect("stdout"),
        stderr: err.join().expect("stderr"),
        took: start.elapsed(),
    };
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    run
}

/// Run `host-sim` with `args` from the repository root.
pub fn run(args: &[&str]) -> Run {
    let mut cmd = host_sim();
    cmd.args(args).current_dir(root());
    finish(cmd)
}

/// Run `host-sim command <reference machine> args…` from the repository root.
pub fn run_machine(command: &str, args: &[&str]) -> Run {
    let m = machine();
    let mut all = vec![command, m.to_str().expect("a UTF-8 path")];
    all.extend_from_slice(args);
    run(&all)
}

/// The keys of a JSON object, in order (the docs fix the order).
pub fn keys(v: &Value) -> Vec<&str> {
    v.as_object()
        .expect("a JSON object")
        .keys()
        .map(String::as_str)
        .collect()
}

/// The processor in the loop's firmware (the binary `pil`, built for the
/// reference machine) when it and the tools that run it are there, or `None`
/// (skipped, said on stderr) where they are absent outside CI; in CI
/// (`CI=true`, where `scripts/test-all.sh` builds it first) their absence fails.
#[allow(dead_code)]
pub fn pil_firmware() -> Option<PathBuf> {
    let target = std::env::var_os("CARGO_TARGET_DIR")
        .map(PathBuf::from)
        .unwrap_or_else(|| root().join("firmware/target"));
    let target = if target.is_absolute() {
        target
    } else {
        root().join(target)
    };
    let elf = target.join("thumbv7em-none-eabihf/release/pil");
    let on_path = |tool: &str| {
        std::env::var_os("PATH")
            .is_some_and(|p| std::env::split_paths(&p).any(|d| d.join(tool).is_file()))
    };
    let mut missing = Vec::new();
    if !elf.is_file() {
        missing.push(format!(
            "{} (cd firmware && cargo build --release --features pil --bin pil)",
            elf.display()
        ));
    }
    for tool in ["qemu-system-arm", "defmt-print"] {
        if !on_path(tool) {
            missing.push(format!("{tool} on PATH"));
        }
    }
    if missing.is_empty() {
        return Some(elf);
    }
    let why = format!("processor in the loop: missing {}", missing.join(", "));
    assert!(std::env::var("CI").as_deref() != Ok("true"), "{why}");
    eprintln!("skipped: {why}");
    None
}

/// The `pil` ELF built for the machine file `machine`: `elf` (from
/// [`pil_firmware`]) for the reference machine, `ELF-STEM` beside it for another
/// machine file `STEM.toml` (scripts/test-all.sh builds those the tests use);
/// `None` (skipped, said on stderr) where that one is absent outside CI,
/// failing in CI.
pub fn pil_firmware_for(elf: &Path, machine: &Path) -> Option<PathBuf> {
    if machine.ends_with("examples/vibro-driver.toml") {
        return Some(elf.to_path_buf());
    }
    let stem = machine.file_stem().expect("a file name").to_string_lossy();
    let other = PathBuf::from(format!("{}-{stem}", elf.display()));
    if other.is_file() {
        return Some(other);
    }
    let why = format!(
        "no {}: build it with `cd firmware && VIBRO_MACHINE={} cargo build --release --features pil --bin pil` and copy the ELF there",
        other.display(),
        machine.display()
    );
    assert!(std::env::var("CI").as_deref() != Ok("true"), "{why}");
    eprintln!("skipped: {why}");
    None
}
