//! `host-sim device tune` through the real binary against `host-sim device-sim`
//! over TCP, the answers typed by the test on stdin: every kind of answer, the
//! measured file (rows, resume skipping the points in it, a file in its own
//! column order continued in it, an existing `--out` refused), `--write` making
//! a table the device takes, Ctrl-C and a lost link stopping the sweep with the
//! rows kept, and bad input refused before the device is asked anything.
//!
//! The grid is one speed and three offsets, held 1 s after 0.5 s of settling: a
//! point takes about 3.5 s on the simulator (the offset held 0.7 to 1.2 s after the
//! hold, the stop to rest about 1 s).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::Duration;

mod common;
use common::device_sim::DeviceSim;
use common::Run;

use host_sim::machine::tuning_file;

impl DeviceSim {
    /// `host-sim device --port PORT args...` with `stdin` as its input.
    fn run(&self, args: &[&str], stdin: &str) -> Run {
        let mut cmd = common::host_sim();
        cmd.args(["device", "--port", &self.port]).args(args);
        with_stdin(cmd, stdin)
    }
}

/// Runs `cmd` with `stdin` written to its input (then closed), within 60 s.
fn with_stdin(mut cmd: Command, stdin: &str) -> Run {
    let file = common::scratch("cli-device-tune", &format!("stdin-{}", unique()));
    std::fs::write(&file, stdin).unwrap();
    cmd.stdin(std::fs::File::open(&file).unwrap());
    common::finish_within(cmd, Duration::from_secs(60))
}

/// A number for scratch names, new at every call.
fn unique() -> usize {
    use std::sync::atomic::{AtomicUsize, Ordering};
    static N: AtomicUsize = AtomicUsize::new(0);
    N.fetch_add(1, Ordering::SeqCst)
}

fn scratch(name: &str) -> PathBuf {
    let path = common::scratch("cli-device-tune", name);
    let _ = std::fs::remove_file(&path);
    path
}

/// The sweep of every test: 3000 rpm; 0, 90 and 180 deg; 1 s held after 0.5 s.
const GRID: [&str; 9] = [
    "tune",
    "--speeds",
    "3000",
    "--offsets",
    "0:180:90",
    "--for",
    "1",
    "--settle",
    "0.5",
];

/// [`GRID`] with `more` options: a flag of the grid given again replaces its
/// value, others are added.
fn grid_and(more: &[&str]) -> Vec<String> {
    let mut args: Vec<String> = GRID.iter().map(|s| s.to_string()).collect();
    for pair in more.chunks(2) {
        match args.iter().position(|a| a == pair[0]) {
            Some(i) if pair.len() == 2 => args[i + 1] = pair[1].to_string(),
            _ => args.extend(pair.iter().map(|s| s.to_string())),
        }
    }
    args
}

fn s(p: &Path) -> &str {
    p.to_str().unwrap()
}

/// The points named by the mark lines of `stdout`, in order.
fn marks(stdout: &str) -> Vec<&str> {
    stdout
        .lines()
        .filter_map(|l| l.strip_prefix("mark: "))
        .map(|l| l.split(':').next().unwrap_or(""))
        .collect()
}

#[test]
fn answers_are_recorded_resumed_and_made_into_a_table() {
    let dev = DeviceSim::start(&[]);
    let csv = scratch("sweep.csv");
    let table = scratch("sweep.toml");

    // 0 deg: nonsense, then 12 mm; 90 deg: Enter (run again), then skipped;
    // 180 deg: q (it ran; not recorded).
    let args = grid_and(&["--out", s(&csv)]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = dev.run(&args, "twelve\n12\n\ns\nq\n");
    assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
    assert_eq!(
        marks(&r.stdout),
        [
            "3000 rpm, 0 deg",
            "3000 rpm, 90 deg",
            "3000 rpm, 90 deg",
            "3000 rpm, 180 deg"
        ],
        "{}",
        r.stdout
    );
    assert!(
        r.stdout.contains("not an answer: \"twelve\""),
        "{}",
        r.stdout
    );
    assert!(
        r.stdout
            .contains("device tune: 1 measured, 1 skipped, 1 repeated, 1 left"),
        "{}",
        r.stdout
    );
    // 12 mm in 1 s: 0.012 m/s.
    let rows = "speed_rpm,offset_deg,velocity_mps\n3000,0,0.012\n";
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), rows);

    // The file exists: --out refuses it before the device is asked, untouched.
    let r = dev.run(&args, "");
    r.refused("--out: the file exists: continue it with --resume");
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), rows);

    // Resumed: 0 deg is in the file and skipped; 30 mm at 90, -6 mm at 180.
    let args = grid_and(&["--resume", s(&csv), "--write", s(&table)]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = dev.run(&args, "30\n-6\n");
    assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
    assert_eq!(
        marks(&r.stdout),
        ["3000 rpm, 90 deg", "3000 rpm, 180 deg"],
        "{}",
        r.stdout
    );
    assert_eq!(
        std::fs::read_to_string(&csv).unwrap(),
        format!("{rows}3000,90,0.03\n3000,180,-0.006\n")
    );
    // The peak fit by hand: 12, 30, -6 mm/s at 0, 90, 180 deg; divided
    // differences 0.2 and -0.4 mm/s per deg, a = -0.6 / 180, b = 0.2 + 90 a =
    // -0.1, vertex 90 - b / (2 a) = 75 deg right; left the most negative, 180
    // deg, at the end of a range that does not go round: kept.
    let text = std::fs::read_to_string(&table).unwrap();
    assert_eq!(
        tuning_file::parse("t", &text).unwrap(),
        [(3000.0, 75.0, 180.0)]
    );
    // The device takes it: the sweep left the rotors at rest.
    let w = dev.run(&["table", "write", s(&table)], "");
    assert_eq!(w.status, 0, "{}{}", w.stdout, w.stderr);
    let read = dev.run(&["table", "read"], "");
    assert!(
        read.stdout.contains("right_offset_deg = 75.0"),
        "{}",
        read.stdout
    );
}

#[test]
fn a_file_in_its_own_column_order_is_resumed_and_continued_in_it() {
    let dev = DeviceSim::start(&[]);
    let csv = scratch("reordered.csv");
    // A file as `calibrate` reads it, written by hand: a comment, the columns in
    // another order with weights, 0 deg and -270 deg (90 deg) measured.
    let rows = "# bench, 2 May\nvelocity_mps,weight,speed_rpm,offset_deg\n0.012,2,3000,0\n\n0.03,1,3000,-270\n";
    std::fs::write(&csv, rows).unwrap();
    let args = grid_and(&["--resume", s(&csv)]);
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let r = dev.run(&args, "-6\n");
    assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
    assert!(
        r.stdout
            .contains("device tune: 1 point to measure (2 of the grid already in"),
        "{}",
        r.stdout
    );
    assert_eq!(marks(&r.stdout), ["3000 rpm, 180 deg"], "{}", r.stdout);
    // -6 mm in 1 s, in the file's own column order, weight 1.
    assert_eq!(
        std::fs::read_to_string(&csv).unwrap(),
        format!("{rows}-0.006,1,3000,180\n")
    );
}

/// Starts a sweep resuming `csv`, waits for its first mark line, calls `then`,
/// and returns the run.
fn interrupt_after_mark(port: &str, csv: &Path, then: impl FnOnce(&mut Child)) -> Run {
    let args = grid_and(&["--resume", s(csv)]);
    let mut child = common::host_sim()
        .args(["device", "--port", port])
        .args(&args)
        .stdin(Stdio::piped())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("host-sim runs");
    let mut stdout = BufReader::new(child.stdout.take().expect("piped"));
    let mut seen = String::new();
    loop {
        let mut line = String::new();
        if stdout.read_line(&mut line).unwrap() == 0 {
            break;
        }
        seen.push_str(&line);
        if line.starts_with("mark: ") {
            then(&mut child);
            break;
        }
    }
    let _ = std::io::Read::read_to_string(&mut stdout, &mut seen);
    let out = child.wait_with_output().unwrap();
    let run = Run {
        status: out.status.code().unwrap_or(-1),
        stdout: seen,
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        took: Duration::ZERO,
    };
    assert!(!run.stderr.contains("panicked"), "{}", run.stderr);
    run
}

/// A measured file with one row (0 deg), so the sweep starts at 90 deg.
fn one_row(name: &str) -> (PathBuf, &'static str) {
    let csv = scratch(name);
    let rows = "speed_rpm,offset_deg,velocity_mps\n3000,0,0.012\n";
    std::fs::write(&csv, rows).unwrap();
    (csv, rows)
}

#[cfg(unix)]
#[test]
fn ctrl_c_stops_the_machine_and_keeps_the_rows() {
    let dev = DeviceSim::start(&[]);
    let (csv, rows) = one_row("ctrl-c.csv");
    let r = interrupt_after_mark(&dev.port, &csv, |child| {
        // Ctrl-C to the child this test started, by its id.
        let pid = nix::unistd::Pid::from_raw(i32::try_from(child.id()).unwrap());
        nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
    });
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    // "Stopped" as the status said it after the stop: idle, rotors at rest.
    let (first, rest) = r.stderr.split_once('\n').unwrap();
    assert!(
        first.starts_with(
            "error: 3000 rpm, 90 deg: measuring: interrupted by SIGINT (Ctrl-C); the machine is stopped: at rest after "
        ) && first.contains(" s (state idle, rotors at "),
        "{}",
        r.stderr
    );
    assert!(rest.starts_with("1 row in "), "{}", r.stderr);
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), rows);
    // The device says so too.
    let status = dev.run(&["status"], "");
    let state = status.stdout.lines().next().unwrap_or("");
    assert!(state.ends_with("idle"), "{}", status.stdout);
}

#[test]
fn a_lost_link_ends_the_sweep_with_the_rows_kept() {
    let mut dev = DeviceSim::start(&[]);
    let (csv, rows) = one_row("lost.csv");
    // The device dies while the point is measured.
    let port = dev.port.clone();
    let r = interrupt_after_mark(&port, &csv, |_| {
        dev.kill();
    });
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    assert!(r.stderr.starts_with("error: "), "{}", r.stderr);
    assert!(
        r.stderr.contains("1 row in ") && r.stderr.contains("(continue with --resume "),
        "{}",
        r.stderr
    );
    assert_eq!(std::fs::read_to_string(&csv).unwrap(), rows);
}

#[test]
fn bad_input_is_refused_before_the_device_is_asked() {
    // Nothing listens there: every refusal comes before the port is opened.
    let port = "tcp:127.0.0.1:1";
    let bad_header = scratch("bad-header.csv");
    std::fs::write(&bad_header, "speed,offset,v\n").unwrap();
    let bad_row = scratch("bad-row.csv");
    std::fs::write(
        &bad_row,
        "speed_rpm,offset_deg,velocity_mps\n3000,0,0.01\n3000,90,fast\n",
    )
    .unwrap();
    // Rows a float reads but no measurement gives (issue 23: they made a wrong
    // table, exit 0): refused with their lines and columns.
    let huge = scratch("huge.csv");
    std::fs::write(
        &huge,
        "speed_rpm,offset_deg,velocity_mps,weight\n3000,90,0.03,1e308\n3000,135,1e308,1\n",
    )
    .unwrap();
    let missing = scratch("missing.csv");
    let out = scratch("new.csv");
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec!["--resume", s(&bad_header)],
            format!(
                "error: {}: line 1: header: unknown column `speed` (allowed: speed_rpm, offset_deg, velocity_mps, weight)",
                bad_header.display()
            ),
        ),
        (
            vec!["--resume", s(&bad_row)],
            format!(
                "error: {}: line 3: velocity_mps: must be a finite number (got \"fast\")",
                bad_row.display()
            ),
        ),
        (
            vec!["--resume", s(&huge), "--write", "t.toml"],
            format!(
                "error: {0}: line 2: weight: must be within [1e-6, 1e6] (weights are relative: scale them) (got 1e308)\n\
                 error: {0}: line 3: velocity_mps: must be within [-10, 10] m/s (got 1e308)",
                huge.display()
            ),
        ),
        (
            vec!["--resume", s(&missing)],
            format!("error: {}: --resume: cannot read the file", missing.display()),
        ),
        (
            vec!["--out", s(&out), "--write", "t.toml", "--offsets", "0:90:90"],
            "error: --write: --offsets 0:90:90 gives 2 offsets; the peak fit needs at least 3 per speed".into(),
        ),
        (
            vec!["--out", s(&out), "--for", "0"],
            "error: --for: must be a number of seconds above 0 (got 0)".into(),
        ),
        (
            vec!["--out", s(&out), "--settle", "-1"],
            "error: --settle: must be a number of seconds, 0 or more (got -1)".into(),
        ),
        (
            vec!["--out", s(&out), "--speeds", "-100"],
            "error: --speeds -100: -100 rpm: speeds must be above 0".into(),
        ),
        (vec![], "--out <FILE.csv>".into()),
        (
            vec!["--out", s(&out), "--resume", s(&bad_row)],
            "cannot be used with".into(),
        ),
    ];
    for (more, expect) in cases {
        let mut cmd = common::host_sim();
        cmd.args(["device", "--port", port]).args(grid_and(&more));
        let r = with_stdin(cmd, "");
        r.refused(&expect);
        assert!(!out.exists(), "{more:?}");
    }
}
