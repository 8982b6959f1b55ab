//! `host-sim calibrate --shard I/N` and `host-sim merge` of a fit's parts through
//! the real binary: a one-key fit (restitution, two measured points, 2 s runs)
//! run whole and as three parts merged gives the same stdout (table and JSON) and
//! the same `--write` machine file, byte for byte; the parts split the
//! multistart's starts; merge refuses an edited part, a resealed part whose start
//! or refusal is not the fit's, a part of another measured file, a measured file
//! changed since, a missing part and `--plot` (exit 2, the file named).

use std::path::{Path, PathBuf};

use host_sim::calibrate::part::Part;
use serde_json::Value;

mod common;
use common::parts::{bytes, merge, merges_to_the_whole, resealed, run_in, scratch_with_machine};
use common::Run;

/// The measured file: two points at 3000 rpm, one measured twice.
const MEASURED: &str =
    "speed_rpm,offset_deg,velocity_mps\n3000,90,0.030\n3000,90,0.031\n3000,270,-0.031\n";

/// `calibrate m.toml --measured meas.csv --fit restitution`, 2 s runs at the
/// loosest tolerance (the one key: 1 + 6 starts).
const FIT: [&str; 10] = [
    "calibrate",
    "m.toml",
    "--measured",
    "meas.csv",
    "--fit",
    "contacts.*.restitution",
    "--t-end",
    "2",
    "--set",
    "simulation.rtol=1e-3",
];

/// A fresh scratch directory `name` with the reference machine (its tuning
/// table beside it) as `m.toml` and the measured file as `meas.csv`.
fn dir(name: &str) -> PathBuf {
    let d = scratch_with_machine("cli-merge-calibrate", name);
    std::fs::write(d.join("meas.csv"), MEASURED).unwrap();
    d
}

/// The fit with `extra` options in `cwd`.
fn calibrate(cwd: &Path, extra: &[&str]) -> Run {
    run_in(cwd, &[&FIT[..], extra].concat())
}

/// Part `i` of `n` of the fit written to `cwd/c{i}.json`.
fn parts(cwd: &Path, n: usize) {
    for i in 1..=n {
        let shard = format!("{i}/{n}");
        let out = format!("c{i}.json");
        let r = calibrate(cwd, &["--shard", &shard, "--out-part", &out]);
        assert_eq!(r.status, 0, "{}", r.stderr);
        assert!(r.stdout.is_empty(), "{}", r.stdout);
    }
}

fn read(p: PathBuf) -> Value {
    serde_json::from_slice(&bytes(p)).unwrap()
}

#[test]
fn three_parts_of_a_fit_merge_to_the_whole_fit() {
    let (whole, sharded) = (dir("whole"), dir("sharded"));
    let outputs = ["--write", "fitted.toml"];
    let table = calibrate(&whole, &outputs);
    assert_eq!(table.status, 0, "{}", table.stderr);
    let json = calibrate(&whole, &["--format", "json"]);
    assert_eq!(json.status, 0, "{}", json.stderr);

    parts(&sharded, 3);
    // The seven starts, interleaved: 0, 3, 6 / 1, 4 / 2, 5; each with a run
    // per measured point; together the whole fit's starts, to the bit.
    let whole_starts = serde_json::from_str::<Value>(&json.stdout).unwrap()["fit"]["starts"]
        .as_array()
        .unwrap()
        .clone();
    assert_eq!(whole_starts.len(), 7);
    for (i, expected) in [(1, vec![0, 3, 6]), (2, vec![1, 4]), (3, vec![2, 5])] {
        let p = read(sharded.join(format!("c{i}.json")));
        let starts = p["starts"].as_array().unwrap();
        let got: Vec<u64> = starts
            .iter()
            .map(|s| s["start"].as_u64().unwrap())
            .collect();
        assert_eq!(got, expected, "part {i}");
        for s in starts {
            assert_eq!(s["runs"].as_array().unwrap().len(), 2);
            let k = s["start"].as_u64().unwrap() as usize;
            assert_eq!(s["u"], whole_starts[k]["u"], "start {k}");
        }
    }
    merges_to_the_whole(
        &sharded,
        &whole,
        &["c1.json", "c2.json", "c3.json"],
        &outputs,
        (&table, &json),
        // The closing line: the runs the parts made are not the merge's seconds'.
        ", 7 evaluations of them (14 runs) made in the parts, the other ",
    );
    // The plan: the seven starts' runs made in the parts, the time the rest's
    // (54 evaluations x 2 points = 108 runs, 94 left).
    let merged = merge(&sharded, &["c1.json", "c2.json", "c3.json"]);
    assert_eq!(merged.status, 0, "{}", merged.stderr);
    let plan = merged.stderr.lines().next().unwrap_or_default();
    assert!(
        plan.starts_with(
            "calibrate: up to 54 evaluations x 2 points = 108 runs of 2 s, 7 evaluations of them (14 runs) made in the parts; one took "
        ) && plan.ends_with(" for the other 94 runs"),
        "{}",
        merged.stderr
    );
}

#[test]
fn merge_refuses_parts_that_are_not_one_fit_or_were_edited() {
    let d = dir("refusals");
    parts(&d, 2);
    // Part 2 of the fit of another measured file.
    std::fs::write(
        d.join("other.csv"),
        MEASURED.replace("0.031\n3000", "0.032\n3000"),
    )
    .unwrap();
    let mut other = FIT.to_vec();
    other[3] = "other.csv";
    let r = run_in(
        &d,
        &[&other[..], &["--shard", "2/2", "--out-part", "other.json"]].concat(),
    );
    assert_eq!(r.status, 0, "{}", r.stderr);
    // A run edited by hand; resealed: a start moved, a refusal made up.
    let mut edited = read(d.join("c2.json"));
    edited["starts"][0]["runs"][0]["mean_velocity"] = 0.05.into();
    std::fs::write(d.join("edited.json"), edited.to_string()).unwrap();
    resealed(&d, "c2.json", "moved.json", |p: &mut Part| {
        p.starts[0].u[0] += 1e-9
    });
    resealed(&d, "c2.json", "made-up.json", |p: &mut Part| {
        p.starts[0].refused = Some("error: refused".into());
        p.starts[0].runs.clear();
    });

    let cases: &[(&[&str], &str)] = &[
        (
            &["c1.json", "other.json"],
            "other.json: a part of another fit than c1.json: the measured file differs (sha256 ",
        ),
        (
            &["c1.json", "edited.json"],
            "edited.json: a damaged partial result: part 2/2: part_sha256 does not match its contents",
        ),
        (
            &["c1.json", "moved.json"],
            "moved.json: a damaged partial result: start 1: not the start the fit makes there",
        ),
        (
            &["c1.json", "made-up.json"],
            "made-up.json: a damaged partial result: start 1: refused: \"error: refused\" where the machine reader says null",
        ),
        (
            &["c1.json"],
            "merge: part 2 of 2 missing: given 1/2 (c1.json); a fit in 2 parts needs all of them",
        ),
        (
            &["c1.json", "c2.json", "--plot", "p.svg"],
            "merge: --plot: calibrate has no plot",
        ),
    ];
    for (args, message) in cases {
        let r = merge(&d, args);
        r.refused(message);
        assert!(r.stdout.is_empty(), "{args:?}: {}", r.stdout);
    }
    // The measured file changed since the parts were made.
    std::fs::write(d.join("meas.csv"), MEASURED.replace("0.030", "0.029")).unwrap();
    merge(&d, &["c1.json", "c2.json"])
        .refused("meas.csv: not the measured file the parts were made from (its sha256 is ");
}
