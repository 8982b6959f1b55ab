//! `host-sim device capture` and `host-sim replay` through the real binaries,
//! against `host-sim device-sim --machine examples/vibro-driver.toml` (the
//! example's whole plant and the controller built from it): a capture of a
//! travel replays on its own machine file, its re-run check passing; and every
//! bad input is refused with its reason, exit 2 (a user's mistake) or 1 (the
//! link), nothing half written: a file cut short, a row edited, a row edited
//! with its checksum made good again, a capture of firmware built for another
//! file, one that starts with the rotors turning, not a capture at all, a window
//! longer than the board's buffer, options that do not go together, and the
//! link lost while the records are read (the motors stopped before).

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::Stdio;

use host_sim::capture::CaptureFile;

mod common;
use common::device_sim::DeviceSim;
use common::Run;

fn host_sim(args: &[&str]) -> Run {
    let mut cmd = common::host_sim();
    cmd.args(args).stdin(Stdio::null());
    common::finish(cmd)
}

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-device-capture", name)
}

/// `replay MACHINE CAPTURE [args]`.
fn replay(machine: &Path, capture: &Path, args: &[&str]) -> Run {
    let mut all = vec![
        "replay",
        machine.to_str().unwrap(),
        capture.to_str().unwrap(),
    ];
    all.extend_from_slice(args);
    host_sim(&all)
}

/// A user's mistake: exit 2, `said` on stderr, no panic.
fn refused(r: &Run, said: &str) {
    assert_eq!(r.status, 2, "{}{}", r.stdout, r.stderr);
    assert!(r.stderr.contains(said), "wanted {said:?} in: {}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
}

/// The capture file's text with row `k`'s field `column` set to `value`, and
/// its checksum made good again when `reseal`.
fn edited(text: &str, k: usize, column: &str, value: &str, reseal: bool) -> String {
    let columns: Vec<&str> = host_sim::capture::file::COLUMNS.split(',').collect();
    let c = columns.iter().position(|n| *n == column).unwrap();
    let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
    let header = lines.iter().position(|l| !l.starts_with('#')).unwrap();
    let mut fields: Vec<String> = lines[header + 1 + k]
        .split(',')
        .map(str::to_string)
        .collect();
    fields[c] = value.to_string();
    lines[header + 1 + k] = fields.join(",");
    if reseal {
        let rows: String = lines[header..].iter().map(|l| format!("{l}\n")).collect();
        let crc = shared::codec::crc::crc32(rows.as_bytes());
        let at = lines
            .iter()
            .position(|l| l.starts_with("# rows_crc32:"))
            .unwrap();
        lines[at] = format!("# rows_crc32: {crc:08x}");
    }
    lines.iter().map(|l| format!("{l}\n")).collect()
}

#[cfg(unix)]
#[test]
fn a_capture_replays_on_its_machine_and_every_bad_one_is_refused() {
    let example = common::machine();
    let dev = DeviceSim::start(&["--machine", example.to_str().unwrap()]);
    let capture = scratch("travel.csv");
    let said = dev.device(&[
        "capture",
        "--for",
        "1",
        "--travel",
        "right",
        "--speed",
        "3000",
        "--out",
        capture.to_str().unwrap(),
    ]);
    assert!(said.contains("capture: 1000 ticks"), "{said}");
    assert!(said.contains("states idle -> starting"), "{said}");
    let text = std::fs::read_to_string(&capture).unwrap();
    let file = CaptureFile::parse(&text).unwrap();
    assert_eq!(file.records.len(), 1000);
    assert_eq!(file.to_text(), text, "the file reads back to the same text");

    // On its own machine: the board's controller re-run writes what it recorded.
    let r = replay(&example, &capture, &[]);
    assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
    assert!(
        r.stdout
            .contains("writes its recorded outputs at every tick"),
        "{}",
        r.stdout
    );

    // A file cut short, and one with a row edited.
    let lines: Vec<&str> = text.lines().collect();
    let cut = scratch("cut.csv");
    let kept: String = lines[..lines.len() - 100]
        .iter()
        .map(|l| format!("{l}\n"))
        .collect();
    std::fs::write(&cut, kept).unwrap();
    refused(&replay(&example, &cut, &[]), "the file is cut short");
    let touched = scratch("touched.csv");
    std::fs::write(&touched, edited(&text, 500, "current1_a", "0.5", false)).unwrap();
    refused(
        &replay(&example, &touched, &[]),
        "do not match their checksum",
    );

    // An edit with its checksum made good: the controller does not write it.
    let sealed = scratch("sealed.csv");
    std::fs::write(&sealed, edited(&text, 300, "duty1", "0.9", true)).unwrap();
    refused(
        &replay(&example, &sealed, &[]),
        "the capture's outputs are not those of the controller",
    );

    // Firmware built for another file.
    let other = common::root().join("tests/fixtures/wide-rotors-machine.toml");
    refused(
        &replay(
            &example,
            &capture,
            &["--firmware-machine", other.to_str().unwrap()],
        ),
        "recorded by firmware built for another machine file",
    );

    // Not a capture.
    let not = scratch("not.csv");
    std::fs::write(&not, "speed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n").unwrap();
    refused(&replay(&example, &not, &[]), "not a capture file");

    // A capture that starts with the rotors turning: no start to replay from.
    dev.device(&["travel", "right", "--speed", "3000"]);
    std::thread::sleep(std::time::Duration::from_millis(1500));
    let running = scratch("running.csv");
    dev.device(&[
        "capture",
        "--for",
        "0.2",
        "--out",
        running.to_str().unwrap(),
    ]);
    dev.device(&["stop"]);
    refused(
        &replay(&example, &running, &[]),
        "a replay starts the twin idle and at rest",
    );

    // A window longer than the board's buffer: refused before anything is armed.
    let never = scratch("never.csv");
    let r = host_sim(&[
        "device",
        "--port",
        &dev.port,
        "capture",
        "--for",
        "3",
        "--out",
        never.to_str().unwrap(),
    ]);
    refused(&r, "the device records 1 to 2048 ticks");
    assert!(!never.exists());
}

/// Options that do not go together are refused before the port is opened (no
/// device listens on port 9), nothing written.
#[test]
fn bad_options_are_refused_before_the_device() {
    let out = scratch("never.csv");
    let out_s = out.to_str().unwrap();
    let cases: [(Vec<&str>, &str); 6] = [
        (
            vec!["--for", "0", "--out", out_s],
            "--for: must be a number of seconds above 0",
        ),
        (
            vec!["--for", "1", "--travel", "right", "--out", out_s],
            "--speed: missing",
        ),
        (
            vec!["--for", "1", "--speed", "3000", "--out", out_s],
            "--speed: goes with --travel or --hold",
        ),
        (
            vec![
                "--for", "1", "--travel", "left", "--hold", "90", "--speed", "3000", "--out", out_s,
            ],
            "give one run command, not both",
        ),
        (
            vec![
                "--for", "1", "--hold", "90", "--speed", "-5", "--out", out_s,
            ],
            "--speed: must be a number of rpm above 0",
        ),
        (vec!["--for", "1", "--out", "/no/such/dir/c.csv"], "--out"),
    ];
    for (args, said) in cases {
        let mut all = vec!["device", "--port", "tcp:127.0.0.1:9", "capture"];
        all.extend_from_slice(&args);
        refused(&host_sim(&all), said);
    }
    assert!(!out.exists());
}

/// The link lost while the records are read: exit 1 naming the link, the
/// motors stopped before the read began, nothing written.
#[cfg(unix)]
#[test]
fn a_link_lost_mid_read_writes_nothing() {
    let example = common::machine();
    let mut dev = DeviceSim::start(&["--machine", example.to_str().unwrap()]);
    let out = scratch("lost.csv");
    let mut cmd = common::host_sim();
    cmd.args([
        "device",
        "--port",
        &dev.port,
        "--retries",
        "2",
        "capture",
        "--for",
        "2",
        "--travel",
        "right",
        "--speed",
        "3000",
        "--out",
        out.to_str().unwrap(),
    ])
    .stdin(Stdio::null())
    .stdout(Stdio::piped())
    .stderr(Stdio::piped());
    let mut child = cmd.spawn().unwrap();
    let mut lines = BufReader::new(child.stdout.take().unwrap()).lines();
    let mut printed = Vec::new();
    // The read begins once the rotors are at rest after the stop.
    for line in lines.by_ref() {
        let line = line.unwrap();
        printed.push(line.clone());
        if line.starts_with("stop: at rest") {
            dev.kill();
            break;
        }
    }
    let rest: Vec<String> = lines.map_while(Result::ok).collect();
    let output = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert_eq!(
        output.status.code(),
        Some(1),
        "{printed:?} {rest:?} {stderr}"
    );
    assert!(
        printed.iter().any(|l| l.starts_with("stop: at rest")),
        "{printed:?}"
    );
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(!out.exists(), "nothing written");
}
