//! `host-sim tune --shard I/N` and `host-sim merge` through the real binary: a tiny
//! sweep run whole and as three parts merged gives the same stdout (table and
//! JSON), the same `--write` table and the same `--plot` SVG, byte for byte; merge
//! refuses a missing, a duplicate and a foreign part, parts that disagree on N, a
//! file that is not a part, an edited part and the wrong machine file (exit 2, the
//! file named); tune refuses a bad `--shard`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use host_sim::tune::part::Part;
use serde_json::Value;

mod common;
use common::parts::{bytes, merge, merges_to_the_whole, resealed, run_in};
use common::{machine, Run, TINY_GRID as GRID};

/// A fresh scratch directory `name` of this test binary.
fn dir(name: &str) -> PathBuf {
    let d = common::scratch("cli-merge", name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).expect("scratch directory");
    d
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

    assert!(table.stdout.contains("best offsets"), "{}", table.stdout);
    // Any order of the parts; JSON as well.
    merges_to_the_whole(
        &sharded,
        &whole,
        &["p1.json", "p2.json", "p3.json"],
        &outputs,
        (&table, &json),
        "merge: 3 parts of 8 grid runs",
    );
}

/// Runs through the floor (the one-foot machine) go through the parts as no
/// travel, their reason kept, and merge to the whole sweep's output.
#[test]
fn runs_through_the_floor_merge_as_no_travel() {
    let m = common::root()
        .join("tests/fixtures/one-foot-machine.toml")
        .canonicalize()
        .unwrap();
    let d = dir("through-the-floor");
    let grid = [
        "--speeds",
        "3000",
        "--offsets",
        "0:360:180",
        "--t-end",
        "0.5",
    ];
    let whole = tune(&d, &m, &grid, &["--format", "json"]);
    assert_eq!(whole.status, 0, "{}", whole.stderr);
    part(&d, &m, &grid, "1/2", "p1.json");
    part(&d, &m, &grid, "2/2", "p2.json");
    let p: Value = serde_json::from_slice(&bytes(d.join("p1.json"))).unwrap();
    assert_eq!(p["version"], 5);
    assert_eq!(
        p["runs"][0]["run"]["not_a_travel"],
        "platform went through the fundament at t = 0.053 s"
    );
    assert!(p["runs"][0]["run"]["not_held"].is_null());
    let merged = merge(&d, &["p1.json", "p2.json", "--format", "json"]);
    assert_eq!(merged.status, 0, "{}", merged.stderr);
    assert_eq!(merged.stdout, whole.stdout);
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

/// Part `name` in `d` with `edit` made to its JSON, written as `out`: a hand edit
/// (the hashes left as they were).
fn hand_edited(d: &Path, name: &str, out: &str, edit: impl FnOnce(&mut Value)) {
    let mut part: Value = serde_json::from_slice(&bytes(d.join(name))).unwrap();
    edit(&mut part);
    let text = serde_json::to_string_pretty(&part).unwrap();
    std::fs::write(d.join(out), text).unwrap();
}

/// `host-sim merge args...` in `cwd`, failing (not hanging) if it runs on past
/// [`WATCHDOG`].
fn merge_within(cwd: &Path, args: &[&str]) -> Run {
    let mut cmd = common::host_sim();
    cmd.arg("merge").args(args).current_dir(cwd);
    common::finish_within(cmd, WATCHDOG)
}

/// Long enough for a merge of the tiny grid on a loaded machine (a few seconds);
/// the defects these tests guard against never end.
const WATCHDOG: Duration = Duration::from_secs(120);

/// The outcome of the run of `part` at `speed_rpm`, `offset_deg`.
fn run_at(part: &mut Value, speed_rpm: f64, offset_deg: f64) -> &mut Value {
    part["runs"]
        .as_array_mut()
        .unwrap()
        .iter_mut()
        .map(|r| &mut r["run"])
        .find(|r| r["speed_rpm"] == speed_rpm && r["offset_deg"] == offset_deg)
        .expect("the part has the run")
}

/// The three parts of the tiny sweep in a fresh scratch directory `name`.
fn three_parts(name: &str) -> PathBuf {
    let m = machine().canonicalize().unwrap();
    let d = dir(name);
    for i in 1..=3 {
        part(&d, &m, &GRID, &format!("{i}/3"), &format!("p{i}.json"));
    }
    d
}

#[test]
fn merge_refuses_a_part_whose_runs_were_edited() {
    let d = three_parts("edited-runs");
    // Part 2 holds 3000 rpm, 0 deg (grid point 4), which travels neither way;
    // as 0.05 m/s it became the best right offset of 3000 rpm.
    let edits: [(&str, Value); 5] = [
        ("mean_velocity", 0.05.into()),
        ("mean_velocity", "NaN".into()),
        ("mean_velocity", "inf".into()),
        ("mean_velocity", 1e308.into()),
        ("not_held", "the offset was not held".into()),
    ];
    for (k, (key, value)) in edits.into_iter().enumerate() {
        let name = format!("edit{k}.json");
        hand_edited(&d, "p2.json", &name, |p| {
            run_at(p, 3000.0, 0.0)[key] = value.clone();
        });
        let r = merge_within(&d, &["p1.json", &name, "p3.json"]);
        r.refused(&format!(
            "error: {name}: a damaged partial result: part 2/3: part_sha256 does not match its contents"
        ));
        assert!(r.stdout.is_empty(), "{key} = {value}: {}", r.stdout);
    }
    // The machine file's path is the part's too.
    hand_edited(&d, "p1.json", "path.json", |p| {
        p["machine"]["path"] = "/dev/zero".into();
    });
    merge_within(&d, &["path.json", "p2.json", "p3.json"]).refused(
        "error: path.json: a damaged partial result: part 1/3: part_sha256 does not match",
    );
    // Unedited, they merge.
    let r = merge_within(&d, &["p1.json", "p2.json", "p3.json"]);
    assert_eq!(r.status, 0, "{}", r.stderr);
}

/// The three parts in `d` with `edit` made to each and their hashes recomputed,
/// as `TAG1.json`, ...: merged, refused with `message`, within [`WATCHDOG`].
fn all_resealed_refused(d: &Path, tag: &str, edit: impl Fn(&mut Part), message: &str) {
    let names: Vec<String> = (1..=3).map(|i| format!("{tag}{i}.json")).collect();
    for (i, name) in (1..=3).zip(&names) {
        resealed(d, &format!("p{i}.json"), name, &edit);
    }
    let args: Vec<&str> = names.iter().map(String::as_str).collect();
    let r = merge_within(d, &args);
    r.refused(message);
    assert!(r.stdout.is_empty(), "{tag}: {}", r.stdout);
}

#[test]
fn merge_checks_a_resealed_part_as_tune_checks_its_options() {
    let d = three_parts("resealed");
    // A held run without a mean velocity: no run makes that.
    for (k, v) in [f64::NAN, f64::INFINITY].into_iter().enumerate() {
        let name = format!("value{k}.json");
        resealed(&d, "p2.json", &name, |p: &mut Part| {
            let r = &mut p.runs.iter_mut().find(|r| r.point == 4).unwrap().run;
            r.mean_velocity = v;
        });
        merge_within(&d, &["p1.json", &name, "p3.json"]).refused(&format!(
            "error: {name}: a damaged partial result: run 4 (3000 rpm, 0 deg): mean_velocity {v} with not_held and not_a_travel null"
        ));
    }
    // Parts of another host-sim: the merge's check runs would be this one's.
    all_resealed_refused(
        &d,
        "old",
        |p| p.sweep.host_sim_version = "0.0.1".into(),
        &format!(
            "error: old1.json: a part of host-sim 0.0.1, this is host-sim {}: run the parts and the merge with one host-sim",
            env!("CARGO_PKG_VERSION")
        ),
    );
    // Sweeps tune refuses: they would run for ever, or the controller refuse them.
    all_resealed_refused(
        &d,
        "t-end",
        |p| p.sweep.t_end = 1e300,
        "error: t-end1.json: a sweep tune refuses: --t-end 1e300: at most 3600 s of simulated time in one run",
    );
    all_resealed_refused(
        &d,
        "step",
        |p| p.sweep.set = vec!["simulation.output_step=1e-300".into()],
        "error: step1.json: a sweep tune refuses: simulation.output_step 1e-300: ",
    );
    all_resealed_refused(
        &d,
        "speed",
        |p| {
            // The grid's speed and its runs'.
            p.sweep.speeds_rpm[1] = 9000.0;
            for r in p.runs.iter_mut().filter(|r| r.run.speed_rpm == 3000.0) {
                r.run.speed_rpm = 9000.0;
            }
        },
        "error: speed1.json: a sweep tune refuses: --speeds 2750:3000:250: 9000 rpm outside the controller's speed range",
    );
    // A machine file that never ends, and a named pipe no one writes to: refused,
    // neither read nor waited on.
    all_resealed_refused(
        &d,
        "zero",
        |p| p.machine.path = "/dev/zero".into(),
        "error: /dev/zero: cannot read the file: a device, not a regular file (an input file is read whole): the machine file the parts were made from",
    );
    let fifo = d.join("fifo.toml");
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo");
    let fifo = fifo.to_str().unwrap().to_string();
    all_resealed_refused(
        &d,
        "fifo",
        |p| p.machine.path = fifo.clone(),
        "fifo.toml: cannot read the file: a named pipe (FIFO), not a regular file",
    );
}

/// `r` refused (exit 2) with `needle` in one short error, nothing on stdout.
fn refused_short(r: &Run, needle: &str) {
    let head: String = r.stderr.chars().take(600).collect();
    assert_eq!(r.status, 2, "exit {}: {head}", r.status);
    assert!(r.stderr.contains(needle), "{needle:?} not in: {head}");
    assert!(
        r.stderr.len() < 600,
        "{} bytes of error: {head}",
        r.stderr.len()
    );
    assert!(r.stdout.is_empty(), "{}", r.stdout.len());
}

/// What `tune` never writes, in a part whose hashes were recomputed, is refused
/// (issue 23): a mean velocity beyond the measured file's bound, more plant
/// warnings than a run keeps or a longer one; and every field an error quotes is
/// cut (a 10 MB field gave a 10 MB line).
#[test]
fn merge_bounds_the_values_of_a_resealed_part() {
    let d = three_parts("bounds");
    let long = "q".repeat(10_000_000);
    let merged = |name: &str| merge_within(&d, &["p1.json", name, "p3.json"]);
    let damaged =
        |name: &str| format!("error: {name}: a damaged partial result: run 4 (3000 rpm, 0 deg): ");
    // Faster than any travel by impacts, whether the offset was held or not.
    for (k, (v, not_held)) in [(12345.5, None), (-10.5, Some("ended `fault`"))]
        .into_iter()
        .enumerate()
    {
        let name = format!("fast{k}.json");
        resealed(&d, "p2.json", &name, |p: &mut Part| {
            let r = &mut p.runs.iter_mut().find(|r| r.point == 4).unwrap().run;
            r.mean_velocity = v;
            r.not_held = not_held.map(String::from);
        });
        refused_short(
            &merged(&name),
            &format!(
                "{}mean_velocity {v} m/s: beyond the 10 m/s of any travel by impacts (tune writes no such run)",
                damaged(&name)
            ),
        );
    }
    // A run that was no travel has no mean velocity.
    resealed(&d, "p2.json", "travel.json", |p: &mut Part| {
        let r = &mut p.runs.iter_mut().find(|r| r.point == 4).unwrap().run;
        r.not_a_travel = Some("platform went through the fundament".into());
    });
    refused_short(
        &merged("travel.json"),
        &format!("{}mean_velocity ", damaged("travel.json")),
    );
    // More plant warnings than a run keeps, or a longer one.
    resealed(&d, "p2.json", "many.json", |p: &mut Part| {
        let r = &mut p.runs.iter_mut().find(|r| r.point == 4).unwrap().run;
        r.plant_warnings = vec!["contacts: Painleve configuration".into(); 100];
    });
    refused_short(
        &merged("many.json"),
        &format!("{}100 plant warnings", damaged("many.json")),
    );
    for field in ["warning", "not_held"] {
        let name = format!("long-{field}.json");
        resealed(&d, "p2.json", &name, |p: &mut Part| {
            let r = &mut p.runs.iter_mut().find(|r| r.point == 4).unwrap().run;
            match field {
                "warning" => r.plant_warnings = vec![long.clone()],
                _ => r.not_held = Some(long.clone()),
            }
        });
        refused_short(&merged(&name), "... (10000000 bytes)");
    }
    // Fields quoted in errors: cut.
    hand_edited(&d, "p2.json", "format.json", |p| {
        p["format"] = long.clone().into()
    });
    refused_short(
        &merged("format.json"),
        "format.json: not a partial result of `host-sim tune --shard`: its format is \"qqq",
    );
    hand_edited(&d, "p2.json", "version.json", |p| {
        p["version"] = long.clone().into()
    });
    refused_short(
        &merged("version.json"),
        "version.json: partial result version \"qqq",
    );
    resealed(&d, "p2.json", "host.json", |p: &mut Part| {
        p.sweep.host_sim_version = long.clone()
    });
    refused_short(&merged("host.json"), "host.json: a part of host-sim qqq");
    resealed(&d, "p2.json", "shard.json", |p: &mut Part| {
        p.machine.path = long.clone()
    });
    refused_short(&merged("shard.json"), "... (10000000 bytes)");
}

/// An output that cannot be written does not throw the merged sweep away (issue
/// 23): the result is printed, then the error (Linux's `/dev/full`).
#[cfg(target_os = "linux")]
#[test]
fn an_output_that_cannot_be_written_still_prints_the_merged_sweep() {
    let d = three_parts("full");
    let r = merge_within(
        &d,
        &["p1.json", "p2.json", "p3.json", "--write", "/dev/full"],
    );
    r.printed_then_full("--write", "best offsets");
}
