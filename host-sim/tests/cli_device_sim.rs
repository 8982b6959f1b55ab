//! `host-sim device-sim --machine M.toml --truth FILE.csv` through the real
//! binaries: the reference machine's whole plant behind the link, driven by
//! `host-sim device` (status, hold, travel, stop through `--for`), its platform's
//! true pose read from the truth file while the device runs; the machine's rotors
//! with its platform held (`--platform-held`), and without a machine the
//! reference machine's; and its refusals of bad input (exit 2, nothing served).

use std::path::PathBuf;
use std::process::Stdio;
use std::time::{Duration, Instant};

mod common;
use common::device_sim::{truth_rows, x_at, DeviceSim};
use common::Run;

fn host_sim(args: &[&str]) -> Run {
    let mut cmd = common::host_sim();
    cmd.args(args).stdin(Stdio::null());
    common::finish(cmd)
}

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-device-sim", name)
}

/// Hold 90 degrees at 3000 rpm for 4 s (the link kept alive by `--for`), then
/// travel left at 3000 rpm (the machine's table's offset) for 4 s: the truth file
/// shows the platform going right, then left, by about what `host-sim run` finds
/// at those points: 33.3 mm/s right at 90 degrees, 33.3 mm/s left with the table (270)
/// (`host-sim run examples/vibro-driver.toml --command right --offset 90` and
/// `--command left`, 4 s). Each hold reaches speed and its offset within 1.7 s
/// (the speed ramp, then the offset reference at 180 deg/s), so at least 2.3 s of
/// each 4 s are steady travel, about 73 mm: at least 40 mm each way leaves room
/// for the host's start-up and the ramps' own travel either way. The file is
/// read while the device runs: its last row is no older than 50 ms (a row every
/// 10 ms, each flushed).
#[cfg(unix)]
#[test]
fn the_truth_shows_the_platform_travel_right_then_left() {
    let truth = scratch("truth.csv");
    let machine = common::machine();
    let dev = DeviceSim::start(&[
        "--machine",
        machine.to_str().unwrap(),
        "--truth",
        truth.to_str().unwrap(),
    ]);
    let t0 = dev.uptime();
    let hold = dev.device(&["hold", "--offset", "90", "--speed", "3000", "--for", "4"]);
    assert!(hold.contains("stop: accepted"), "{hold}");
    let t1 = dev.uptime();
    let left = dev.device(&["travel", "left", "--speed", "3000", "--for", "4"]);
    assert!(left.contains("stop: accepted"), "{left}");
    let t2 = dev.uptime();

    // Fresh: read while the device runs.
    let rows = truth_rows(&truth);
    let last = rows.last().expect("rows")[0];
    assert!(last >= t2 - 0.05, "last row at {last} s, uptime {t2} s");
    // A row every 10 ms from 0.
    for (k, r) in rows.iter().enumerate() {
        assert!((r[0] - k as f64 * 0.01).abs() < 1e-9, "row {k}: {r:?}");
    }
    let right = x_at(&rows, t1) - x_at(&rows, t0);
    let leftward = x_at(&rows, t2) - x_at(&rows, t1);
    assert!(right > 0.040, "right: {right} m from {t0} to {t1} s");
    assert!(leftward < -0.040, "left: {leftward} m from {t1} to {t2} s");
    // Standing on the floor: the centre of mass near its 30 mm, level.
    for r in &rows {
        assert!((r[2] - 0.03).abs() < 0.005 && r[3].abs() < 0.1, "{r:?}");
    }

    // Ctrl-C ends it cleanly; the last note says how far the platform went.
    let (status, stderr) = dev.interrupt();
    assert_eq!(status, 0, "{stderr}");
    let end = truth_rows(&truth);
    let travelled = end.last().unwrap()[1] - end[0][1];
    // In the tool's words: 4 decimals, a sign unless it rounds to 0 (right then
    // left at one speed ends near where it began, either side of 0).
    let note = format!(
        "the platform travelled {} m",
        host_sim::numbers::fixed_signed(travelled, 4)
    );
    assert!(stderr.contains(&note), "{note:?} not in {stderr}");
    assert!(stderr.contains("x real time"), "{stderr}");
}

/// Bad input is refused before anything is served: exit 2, a line naming the
/// option or file, no port printed, no truth file left where none could be.
#[test]
fn bad_input_is_refused_before_serving() {
    let machine = common::machine();
    let machine = machine.to_str().unwrap();
    let dir = std::env::temp_dir();
    let missing_dir = scratch("no-such-dir").join("truth.csv");
    // A machine whose control tick is not a whole number of milliseconds.
    let text = std::fs::read_to_string(machine)
        .unwrap()
        .replace("rate_hz = 1000", "rate_hz = 1500")
        .replace(
            "tuning_table = \"vibro-driver.tuning.toml\"",
            &format!(
                "tuning_table = {:?}",
                common::root().join("examples/vibro-driver.tuning.toml")
            ),
        );
    let fast = scratch("fast.toml");
    std::fs::write(&fast, text).unwrap();
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec!["--machine", machine, "--truth", dir.to_str().unwrap()],
            format!("error: --truth: cannot write {}: is a directory", dir.display()),
        ),
        (
            vec!["--machine", machine, "--truth", missing_dir.to_str().unwrap()],
            format!("error: --truth: cannot write {}: ", missing_dir.display()),
        ),
        (
            vec!["--truth", "t.csv"],
            "--machine <MACHINE.toml>".to_string(),
        ),
        (
            vec!["--platform-held"],
            "--machine <MACHINE.toml>".to_string(),
        ),
        (
            vec!["--machine", "no-such-machine.toml"],
            "no-such-machine.toml".to_string(),
        ),
        (
            vec!["--machine", fast.to_str().unwrap()],
            format!(
                "error: {}: controller.rate_hz: device-sim runs control ticks of whole milliseconds",
                fast.display()
            ),
        ),
        // The controller keeps the link timeout as f32: 1e-46 would be 0 there
        // (link_lost at the first tick), 1e39 infinite (never).
        (
            vec!["--link-timeout", "1e-46"],
            "error: --link-timeout: must be a number of seconds above 0 (got 1e-46)".to_string(),
        ),
        (
            vec!["--link-timeout", "1e39"],
            "error: --link-timeout: must be a number of seconds above 0 (got 1e39)".to_string(),
        ),
    ];
    for (args, expect) in cases {
        let mut all = vec![
            "device-sim",
            "--listen",
            "tcp:127.0.0.1:0",
            "--duration",
            "5",
        ];
        all.extend_from_slice(&args);
        let r = host_sim(&all);
        r.refused(&expect);
        assert_eq!(r.stdout, "", "{args:?}");
        // Ours are one line (the argument parser's usage error has its own form).
        if expect.starts_with("error: ") {
            assert_eq!(r.stderr.lines().count(), 1, "{args:?}: {}", r.stderr);
        }
    }
    assert!(!missing_dir.exists());
}

/// Without `--machine`, `device-sim` runs the reference machine's rotors with
/// the platform held, and says so: no travel in its last note (the tests of
/// `cli_device.rs` cover the rest).
#[cfg(unix)]
#[test]
fn without_a_machine_the_reference_rotors_serve_with_the_platform_held() {
    let dev = DeviceSim::start(&[]);
    assert!(dev.uptime() >= 0.0);
    let (status, stderr) = dev.interrupt();
    assert_eq!(status, 0, "{stderr}");
    assert!(
        stderr.contains("on the reference machine's rotors, its platform held"),
        "{stderr}"
    );
    assert!(!stderr.contains("travelled"), "{stderr}");
}

/// `--machine M.toml --platform-held`: the machine's controller drives its rotors
/// to 3000 rpm (`hold --for`, the status while holding at speed) while every row
/// of the truth file has the platform exactly at its start pose (x 0, y 0.03 m,
/// angle 0: `examples/vibro-driver.toml`'s `[platform]`), and the last note gives
/// no travel.
#[cfg(unix)]
#[test]
fn platform_held_turns_the_rotors_and_the_platform_stays() {
    let truth = scratch("held.csv");
    let machine = common::machine();
    let dev = DeviceSim::start(&[
        "--machine",
        machine.to_str().unwrap(),
        "--platform-held",
        "--truth",
        truth.to_str().unwrap(),
    ]);
    let hold = dev.device(&["hold", "--offset", "90", "--speed", "3000", "--for", "2"]);
    assert!(hold.contains("stop: accepted"), "{hold}");
    assert!(hold.contains("  running  speed"), "{hold}");
    let rows = truth_rows(&truth);
    assert!(rows.len() > 100, "{} rows", rows.len());
    for r in &rows {
        assert_eq!(r[1..], [0.0, 0.03, 0.0], "row {r:?}");
    }
    let (status, stderr) = dev.interrupt();
    assert_eq!(status, 0, "{stderr}");
    assert!(
        stderr.contains("on its rotors, the platform held"),
        "{stderr}"
    );
    assert!(!stderr.contains("travelled"), "{stderr}");
}

/// A machine whose platform goes through the fundament behind the link (the
/// reference machine without its foot K2 tips onto its side) is watched as
/// `host-sim run` watches its trace: the warning names it, and the last note
/// gives no travel instead of the distance the platform fell.
#[cfg(unix)]
#[test]
fn a_platform_through_the_fundament_is_no_travel() {
    let one_foot = common::root().join("tests/fixtures/one-foot-machine.toml");
    let dev = DeviceSim::start(&["--machine", one_foot.to_str().unwrap()]);
    // Half a second of device time: the platform falls within it, unpowered.
    let start = Instant::now();
    while dev.uptime() < 0.5 {
        assert!(start.elapsed() < Duration::from_secs(120), "no uptime");
        std::thread::sleep(Duration::from_millis(50));
    }
    let (status, stderr) = dev.interrupt();
    assert_eq!(status, 0, "{stderr}");
    assert!(
        stderr.contains("; no travel to report: platform went through the fundament at t = "),
        "{stderr}"
    );
    // When: as `host-sim run` finds it on the same machine, windings open as on
    // the idle device (a second path to the same fall: its trace rows every
    // 1 ms against the device's ticks), within a tick or two.
    let at = |text: &str| -> f64 {
        let rest = &text[text.find("through the fundament at t = ").expect(text) + 29..];
        rest[..rest.find(" s").expect(text)].parse().expect(text)
    };
    let r = common::host_sim()
        .args(["run", one_foot.to_str().unwrap(), "--open-loop", "coast"])
        .args(["--t-end", "0.2", "--format", "json"])
        .output()
        .expect("host-sim run");
    let run: serde_json::Value = serde_json::from_slice(&r.stdout).expect("JSON");
    let (device_t, run_t) = (
        at(&stderr),
        at(run["not_a_travel"].as_str().expect("no travel")),
    );
    assert!(
        (device_t - run_t).abs() <= 0.002,
        "device-sim {device_t} s, run {run_t} s"
    );
    assert!(!stderr.contains("travelled"), "{stderr}");
    assert!(
        stderr.contains(
            "device-sim: warning: platform went through the fundament (only contact points meet it): first "
        ),
        "{stderr}"
    );
}
