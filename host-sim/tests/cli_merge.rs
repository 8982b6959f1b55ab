//! `host-sim tune --shard I/N` and `host-sim merge` through the real binary: a tiny
//! sweep run whole and as three parts merged gives the same stdout (table and
//! JSON), the same `--write` table and the same `--plot` SVG, byte for byte; merge
//! refuses a missing, a duplicate and a foreign part, parts that disagree on N, a
//! file that is not a part, an edited part and the wrong machine file (exit 2, the
//! file named); tune refuses a bad `--shard`.

use std::path::{Path, PathBuf};

mod common;
use common::{machine, Run, TINY_GRID as GRID};

/// A fresh scratch directory `name` of this test binary.
fn dir(name: &str) -> PathBuf {
    let d = common::scratch("cli-merge", name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch directory");
    d
}

/// Runs `host-sim` with `args` in directory `cwd`.
fn run_in(cwd: &Path, args: &[&str]) -> Run {
    let mut cmd = common::host_sim();
    cmd.args(args).current_dir(cwd);
    common::finish(cmd)
}

/// `host-sim tune MACHINE GRID extra...` in `cwd`, the machine named by its
/// absolute path (so that every directory names it alike).
fn tune(cwd: &Path, machine: &Path, grid: &[&str], extra: &[&str]) -> Run {
    let mut args = vec!["tune", machine.to_str().unwrap()];
    args.extend_from_slice(grid);
    args.extend_from_slice(extra);
    run_in(cwd, &args)
}

/// Writes part `i` of `n` of the sweep to `cwd/name`; asserts success.
fn part(cwd: &Path, machine: &Path, grid: &[&str], shard: &str, name: &str) {
    let r = tune(cwd, machine, grid, &["--shard", shard, "--out-part", name]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    assert!(r.stdout.is_empty(), "{}", r.stdout);
    assert!(cwd.join(name).is_file());
}

/// `host-sim merge args...` in `cwd`.
fn merge(cwd: &Path, args: &[&str]) -> Run {
    let mut all = vec!["merge"];
    all.extend_from_slice(args);
    run_in(cwd, &all)
}

fn bytes(p: PathBuf) -> Vec<u8> {
    std::fs::read(&p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

#[test]
fn three_parts_merge_to_the_output_of_the_whole_sweep() {
    let m = machine().canonicalize().unwrap();
    let (whole, sharded) = (dir("whole"), dir("sharded"));
    let outputs = ["--write", "t.tuning.toml", "--plot", "p.svg"];

    let table = tune(&whole, &m, &GRID, &outputs);
    assert_eq!(table.status, 0, "{}", table.stderr);
    let json = tune(&whole, &m, &GRID, &["--format", "json"]);
    assert_eq!(json.status, 0, "{}", json.stderr);

    for i in 1..=3 {
        part(
            &sharded,
            &m,
            &GRID,
            &format!("{i}/3"),
            &format!("p{i}.json"),
        );
    }
    // Without --out-part the part goes to stdout, the same bytes.
    let to_stdout = tune(&sharded, &m, &GRID, &["--shard", "2/3"]);
    assert_eq!(to_stdout.status, 0, "{}", to_stdout.stderr);
    assert_eq!(to_stdout.stdout.as_bytes(), bytes(sharded.join("p2.json")));

    let mut args = vec!["p1.json", "p2.json", "p3.json"];
    args.extend_from_slice(&outputs);
    let merged = merge(&sharded, &args);
    assert_eq!(merged.status, 0, "{}", merged.stderr);
    assert!(
        merged.stderr.contains("merge: 3 parts of 8 grid runs"),
        "{}",
        merged.stderr
    );
    assert_eq!(merged.stdout, table.stdout);
    assert!(table.stdout.contains("best offsets"), "{}", table.stdout);
    for file in ["t.tuning.toml", "p.svg"] {
        assert_eq!(
            bytes(sharded.join(file)),
            bytes(whole.join(file)),
            "{file} differs"
        );
    }
    // Any order of the parts; JSON as well.
    let merged = merge(
        &sharded,
        &["p3.json", "p1.json", "p2.json", "--format", "json"],
    );
    assert_eq!(merged.status, 0, "{}", merged.stderr);
    assert_eq!(merged.stdout, json.stdout);
}

#[test]
fn merge_refuses_parts_that_are_not_one_whole_sweep() {
    let m = machine().canonicalize().unwrap();
    let d = dir("refusals");
    for i in 1..=3 {
        part(&d, &m, &GRID, &format!("{i}/3"), &format!("p{i}.json"));
    }
    // A part of another grid (offsets every 120 degrees).
    let mut other_grid = GRID;
    other_grid[3] = "0:360:120";
    part(&d, &m, &other_grid, "3/3", "other-grid.json");
    // A part of another machine file (the same machine with one more comment).
    let copy = d.join("copy.toml");
    let text = std::fs::read_to_string(&m).unwrap() + "\n# a copy\n";
    std::fs::write(&copy, text).unwrap();
    part(&d, &copy, &GRID, "3/3", "other-machine.json");
    // Part 2 of 2 of the same sweep.
    part(&d, &m, &GRID, "2/2", "half.json");
    // Not parts.
    std::fs::write(d.join("notes.txt"), "speeds 2750, 3000\n").unwrap();
    let r = tune(&d, &m, &GRID, &["--format", "json"]);
    std::fs::write(d.join("result.json"), r.stdout).unwrap();
    // A part edited after it was written (its end time).
    let edited = std::fs::read_to_string(d.join("p3.json"))
        .unwrap()
        .replace("\"t_end\": 4.0", "\"t_end\": 5.0");
    std::fs::write(d.join("edited.json"), edited).unwrap();
    // A part claiming N beyond any grid (its only run the grid's first point).
    let mut huge: serde_json::Value = serde_json::from_slice(&bytes(d.join("p1.json"))).unwrap();
    huge["shard"]["count"] = 100_000_000_000_000u64.into();
    huge["runs"].as_array_mut().unwrap().truncate(1);
    std::fs::write(d.join("huge.json"), huge.to_string()).unwrap();

    let cases: &[(&[&str], &str)] = &[
        (&["p1.json", "p2.json"], "part 3 of 3 missing"),
        (&["p2.json"], "parts 1, 3 of 3 missing"),
        (
            &["p1.json", "p2.json", "p2.json", "p3.json"],
            "p2.json: part 2/3 again (p2.json is part 2/3 too)",
        ),
        (
            &["p1.json", "p2.json", "other-grid.json"],
            "other-grid.json: a part of another sweep than p1.json: --offsets differs (0:360:90 = [0, 90, 180, 270] deg in p1.json, 0:360:120 = [0, 120, 240] deg in other-grid.json)",
        ),
        (
            &["p1.json", "p2.json", "other-machine.json"],
            "other-machine.json: a part of another sweep than p1.json: the machine file differs (sha256 ",
        ),
        (
            &["p1.json", "p2.json", "half.json"],
            "half.json: part 2/2 but p1.json is part 1/3: the parts disagree on N",
        ),
        (
            &["p1.json", "p2.json", "notes.txt"],
            "notes.txt: not a partial result of `host-sim tune --shard`: not JSON",
        ),
        (
            &["p1.json", "p2.json", "result.json"],
            "result.json: not a partial result of `host-sim tune --shard`: no \"format\"",
        ),
        (
            &["p1.json", "p2.json", "edited.json"],
            "edited.json: a damaged partial result: sweep_sha256 does not match",
        ),
        (
            &["huge.json"],
            "huge.json: a damaged partial result: shard 1/100000000000000: not 1 <= I <= N <= 10000",
        ),
        (&["p1.json", "p2.json", "p4.json"], "p4.json: cannot read"),
        (
            &["p1.json", "p2.json", "p3.json", "--machine", "copy.toml"],
            "copy.toml: not the machine file the parts were made from",
        ),
    ];
    for (args, message) in cases {
        let r = merge(&d, args);
        r.refused(message);
        assert!(r.stdout.is_empty(), "{args:?}: {}", r.stdout);
    }
    // The right machine file, found where the parts name it or given: merged.
    let r = merge(
        &d,
        &[
            "p1.json",
            "p2.json",
            "p3.json",
            "--machine",
            m.to_str().unwrap(),
        ],
    );
    assert_eq!(r.status, 0, "{}", r.stderr);
}

#[test]
fn tune_refuses_a_bad_shard() {
    let m = machine();
    let m = m.to_str().unwrap();
    let d = dir("bad-shard");
    for (shard, message) in [
        (
            "0/3",
            "'0/3' for '--shard <I/N>': I must be from 1 to N = 3",
        ),
        (
            "4/3",
            "'4/3' for '--shard <I/N>': I must be from 1 to N = 3",
        ),
        ("1/0", "'1/0' for '--shard <I/N>': N must be from 1"),
        ("a/b", "'a/b' for '--shard <I/N>': expected I/N"),
        ("1", "'1' for '--shard <I/N>': expected I/N"),
        ("-1/3", "'-1/3' for '--shard <I/N>': expected I/N"),
    ] {
        let r = run_in(&d, &["tune", m, &format!("--shard={shard}")]);
        r.refused(message);
    }
    // The outputs of the whole sweep are merge's, not a part's.
    let r = run_in(&d, &["tune", m, "--shard", "1/2", "--write", "t.toml"]);
    r.refused("'--shard <I/N>' cannot be used with '--write <FILE.toml>'");
    let r = run_in(&d, &["tune", m, "--out-part", "p.json"]);
    r.refused("--shard");
    assert!(
        std::fs::read_dir(&d).unwrap().next().is_none(),
        "nothing written"
    );
}
