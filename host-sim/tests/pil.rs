//! `host-sim run --firmware ELF` (processor in the loop, docs/pil.md) through
//! the real binary: the firmware's binary `pil` on QEMU against the controller in
//! the loop (travel right and left on the reference machine and on another one,
//! and the one-rotor machine, each on the ELF built for it), the run's
//! determinism, QEMU behind a wrapper script, and the refusals (exit 2) of a
//! firmware built for another machine file, of a missing ELF and of missing
//! tools.
//!
//! These tests build nothing. The runs need the ELF
//! (`cd firmware && cargo build --release --features pil --bin pil`),
//! `qemu-system-arm` and `defmt-print`: without them a run is skipped with a
//! message, except in CI (`CI=true`), where `scripts/test-all.sh` builds the
//! ELFs before the tests and a missing piece fails.

use std::path::{Path, PathBuf};

use serde_json::Value;

mod common;
use common::{machine, root, run, Run};

fn scratch(name: &str) -> PathBuf {
    common::scratch("pil", name)
}

/// `host-sim run` of the reference machine, travelling right, with `more`.
fn travel(more: &[&str]) -> Run {
    let m = machine();
    let mut args = vec![
        "run",
        m.to_str().expect("a UTF-8 path"),
        "--command",
        "right",
        "--format",
        "json",
    ];
    args.extend_from_slice(more);
    run(&args)
}

/// The command of `host-sim run` of the reference machine travelling right, with
/// `more`, from the repository's root.
fn travel_command(more: &[&str]) -> std::process::Command {
    let m = machine();
    let mut cmd = common::host_sim();
    cmd.args([
        "run",
        m.to_str().expect("a UTF-8 path"),
        "--command",
        "right",
    ])
    .args(more)
    .current_dir(root());
    cmd
}

fn number(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} in {v}"))
}

/// A 3 s travel of `machine` on `command`, with `more`: the JSON summary and the
/// controller's states from `--events` (time, state).
fn travel_of(
    machine: &Path,
    command: &str,
    tag: &str,
    more: &[&str],
) -> (Value, Vec<(f64, String)>) {
    let events = scratch(&format!("{tag}.events.csv"));
    let mut args = vec![
        "run",
        machine.to_str().expect("a UTF-8 path"),
        "--command",
        command,
        "--t-end",
        "3",
        "--format",
        "json",
        "--events",
        events.to_str().expect("a UTF-8 path"),
    ];
    args.extend_from_slice(more);
    let r = run(&args);
    assert_eq!(r.status, 0, "{tag}: {}", r.stderr);
    let summary: Value = serde_json::from_str(&r.stdout).expect("JSON");
    let text = std::fs::read_to_string(&events).expect("the events");
    let states = text
        .lines()
        .skip(1)
        .filter_map(|line| {
            let f: Vec<&str> = line.split(',').collect();
            (f[1] == "state").then(|| (f[0].parse().expect("a time"), f[8].to_string()))
        })
        .collect();
    (summary, states)
}

/// `command` on `machine` for 3 s with the firmware (`elf`) in the loop and with
/// the controller in the loop, checked alike: `running`, no fault, the mean
/// velocity within 2 % of the controller in the loop's (which moves at least 5
/// mm/s), the phase error's RMS within 0.5 degree of it, the same controller
/// states at the same ticks, an instruction count for every tick, the
/// firmware's log clean. The two summaries, firmware's first.
fn same_travel(machine: &Path, elf: &Path, command: &str) -> (Value, Value) {
    let stem = machine.file_stem().unwrap().to_string_lossy().to_string();
    let tag = format!("{stem}-{command}");
    let log = scratch(&format!("{tag}.log"));
    let (p, p_states) = travel_of(
        machine,
        command,
        &format!("{tag}-pil"),
        &[
            "--firmware",
            elf.to_str().unwrap(),
            "--firmware-log",
            log.to_str().unwrap(),
        ],
    );
    let (s, s_states) = travel_of(machine, command, &format!("{tag}-sil"), &[]);
    assert_eq!(p["state"], "running", "{tag}: {p}");
    assert_eq!(p["faults"], s["faults"], "{tag}: {p}");
    assert_eq!(p["faults"], Value::Array(vec![]), "{tag}: {p}");
    assert_eq!(p["firmware"]["log"], log.to_str().unwrap());
    let (vp, vs) = (number(&p, "mean_velocity"), number(&s, "mean_velocity"));
    assert!(vs.abs() > 0.005, "{tag}: {vs}");
    assert!(
        (vp - vs).abs() <= 0.02 * vs.abs(),
        "{tag}: {vp} against {vs}"
    );
    let (ep, es) = (
        number(&p, "phase_error_deg_rms"),
        number(&s, "phase_error_deg_rms"),
    );
    assert!((ep - es).abs() <= 0.5, "{tag}: {ep} against {es}");
    // The same states at the same ticks, but the firmware's first tick, which
    // runs before the command's frame has arrived (docs/pil.md): `idle` at 0,
    // then each state one tick later.
    assert_eq!(p_states.first(), Some(&(0.0, "idle".to_string())), "{tag}");
    let p_states = &p_states[1..];
    assert_eq!(
        p_states.iter().map(|s| &s.1).collect::<Vec<_>>(),
        s_states.iter().map(|s| &s.1).collect::<Vec<_>>(),
        "{tag}"
    );
    for (a, b) in p_states.iter().zip(&s_states) {
        assert!(
            (a.0 - b.0 - 0.001).abs() < 1e-9,
            "{tag}: {a:?} against {b:?}"
        );
    }
    // One cost per tick, from the firmware's own clock: 3 s at 1 kHz.
    let cost = &p["firmware"]["instructions_per_tick"];
    assert_eq!(cost["ticks"], 3000, "{tag}: {cost}");
    let (mean, max) = (number(cost, "mean"), number(cost, "max"));
    assert!(mean > 0.0 && mean <= max, "{tag}: {cost}");
    let text = std::fs::read_to_string(&log).expect("the firmware's log");
    assert!(text.contains("state running"), "{tag}: {text}");
    assert!(!text.contains("ERROR"), "{tag}: {text}");
    (p, s)
}

/// Each two-rotor machine with its firmware travelling right and left as with
/// the controller in the loop ([`same_travel`]), the commanded way, at the
/// offset of its own tuning table: the reference machine and one with other
/// rotor spacing, motor and tuning table
/// (`tests/fixtures/wide-rotors-machine.toml`, its tuned offset 70 degrees
/// against the reference's 90), each on the ELF built for it.
#[test]
fn the_firmware_in_the_loop_travels_as_the_controller_in_the_loop() {
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    let machines = [
        (machine(), 90.0),
        (root().join("tests/fixtures/wide-rotors-machine.toml"), 70.0),
    ];
    for (machine, right_deg) in machines {
        let Some(elf) = common::pil_firmware_for(&elf, &machine) else {
            continue;
        };
        for (command, sign, offset_deg) in
            [("right", 1.0, right_deg), ("left", -1.0, 360.0 - right_deg)]
        {
            let (p, _) = same_travel(&machine, &elf, command);
            assert!(sign * number(&p, "mean_velocity") > 0.01, "{command}: {p}");
            let offset = number(&p, "phase_offset_deg");
            assert!((offset - offset_deg).abs() < 1.0, "{command}: {offset} deg");
        }
    }
}

/// The one-rotor machine (`tests/fixtures/one-rotor-machine.toml`) on the ELF
/// built for it: its one rotor held at speed, the second bridge never driven,
/// the travel as with the controller in the loop, and the same warning that a
/// direction means nothing to it.
#[test]
fn the_one_rotor_machine_runs_on_its_firmware_as_on_the_controller_in_the_loop() {
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    let machine = root().join("tests/fixtures/one-rotor-machine.toml");
    let Some(elf) = common::pil_firmware_for(&elf, &machine) else {
        return;
    };
    let (p, s) = same_travel(&machine, &elf, "right");
    assert_eq!(p["rotors"], 1, "{p}");
    let speed = p["rotor_speed_rpm"].as_array().expect("speeds");
    assert_eq!(speed.len(), 1, "{p}");
    assert!((speed[0].as_f64().unwrap() - 3000.0).abs() < 1.0, "{p}");
    let warned = |v: &Value| {
        v["warnings"]
            .as_array()
            .expect("warnings")
            .iter()
            .filter(|w| w.as_str().unwrap_or("").contains("has one rotor"))
            .count()
    };
    assert_eq!((warned(&p), warned(&s)), (1, 1), "{p}\n{s}");
}

#[test]
fn two_runs_give_the_same_bytes() {
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    // Every output of a run: the trace, the events, the plot, the animation
    // and the firmware's log, each run writing its own.
    let outputs = [
        "trace.csv",
        "events.csv",
        "plot.svg",
        "animation.html",
        "firmware.log",
    ];
    let runs: Vec<(Run, Vec<Vec<u8>>)> = (0..2)
        .map(|i| {
            let files: Vec<PathBuf> = outputs
                .iter()
                .map(|f| scratch(&format!("same-{i}-{f}")))
                .collect();
            let path = |k: usize| files[k].to_str().unwrap();
            let r = travel(&[
                "--t-end",
                "1",
                "--firmware",
                elf.to_str().unwrap(),
                "--out",
                path(0),
                "--events",
                path(1),
                "--plot",
                path(2),
                "--animate",
                path(3),
                "--firmware-log",
                path(4),
            ]);
            assert_eq!(r.status, 0, "{}", r.stderr);
            let bytes = files
                .iter()
                .map(|f| std::fs::read(f).expect("an output"))
                .collect();
            (r, bytes)
        })
        .collect();
    // The summaries name each run's own log: the same but for that.
    let summary = |r: &Run, i: usize| r.stdout.replace(&format!("same-{i}-"), "same-");
    assert_eq!(summary(&runs[0].0, 0), summary(&runs[1].0, 1));
    for (k, name) in outputs.iter().enumerate() {
        assert!(!runs[0].1[k].is_empty(), "{name} is empty");
        assert!(runs[0].1[k] == runs[1].1[k], "the runs' {name} differ");
    }
}

#[test]
fn a_firmware_built_for_another_machine_file_is_refused() {
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    // The same machine without its [uncertainty] (which the run does not read),
    // its tuning table named by an absolute path: other bytes, another CRC-32.
    let other = scratch("other-machine.toml");
    std::fs::write(&other, common::reference_without_uncertainty()).unwrap();
    let out = scratch("refused.csv");
    let r = run(&[
        "run",
        other.to_str().unwrap(),
        "--command",
        "right",
        "--t-end",
        "0.1",
        "--firmware",
        elf.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(r.status, 2, "{}", r.stderr);
    assert!(r.stderr.contains("vibro-driver.toml"), "{}", r.stderr);
    assert!(r.stderr.contains("other-machine.toml"), "{}", r.stderr);
    assert!(r.stderr.contains("VIBRO_MACHINE="), "{}", r.stderr);
    assert!(!r.stderr.contains("panicked"), "{}", r.stderr);
    assert!(!out.exists(), "nothing written");
}

#[test]
fn a_missing_elf_is_refused_with_the_command_that_builds_it() {
    let r = travel(&["--t-end", "0.1", "--firmware", "no/such/pil"]);
    assert_eq!(r.status, 2, "{}", r.stderr);
    assert!(
        r.stderr
            .contains("cargo build --release --features pil --bin pil"),
        "{}",
        r.stderr
    );
}

#[test]
fn missing_tools_are_refused_with_the_commands_that_install_them() {
    // Any file passes the ELF's check; an empty PATH has neither tool.
    let empty = scratch("empty-path");
    std::fs::create_dir_all(&empty).unwrap();
    let m = machine();
    let mut cmd = travel_command(&["--t-end", "0.1", "--firmware", m.to_str().unwrap()]);
    cmd.env("PATH", Path::new(&empty));
    let r = common::finish(cmd);
    assert_eq!(r.status, 2, "{}", r.stderr);
    assert!(
        r.stderr.contains("apt-get install -y qemu-system-arm"),
        "{}",
        r.stderr
    );
    assert!(
        r.stderr.contains("cargo install --locked defmt-print"),
        "{}",
        r.stderr
    );
}

/// QEMU started through a wrapper script that runs it as its child (not by
/// `exec`): at the run's end host-sim stops QEMU's whole process group, so the
/// real QEMU does not live on holding the decoder's input open, and the run
/// ends with no warning: the decoder (defmt-print) ended by itself. (Before,
/// killing the wrapper alone left host-sim waiting for the decoder for ever;
/// with the decoder killed after a while instead, the summary warns that the
/// log may be cut.)
#[test]
fn qemu_behind_a_wrapper_script_is_stopped_with_it() {
    use std::os::unix::fs::PermissionsExt;
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    let path = std::env::var_os("PATH").unwrap_or_default();
    let qemu = std::env::split_paths(&path)
        .map(|d| d.join("qemu-system-arm"))
        .find(|p| p.is_file())
        .expect("qemu-system-arm on PATH (pil_firmware checked)");
    let dir = scratch("wrapper");
    std::fs::create_dir_all(&dir).unwrap();
    let wrapper = dir.join("qemu-system-arm");
    std::fs::write(
        &wrapper,
        format!("#!/bin/sh\n'{}' \"$@\"\nexit $?\n", qemu.display()),
    )
    .unwrap();
    std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755)).unwrap();
    let mut dirs = vec![dir.clone()];
    dirs.extend(std::env::split_paths(&path));
    let log = scratch("wrapper.log");
    let mut cmd = travel_command(&[
        "--t-end",
        "0.2",
        "--format",
        "json",
        "--firmware",
        elf.to_str().unwrap(),
        "--firmware-log",
        log.to_str().unwrap(),
    ]);
    cmd.env("PATH", std::env::join_paths(dirs).unwrap());
    // A liveness bound, not a timing: the run takes about a second.
    let r = common::finish_within(cmd, std::time::Duration::from_secs(120));
    assert_eq!(r.status, 0, "{}", r.stderr);
    // The decoder ended by itself once QEMU was stopped: not killed, no warning.
    let summary: Value = serde_json::from_str(&r.stdout).expect("JSON");
    assert_eq!(summary["warnings"], Value::Array(vec![]), "{summary}");
    let text = std::fs::read_to_string(&log).expect("the firmware's log");
    assert!(text.contains("pil: the host is the board"), "{text}");
}
