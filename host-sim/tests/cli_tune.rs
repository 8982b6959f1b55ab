//! `host-sim tune` through the real binary: the documented JSON on a tiny grid, the
//! same output on one and on two threads, best offsets on the right side of the
//! vertical for the reference machine, a `--write` table that a machine file can
//! name, and clear refusals (exit 2, no panic) of bad options.

use std::path::{Path, PathBuf};

use host_sim::machine::tuning_file;
use host_sim::machine::Machine;
use host_sim::simulation::closed_loop;
use serde_json::Value;

mod common;
use common::{keys, machine, Run};

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-tune", name)
}

/// Runs `host-sim` with `args` on `threads` rayon threads (None: all cores).
fn run_on(threads: Option<usize>, args: &[&str]) -> Run {
    let mut cmd = common::host_sim();
    cmd.args(args);
    match threads {
        Some(n) => cmd.env("RAYON_NUM_THREADS", n.to_string()),
        None => cmd.env_remove("RAYON_NUM_THREADS"),
    };
    common::finish(cmd)
}

/// The tiny grid ([`common::TINY_GRID`]) on `threads` threads.
fn tiny(threads: usize, write: &Path, plot: &Path) -> Run {
    let m = machine();
    let mut args = vec!["tune", m.to_str().unwrap()];
    args.extend_from_slice(&common::TINY_GRID);
    args.extend_from_slice(&[
        "--format",
        "json",
        "--write",
        write.to_str().unwrap(),
        "--plot",
        plot.to_str().unwrap(),
    ]);
    run_on(Some(threads), &args)
}

#[test]
fn a_tiny_sweep_gives_the_documented_json_the_same_on_one_and_two_threads() {
    let (w1, w2) = (scratch("one.tuning.toml"), scratch("two.tuning.toml"));
    let (p1, p2) = (scratch("one.svg"), scratch("two.svg"));
    let one = tiny(1, &w1, &p1);
    let two = tiny(2, &w2, &p2);
    assert_eq!(one.status, 0, "{}", one.stderr);
    assert_eq!(two.status, 0, "{}", two.stderr);

    // Determinism: stdout and files byte for byte, whatever the thread count.
    assert_eq!(one.stdout, two.stdout);
    // (The header's "regenerate with" command names the file written.)
    let table = |p: &Path, name: &str| {
        std::fs::read_to_string(p)
            .unwrap()
            .replace(name, "NAME.tuning.toml")
    };
    assert_eq!(table(&w1, "one.tuning.toml"), table(&w2, "two.tuning.toml"));
    assert_eq!(std::fs::read(&p1).unwrap(), std::fs::read(&p2).unwrap());
    assert!(
        one.stderr.contains("tune: ") && one.stderr.contains(" runs in "),
        "{}",
        one.stderr
    );

    // The documented keys, in order (docs/tuning.md, "Output").
    let doc: Value = serde_json::from_str(&one.stdout).expect("JSON");
    assert_eq!(keys(&doc), ["grid", "best", "warnings"]);
    let grid = doc["grid"].as_array().unwrap();
    assert_eq!(grid.len(), 8, "2 speeds x 4 offsets");
    for p in grid {
        assert_eq!(
            keys(p),
            [
                "speed_rpm",
                "offset_deg",
                "mean_velocity",
                "not_held",
                "not_a_travel"
            ]
        );
        assert!(p["mean_velocity"].is_f64());
        assert!(
            p["not_held"].is_null() && p["not_a_travel"].is_null(),
            "{p}"
        );
    }
    let offsets: Vec<f64> = grid[..4]
        .iter()
        .map(|p| p["offset_deg"].as_f64().unwrap())
        .collect();
    assert_eq!(offsets, [0.0, 90.0, 180.0, 270.0]);
    assert_eq!(keys(&doc["best"]), ["right", "left"]);
    assert!(
        doc["warnings"].as_array().unwrap().is_empty(),
        "{}",
        doc["warnings"]
    );

    // Best offsets of the reference machine: right in (0, 180) travelling right,
    // left in (180, 360) travelling left (force along offset / 2: up-and-right
    // for offsets in (0, 180)).
    for (way, lo, hi, sign) in [("right", 0.0, 180.0, 1.0), ("left", 180.0, 360.0, -1.0)] {
        let list = doc["best"][way].as_array().unwrap();
        assert_eq!(list.len(), 2, "{way}: one per speed");
        for b in list {
            assert_eq!(keys(b), ["speed_rpm", "offset_deg", "mean_velocity"]);
            let o = b["offset_deg"].as_f64().unwrap();
            let v = b["mean_velocity"].as_f64().unwrap();
            assert!(o > lo && o < hi, "{way}: offset {o}");
            assert!(sign * v > 0.005, "{way}: mean velocity {v} m/s");
        }
    }

    // The table reads back, the controller takes it, a machine file can name it.
    let text = std::fs::read_to_string(&w1).unwrap();
    let rows = tuning_file::parse("one.tuning.toml", &text).expect("a tuning table");
    assert_eq!(rows.len(), 2);
    assert_eq!((rows[0].0, rows[1].0), (2750.0, 3000.0));
    assert!(tuning_file::table(&rows).is_ok());
    assert!(text.starts_with("# "), "a header comment");
    let machine_text = std::fs::read_to_string(machine())
        .unwrap()
        .replace(
            "# tuning_table = \"vibro-driver.tuning.toml\"",
            "tuning_table = \"one.tuning.toml\"",
        )
        .replace(
            "tuning_table = \"vibro-driver.tuning.toml\"",
            "tuning_table = \"one.tuning.toml\"",
        );
    let dir = w1.parent().unwrap();
    let m = Machine::from_text("m.toml", &machine_text, dir, &[]).expect("the machine");
    assert_eq!(m.controller.tuning_table.as_deref(), Some(w1.as_path()));
    let params = closed_loop::params(&m).expect("the machine's table loads");
    assert_eq!(params.tuning.rows().len(), 2);

    // The plot is a well-formed SVG with a line per speed.
    let svg = std::fs::read_to_string(&p1).unwrap();
    roxmltree::Document::parse(&svg).expect("well-formed SVG");
    assert!(svg.contains("2750 rpm") && svg.contains("3000 rpm"));
}

/// `tune` of the reference machine at 3000 rpm and one offset, runs of `t_end`.
fn one_point(offset: &str, t_end: &str) -> Run {
    let m = machine();
    let args = ["--speeds", "3000", "--offsets", offset, "--t-end", t_end];
    let mut all = vec!["tune", m.to_str().unwrap()];
    all.extend(args);
    run_on(None, &all)
}

#[test]
fn one_point_prints_a_table_and_warns_when_the_run_is_too_short() {
    let r = one_point("90", "0.5");
    assert_eq!(r.status, 0, "{}", r.stderr);
    for text in [
        "rpm \\ deg",
        "best offsets",
        "* the offset was not held",
        "3000 rpm, 90 deg: offset not held",
        "raise --t-end",
    ] {
        assert!(r.stdout.contains(text), "no {text:?} in\n{}", r.stdout);
    }
}

/// One speed, four offsets, 3 s (offsets held from about 1.2 s), the loosest
/// tolerance: 4 grid runs and at most 2 checks.
const ONE_SPEED: [&str; 8] = [
    "--speeds",
    "3000",
    "--offsets",
    "0:360:90",
    "--t-end",
    "3",
    "--set",
    "simulation.rtol=1e-3",
];

/// Frictionless feet: nothing to push on, so no travel, and every run's mean
/// velocity is what the sideways sway leaves (micrometres per second). Neither
/// way is travel: each is warned of, and `--write` writes the least bad offsets,
/// as for any speed without travel one way (issue 23: a right offset was written
/// from +1.8e-9 m/s without a word).
#[test]
fn frictionless_feet_travel_no_way_and_say_so() {
    let m = machine();
    let write = scratch("frictionless.tuning.toml");
    let r = run_on(
        None,
        &[
            ["tune", m.to_str().unwrap()].as_slice(),
            &ONE_SPEED,
            &[
                "--set",
                "contacts.K1.friction=0",
                "--set",
                "contacts.K2.friction=0",
                "--format",
                "json",
                "--write",
                write.to_str().unwrap(),
            ],
        ]
        .concat(),
    );
    assert_eq!(r.status, 0, "{}", r.stderr);
    let doc: Value = serde_json::from_str(&r.stdout).expect("JSON");
    // The premise: no run travels.
    for p in doc["grid"].as_array().unwrap() {
        let v = p["mean_velocity"].as_f64().unwrap();
        assert!(v.abs() < 1e-4, "{p}");
    }
    let warnings: Vec<&str> = doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    for way in ["right", "left"] {
        let says = format!("3000 rpm: no offset travels {way} faster than 0.5 mm/s: the best is ");
        assert!(
            warnings.iter().any(|w| w.starts_with(&says)),
            "{says:?} not in {warnings:?}"
        );
    }
    let rows = tuning_file::parse("t", &std::fs::read_to_string(&write).unwrap()).unwrap();
    assert_eq!(rows.len(), 1);
}

/// Off a terminal the progress is a line every few seconds;
/// `VIBRO_PROGRESS_EVERY=0` makes it a line at every run, so that the test waits
/// on no clock. The total counts the check runs (two a speed) from the first
/// line on (issue 23: nothing was printed off a terminal, and the bar's total
/// grew when the checks were added).
#[test]
fn progress_off_a_terminal_is_lines_with_a_fixed_total() {
    let m = machine();
    let mut cmd = common::host_sim();
    cmd.args(["tune", m.to_str().unwrap()])
        .args(ONE_SPEED)
        .env("VIBRO_PROGRESS_EVERY", "0");
    let r = common::finish(cmd);
    assert_eq!(r.status, 0, "{}", r.stderr);
    // "tune: 3/6 runs, 0 s elapsed, ~1 s left": 4 grid runs and 2 checks.
    let counts: Vec<(u64, u64)> = r
        .stderr
        .lines()
        .filter(|l| l.contains(" elapsed"))
        .map(|l| {
            let counts = l
                .strip_prefix("tune: ")
                .and_then(|l| l.split(" runs, ").next())
                .unwrap_or_else(|| panic!("{l}"));
            let (done, total) = counts.split_once('/').unwrap();
            (done.parse().unwrap(), total.parse().unwrap())
        })
        .collect();
    assert!(counts.len() >= 5, "{}", r.stderr);
    assert!(counts.iter().all(|c| c.1 == 6), "{counts:?}");
    assert!(counts.windows(2).all(|w| w[0].0 <= w[1].0), "{counts:?}");
    assert_eq!(counts.last(), Some(&(6, 6)));
}

/// A run whose offset reference is still ramping at its last tick never reached
/// the held offset: the warning says so with the run's end (it printed `at t = -
/// s`). At 3000 rpm the reference reaches 180 deg at about 1.18 s.
#[test]
fn an_offset_never_reached_is_said_so_with_the_end_of_the_run() {
    let r = one_point("180", "1.1");
    assert_eq!(r.status, 0, "{}", r.stderr);
    assert!(
        r.stdout.contains(
            "3000 rpm, 180 deg: offset not held: the offset reference had not reached the held offset by the end of the run, t = 1.1 s (raise --t-end)"
        ),
        "{}",
        r.stdout
    );
    assert!(!r.stdout.contains("t = -"), "{}", r.stdout);
}

#[test]
fn bad_options_exit_2_naming_the_option() {
    let m = machine();
    let m = m.to_str().unwrap();
    let cases: &[(&[&str], &str)] = &[
        (
            &["--speeds", "3500:2500:250"],
            "'3500:2500:250' for '--speeds <A:B:STEP>': B must be >= A",
        ),
        (
            &["--offsets", "0:360:0"],
            "'0:360:0' for '--offsets <A:B:STEP>': STEP must be > 0",
        ),
        (
            &["--offsets", "0:360:-15"],
            "'0:360:-15' for '--offsets <A:B:STEP>': STEP must be > 0",
        ),
        (
            &["--offsets", "nan:360:15"],
            "'nan:360:15' for '--offsets <A:B:STEP>': A, B and STEP must be finite",
        ),
        (
            &["--offsets", "0:360"],
            "'0:360' for '--offsets <A:B:STEP>': expected A:B:STEP",
        ),
        (
            &["--offsets", "0:720:15"],
            "'0:720:15' for '--offsets <A:B:STEP>': spans more than one turn",
        ),
        (
            &["--offsets", "0:1e6:1"],
            "'0:1e6:1' for '--offsets <A:B:STEP>': 1000001 points, at most 10000",
        ),
        (
            &["--speeds", "100:500:100"],
            "--speeds 100:500:100: 100, 200 rpm outside the controller's speed range",
        ),
        (
            &["--speeds", "1000:4000:1"],
            "3001 speeds x 24 offsets = 72024 runs, at most 10000",
        ),
        (&["--t-end", "0"], "--t-end 0: must be a positive number"),
        (
            &["--t-end", "nan"],
            "--t-end NaN: must be a positive number",
        ),
        (
            &["--speeds", "1000:4200:100", "--write", "x.toml"],
            "--write: the controller's table holds at most 32 rows",
        ),
        (&["--set", "platform.mass=-1"], "platform.mass"),
    ];
    for (extra, message) in cases {
        let mut args = vec!["tune", m];
        args.extend_from_slice(extra);
        let r = run_on(None, &args);
        assert_eq!(r.status, 2, "{args:?}: {}", r.stderr);
        assert!(r.stderr.contains(message), "{args:?}: {}", r.stderr);
        assert!(r.stdout.is_empty(), "{args:?}: {}", r.stdout);
    }
    // Several problems at once, one line each (the ranges are the parser's: it
    // names the first bad value with the command's usage).
    let r = run_on(
        None,
        &[
            "tune",
            m,
            "--speeds",
            "1500:4000:1",
            "--offsets",
            "0:360:1",
            "--t-end",
            "-1",
        ],
    );
    assert_eq!(r.status, 2);
    assert_eq!(r.stderr.lines().count(), 2, "{}", r.stderr);
    // A machine file that is not there.
    let r = run_on(None, &["tune", "no-such-machine.toml"]);
    r.refused("no-such-machine.toml");
}

/// Issue 23: a machine that sinks through the floor (the reference machine without
/// its right foot) gave a grid of travel speeds and best offsets from them. Each
/// run is now no travel, with no mean velocity, and no best offset is taken from
/// it; it is said so in its own words and mark, not as an offset not held.
#[test]
fn runs_through_the_floor_are_no_travel() {
    let one_foot = common::root().join("tests/fixtures/one-foot-machine.toml");
    let one_foot = one_foot.to_str().unwrap();
    let args = [
        "tune",
        one_foot,
        "--speeds",
        "3000",
        "--offsets",
        "0:360:180",
        "--t-end",
        "1",
    ];
    let r = run_on(Some(1), &[&args[..], &["--format", "json"]].concat());
    assert_eq!(r.status, 0, "{}", r.stderr);
    let doc: Value = serde_json::from_str(&r.stdout).expect("JSON");
    let grid = doc["grid"].as_array().unwrap();
    assert_eq!(grid.len(), 2, "{doc}");
    for p in grid {
        assert!(p["mean_velocity"].is_null(), "{doc}");
        assert!(p["not_held"].is_null(), "{doc}");
        assert_eq!(
            p["not_a_travel"], "platform went through the fundament at t = 0.053 s",
            "{doc}"
        );
    }
    for way in ["right", "left"] {
        assert_eq!(doc["best"][way], serde_json::json!([]), "{doc}");
    }
    let warnings: Vec<&str> = doc["warnings"]
        .as_array()
        .unwrap()
        .iter()
        .map(|w| w.as_str().unwrap())
        .collect();
    for offset in ["0", "180"] {
        let breach = format!(
            "3000 rpm, {offset} deg: not a travel: platform went through the fundament at t = 0.053 s"
        );
        assert!(warnings.contains(&breach.as_str()), "{warnings:#?}");
    }
    assert!(
        !warnings.iter().any(|w| w.contains("offset not held")),
        "{warnings:#?}"
    );
    // The table marks the cells as no travel, not as offsets not held.
    let r = run_on(Some(1), &args);
    assert_eq!(r.status, 0, "{}", r.stderr);
    assert!(
        r.stdout.contains("\n3000       nan!  nan!\n"),
        "{}",
        r.stdout
    );
    assert!(
        r.stdout
            .contains("! not a travel in this run: no mean velocity (see the warnings)"),
        "{}",
        r.stdout
    );
    assert!(
        !r.stdout.contains("the offset was not held"),
        "{}",
        r.stdout
    );
}

/// An output that cannot be written does not throw the sweep away (issue 23): the
/// result is printed, then the error, exit 2 as for any output refused (Linux's
/// `/dev/full`: every write fails).
#[cfg(target_os = "linux")]
#[test]
fn an_output_that_cannot_be_written_still_prints_the_sweep() {
    let m = machine();
    for option in ["--write", "--plot"] {
        let r = run_on(
            None,
            &[
                "tune",
                m.to_str().unwrap(),
                "--speeds",
                "3000",
                "--offsets",
                "0:360:90",
                "--t-end",
                "3",
                "--set",
                "simulation.rtol=1e-3",
                option,
                "/dev/full",
            ],
        );
        r.printed_then_full(option, "best offsets");
    }
}
