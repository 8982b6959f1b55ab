//! `host-sim device` through the real binary against the firmware's link code
//! (`shared::protocol::link::Link` with the controller on the reference machine's
//! rotors, the platform held, and a
//! `SimFlash`, served in this process over TCP, or as `host-sim device-sim` behind
//! a pseudo-terminal): every subcommand, a table round trip, telemetry as CSV, a
//! noisy line, a silent device, devices that answer wrongly (an Ack for another
//! request, an acknowledged stream that never comes), and clear refusals (exit 2,
//! no panic) of bad input.

use std::io::{BufRead, BufReader};
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

mod common;
use common::fake_device::{self, ack};
use common::Run;

use host_sim::device::commands::TABLE_HEADER;
use host_sim::device::serve::{serve_watched, Endpoint, Watch};
use host_sim::device::sim::{Noise, SimDevice};
use host_sim::machine::tuning_file;
use shared::controller::self_test::SelfTestStatus;
use shared::controller::{Faults, State};
use shared::protocol::link::no_telemetry;
use shared::protocol::{MessageId, Request, Response, StatusReport};
use shared::storage;

/// The bound against a hang: a command, or a wait for what the device shows.
const HANG: Duration = Duration::from_secs(120);

/// A simulated device served over TCP on this machine until dropped.
struct Device {
    port: String,
    stop: Arc<AtomicBool>,
    /// While set, the device's clock stands once its self-test runs
    /// ([`HoldSelfTest`]).
    hold: Arc<AtomicBool>,
    thread: Option<JoinHandle<SimDevice>>,
}

/// How the test's device is served: until the test stops it (or ten minutes,
/// whatever happens to the test), its clock held while `hold` is set and its
/// self-test runs.
struct HoldSelfTest {
    stop: Arc<AtomicBool>,
    hold: Arc<AtomicBool>,
    end: Instant,
}

impl Watch for HoldSelfTest {
    fn go_on(&mut self) -> bool {
        !self.stop.load(Ordering::SeqCst) && Instant::now() < self.end
    }

    fn held(&mut self, device: &SimDevice) -> bool {
        self.hold.load(Ordering::SeqCst)
            && device.link_state().self_test.status == SelfTestStatus::Running
    }
}

impl Device {
    /// The device with the test's long link timeout
    /// ([`common::device_sim::LINK_TIMEOUT_S`]): the link handed from one
    /// `host-sim device` process to the next never times out on a loaded
    /// machine.
    fn start(noise: Noise) -> Device {
        let link_timeout: f32 = common::device_sim::LINK_TIMEOUT_S.parse().unwrap();
        Device::on(SimDevice::new(None, noise).with_link_timeout(link_timeout))
    }

    /// `device` served.
    fn on(mut device: SimDevice) -> Device {
        let mut endpoint = Endpoint::tcp("127.0.0.1:0").expect("listens");
        let port = endpoint.port_name();
        let stop = Arc::new(AtomicBool::new(false));
        let hold = Arc::new(AtomicBool::new(false));
        let mut watch = HoldSelfTest {
            stop: stop.clone(),
            hold: hold.clone(),
            end: Instant::now() + Duration::from_secs(600),
        };
        let thread = std::thread::spawn(move || {
            serve_watched(&mut endpoint, &mut device, &mut watch);
            device
        });
        Device {
            port,
            stop,
            hold,
            thread: Some(thread),
        }
    }

    /// The status until `done` says it shows what is awaited (at most [`HANG`]);
    /// that status.
    fn status_until(&self, what: &str, done: impl Fn(&str) -> bool) -> String {
        let start = Instant::now();
        loop {
            let s = self.run(&["status"]);
            if done(s.ok()) {
                return s.stdout;
            }
            assert!(
                start.elapsed() < HANG,
                "{what}: not after {HANG:?}:\n{}",
                s.stdout
            );
            std::thread::sleep(Duration::from_millis(50));
        }
    }

    /// Stop serving; the device as it ended.
    fn finish(mut self) -> SimDevice {
        self.stop.store(true, Ordering::SeqCst);
        self.thread
            .take()
            .expect("running")
            .join()
            .expect("the device thread ran")
    }

    /// `host-sim device --port PORT args...`.
    fn run(&self, args: &[&str]) -> Run {
        let mut all = vec!["device", "--port", &self.port];
        all.extend_from_slice(args);
        host_sim(&all)
    }
}

impl Drop for Device {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::SeqCst);
    }
}

/// What the tests expect of a finished run.
trait Outcome {
    /// Exit 0: its standard output.
    fn ok(&self) -> &str;
    /// Exit 2 (a user's mistake): its standard error.
    fn usage(&self) -> &str;
}

impl Outcome for Run {
    fn ok(&self) -> &str {
        assert_eq!(
            self.status, 0,
            "stdout:\n{}\nstderr:\n{}",
            self.stdout, self.stderr
        );
        &self.stdout
    }

    fn usage(&self) -> &str {
        assert_eq!(
            self.status, 2,
            "stdout:\n{}\nstderr:\n{}",
            self.stdout, self.stderr
        );
        &self.stderr
    }
}

/// Runs `host-sim` with `args`, no standard input, at most [`HANG`].
fn host_sim(args: &[&str]) -> Run {
    let mut cmd = common::host_sim();
    cmd.args(args).stdin(Stdio::null());
    common::finish_within(cmd, HANG)
}

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-device", name)
}

/// The value of `key` in `host-sim device status` output.
fn field<'a>(status: &'a str, key: &str) -> &'a str {
    status
        .lines()
        .find_map(|l| l.strip_prefix(key).map(str::trim))
        .unwrap_or_else(|| panic!("no `{key}` in\n{status}"))
}

#[test]
fn status_travel_stop_and_a_refused_table_write() {
    let dev = Device::start(Noise::default());
    let s = dev.run(&["status"]);
    assert_eq!(field(s.ok(), "state"), "idle");
    assert_eq!(field(s.ok(), "faults"), "none");

    let t = dev.run(&["travel", "right", "--speed", "3000"]);
    assert!(
        t.ok().contains("travel right at 3000 rpm: accepted"),
        "{}",
        t.stdout
    );
    let s = dev.run(&["status"]);
    let state = field(s.ok(), "state");
    assert!(state == "starting" || state == "running", "{}", s.stdout);

    // A device refusal is exit 1 with the reason: no table write while the
    // rotors are driven.
    let file = scratch("refused.toml");
    std::fs::write(&file, tuning_file::write(&[(3000.0, 80.0, 280.0)], "t")).unwrap();
    let w = dev.run(&["table", "write", file.to_str().unwrap()]);
    assert_eq!(w.status, 1, "{}{}", w.stdout, w.stderr);
    assert!(
        w.stderr
            .contains("refused WriteTuningTable: the motors must be stopped"),
        "{}",
        w.stderr
    );

    let t = dev.run(&["stop"]);
    assert_eq!(t.ok(), "stop: accepted\n");
    let s = dev.run(&["status"]);
    let state = field(s.ok(), "state");
    assert!(state == "stopping" || state == "idle", "{}", s.stdout);
    dev.finish();
}

/// `hold --for` keeps the link alive with its heartbeats for longer than the
/// device's link timeout (2 s here: forty heartbeats of 50 ms may go missing
/// before it), then stops and waits for rest.
#[test]
fn hold_for_keeps_the_link_then_stops_at_rest() {
    let dev = Device::on(SimDevice::new(None, Noise::default()).with_link_timeout(2.0));
    let h = dev.run(&["hold", "--offset", "120", "--speed", "2800", "--for", "5"]);
    let out = h.ok();
    assert!(
        out.contains("hold offset 120 deg at 2800 rpm: accepted"),
        "{out}"
    );
    let after = out
        .lines()
        .find(|l| l.starts_with("after "))
        .unwrap_or_else(|| panic!("{out}"));
    assert!(after.contains(" running "), "{out}");
    assert!(after.contains("(target 120.0)"), "{out}");
    assert!(after.ends_with("faults none"), "{out}");
    assert!(
        out.contains("stop: accepted\nstop: at rest after "),
        "{out}"
    );
    assert!(out.contains(" (state idle, rotors at "), "{out}");
    // It returned at rest, so a table write right after it is taken (issue 23:
    // it returned while the rotors ran down, and the write was refused).
    let at_rest = scratch("at-rest.toml");
    std::fs::write(&at_rest, tuning_file::write(&[(3000.0, 90.0, 270.0)], "t")).unwrap();
    let w = dev.run(&["table", "write", at_rest.to_str().unwrap()]);
    assert!(w.ok().starts_with("table write: 1 row "), "{}", w.stdout);
    dev.finish();
}

/// Travel without heartbeats on a device with the firmware's link timeout
/// (0.5 s): the controller latches link_lost; reset clears it. The status is
/// asked a second apart (a request keeps the link alive), until the fault
/// shows.
#[test]
fn a_lost_link_latches_link_lost_and_reset_clears_it() {
    let dev = Device::on(SimDevice::new(None, Noise::default()));
    dev.run(&["travel", "left", "--speed", "3000"]).ok();
    let start = Instant::now();
    let s = loop {
        std::thread::sleep(Duration::from_secs(1));
        let s = dev.run(&["status"]);
        if field(s.ok(), "state") == "fault" {
            break s;
        }
        assert!(
            start.elapsed() < HANG,
            "no fault after {HANG:?}:\n{}",
            s.stdout
        );
    };
    assert_eq!(field(&s.stdout, "faults"), "link_lost", "{}", s.stdout);
    let r = dev.run(&["reset"]);
    assert_eq!(r.ok(), "reset: accepted; state idle, faults none\n");
    dev.finish();
}

#[test]
fn a_table_written_reads_back_identical_and_is_in_flash() {
    let dev = Device::start(Noise::default());
    let rows = tuning_file::read(&PathBuf::from(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../examples/vibro-driver.tuning.toml"
    )))
    .expect("the example table reads");
    // The file as `table read` writes it, so the round trip is byte for byte.
    let file = scratch("table.toml");
    let text = tuning_file::write(&rows, TABLE_HEADER);
    std::fs::write(&file, &text).unwrap();
    let w = dev.run(&["table", "write", file.to_str().unwrap()]);
    assert!(w.ok().contains("5 rows"), "{}", w.stdout);

    let back = scratch("table-back.toml");
    let _ = std::fs::remove_file(&back);
    let r = dev.run(&["table", "read", "--out", back.to_str().unwrap()]);
    assert!(r.ok().contains("5 rows written to"), "{}", r.stdout);
    assert_eq!(std::fs::read_to_string(&back).unwrap(), text);
    // To stdout as well.
    assert_eq!(dev.run(&["table", "read"]).ok(), text);

    let device = dev.finish();
    let stored = storage::load(device.flash()).expect("a record in flash");
    assert_eq!(stored.record.tuning, tuning_file::table(&rows).unwrap());
    assert_eq!(device.link_state().tuning, stored.record.tuning);
}

#[test]
fn telemetry_as_csv_has_a_header_and_n_rows() {
    let dev = Device::start(Noise::default());
    let csv = scratch("telemetry.csv");
    let _ = std::fs::remove_file(&csv);
    let t = dev.run(&[
        "telemetry",
        "--period",
        "20",
        "--count",
        "6",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(
        t.ok().contains("telemetry: 6 frames written to"),
        "{}",
        t.stdout
    );
    // The readable lines too.
    assert_eq!(t.stdout.lines().filter(|l| l.contains(" idle ")).count(), 6);
    let text = std::fs::read_to_string(&csv).unwrap();
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 7, "{text}");
    assert_eq!(lines[0], common::TELEMETRY_CSV_HEADER);
    let columns = common::TELEMETRY_CSV_HEADER.split(',').count();
    let mut last = None;
    for row in &lines[1..] {
        let fields: Vec<&str> = row.split(',').collect();
        assert_eq!(fields.len(), columns, "{row}");
        assert_eq!(fields[1], "idle");
        let uptime: u32 = fields[0].parse().unwrap();
        assert!(last.is_none_or(|l| uptime > l), "{text}");
        last = Some(uptime);
    }

    // To stdout: the header and the rows only.
    let t = dev.run(&["telemetry", "--period", "20", "--count", "3", "--csv", "-"]);
    let lines: Vec<&str> = t.ok().lines().collect();
    assert_eq!(lines.len(), 4, "{}", t.stdout);
    assert_eq!(lines[0], common::TELEMETRY_CSV_HEADER);

    // By duration, readable lines: about 5 frames in 0.5 s at 100 ms.
    let t = dev.run(&["telemetry", "--duration", "0.5"]);
    let n = t.ok().lines().count();
    assert!((2..=7).contains(&n), "{}", t.stdout);

    // The stream is off at the end.
    let device = dev.finish();
    assert_eq!(device.link_state().telemetry_period_ms, 0);
}

#[test]
fn a_noisy_line_still_gives_the_right_answers() {
    // A bit flipped in every 211th byte either way, garbage before every 3rd
    // frame the device sends.
    let dev = Device::start(Noise {
        flip_every: Some(211),
        garbage_every: Some(3),
    });
    let r = |args: &[&str]| {
        let mut all = vec!["--retries", "10"];
        all.extend_from_slice(args);
        dev.run(&all)
    };
    for _ in 0..3 {
        let s = r(&["status"]);
        assert_eq!(field(s.ok(), "state"), "idle");
    }
    r(&["travel", "right", "--speed", "3000"]).ok();
    let t = r(&["telemetry", "--period", "20", "--count", "20", "--csv", "-"]);
    let rows: Vec<&str> = t.ok().lines().skip(1).collect();
    assert_eq!(rows.len(), 20);
    assert!(rows
        .iter()
        .all(|l| l.contains(",starting,") || l.contains(",running,")));
    assert_eq!(r(&["stop"]).ok(), "stop: accepted\n");
    let s = r(&["status"]);
    let state = field(s.ok(), "state");
    assert!(state == "stopping" || state == "idle", "{}", s.stdout);
    dev.finish();
}

/// A line so noisy that no status report crosses it whole (a bit flipped in
/// every 12th byte): bytes came, so the hint is the line's, not the port's
/// (issue 23: "is the port right, the device powered" for a noisy line).
#[test]
fn a_line_too_noisy_for_an_answer_says_so() {
    let dev = Device::start(Noise {
        flip_every: Some(12),
        garbage_every: None,
    });
    let r = dev.run(&["--retries", "2", "status"]);
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    assert!(
        r.stderr
            .contains("no answer from the device to GetStatus after 3 tries of 100 ms, though ")
            && r.stderr.contains("a noisy line"),
        "{}",
        r.stderr
    );
    assert!(!r.stderr.contains("is the port right"), "{}", r.stderr);
    dev.finish();
}

#[test]
fn a_device_that_never_answers_is_a_clear_timeout() {
    // Accepts, reads and says nothing.
    let port = fake_device::silent();
    let r = host_sim(&["device", "--port", &port, "--retries", "2", "status"]);
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    assert!(
        r.stderr.contains(
            "no answer from the device to GetStatus after 3 tries of 100 ms, and no byte at all (is the port right"
        ),
        "{}",
        r.stderr
    );
}

#[test]
fn bad_input_is_refused_with_exit_2() {
    let table = scratch("bad-table.toml");
    std::fs::write(
        &table,
        "[[rows]]\nspeed_rpm = 3000\nright_offset_deg = 400\nleft_offset_deg = 10\n",
    )
    .unwrap();
    let missing = scratch("no-such-table.toml");
    let p = "tcp:127.0.0.1:9";
    let cases: Vec<(Vec<&str>, &str)> = vec![
        (vec!["device", "status"], "--port: missing"),
        (
            vec!["device", "--port", "tcp:localhost", "status"],
            "tcp:HOST:PORT",
        ),
        (
            vec!["device", "--port", p, "travel", "up", "--speed", "3000"],
            "right",
        ),
        (vec!["device", "--port", p, "travel", "right"], "--speed"),
        (
            vec!["device", "--port", p, "travel", "right", "--speed", "fast"],
            "--speed",
        ),
        (
            vec!["device", "--port", p, "travel", "right", "--speed", "NaN"],
            "--speed",
        ),
        (
            vec!["device", "--port", p, "travel", "left", "--speed", "-5"],
            "above 0",
        ),
        (
            vec![
                "device", "--port", p, "hold", "--offset", "inf", "--speed", "3000",
            ],
            "--offset",
        ),
        (
            vec!["device", "--port", p, "telemetry", "--period", "5"],
            "--period: must be 20 to 65535",
        ),
        (
            vec!["device", "--port", p, "telemetry", "--count", "0"],
            "--count",
        ),
        (
            vec![
                "device",
                "--port",
                p,
                "telemetry",
                "--duration",
                "1",
                "--count",
                "3",
            ],
            "--count",
        ),
        (
            vec!["device", "--port", p, "self-test", "--timeout", "-1"],
            "--timeout",
        ),
        (
            vec![
                "device",
                "--port",
                p,
                "table",
                "write",
                table.to_str().unwrap(),
            ],
            "rows[0].right_offset_deg",
        ),
        (
            vec![
                "device",
                "--port",
                p,
                "table",
                "write",
                missing.to_str().unwrap(),
            ],
            "no-such-table.toml",
        ),
        (
            vec![
                "device",
                "--port",
                p,
                "telemetry",
                "--csv",
                "/no/such/dir/t.csv",
            ],
            "/no/such/dir",
        ),
        (
            vec![
                "device",
                "--port",
                p,
                "table",
                "read",
                "--out",
                "/no/such/dir/t.toml",
            ],
            "/no/such/dir",
        ),
        (
            vec!["device", "--port", "/no/such/tty", "status"],
            "/no/such/tty",
        ),
        (vec!["device", "--port", p, "frobnicate"], "frobnicate"),
        (
            vec!["device-sim", "--listen", "/dev/ttyS0"],
            "tcp:HOST:PORT",
        ),
        (vec!["device-sim", "--flip-every", "0"], "--flip-every"),
        (
            vec!["device-sim", "--table", missing.to_str().unwrap()],
            "no-such-table.toml",
        ),
    ];
    for (args, expect) in cases {
        let r = host_sim(&args);
        let stderr = r.usage();
        assert!(stderr.contains(expect), "{args:?}: {stderr}");
    }
}

#[cfg(unix)]
#[test]
fn device_sim_serves_a_pseudo_terminal() {
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["device-sim", "--duration", common::device_sim::LIFETIME_S])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .expect("device-sim runs");
    let mut first = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    let port = first
        .trim()
        .strip_prefix("port: ")
        .unwrap_or_else(|| panic!("first line {first:?}"))
        .to_string();
    assert!(port.starts_with("/dev/"), "{port}");
    let s = host_sim(&["device", "--port", &port, "status"]);
    let result = s.status;
    let t = host_sim(&["device", "--port", &port, "table", "read"]);
    // Ends the process it started, by its handle.
    let _ = child.kill();
    let _ = child.wait();
    assert_eq!(result, 0, "{}", s.stderr);
    assert_eq!(field(&s.stdout, "state"), "idle");
    assert!(t.ok().contains("right_offset_deg = 90.0"), "{}", t.stdout);
}

#[cfg(unix)]
#[test]
fn ctrl_c_ends_the_stream_cleanly() {
    let dev = Device::start(Noise::default());
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args(["device", "--port", &dev.port, "telemetry", "--period", "20"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("host-sim runs");
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    // Two frames, then Ctrl-C.
    for _ in 0..2 {
        let line = lines.next().expect("a line").unwrap();
        assert!(line.contains(" idle "), "{line}");
    }
    // Ctrl-C to the child this test started, by its id.
    let pid = nix::unistd::Pid::from_raw(i32::try_from(child.id()).unwrap());
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
    let status = child.wait().unwrap();
    assert_eq!(status.code(), Some(0));
    let device = dev.finish();
    assert_eq!(device.link_state().telemetry_period_ms, 0);
}

/// Ctrl-C during `travel --for` ends the hold early but not the command's care:
/// the motors are stopped and awaited at rest as after the whole time, the time
/// actually held is said, and the command fails naming the signal (it did not
/// do what was asked: exit 1).
#[test]
fn ctrl_c_during_travel_for_stops_at_rest_and_says_so() {
    let dev = Device::start(Noise::default());
    let mut child = Command::new(env!("CARGO_BIN_EXE_host-sim"))
        .args([
            "device", "--port", &dev.port, "travel", "right", "--speed", "3000",
        ])
        .args(["--for", "600"])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("host-sim runs");
    let start = Instant::now();
    // The first line only: the command prints nothing more until the signal.
    let mut reader = BufReader::new(child.stdout.take().unwrap());
    let mut first = String::new();
    reader.read_line(&mut first).expect("a line");
    assert_eq!(first, "travel right at 3000 rpm: accepted\n");
    child.stdout = Some(reader.into_inner());
    let pid = nix::unistd::Pid::from_raw(i32::try_from(child.id()).unwrap());
    nix::sys::signal::kill(pid, nix::sys::signal::Signal::SIGINT).unwrap();
    let r = common::wait_within(&mut child, start, HANG);
    let (out, stderr) = (r.stdout.trim_end().to_string(), r.stderr);
    let rest: Vec<&str> = out.lines().collect();
    assert_eq!(r.status, 1, "{out}\n{stderr}");
    // The time held, not the 600 s asked.
    let held: f64 = rest[0]
        .strip_prefix("after ")
        .and_then(|l| l.split(" s: ").next())
        .and_then(|t| t.parse().ok())
        .unwrap_or_else(|| panic!("{out}"));
    assert!(held < 600.0, "{out}");
    assert_eq!(rest[1], "stop: accepted", "{out}");
    assert!(rest[2].starts_with("stop: at rest after "), "{out}");
    assert!(
        stderr.starts_with(&format!(
            "error: interrupted by SIGINT (Ctrl-C) after {held:.1} s of --for 600 s; the motors were stopped and are at rest"
        )),
        "{stderr}"
    );
    dev.finish();
}

/// The self-test on request: too short a `--timeout` is a clear error while the
/// test still runs on the device, a second request meanwhile is refused as
/// busy. The device's clock is held while its self-test runs (the link still
/// answers), so the second request finds it running however long the machine
/// took to start the process; let go, the stop aborts it. Then it runs whole.
#[test]
fn the_self_test_runs_and_reports_each_rotor() {
    let dev = Device::start(Noise::default());
    dev.hold.store(true, Ordering::SeqCst);
    let t = dev.run(&["self-test", "--timeout", "3"]);
    assert_eq!(t.status, 1, "{}{}", t.stdout, t.stderr);
    assert!(
        t.stderr
            .contains("the self-test did not finish within 3 s (--timeout); status: running"),
        "{}",
        t.stderr
    );
    let busy = dev.run(&["self-test"]);
    assert_eq!(busy.status, 1, "{}{}", busy.stdout, busy.stderr);
    assert!(
        busy.stderr.contains("refused RunSelfTest: busy"),
        "{}",
        busy.stderr
    );
    dev.run(&["stop"]).ok();
    dev.hold.store(false, Ordering::SeqCst);
    // The stop aborts it; once the rotors rest, it runs whole.
    dev.status_until("idle at rest", |s| {
        field(s, "state") == "idle" && speeds(s).iter().all(|v| v.abs() <= 10.0)
    });
    let t = dev.run(&["self-test"]);
    let out = t.ok();
    assert!(out.starts_with("self-test       done\n"), "{out}");
    assert_eq!(out.matches("PASS").count(), 2, "{out}");
    assert_eq!(out.matches("counts per rev     4096").count(), 2, "{out}");
    dev.finish();
}

/// The two rotor speeds of `host-sim device status` output, rpm.
fn speeds(status: &str) -> [f64; 2] {
    // `2999.0 / 3001.0 rpm (rotor 1 / rotor 2)`
    let words: Vec<&str> = field(status, "speed").split_whitespace().collect();
    let rpm = |k: usize| -> f64 {
        words
            .get(k)
            .and_then(|w| w.parse().ok())
            .unwrap_or_else(|| panic!("no speed in\n{status}"))
    };
    [rpm(0), rpm(2)]
}

/// Regression: `device stop` printed "stop: accepted" (exit 0) when the device
/// answered Stop with an Ack for a Heartbeat at Stop's sequence number. The
/// command took any Ack as acceptance without reading which request it
/// acknowledged, so an operator was told the motors stopped when the device had
/// said nothing of the kind. Every answer is now checked against its request.
#[test]
fn an_ack_for_another_request_is_no_acceptance() {
    let port = fake_device::answering(|_| {
        vec![Response::Ack {
            request: MessageId::Heartbeat as u8,
        }]
    });
    let table = scratch("ack-check.toml");
    std::fs::write(&table, tuning_file::write(&[(3000.0, 80.0, 280.0)], "t")).unwrap();
    let cases: [(&[&str], &str); 7] = [
        (&["stop"], "Stop"),
        (&["travel", "right", "--speed", "3000"], "Travel"),
        (&["hold", "--offset", "90", "--speed", "3000"], "HoldOffset"),
        (&["reset"], "ResetFaults"),
        (&["telemetry", "--count", "1"], "StreamTelemetry"),
        // The self-test asks the status first (to wait for the rotors at rest).
        (&["self-test"], "GetStatus"),
        (
            &["table", "write", table.to_str().unwrap()],
            "WriteTuningTable",
        ),
    ];
    for (args, request) in cases {
        let mut all = vec!["device", "--port", &port];
        all.extend_from_slice(args);
        let r = host_sim(&all);
        assert_eq!(r.status, 1, "{args:?}: {}{}", r.stdout, r.stderr);
        assert!(!r.stdout.contains("accepted"), "{args:?}: {}", r.stdout);
        assert!(!r.stdout.contains("stored"), "{args:?}: {}", r.stdout);
        assert!(
            r.stderr.contains(&format!(
                "error: the device answered {request} with an Ack for Heartbeat, not an answer to {request}"
            )),
            "{args:?}: {}",
            r.stderr
        );
    }

    // The other way round: the heartbeats of `travel --for` answered by an Ack
    // for Travel; and an Ack where a report is due (status, table read).
    let port = fake_device::answering(|request| match request {
        Request::Command(shared::controller::Command::Heartbeat) => vec![Response::Ack {
            request: MessageId::Travel as u8,
        }],
        _ => vec![ack(request)],
    });
    let r = host_sim(&[
        "device", "--port", &port, "travel", "left", "--speed", "3000", "--for", "1",
    ]);
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    assert!(
        r.stderr.contains(
            "error: the device answered Heartbeat with an Ack for Travel, not an answer to Heartbeat"
        ),
        "{}",
        r.stderr
    );
    for (args, request) in [(["status"], "GetStatus"), (["reset"], "GetStatus")] {
        let mut all = vec!["device", "--port", &port];
        all.extend_from_slice(&args);
        let r = host_sim(&all);
        assert_eq!(r.status, 1, "{args:?}: {}{}", r.stdout, r.stderr);
        assert!(
            r.stderr
                .contains(&format!("answered {request} with an Ack for {request}")),
            "{args:?}: {}",
            r.stderr
        );
    }
    let r = host_sim(&["device", "--port", &port, "table", "read"]);
    assert_eq!(r.status, 1, "{}{}", r.stdout, r.stderr);
    assert_eq!(r.stdout, "");
    assert!(
        r.stderr
            .contains("answered ReadTuningTable with an Ack for ReadTuningTable"),
        "{}",
        r.stderr
    );
}

/// Regression: `device telemetry --count N` never ended when no telemetry frame
/// came (a device that acknowledges StreamTelemetry but does not stream, a line
/// no frame crosses whole): it counted frames and heartbeated for ever, with no
/// deadline on the frames. A stream silent for max(1 s, 5 periods) now ends the
/// run (exit 1), the stream turned off; a `--duration` run the same way.
#[test]
fn a_stream_that_never_comes_ends_the_run() {
    // Acknowledges every request and never streams.
    let port = fake_device::answering(|request| vec![ack(request)]);
    let runs: [(&[&str], f64); 3] = [
        (&["telemetry", "--count", "3"], 1.0),
        (&["telemetry", "--period", "400", "--duration", "30"], 2.0),
        (&["telemetry", "--duration", "0.5", "--csv", "-"], 0.5),
    ];
    for (args, quiet_s) in runs {
        let mut all = vec!["device", "--port", &port];
        all.extend_from_slice(args);
        let mut cmd = common::host_sim();
        cmd.args(&all).stdin(Stdio::null());
        let r = common::finish_within(cmd, HANG);
        assert_eq!(r.status, 1, "{args:?}: {}{}", r.stdout, r.stderr);
        let expected = format!("error: no telemetry from the device in {quiet_s:.1} s");
        assert!(r.stderr.starts_with(&expected), "{args:?}: {}", r.stderr);
        assert!(
            r.stderr.contains("0 frames before"),
            "{args:?}: {}",
            r.stderr
        );
    }
}

/// A status report of the fake devices: `state` with `faults` at `uptime_ms`,
/// the rotors at rest.
fn report(uptime_ms: u32, state: State, faults: Faults) -> StatusReport {
    StatusReport {
        uptime_ms,
        state,
        faults,
        telemetry: no_telemetry(),
        rx_dropped: 0,
    }
}

/// Regression: `device reset` slept 20 ms after the Ack and printed the status
/// then, so a device whose control tick came later (a busy machine running
/// `device-sim`) was reported still in fault. The controller takes the reset at
/// its next tick: the command now asks until the status is of a later tick
/// than the first one asked. Here a device whose clock stands for the first
/// status after the reset (still the fault) and moves on at the next.
#[test]
fn reset_reports_the_status_after_the_controllers_tick() {
    use std::sync::atomic::AtomicU32;
    static ASKED: AtomicU32 = AtomicU32::new(0);
    let port = fake_device::answering(|request| match request {
        Request::GetStatus => {
            let n = ASKED.fetch_add(1, Ordering::SeqCst);
            vec![Response::Status(if n == 0 {
                report(1000, State::Fault, Faults::LINK_LOST)
            } else {
                report(1001 + n, State::Idle, Faults::NONE)
            })]
        }
        _ => vec![ack(request)],
    });
    let r = host_sim(&["device", "--port", &port, "reset"]);
    assert_eq!(r.ok(), "reset: accepted; state idle, faults none\n");
}

/// Regression: `device-sim --listen` on a port already taken exited 1, the
/// status of a failed run, though the port is the user's to change (a user
/// mistake is 2, as for a `--port` that cannot be opened).
#[test]
fn device_sim_on_a_busy_port_is_a_usage_error() {
    let taken = TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = taken.local_addr().unwrap().to_string();
    let r = host_sim(&["device-sim", "--listen", &format!("tcp:{addr}")]);
    let stderr = r.usage();
    assert!(
        stderr.starts_with(&format!("error: --listen: cannot listen on {addr}: ")),
        "{stderr}"
    );
    assert_eq!(r.stdout, "");
    drop(taken);
}

/// The telemetry CSV's header the tests hold is the one docs/cli-device.md
/// documents, as a line of its own.
#[test]
fn telemetry_csv_header_is_the_documented_one() {
    let doc = std::fs::read_to_string(common::root().join("docs/cli-device.md")).unwrap();
    assert!(
        doc.lines().any(|l| l == common::TELEMETRY_CSV_HEADER),
        "docs/cli-device.md does not show the header {}",
        common::TELEMETRY_CSV_HEADER
    );
}
