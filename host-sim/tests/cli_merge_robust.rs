//! `host-sim tune --robust --shard I/N` and `host-sim merge` of its parts through
//! the real binary: a small robust sweep (one speed, four offsets, two machines
//! from three starts, 2 s runs) run whole and as three parts merged gives the same
//! stdout (table and JSON), the same `--write` table and the same `--plot` SVG,
//! byte for byte; the parts split the runs (grid points on machines), not the
//! grid; merge refuses a robust part beside a plain one or one of another draw,
//! a hand-edited run, and a resealed part whose runs or machines are not its
//! shard's (exit 2, the file named).

use std::path::{Path, PathBuf};

use host_sim::tune::part::Part;
use serde_json::Value;

mod common;
use common::parts::{bytes, merge, merges_to_the_whole, resealed, run_in, scratch_with_machine};
use common::Run;

/// The sweep: 3000 rpm, four offsets, 2 s, the loosest tolerance (as
/// cli_tune_robust's grid, shorter), on the nominal machine and one drawn from
/// the reference machine's own `[uncertainty]`: 4 points x 6 machines = 24 runs.
const ROBUST: [&str; 13] = [
    "--speeds",
    "3000",
    "--offsets",
    "0:270:90",
    "--t-end",
    "2",
    "--set",
    "simulation.rtol=1e-3",
    "--robust",
    "--samples",
    "2",
    "--seed",
    "1",
];

/// A fresh scratch directory `name` of this test binary, with the reference
/// machine file (and its tuning table) copied in as `m.toml`.
fn dir(name: &str) -> PathBuf {
    scratch_with_machine("cli-merge-robust", name)
}

/// `host-sim tune m.toml ROBUST extra...` in `cwd`.
fn tune(cwd: &Path, extra: &[&str]) -> Run {
    let mut args = vec!["tune", "m.toml"];
    args.extend_from_slice(&ROBUST);
    args.extend_from_slice(extra);
    run_in(cwd, &args)
}

/// Writes part `shard` of the robust sweep (with `extra` options) to `cwd/name`.
fn part(cwd: &Path, shard: &str, name: &str, extra: &[&str]) {
    let mut args = vec!["--shard", shard, "--out-part", name];
    args.extend_from_slice(extra);
    let r = tune(cwd, &args);
    assert_eq!(r.status, 0, "{}", r.stderr);
    assert!(r.stdout.is_empty(), "{}", r.stdout);
}

fn read(p: PathBuf) -> Value {
    serde_json::from_slice(&bytes(p)).unwrap()
}

#[test]
fn three_robust_parts_merge_to_the_output_of_the_whole_robust_sweep() {
    let (whole, sharded) = (dir("whole"), dir("sharded"));
    let outputs = ["--write", "t.tuning.toml", "--plot", "p.svg"];
    let table = tune(&whole, &outputs);
    assert_eq!(table.status, 0, "{}", table.stderr);
    assert!(
        table.stdout.contains("tune --robust m.toml"),
        "{}",
        table.stdout
    );
    let json = tune(&whole, &["--format", "json"]);
    assert_eq!(json.status, 0, "{}", json.stderr);

    for i in 1..=3 {
        part(&sharded, &format!("{i}/3"), &format!("p{i}.json"), &[]);
    }
    // The parts split the 24 runs, 8 each, interleaved in run order
    // (j = machine * 4 + point): every part runs some of every machine's.
    let mut seen = Vec::new();
    for i in 1..=3 {
        let p = read(sharded.join(format!("p{i}.json")));
        assert_eq!(p["version"], 5);
        assert_eq!(p["sweep"]["robust"]["samples"], 2);
        let runs = p["runs"].as_array().unwrap();
        assert_eq!(runs.len(), 8, "part {i}");
        for r in runs {
            let j = r["machine"].as_u64().unwrap() * 4 + r["point"].as_u64().unwrap();
            assert_eq!(j % 3, i - 1, "part {i} holds run {j}");
            seen.push(j);
        }
    }
    seen.sort_unstable();
    assert_eq!(seen, (0..24).collect::<Vec<u64>>());

    merges_to_the_whole(
        &sharded,
        &whole,
        &["p1.json", "p2.json", "p3.json"],
        &outputs,
        (&table, &json),
        "merge: 3 parts of 24 robust runs",
    );
}

#[test]
fn merge_refuses_robust_parts_that_are_not_one_sweep_or_were_edited() {
    let d = dir("refusals");
    // Four parts, to keep each small: the refusals come before any run.
    for i in 1..=4 {
        part(&d, &format!("{i}/4"), &format!("p{i}.json"), &[]);
    }
    // Part 4 of another draw (seed 2) and of the plain sweep (ROBUST without
    // its last five options, --robust --samples 2 --seed 1).
    let mut seed2 = ROBUST[..11].to_vec();
    seed2.extend_from_slice(&["--seed", "2"]);
    let plain = ROBUST[..8].to_vec();
    for (options, name) in [(seed2, "seed2.json"), (plain, "plain.json")] {
        let mut args = vec!["tune", "m.toml"];
        args.extend_from_slice(&options);
        args.extend_from_slice(&["--shard", "4/4", "--out-part", name]);
        let r = run_in(&d, &args);
        assert_eq!(r.status, 0, "{}", r.stderr);
    }
    // A run's mean velocity edited by hand (the hashes left as they were).
    let mut edited = read(d.join("p2.json"));
    edited["runs"][0]["run"]["mean_velocity"] = 0.05.into();
    std::fs::write(d.join("edited.json"), edited.to_string()).unwrap();
    // Resealed: a run moved to another machine; a run dropped; no samples.
    resealed(&d, "p2.json", "moved.json", |p: &mut Part| {
        p.runs[0].machine += 1
    });
    resealed(&d, "p2.json", "dropped.json", |p: &mut Part| {
        p.runs.pop();
    });
    resealed(&d, "p2.json", "zero.json", |p: &mut Part| {
        p.sweep.robust.as_mut().unwrap().samples = 0
    });

    let cases: &[(&str, &str)] = &[
        (
            "seed2.json",
            "seed2.json: a part of another sweep than p1.json: --robust differs (--samples 2 --seed 1 in p1.json, --samples 2 --seed 2 in seed2.json)",
        ),
        (
            "plain.json",
            "plain.json: a part of another sweep than p1.json: --robust differs (--samples 2 --seed 1 in p1.json, none: the plain sweep in plain.json)",
        ),
        (
            "edited.json",
            "edited.json: a damaged partial result: part 2/4: part_sha256 does not match its contents",
        ),
        (
            "moved.json",
            "moved.json: a damaged partial result: its runs are not the runs of part 2/4",
        ),
        (
            "dropped.json",
            "dropped.json: a damaged partial result: its runs are not the runs of part 2/4",
        ),
        (
            "zero.json",
            "zero.json: a damaged partial result: robust.samples 0: not a count of machines from 1 to 1000",
        ),
    ];
    for (bad, message) in cases {
        let second = if *bad == "seed2.json" || *bad == "plain.json" {
            "p2.json"
        } else {
            bad
        };
        let fourth = if *bad == "seed2.json" || *bad == "plain.json" {
            bad
        } else {
            "p4.json"
        };
        let r = merge(&d, &["p1.json", second, "p3.json", fourth]);
        r.refused(message);
        assert!(r.stdout.is_empty(), "{bad}: {}", r.stdout);
    }
    // A part of the format before robust parts (version 3, no run's machine).
    let mut old = read(d.join("p3.json"));
    old["version"] = 3.into();
    std::fs::write(d.join("old.json"), old.to_string()).unwrap();
    merge(&d, &["p1.json", "p2.json", "old.json", "p4.json"])
        .refused("error: old.json: partial result version 3: this host-sim reads version 5");
    // The four parts as written merge.
    let r = merge(&d, &["p1.json", "p2.json", "p3.json", "p4.json"]);
    assert_eq!(r.status, 0, "{}", r.stderr);
}

/// A part holds at most 10 000 runs (what merge reads back whole): a robust
/// sweep too large for N parts is refused before any run, naming the N it needs.
#[test]
fn a_robust_part_too_large_is_refused_before_any_run() {
    let d = dir("too-large");
    let r = run_in(
        &d,
        &[
            "tune",
            "m.toml",
            "--speeds",
            "3000",
            "--offsets",
            "0:359:1",
            "--robust",
            "--samples",
            "10",
            "--shard",
            "1/1",
        ],
    );
    r.refused("error: tune --robust --shard 1/1: 10800 runs in this part, at most 10000 a part: the sweep has 10800 runs, give N of at least 2");
}
