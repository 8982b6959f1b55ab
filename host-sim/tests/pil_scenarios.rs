//! `host-sim scenario FILE --firmware ELF` (docs/pil.md, docs/scenarios.md)
//! through the real binary: every scenario of `tests/scenarios/` on the firmware
//! on QEMU is judged as with the controller in the loop (the same verdict per
//! expectation, the same final state, the same faults latched after each
//! injection), each on the ELF built for its machine (`one-foot.toml`'s beside
//! the reference one); a late tick of a whole period, which would skip a tick
//! there, is refused naming the fault.
//!
//! These tests build nothing: they need the ELF, `qemu-system-arm` and
//! `defmt-print` (skipped without them outside CI, failing in CI; see
//! `common::pil_firmware`).

use std::path::Path;

use serde_json::Value;

mod common;
use common::{root, run};

/// The scenario's report as JSON, with `more` arguments; its exit status.
fn judged(file: &Path, more: &[&str]) -> (i32, Value, String) {
    let mut args = vec![
        "scenario",
        file.to_str().expect("UTF-8"),
        "--format",
        "json",
    ];
    args.extend_from_slice(more);
    let r = run(&args);
    let v = serde_json::from_str(&r.stdout).unwrap_or(Value::Null);
    (r.status, v, r.stderr)
}

/// What the comparison looks at: every expectation's verdict, the final state,
/// the faults latched after every injection.
fn verdicts(v: &Value) -> Value {
    let pick = |list: &str, keys: &[&str]| -> Vec<Value> {
        v[list]
            .as_array()
            .map(|a| {
                a.iter()
                    .map(|e| keys.iter().map(|k| e[*k].clone()).collect())
                    .collect()
            })
            .unwrap_or_default()
    };
    serde_json::json!({
        "final_state": v["final_state"],
        "expectations": pick("expectations", &["key", "pass"]),
        "injections": pick("injections", &["key", "latched"]),
    })
}

#[test]
fn every_scenario_is_judged_on_the_firmware_as_on_the_controller_in_the_loop() {
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    let mut files: Vec<_> = std::fs::read_dir(root().join("tests/scenarios"))
        .expect("tests/scenarios")
        .map(|e| e.expect("an entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    assert!(!files.is_empty());
    for file in &files {
        let name = file.file_name().unwrap().to_string_lossy().to_string();
        let log = common::scratch("pil-scenarios", &format!("{name}.log"));
        let (sil_status, sil, sil_err) = judged(file, &[]);
        let machine = Path::new(sil["machine"].as_str().expect("the report's machine"));
        let Some(elf) = common::pil_firmware_for(&elf, machine) else {
            continue;
        };
        let elf = elf.to_str().expect("UTF-8");
        let (status, pil, err) = judged(
            file,
            &["--firmware", elf, "--firmware-log", log.to_str().unwrap()],
        );
        assert_eq!(status, sil_status, "{name}: {err}\n{sil_err}");
        assert_eq!(verdicts(&pil), verdicts(&sil), "{name}:\n{pil}\n{sil}");
    }
}

#[test]
fn a_late_tick_of_a_whole_period_is_refused_naming_it() {
    let Some(elf) = common::pil_firmware() else {
        return;
    };
    let file = common::scratch("pil-scenarios", "late.toml");
    let text = std::fs::read_to_string(root().join("tests/scenarios/starved-loop.toml"))
        .expect("starved-loop.toml")
        .replace(
            "../../examples/",
            &format!("{}/examples/", root().display()),
        )
        .replacen("late_us = 300", "late_us = 1000", 1);
    std::fs::write(&file, text).expect("a scenario");
    let (status, _, err) = judged(&file, &["--firmware", elf.to_str().unwrap()]);
    assert_eq!(status, 2, "{err}");
    assert!(
        err.contains("faults[0]: late_ticks 1000 us: cannot be injected with --firmware"),
        "{err}"
    );
}
