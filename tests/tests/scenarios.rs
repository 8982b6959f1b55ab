//! Every scenario file in `tests/scenarios/` runs through the library (the same code
//! as `host-sim scenario FILE`) and every expectation must hold: each injected fault
//! reaches its safe state within its detection bound, the platform travels as
//! commanded, and nothing panics. No body goes through the fundament or tips over
//! in a scenario that does not expect it (only `one-foot.toml` does, by design). A
//! failure prints the whole report.
//!
//! One test per file, so that they run in parallel and a failure names its file;
//! [`every_scenario_file_has_a_test`] keeps the list and the directory in step.

use std::path::{Path, PathBuf};

use host_sim::machine::input;
use host_sim::scenario::file::Expectation;
use host_sim::scenario::{file, judge, report};

/// The directory of the scenario files.
fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios")
}

/// Loads and runs one scenario file; panics with the report unless all pass.
fn check(name: &str) {
    let path = dir().join(name);
    let s =
        file::load(&path).unwrap_or_else(|p| panic!("{name} is refused:\n{}", input::render(&p)));
    let report = judge::run(&s);
    assert!(
        report.passed(),
        "{name}: some expectations fail\n{}",
        report::table(&report)
    );
    let expects_breach = s
        .expectations
        .iter()
        .any(|(_, e)| matches!(e, Expectation::Breach { .. }));
    if !expects_breach {
        let breach = report
            .warnings
            .iter()
            .find(|w| w.contains("through the fundament") || w.contains("tipped over"));
        assert_eq!(breach, None, "{name}: a body left the model unexpected");
    }
}

/// One test per scenario file, named after it.
macro_rules! scenarios {
    ($($test:ident => $file:literal,)*) => {
        /// The files the tests below run.
        const FILES: &[&str] = &[$($file),*];
        $(
            #[test]
            fn $test() {
                check($file);
            }
        )*
    };
}

scenarios! {
    travel_right => "travel-right.toml",
    travel_left => "travel-left.toml",
    direction_change => "direction-change.toml",
    stop => "stop.toml",
    encoder_dropout => "encoder-dropout.toml",
    jammed_rotor => "jammed-rotor.toml",
    supply_sag => "supply-sag.toml",
    current_offset => "current-offset.toml",
    lost_commands => "lost-commands.toml",
    estop => "estop.toml",
    starved_loop => "starved-loop.toml",
    one_foot => "one-foot.toml",
}

#[test]
fn every_scenario_file_has_a_test() {
    let mut on_disk: Vec<String> = std::fs::read_dir(dir())
        .expect("tests/scenarios exists")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".toml"))
        .collect();
    on_disk.sort();
    let mut listed: Vec<String> = FILES.iter().map(|f| f.to_string()).collect();
    listed.sort();
    assert_eq!(
        on_disk, listed,
        "add a line to `scenarios!` in tests/tests/scenarios.rs for each file"
    );
}
