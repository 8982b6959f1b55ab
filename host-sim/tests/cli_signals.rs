//! Signals in the middle of writing files, through the real binary: SIGINT
//! (Ctrl-C), SIGTERM and SIGHUP end a run with its files whole and a message naming
//! the signal; SIGKILL, which no program can catch, leaves nothing beside the
//! targets (the files are written without a name until the end, where the file
//! system allows it). Each signal is sent once the process is seen writing its
//! output (its open descriptors, read from `/proc`), never after a guessed delay.
//! A process that does not end after its signal is killed and the test fails
//! (within [`LIMIT`]); one that ignores it ends by itself within seconds (a short
//! `--t-end`), never filling the disk; a failing test kills what it started. A
//! run stalled inside one control tick sees its signal within one integrator
//! attempt, not at the tick's end.
#![cfg(target_os = "linux")]

use std::fs;
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Stdio};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use nix::sys::signal::{kill, Signal};
use nix::unistd::Pid;

mod common;
use common::{host_sim, machine, root, whole_csv};

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
        whole_csv(&dir.join("t.csv"));
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

/// A run stalled inside one control tick: the reference machine set spinning at
/// 500 rad/s lands at 3.53 s, and from there its steps are 1e-10 s, so the tick
/// from 3.529 s would take hours (the progress guard's budget raised out of the
/// way). SIGTERM once the progress line of that tick's start is out ends it
/// within one integrator attempt, at a time inside the tick, with its files whole.
/// It used to be seen only at the end of the tick.
#[test]
fn a_signal_ends_a_run_stalled_inside_a_control_tick_with_its_files_whole() {
    let dir = empty_dir("stalled");
    let (t, e) = (dir.join("t.csv"), dir.join("e.csv"));
    let m = machine();
    let mut started = Started(
        host_sim()
            // A progress line at every control tick: the one of 3.529 s says the
            // run is in the tick that stalls.
            .env("VIBRO_PROGRESS_EVERY", "0")
            .args([
                "run",
                m.to_str().unwrap(),
                "--command",
                "right",
                "--set",
                "platform.angular_velocity=500",
                "--set",
                "simulation.progress_budget=1000000000000",
                "--out",
                t.to_str().unwrap(),
                "--events",
                e.to_str().unwrap(),
            ])
            .current_dir(root())
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .expect("host-sim starts"),
    );
    // Every line of stderr, as it comes, to `lines`; the whole at the end.
    let (lines, seen) = mpsc::channel();
    let stderr = started.0.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut all = String::new();
        for line in BufReader::new(stderr).lines().map_while(Result::ok) {
            all += &line;
            all.push('\n');
            let _ = lines.send(line);
        }
        all
    });
    let start = Instant::now();
    loop {
        let line = seen
            .recv_timeout(LIMIT.saturating_sub(start.elapsed()))
            .expect("host-sim reaches the tick at 3.529 s");
        if line.starts_with("run: 3529/10000 ms simulated") {
            break;
        }
    }
    let child = &mut started.0;
    kill(Pid::from_raw(child.id() as i32), Signal::SIGTERM).unwrap();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        assert!(start.elapsed() < LIMIT, "the stalled run ignored SIGTERM");
        std::thread::sleep(Duration::from_millis(20));
    };
    let stderr = reader.join().unwrap();
    assert_eq!(status.code(), Some(1), "{stderr}");
    let message = stderr
        .lines()
        .find(|l| l.starts_with("error: "))
        .unwrap_or_else(|| panic!("no error line: {stderr}"));
    let at: f64 = message
        .strip_prefix("error: run: interrupted by SIGTERM at t = ")
        .and_then(|m| m.split(' ').next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{message}"));
    assert!((3.529..3.53).contains(&at), "{message}");
    assert!(
        message.ends_with(" s of 10 s; the files asked for hold the run up to there, no summary"),
        "{message}"
    );
    assert_eq!(names(&dir), ["e.csv", "t.csv"]);
    let last: f64 = whole_csv(&t).last().unwrap()[0].parse().unwrap();
    assert!((3.529..3.53).contains(&last), "the trace ends at {last}");
    whole_csv(&e);
    fs::remove_dir_all(&dir).unwrap();
}
