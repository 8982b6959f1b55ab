//! `host-sim calibrate` through the real binary: refusals of bad input (exit 2,
//! nothing written), and a calibration from synthetic measurements of a machine
//! whose keys the test knows: the keys recovered within a tolerance derived from
//! the noise, the table tuned on the calibrated file as fast on the known machine
//! as that machine's own (95 %), and `--write` changing only the fitted values.

use std::path::PathBuf;

use host_sim::machine::Machine;
use serde_json::Value;

mod common;
use common::{run, Run};

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-calibrate", name)
}

/// The reference machine with `[uncertainty]` ranges for the keys fitted (its
/// tuning table from `examples/`), in a scratch directory of test `name` (tests
/// run in parallel: each writes its own). Friction has no finite valid range: it
/// needs one here.
fn uncertain_machine(name: &str) -> PathBuf {
    common::uncertain_machine(
        &format!("cli-calibrate-{name}"),
        "\"contacts.*.restitution\" = [0.1, 0.45]\n\"contacts.*.friction\" = [0.1, 0.6]\n",
    )
}

/// The known machine: restitution and friction away from the file's 0.3 and 0.4,
/// far enough that the file's own tuning table is too slow on it (below).
const TRUE_RESTITUTION: f64 = 0.22;
const TRUE_FRICTION: f64 = 0.22;

/// Runs of these tests: 3 s (the offsets measured, up to 150 degrees, are held
/// from about 1.2 s), the loosest tolerance (benchmarks/plant.md: the same
/// tuning table as 1e-8).
const RUNS: [&str; 4] = ["--t-end", "3", "--set", "simulation.rtol=1e-3"];

fn known_sets() -> Vec<String> {
    let mut sets = Vec::new();
    for k in ["K1", "K2"] {
        sets.push(format!("contacts.{k}.restitution={TRUE_RESTITUTION}"));
        sets.push(format!("contacts.{k}.friction={TRUE_FRICTION}"));
    }
    sets
}

/// `host-sim tune MACHINE --speeds S --offsets O` with the runs' options and `sets`.
fn tune(machine: &str, speeds: &str, offsets: &str, sets: &[String]) -> Value {
    let mut args = vec!["tune", machine, "--speeds", speeds, "--offsets", offsets];
    args.extend_from_slice(&RUNS);
    for s in sets {
        args.extend(["--set", s.as_str()]);
    }
    args.extend(["--format", "json"]);
    let r = run(&args);
    assert_eq!(r.status, 0, "{}", r.stderr);
    serde_json::from_str(&r.stdout).unwrap()
}

/// Standard normal numbers, deterministic: SplitMix64 and Box-Muller.
struct Normal(u64);

impl Normal {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn next(&mut self) -> f64 {
        let (u1, u2) = (1.0 - self.unit(), self.unit());
        (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
    }
}

/// Measurement noise, m/s: 0.5 mm/s, about 2 % of the travel speeds measured.
const SIGMA: f64 = 0.5e-3;

fn calibrate(machine: &str, measured: &str, extra: &[&str]) -> Run {
    let mut args = vec![
        "calibrate",
        machine,
        "--measured",
        measured,
        "--fit",
        "contacts.*.restitution,contacts.*.friction",
    ];
    args.extend_from_slice(&RUNS);
    args.extend_from_slice(extra);
    run(&args)
}

/// The whole mechanism on two speeds, each offset measured twice.
#[test]
fn synthetic_measurements_are_recovered_and_the_tuning_carries_over() {
    let m = uncertain_machine("synthetic");
    let m = m.to_str().unwrap();
    let known = known_sets();

    // Measurements: the known machine's speeds at 2750 and 3250 rpm (away from
    // the reference machine's two gaits at 3500 rpm), 40, 90 and 140 degrees,
    // each twice with its own Gaussian noise of SIGMA.
    let truth = tune(m, "2750:3250:500", "40:140:50", &known);
    let mut noise = Normal(14);
    let mut csv = String::from("speed_rpm,offset_deg,velocity_mps\n");
    for g in truth["grid"].as_array().unwrap() {
        for _ in 0..2 {
            let v = g["mean_velocity"].as_f64().unwrap() + SIGMA * noise.next();
            csv += &format!("{},{},{v:.7}\n", g["speed_rpm"], g["offset_deg"]);
        }
    }
    let measured = scratch("measured.csv");
    std::fs::write(&measured, &csv).unwrap();

    // The fit, from the file's values.
    let out = scratch("calibrated.toml");
    let r = calibrate(
        m,
        measured.to_str().unwrap(),
        &["--format", "json", "--write", out.to_str().unwrap()],
    );
    assert_eq!(r.status, 0, "{}", r.stderr);
    let c: Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(c["rows"].as_array().unwrap().len(), 12);
    assert_eq!(
        c["warnings"].as_array().unwrap().len(),
        0,
        "{}",
        c["warnings"]
    );

    // Recovered: |fit - true| <= 3 standard errors (the measurements' part scaled
    // from the fit's s to the noise's known SIGMA: 99.7 % of a linear model's
    // fits; the simulator's numerical part as it is) plus the search's resolution
    // (precision.rs: how far the compass search's end may lie from the
    // least-squares point).
    let s = c["fit"]["s"].as_f64().unwrap();
    for (key, truth) in c["keys"]
        .as_array()
        .unwrap()
        .iter()
        .zip([TRUE_RESTITUTION, TRUE_FRICTION])
    {
        let f = |k: &str| key[k].as_f64().unwrap();
        let std_error = (f("std_error_measurement") * SIGMA / s).hypot(f("std_error_numerical"));
        let tolerance = 3.0 * std_error + f("resolution");
        assert!(
            (f("fitted") - truth).abs() <= tolerance,
            "{}: fitted {} true {truth} tolerance {tolerance}",
            key["key"],
            f("fitted")
        );
        assert_eq!(key["identified"], true);
    }
    // The fit's own residuals: s near SIGMA (10 degrees of freedom: 10 s^2 /
    // SIGMA^2 is chi-square, within [2.5, 22.5] with 98 % probability).
    assert!(s > 0.5 * SIGMA && s < 1.5 * SIGMA, "s = {s}");
    // Every row's residual is the simulated minus the measured speed.
    for row in c["rows"].as_array().unwrap() {
        let f = |k: &str| row[k].as_f64().unwrap();
        assert_eq!(f("residual_mps"), f("simulated_mps") - f("measured_mps"));
    }

    // --write: the machine file with the fitted values on the fitted keys' lines,
    // every other line as it was; it reads back and runs.
    let before = std::fs::read_to_string(m).unwrap();
    let after = std::fs::read_to_string(&out).unwrap();
    let (b, a): (Vec<&str>, Vec<&str>) = (before.lines().collect(), after.lines().collect());
    assert_eq!(a.len(), b.len());
    for (x, y) in b.iter().zip(&a) {
        if x != y {
            assert!(
                x.starts_with("restitution =") || x.starts_with("friction ="),
                "{x:?} changed to {y:?}"
            );
        }
    }
    let fitted: Vec<f64> = c["keys"]
        .as_array()
        .unwrap()
        .iter()
        .map(|k| k["fitted"].as_f64().unwrap())
        .collect();
    let numbers = Machine::numbers("c.toml", &after, std::path::Path::new(""), &[]).unwrap();
    for (path, x) in [
        ("contacts[0].restitution", fitted[0]),
        ("contacts[1].restitution", fitted[0]),
        ("contacts[0].friction", fitted[1]),
        ("contacts[1].friction", fitted[1]),
    ] {
        assert!(
            numbers.iter().any(|n| n.key_path == path && n.value == x),
            "{path}"
        );
    }
    let ran = run(&[
        "run",
        out.to_str().unwrap(),
        "--command",
        "right",
        "--t-end",
        "0.2",
    ]);
    assert_eq!(ran.status, 0, "{}", ran.stderr);

    // The table tuned on the calibrated file, on the known machine: at least 95 %
    // of the known machine's own best rightward speed at every speed of the grid.
    let grid = ("2750:3250:500", "30:150:30");
    let own = tune(m, grid.0, grid.1, &known);
    let calibrated = tune(out.to_str().unwrap(), grid.0, grid.1, &[]);
    let best = |t: &Value| -> Vec<(f64, f64, f64)> {
        t["best"]["right"]
            .as_array()
            .unwrap()
            .iter()
            .map(|b| {
                let f = |k: &str| b[k].as_f64().unwrap();
                (f("speed_rpm"), f("offset_deg"), f("mean_velocity"))
            })
            .collect()
    };
    let (own, calibrated) = (best(&own), best(&calibrated));
    assert_eq!(own.len(), 2);
    assert_eq!(calibrated.len(), 2);
    let on_known = |speed: f64, offset: f64| {
        let t = tune(m, &speed.to_string(), &offset.to_string(), &known);
        t["grid"][0]["mean_velocity"].as_f64().unwrap()
    };
    for ((speed, _, v_own), (speed_c, offset, _)) in own.iter().zip(&calibrated) {
        assert_eq!(speed, speed_c);
        let v = on_known(*speed, *offset);
        assert!(
            v >= 0.95 * v_own,
            "{speed} rpm: the calibrated table's {offset} deg gives {v} m/s, the known machine's best {v_own}"
        );
    }
    // The check can fail: the table tuned on the file as it was (restitution 0.3,
    // friction 0.4) is below 95 % at some speed on the known machine.
    let nominal = best(&tune(m, grid.0, grid.1, &[]));
    let slow = own
        .iter()
        .zip(&nominal)
        .any(|((speed, _, v_own), (_, offset, _))| on_known(*speed, *offset) < 0.95 * v_own);
    assert!(
        slow,
        "the file's own table is already within 95 %: the check above tests nothing"
    );
}

#[test]
fn bad_input_is_refused_and_nothing_is_written() {
    let m = uncertain_machine("bad-input");
    let m = m.to_str().unwrap();
    let good = scratch("good.csv");
    std::fs::write(&good, "speed_rpm,offset_deg,velocity_mps\n3000,90,0.03\n").unwrap();
    let good = good.to_str().unwrap();
    let out = scratch("never.toml");
    let write = ["--write", out.to_str().unwrap()];
    let with = |name: &str, text: &str| {
        let p = scratch(name);
        std::fs::write(&p, text).unwrap();
        p.to_str().unwrap().to_string()
    };

    calibrate(m, "no-such.csv", &write).refused("no-such.csv");
    calibrate(
        m,
        &with(
            "header.csv",
            "speed,offset_deg,velocity_mps\n3000,90,0.03\n",
        ),
        &write,
    )
    .refused("header.csv: line 1: header: unknown column `speed`");
    calibrate(
        m,
        &with(
            "nan.csv",
            "speed_rpm,offset_deg,velocity_mps\n3000,90,fast\n",
        ),
        &write,
    )
    .refused("nan.csv: line 2: velocity_mps: must be a finite number (got \"fast\")");
    calibrate(
        m,
        &with(
            "weight.csv",
            "speed_rpm,offset_deg,velocity_mps,weight\n3000,90,0.03,-2\n",
        ),
        &write,
    )
    .refused("weight.csv: line 2: weight: must be within [1e-6, 1e6] (weights are relative: scale them) (got -2)");
    calibrate(
        m,
        &with(
            "fast.csv",
            "speed_rpm,offset_deg,velocity_mps\n9000,90,0.03\n",
        ),
        &write,
    )
    .refused("fast.csv: line 2: speed_rpm: must be within the controller's speed range");

    let fit = |keys: &str| {
        let mut args = vec!["calibrate", m, "--measured", good, "--fit", keys];
        args.extend_from_slice(&write);
        run(&args)
    };
    fit("contacts.*.frction").refused("--fit contacts.*.frction: unknown key `frction`");
    fit("platform.mass").refused(
        "--fit platform.mass: platform.mass must be > 0 and has no finite range to search: give its range in the file's [uncertainty]",
    );
    // The file's value outside the range searched.
    let text = std::fs::read_to_string(m).unwrap();
    assert!(text.contains("\"contacts.*.friction\" = [0.1, 0.6]"));
    let narrow = with("narrow.toml", &text.replace("[0.1, 0.6]", "[0.45, 0.6]"));
    let mut args = vec![
        "calibrate",
        narrow.as_str(),
        "--measured",
        good,
        "--fit",
        "contacts.*.friction",
    ];
    args.extend_from_slice(&write);
    run(&args).refused(
        "--fit contacts.*.friction: the file's value 0.4 lies outside the range searched [0.45, 0.6] ([uncertainty])",
    );
    let mut args = vec![
        "calibrate",
        m,
        "--measured",
        good,
        "--fit",
        "contacts.*.friction",
        "--t-end",
        "-1",
    ];
    args.extend_from_slice(&write);
    run(&args).refused("--t-end -1: must be a positive number");
    assert!(
        !out.exists(),
        "a refused calibration wrote {}",
        out.display()
    );
}

/// The simulator's numerical noise is in the standard error (issue 23, item 7).
/// The truth (restitution 0.40, friction 0.35) measured at rtol 1e-10, standing in
/// for the real machine, at 3250 and 3500 rpm and 30 to 165 degrees (8 points,
/// 3 s runs, 5 of them chaotic: their speeds change by 0.5 to 2.6 mm/s with the
/// tolerance); restitution fitted, friction set to its truth, at rtol 1e-3 and at
/// the default 1e-8. The noise is measured (the chaotic points' speeds move with
/// the tolerance by more than 0.1 mm/s), is in the standard error with the
/// measurements' part (they add in quadrature), is the larger part, and the tool
/// says so, naming the chaotic points.
///
/// What this does not hold, and no longer claims: that the truth lies within 3
/// standard errors of the fit. On chaotic points the sum of squares is itself a
/// rough function of the key (0.4 and 0.468 give 24.3 and 25.0 (mm/s)^2 at 1e-8),
/// so a fit lands wherever the roughness hides the trend, and every change of the
/// plant's rounding moves it (issue 24's speed work: 0.410 to 0.468 at 1e-8, 4 of
/// its standard errors; a fresh-clone CI run of a later change fitted 0.401 at 1e-3).
/// On the two periodic points alone the fit is 0.386 with a standard error of
/// 0.0002: their speeds hardly change with restitution there, and the standard
/// error, a linearisation, does not show it (docs/calibration.md, "Numerical
/// noise").
#[test]
fn the_numerical_noise_is_in_the_standard_error() {
    let m = common::uncertain_machine(
        "cli-calibrate-noise",
        "\"contacts.*.restitution\" = [0.1, 0.6]\n",
    );
    let m = m.to_str().unwrap();
    // `host-sim ARGS` with friction at its truth, as JSON.
    let json = |args: &[&str]| -> Value {
        let mut args = args.to_vec();
        for f in ["contacts.K1.friction=0.35", "contacts.K2.friction=0.35"] {
            args.extend(["--set", f]);
        }
        args.extend(["--t-end", "3", "--format", "json"]);
        let r = run(&args);
        assert_eq!(r.status, 0, "{}", r.stderr);
        serde_json::from_str(&r.stdout).unwrap()
    };
    let truth = json(&[
        "tune",
        m,
        "--speeds",
        "3250:3500:250",
        "--offsets",
        "30:165:45",
        "--set",
        "simulation.rtol=1e-10",
        "--set",
        "contacts.K1.restitution=0.4",
        "--set",
        "contacts.K2.restitution=0.4",
    ]);
    let mut csv = String::from("speed_rpm,offset_deg,velocity_mps\n");
    for g in truth["grid"].as_array().unwrap() {
        let v = g["mean_velocity"].as_f64().unwrap();
        csv += &format!("{},{},{v:.9}\n", g["speed_rpm"], g["offset_deg"]);
    }
    let measured = scratch("chaotic.csv");
    std::fs::write(&measured, &csv).unwrap();

    for rtol in ["simulation.rtol=1e-3", "simulation.rtol=1e-8"] {
        let c = json(&[
            "calibrate",
            m,
            "--measured",
            measured.to_str().unwrap(),
            "--fit",
            "contacts.*.restitution",
            "--set",
            rtol,
        ]);
        let key = &c["keys"][0];
        let f = |k: &str| key[k].as_f64().unwrap();
        // The premise: chaotic points among them, whose speeds move with the
        // tolerance by more than 0.1 mm/s (else this test tests nothing; choose
        // points where they do, docs/calibration.md, "Numerical noise"), and a
        // numerical part of the standard error larger than the measurements'.
        let noisy = c["rows"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|r| r["numerical_mps"].as_f64().unwrap() >= 1e-4)
            .count();
        assert!(
            noisy >= 3,
            "{rtol}: {noisy} of 8 points with noise above 0.1 mm/s"
        );
        assert!(
            f("std_error_numerical") > f("std_error_measurement"),
            "{rtol}: numerical part {} against the measurements' {}",
            f("std_error_numerical"),
            f("std_error_measurement")
        );
        // Its parts add in quadrature, and the noise's is said to be the larger.
        let parts = f("std_error_measurement").hypot(f("std_error_numerical"));
        assert!((f("std_error") - parts).abs() <= 1e-12 * parts);
        let warnings = c["warnings"].as_array().unwrap();
        assert!(
            warnings.iter().any(|w| w
                .as_str()
                .unwrap()
                .contains("the simulator's numerical noise makes more of its standard error")),
            "{rtol}: {warnings:?}"
        );
    }
}

/// A 10 MB field is quoted cut in its one-line error, with its length.
#[test]
fn a_long_field_is_cut_in_its_error() {
    let m = uncertain_machine("long-field");
    let path = scratch("long-field.csv");
    let long = "9".repeat(10_000_000);
    std::fs::write(
        &path,
        format!("speed_rpm,offset_deg,velocity_mps\n3000,90,x{long}\n"),
    )
    .unwrap();
    let r = calibrate(m.to_str().unwrap(), path.to_str().unwrap(), &[]);
    r.refused("line 2: velocity_mps: must be a finite number (got \"x999");
    assert!(r.stderr.contains("... (10000001 bytes)\")"), "{}", r.stderr);
    assert!(r.stderr.len() < 300, "{} bytes of error", r.stderr.len());
}

/// A measured file over 64 MiB is refused before it is parsed, whatever it holds.
#[test]
fn a_file_too_large_is_refused_unread() {
    let m = uncertain_machine("too-large");
    let path = scratch("huge.csv");
    let f = std::fs::File::create(&path).unwrap();
    f.set_len((64 << 20) + 1).unwrap();
    let r = calibrate(m.to_str().unwrap(), path.to_str().unwrap(), &[]);
    r.refused("huge.csv: cannot read the file: too large (67108865 bytes): an input file of this kind has at most 67108864 bytes (64 MiB): a measured file holds one row a run");
    assert!(r.stderr.len() < 400, "{} bytes of error", r.stderr.len());
    std::fs::remove_file(&path).unwrap();
}

/// A measured file `name` of `n` distinct offsets at 3000 rpm, `step` degrees apart.
fn offsets_file(name: &str, n: usize, step: f64) -> PathBuf {
    let mut csv = String::from("speed_rpm,offset_deg,velocity_mps\n");
    for i in 0..n {
        csv += &format!("3000,{},0.02\n", i as f64 * step);
    }
    let path = scratch(name);
    std::fs::write(&path, csv).unwrap();
    path
}

/// `host-sim calibrate` of the machine of test `name`, fitting restitution to
/// `measured`.
fn fit_restitution(name: &str, measured: &std::path::Path) -> std::process::Command {
    let mut cmd = common::host_sim();
    cmd.args(["calibrate"])
        .arg(uncertain_machine(name))
        .arg("--measured")
        .arg(measured)
        .args(["--fit", "contacts.*.restitution"]);
    cmd
}

/// More than 10 000 distinct points: refused before any run (each evaluation of
/// the fit would run each). The limit guards a run that would otherwise go on for
/// days; it is no timing check.
#[test]
fn too_many_points_are_refused() {
    let cmd = fit_restitution("points", &offsets_file("points.csv", 10_001, 0.01));
    let r = common::finish_within(cmd, std::time::Duration::from_secs(120));
    r.refused(
        "more than 10000 distinct (speed, offset) points (1 row beyond the first 10000 points)",
    );
}

/// Many rows at few points: the fit runs the points, its sum of squares is the
/// rows', and the outputs list the first 1000 rows and count the rest; the cost
/// is stated on stderr before the fit.
#[test]
fn many_rows_are_gathered_by_point_and_listed_in_part() {
    let m = uncertain_machine("many-rows");
    let mut noise = Normal(3);
    let mut rows = Vec::new();
    for i in 0..1005 {
        let (offset, v) = if i % 2 == 0 {
            (90, 0.025)
        } else {
            (140, 0.012)
        };
        let w = 1.0 + (i % 3) as f64;
        // As written in the file (7 decimals) and read back.
        let v: f64 = format!("{:.7}", v + SIGMA * noise.next()).parse().unwrap();
        rows.push((offset as f64, v, w));
    }
    let mut csv = String::from("speed_rpm,offset_deg,velocity_mps,weight\n");
    for (o, v, w) in &rows {
        csv += &format!("3000,{o},{v},{w}\n");
    }
    let path = scratch("many-rows.csv");
    std::fs::write(&path, csv).unwrap();
    let args = [
        "calibrate",
        m.to_str().unwrap(),
        "--measured",
        path.to_str().unwrap(),
        "--fit",
        "contacts.*.restitution",
        "--t-end",
        "3",
        "--set",
        "simulation.rtol=1e-3",
    ];
    let r = run(&[&args[..], &["--format", "json"]].concat());
    assert_eq!(r.status, 0, "{}", r.stderr);
    // Before the fit: the file's values and 6 starts, 2 searches of at most 20, 1
    // + 2 for the fit and its Jacobian, 4 at finer tolerances: at most 54
    // evaluations of the 2 points.
    assert!(
        r.stderr
            .starts_with("calibrate: up to 54 evaluations x 2 points = 108 runs of 3 s; one took "),
        "{}",
        r.stderr
    );
    let c: Value = serde_json::from_str(&r.stdout).unwrap();
    assert_eq!(c["rows"].as_array().unwrap().len(), 1000);
    assert_eq!(c["rows"][999]["line"], 1001);
    assert_eq!(c["rows_left_out"], 5);
    assert_eq!(
        (c["fit"]["n"].as_u64(), c["fit"]["points"].as_u64()),
        (Some(1005), Some(2))
    );
    // S over the rows, from each point's simulated speed: the fit's.
    let simulated = |o: f64| {
        c["points"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["offset_deg"].as_f64() == Some(o))
            .unwrap()["simulated_mps"]
            .as_f64()
            .unwrap()
    };
    let s: f64 = rows
        .iter()
        .map(|(o, v, w)| w * (simulated(*o) - v).powi(2))
        .sum();
    let ssr = c["fit"]["ssr"].as_f64().unwrap();
    assert!((s - ssr).abs() <= 1e-12 * s, "rows {s}, fit {ssr}");
    // The table says so too.
    let r = run(&args);
    assert_eq!(r.status, 0, "{}", r.stderr);
    assert!(
        r.stdout
            .contains("... and 5 more rows (the first 1000 are listed; all count in the fit)"),
        "{}",
        r.stdout
    );
}

/// From 500 distinct points on, a warning with the number of runs comes before
/// the fit (the test stops the fit once it is printed).
#[test]
fn many_points_are_warned_of_before_the_fit() {
    use std::io::BufRead;
    let mut child = fit_restitution("many-points", &offsets_file("500-points.csv", 500, 0.5))
        .args(["--t-end", "1"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let stderr = child.stderr.take().unwrap();
    let (tx, rx) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in std::io::BufReader::new(stderr)
            .lines()
            .map_while(Result::ok)
        {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    let mut seen = Vec::new();
    let found = loop {
        match rx.recv_timeout(std::time::Duration::from_secs(120)) {
            Ok(line) if line.starts_with("warning: 500 distinct points measured") => break line,
            Ok(line) => seen.push(line),
            Err(_) => break String::new(),
        }
    };
    let _ = child.kill();
    let _ = child.wait();
    assert!(
        seen.first()
            .is_some_and(|l| l
                .starts_with("calibrate: up to 54 evaluations x 500 points = 27000 runs of 1 s")),
        "{seen:?}"
    );
    assert!(
        found.contains("every evaluation of the fit runs each of them, up to 27000 runs in all"),
        "no warning; stderr: {seen:?}"
    );
}

/// A simulated run through the floor is no travel (issue 23): its rows count with
/// the residual of a run without a speed, and every output says why in its own
/// words, not as an offset not held.
#[test]
fn a_run_through_the_floor_is_no_travel() {
    let one_foot = common::root().join("tests/fixtures/one-foot-machine.toml");
    let measured = scratch("through-the-floor.csv");
    std::fs::write(
        &measured,
        "speed_rpm,offset_deg,velocity_mps\n3000,0,0.010\n3000,0,0.012\n",
    )
    .unwrap();
    let args = [
        "calibrate",
        one_foot.to_str().unwrap(),
        "--measured",
        measured.to_str().unwrap(),
        "--fit",
        "contacts.*.restitution",
        "--t-end",
        "0.5",
    ];
    let r = run(&[&args[..], &["--format", "json"]].concat());
    assert_eq!(r.status, 0, "{}", r.stderr);
    let c: Value = serde_json::from_str(&r.stdout).unwrap();
    let why = "platform went through the fundament at t = 0.053 s";
    for item in [&c["rows"][0], &c["rows"][1], &c["points"][0]] {
        assert_eq!(item["not_a_travel"], why, "{item}");
        assert!(item["not_held"].is_null(), "{item}");
        assert!(item["simulated_mps"].is_null(), "{item}");
    }
    assert_eq!(c["rows"][0]["residual_mps"], 0.1);
    let warning = format!(
        "3000 rpm 0 deg: the simulated run was no travel at the fit ({why}); its rows count with the residual 0.1 m/s from their mean"
    );
    let warnings = c["warnings"].as_array().unwrap();
    assert!(
        warnings.iter().any(|w| *w == warning.as_str()),
        "{warnings:#?}"
    );
    assert!(
        !warnings
            .iter()
            .any(|w| w.as_str().unwrap().contains("did not hold its offset")),
        "{warnings:#?}"
    );
    let r = run(&args);
    assert_eq!(r.status, 0, "{}", r.stderr);
    assert!(r.stdout.contains("no travel"), "{}", r.stdout);
    assert!(!r.stdout.contains("not held"), "{}", r.stdout);
}

/// A machine file that cannot be written does not throw the fit away (issue 23):
/// the result is printed, then the error (Linux's `/dev/full`).
#[cfg(target_os = "linux")]
#[test]
fn a_file_that_cannot_be_written_still_prints_the_fit() {
    let m = uncertain_machine("full");
    let measured = scratch("full.csv");
    std::fs::write(
        &measured,
        "speed_rpm,offset_deg,velocity_mps\n3000,90,0.030\n3000,90,0.031\n",
    )
    .unwrap();
    let r = run(&[
        "calibrate",
        m.to_str().unwrap(),
        "--measured",
        measured.to_str().unwrap(),
        "--fit",
        "contacts.*.restitution",
        "--t-end",
        "3",
        "--set",
        "simulation.rtol=1e-3",
        "--write",
        "/dev/full",
    ]);
    r.printed_then_full("--write", "contacts.*.restitution");
    assert!(r.stdout.starts_with("calibrate "), "{}", r.stdout);
}
