//! `host-sim run --firmware ELF` (processor in the loop, docs/pil.md) through
//! the real binary: the firmware's binary `pil` on QEMU against the controller in
//! the loop, the run's determinism, and the refusals (exit 2) of a firmware built
//! for another machine file, of a missing ELF and of missing tools.
//!
//! These tests build nothing. The runs need the ELF
//! (`cd firmware && cargo build --release --features pil --bin pil`),
//! `qemu-system-arm` and `defmt-print`: without them a run is skipped with a
//! message, except in CI (`CI=true`), where `scripts/test-all.sh` builds the ELF
//! before the tests and a missing piece fails.

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

fn number(v: &Value, key: &str) -> f64 {
    v[key].as_f64().unwrap_or_else(|| panic!("{key} in {v}"))
}

#[test]
fn the_firmware_in_the_loop_travels_as_the_controller_in_the_loop() {
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    let log = scratch("travel.log");
    let pil = travel(&[
        "--t-end",
        "3",
        "--firmware",
        elf.to_str().unwrap(),
        "--firmware-log",
        log.to_str().unwrap(),
    ]);
    assert_eq!(pil.status, 0, "{}", pil.stderr);
    let sil = travel(&["--t-end", "3"]);
    assert_eq!(sil.status, 0, "{}", sil.stderr);
    let (p, s): (Value, Value) = (
        serde_json::from_str(&pil.stdout).expect("JSON"),
        serde_json::from_str(&sil.stdout).expect("JSON"),
    );
    assert_eq!(p["state"], "running", "{p}");
    assert_eq!(p["faults"], s["faults"], "{p}");
    assert_eq!(p["firmware"]["log"], log.to_str().unwrap());
    // The bar: mean velocity within 2 % of the controller in the loop's,
    // the phase error's RMS within 0.5 degree.
    let (vp, vs) = (number(&p, "mean_velocity"), number(&s, "mean_velocity"));
    assert!(
        vs > 0.0 && (vp - vs).abs() <= 0.02 * vs,
        "{vp} against {vs}"
    );
    let (ep, es) = (
        number(&p, "phase_error_deg_rms"),
        number(&s, "phase_error_deg_rms"),
    );
    assert!(ep <= es + 0.5, "{ep} against {es}");
    let text = std::fs::read_to_string(&log).expect("the firmware's log");
    assert!(text.contains("state running"), "{text}");
    assert!(!text.contains("ERROR"), "{text}");
}

#[test]
fn two_runs_give_the_same_bytes() {
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    let runs: Vec<(Run, Vec<u8>, String)> = (0..2)
        .map(|i| {
            let out = scratch(&format!("same-{i}.csv"));
            let log = scratch("same.log");
            let r = travel(&[
                "--t-end",
                "1",
                "--firmware",
                elf.to_str().unwrap(),
                "--firmware-log",
                log.to_str().unwrap(),
                "--out",
                out.to_str().unwrap(),
            ]);
            assert_eq!(r.status, 0, "{}", r.stderr);
            let trace = std::fs::read(&out).expect("the trace");
            let text = std::fs::read_to_string(&log).expect("the log");
            (r, trace, text)
        })
        .collect();
    assert_eq!(runs[0].0.stdout, runs[1].0.stdout);
    assert!(runs[0].1 == runs[1].1, "the traces differ");
    assert_eq!(runs[0].2, runs[1].2);
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
    let mut cmd = common::host_sim();
    cmd.args([
        "run",
        m.to_str().unwrap(),
        "--command",
        "right",
        "--t-end",
        "0.1",
        "--firmware",
        m.to_str().unwrap(),
    ])
    .env("PATH", Path::new(&empty))
    .current_dir(root());
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
