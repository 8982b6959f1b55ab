//! Signals in the middle of writing files, through the real binary: SIGINT
//! (Ctrl-C), SIGTERM and SIGHUP end a run with its files whole and a message naming
//! the signal; SIGKILL, which no program can catch, leaves nothing beside the
//! targets (the files are written without a name until the end, where the file
//! system allows it). Each signal is sent once the process is seen writing its
//! output (its open descriptors, read from `/proc`), never after a guessed delay.
//! A process that does not end after its signal is killed and the test fails
//! (within [`LIMIT`]); one that ignores it ends by itself within seconds (a short
//! `--t-end`), never filling the disk; a failing test kills what it started.
#![cfg(target_os = "linux")]

use std::fs;
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::time::{Duration, Instant};

use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

mod common;
use common::{host_sim, machine, root};

/// Long enough for the process to start writing, and to end after a signal, on a
/// loaded machine; a defect that never writes or never ends fails here instead of
/// hanging the suite.
const LIMIT: Duration = Duration::from_secs(300);

/// A started `host-sim`: killed and reaped when dropped, so that a test that fails
/// before it ends leaves no process behind.
struct Started(Child);

impl Drop for Started {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A fresh, empty directory for one case's outputs.
fn empty_dir(case: &str) -> PathBuf {
    let dir = common::scratch("cli-signals", case);
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(&dir).unwrap();
    dir
}

/// The names in `dir`, sorted (hidden ones too).
fn names(dir: &Path) -> Vec<String> {
    let mut n: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    n.sort();
    n
}

/// Whether `dir`'s file system gives files without a name (`O_TMPFILE`), asked of
/// the kernel directly; where it does not, the named temporary files are the
/// documented fallback.
fn has_unnamed_files(dir: &Path) -> bool {
    use std::os::unix::fs::OpenOptionsExt;
    fs::OpenOptions::new()
        .write(true)
        .custom_flags(nix::libc::O_TMPFILE)
        .open(dir)
        .is_ok()
}

/// Starts `host-sim args` from the repository root, its output captured.
fn start(args: &[&str]) -> Started {
    Started(
        host_sim()
            .args(args)
            .current_dir(root())
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("host-sim starts"),
    )
}

/// Waits until `child` has `files` files open in `dir` with at least `bytes`
/// bytes written to the largest (its descriptors in `/proc/PID/fd`: a file
/// without a name shows there as `DIR/#INODE (deleted)`).
fn wait_writing(started: &mut Started, dir: &Path, files: usize, bytes: u64) {
    let child = &mut started.0;
    let fds = PathBuf::from(format!("/proc/{}/fd", child.id()));
    let start = Instant::now();
    loop {
        assert!(
            child.try_wait().unwrap().is_none(),
            "host-sim ended before writing"
        );
        let open: Vec<u64> = fs::read_dir(&fds)
            .map(|entries| {
                entries
                    .filter_map(|e| {
                        let fd = e.ok()?.path();
                        let to = fs::read_link(&fd).ok()?;
                        to.starts_with(dir).then(|| fs::metadata(&fd).ok())?
                    })
                    .map(|m| m.len())
                    .collect()
            })
            .unwrap_or_default();
        if open.len() >= files && open.iter().any(|&n| n >= bytes) {
            return;
        }
        assert!(start.elapsed() < LIMIT, "host-sim did not start writing");
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Sends `signal` to `started` and waits for its end, at most [`LIMIT`] (then it
/// is killed and the test fails): (exit status, stderr); the status is -1 when
/// the signal killed it.
fn stop(mut started: Started, signal: Signal) -> (i32, String) {
    let child = &mut started.0;
    kill(Pid::from_raw(child.id() as i32), signal).unwrap();
    let r = common::wait_within(child, Instant::now(), LIMIT);
    (r.status, r.stderr)
}

/// `run` with a trace, events and a plot, under way. The signal lands once the
/// trace has 128 KiB (some 0.15 s of simulated time: the reference machine writes
/// about 1 MB of trace a simulated second); `--t-end 60` leaves 400 times that,
/// some 3.5 s of CPU, so the run is still going when the signal comes, and one
/// that ignores it ends by itself with some 80 MB written.
fn start_run(dir: &Path) -> Started {
    let m = machine();
    let path = |n: &str| dir.join(n).to_str().unwrap().to_string();
    let (t, e, p) = (path("t.csv"), path("e.csv"), path("p.svg"));
    let args = [
        "run",
        m.to_str().unwrap(),
        "--command",
        "right",
        "--t-end",
        "60",
        "--out",
        &t,
        "--events",
        &e,
        "--plot",
        &p,
    ];
    let mut child = start(&args);
    // The trace past its first buffer (64 KiB): the run is under way.
    wait_writing(&mut child, dir, 3, 1 << 17);
    child
}

#[test]
fn sigint_sigterm_and_sighup_end_a_run_with_its_files_whole_and_named_in_the_message() {
    for (signal, name) in [
        (Signal::SIGINT, "SIGINT (Ctrl-C)"),
        (Signal::SIGTERM, "SIGTERM"),
        (Signal::SIGHUP, "SIGHUP"),
    ] {
        let dir = empty_dir(&format!("run-{name}"));
        let child = start_run(&dir);
        if has_unnamed_files(&dir) {
            assert!(names(&dir).is_empty(), "while written: {:?}", names(&dir));
        }
        let (status, stderr) = stop(child, signal);
        assert_eq!(status, 1, "{name}: {stderr}");
        assert!(
            stderr.contains(&format!("error: run: interrupted by {name} at t = ")),
            "{name}: {stderr}"
        );
        assert_eq!(names(&dir), ["e.csv", "p.svg", "t.csv"], "{name}");
        let trace = fs::read_to_string(dir.join("t.csv")).unwrap();
        let columns = trace.lines().next().unwrap().split(',').count();
        assert!(trace.ends_with('\n'), "{name}: the trace's last row cut");
        assert!(trace.lines().all(|l| l.split(',').count() == columns));
        let plot = fs::read_to_string(dir.join("p.svg")).unwrap();
        assert!(plot.trim_end().ends_with("</svg>"), "{name}: the plot cut");
        fs::remove_dir_all(&dir).unwrap();
    }
}

#[test]
fn sigkill_in_a_run_leaves_no_file_beside_its_outputs() {
    let dir = empty_dir("run-SIGKILL");
    let child = start_run(&dir);
    let (status, _) = stop(child, Signal::SIGKILL);
    assert_eq!(status, -1);
    if has_unnamed_files(&dir) {
        assert!(names(&dir).is_empty(), "left behind: {:?}", names(&dir));
    } else {
        // The named fallback (docs/development.md, "Output files").
        assert!(names(&dir).iter().all(|n| n.ends_with(".tmp")));
    }
    fs::remove_dir_all(&dir).unwrap();
}

/// `calibrate --write`: the file is opened before the fit, which takes minutes;
/// SIGTERM ends the fit with nothing written, SIGKILL leaves nothing either.
#[test]
fn a_signal_during_calibrate_writes_nothing_and_leaves_nothing() {
    let m = common::uncertain_machine("cli-signals", "\"contacts.*.friction\" = [0.1, 0.6]\n");
    let measured = common::scratch("cli-signals", "measured.csv");
    fs::write(
        &measured,
        "speed_rpm,offset_deg,velocity_mps\n3000,60,0.02\n3000,90,0.03\n3000,120,0.035\n",
    )
    .unwrap();
    for signal in [Signal::SIGTERM, Signal::SIGKILL] {
        let dir = empty_dir(&format!("calibrate-{signal}"));
        let out = dir.join("calibrated.toml");
        let mut child = start(&[
            "calibrate",
            m.to_str().unwrap(),
            "--measured",
            measured.to_str().unwrap(),
            "--fit",
            "contacts.*.friction",
            "--write",
            out.to_str().unwrap(),
        ]);
        wait_writing(&mut child, &dir, 1, 0);
        if has_unnamed_files(&dir) {
            assert!(names(&dir).is_empty(), "while fitted: {:?}", names(&dir));
        }
        let (status, stderr) = stop(child, signal);
        if signal == Signal::SIGKILL {
            assert_eq!(status, -1);
            if has_unnamed_files(&dir) {
                assert!(names(&dir).is_empty(), "left behind: {:?}", names(&dir));
            }
        } else {
            assert_eq!(status, 1, "{stderr}");
            assert!(
                stderr.contains(
                    "error: calibrate: interrupted by SIGTERM: the fit is incomplete, nothing written"
                ),
                "{stderr}"
            );
            assert!(names(&dir).is_empty(), "{:?}", names(&dir));
        }
        fs::remove_dir_all(&dir).unwrap();
    }
}
