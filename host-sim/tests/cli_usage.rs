//! What a new user's mistakes get, through the real binary: an output path that
//! cannot be written is refused naming the option that gave it, before any work;
//! a file given to a command that reads another kind of file is named for what it
//! is, with the command that reads it, in one line.

use std::path::PathBuf;

mod common;
use common::{machine, root, run};

/// A path in a directory that does not exist.
fn nowhere(name: &str) -> String {
    common::scratch("cli-usage", "no-such-dir")
        .join(name)
        .to_str()
        .unwrap()
        .to_string()
}

#[test]
fn an_unwritable_output_is_refused_naming_its_option() {
    let m = machine();
    let m = m.to_str().unwrap();
    let scenario = root().join("tests/scenarios/estop.toml");
    let scenario = scenario.to_str().unwrap();
    let grid = [
        "--speeds",
        "3000",
        "--offsets",
        "0:360:90",
        "--t-end",
        "3600",
    ];
    let cases: Vec<(Vec<&str>, &str, String)> = vec![
        (
            vec!["run", m, "--open-loop", "coast", "--out"],
            "--out",
            nowhere("t.csv"),
        ),
        (
            vec!["run", m, "--open-loop", "coast", "--events"],
            "--events",
            nowhere("e.csv"),
        ),
        (
            vec!["run", m, "--open-loop", "coast", "--plot"],
            "--plot",
            nowhere("p.svg"),
        ),
        (
            vec!["run", m, "--open-loop", "coast", "--animate"],
            "--animate",
            nowhere("a.html"),
        ),
        (
            vec!["scenario", scenario, "--animate"],
            "--animate",
            nowhere("a.html"),
        ),
        (
            [&["tune", m][..], &grid, &["--write"]].concat(),
            "--write",
            nowhere("t.toml"),
        ),
        (
            [&["tune", m][..], &grid, &["--plot"]].concat(),
            "--plot",
            nowhere("t.svg"),
        ),
        (
            [&["tune", m][..], &grid, &["--shard", "1/2", "--out-part"]].concat(),
            "--out-part",
            nowhere("p.json"),
        ),
        (
            [
                &["tune", m][..],
                &grid,
                &["--robust", "--shard", "1/2", "--out-part"],
            ]
            .concat(),
            "--out-part",
            nowhere("r.json"),
        ),
        // The device commands check their files before the port is opened.
        (
            vec!["device", "--port", "/dev/null", "telemetry", "--csv"],
            "--csv",
            nowhere("t.csv"),
        ),
        (
            vec!["device", "--port", "/dev/null", "table", "read", "--out"],
            "--out",
            nowhere("t.toml"),
        ),
    ];
    for (args, option, path) in cases {
        let mut all = args.clone();
        all.push(&path);
        let r = run(&all);
        r.refused(&format!("error: {option}: cannot write {path}: "));
        assert!(!PathBuf::from(&path).exists());
    }
    // calibrate --write: after its inputs are read, before the fit.
    let measured = common::scratch("cli-usage", "measured.csv");
    std::fs::write(
        &measured,
        "speed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n3000,120,0.035\n",
    )
    .unwrap();
    let out = nowhere("c.toml");
    let measured = measured.to_str().unwrap();
    let fit = [
        "calibrate",
        m,
        "--measured",
        measured,
        "--fit",
        "contacts.*.restitution",
    ];
    run(&[&fit[..], &["--write", &out]].concat())
        .refused(&format!("error: --write: cannot write {out}: "));
    // calibrate --shard --out-part: likewise, before its starts run.
    let part = nowhere("c.json");
    run(&[&fit[..], &["--shard", "1/2", "--out-part", &part]].concat())
        .refused(&format!("error: --out-part: cannot write {part}: "));
    // device tune --write: with its measured file, before the port.
    let csv = common::scratch("cli-usage", "device-tune.csv");
    let _ = std::fs::remove_file(&csv);
    let csv = csv.to_str().unwrap();
    run(&[
        "device",
        "--port",
        "/dev/null",
        "tune",
        "--speeds",
        "3000",
        "--offsets",
        "0:180:30",
        "--for",
        "4",
        "--out",
        csv,
        "--write",
        &out,
    ])
    .refused(&format!("error: --write: cannot write {out}: "));
}

/// Two outputs into one stream: the refusal names both options.
#[test]
fn two_outputs_into_one_stream_name_both_options() {
    let m = machine();
    run(&["run", m.to_str().unwrap(), "--open-loop", "coast", "--t-end", "0.1", "--out", "-", "--events", "-"])
        .refused("error: --events: cannot write -: `--out -` writes to that stream already: give each output its own stream");
}

#[test]
fn a_file_of_another_kind_is_named_with_the_command_that_reads_it() {
    let file = |rel: &str| root().join(rel).to_str().unwrap().to_string();
    let (m, case, scenario, table) = (
        file("examples/vibro-driver.toml"),
        file("examples/impact/fig7-four-points.toml"),
        file("tests/scenarios/travel-right.toml"),
        file("examples/vibro-driver.tuning.toml"),
    );
    let machine_file = "this is a machine file (it has [platform] and [[rotors]])";
    let cases: Vec<(Vec<&str>, String)> = vec![
        (
            vec!["impact", &m],
            format!("{m}: {machine_file}, not an impact case: use host-sim run"),
        ),
        (
            vec!["scenario", &m],
            format!("{m}: {machine_file}, not a scenario: use host-sim run"),
        ),
        (
            vec!["device", "--port", "/dev/null", "table", "write", &m],
            format!("{m}: {machine_file}, not a tuning table: use host-sim run"),
        ),
        (
            vec!["run", &case, "--open-loop", "coast"],
            format!("{case}: this is an impact case (it has [body]), not a machine file: use host-sim impact"),
        ),
        (
            vec!["tune", &case, "--set", "simulation.rtol=1e-3"],
            format!("{case}: this is an impact case (it has [body]), not a machine file: use host-sim impact"),
        ),
        (
            vec!["device-sim", "--machine", &case],
            format!("{case}: this is an impact case (it has [body]), not a machine file: use host-sim impact"),
        ),
        (
            vec!["run", &scenario, "--command", "right"],
            format!("{scenario}: this is a scenario (it has machine = \"...\" and [[expect]]), not a machine file: use host-sim scenario"),
        ),
        (
            vec!["run", &table, "--command", "right"],
            format!("{table}: this is a tuning table (it has [[rows]]), not a machine file"),
        ),
    ];
    for (args, said) in cases {
        let r = run(&args);
        r.refused(&format!("error: {said}"));
        assert_eq!(r.stderr.lines().count(), 1, "one line: {}", r.stderr);
    }
}
