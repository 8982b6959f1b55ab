//! `--animate FILE.html` of `host-sim run` and `host-sim scenario` through the real
//! binary: the page is written whole, self-contained and byte-identical for the same
//! run; its frames are the trace's rows (to the page's rounding) every 2 ms with
//! every impact; a 60 s run stays under the documented size; a refused run writes
//! nothing.

use std::path::{Path, PathBuf};

use serde_json::Value;

mod common;
use common::{root, run, run_machine};

fn scratch(name: &str) -> PathBuf {
    common::scratch("cli-animate", name)
}

/// The documented bound on the page of a 60 s run of the reference machine
/// (docs/cli-run.md, "--animate"), bytes.
const SIZE_60_S: u64 = 5_000_000;

/// Simulated time between frames, s (docs/cli-run.md).
const FRAME_STEP: f64 = 2e-3;

/// The reference machine travelling right for `t_end` s at rtol 1e-3 (fast),
/// writing the animation to `page` and the trace and events when given.
fn travel(t_end: &str, page: &Path, trace: Option<(&Path, &Path)>) -> common::Run {
    let mut args = vec![
        "--command",
        "right",
        "--t-end",
        t_end,
        "--set",
        "simulation.rtol=1e-3",
        "--animate",
        page.to_str().unwrap(),
    ];
    if let Some((out, events)) = trace {
        args.extend(["--out", out.to_str().unwrap()]);
        args.extend(["--events", events.to_str().unwrap()]);
    }
    run_machine("run", &args)
}

/// The JSON the page embeds (`<script type="application/json" id="data">`).
fn embedded(page: &str) -> Value {
    let open = r#"<script type="application/json" id="data">"#;
    let start = page.find(open).expect("the data element") + open.len();
    let end = start + page[start..].find("</script>").expect("its end");
    serde_json::from_str(&page[start..end]).expect("the data is JSON")
}

/// Column `name` of the page's data as numbers (`null` as NaN).
fn column(data: &Value, name: &str) -> Vec<f64> {
    data["columns"][name]
        .as_array()
        .unwrap_or_else(|| panic!("no column {name}"))
        .iter()
        .map(|v| v.as_f64().unwrap_or(f64::NAN))
        .collect()
}

/// A CSV file as its header's names and its rows of numbers.
fn read_csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines.next().unwrap().split(',').map(String::from).collect();
    let rows = lines
        .map(|l| l.split(',').map(String::from).collect())
        .collect();
    (header, rows)
}

#[test]
fn the_page_is_self_contained_deterministic_and_holds_the_trace() {
    let (a, b) = (scratch("a.html"), scratch("b.html"));
    let (out, events) = (scratch("a.csv"), scratch("a-events.csv"));
    let r = travel("1", &a, Some((&out, &events)));
    assert_eq!(r.status, 0, "{}", r.stderr);
    let r = travel("1", &b, None);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let page = std::fs::read_to_string(&a).unwrap();
    assert_eq!(
        page.as_bytes(),
        std::fs::read(&b).unwrap(),
        "the same run, another page"
    );

    // Self-contained: nothing to fetch, no external script, style or font.
    for needle in [
        "http://", "https://", "src=", "@import", "<link", "url(", "//cdn",
    ] {
        assert!(!page.contains(needle), "the page has {needle:?}");
    }
    assert!(page.contains("<canvas id=\"scene\"") && page.contains("window.vibro"));

    // The frames: the trace's rows every 2 ms (the 1 ms output step's every
    // second row), the run's end included.
    let data = embedded(&page);
    let t = column(&data, "t");
    assert_eq!(data["frames"].as_u64(), Some(t.len() as u64));
    assert_eq!(t.len(), 501, "1 s / 2 ms + the frame at 0");
    for (k, tk) in t.iter().enumerate() {
        // Rounded to 1 us in the page: within half of it of k * 2 ms.
        assert!(
            (tk - k as f64 * FRAME_STEP).abs() <= 0.5e-6,
            "frame {k} at {tk}"
        );
    }

    // At a few frames, the pose, eccentric angles and contact forces are the
    // trace's row at that time, to the page's rounding: half a unit of the last
    // decimal kept (1e-9 m and rad, 1e-4 rad, 1e-3 N; docs/cli-run.md), with a
    // relative 1e-12 for the decimal reading of both files.
    let (header, rows) = read_csv(&out);
    let at = |name: &str| header.iter().position(|h| h == name).unwrap();
    let checks: [(&str, f64, bool); 9] = [
        ("x", 0.5e-9, false),
        ("y", 0.5e-9, false),
        ("angle", 0.5e-9, false),
        ("phi1", 0.5e-4, true),
        ("phi2", 0.5e-4, true),
        ("fn_K1", 0.5e-3, false),
        ("ft_K1", 0.5e-3, false),
        ("fn_K2", 0.5e-3, false),
        ("ft_K2", 0.5e-3, false),
    ];
    for k in [0, 125, 250, 333, 500] {
        let row = rows
            .iter()
            .find(|r| (r[0].parse::<f64>().unwrap() - t[k]).abs() <= 0.5e-6)
            .unwrap_or_else(|| panic!("no trace row at {}", t[k]));
        for (name, half_unit, angle) in checks {
            let trace: f64 = row[at(name)].parse().unwrap();
            let shown = column(&data, name)[k];
            let mut d = if angle {
                trace.rem_euclid(std::f64::consts::TAU) - shown
            } else {
                trace - shown
            };
            if angle {
                // Circular: 2 pi - 1e-5 rounds to 0 as well as to 6.2832.
                d -= std::f64::consts::TAU * (d / std::f64::consts::TAU).round();
            }
            assert!(
                d.abs() <= half_unit + 1e-12 * trace.abs(),
                "t = {}: {name} {trace} in the trace, {shown} in the page",
                t[k]
            );
        }
    }

    // Every impact of the events file, in order, with its contact.
    let (header, rows) = read_csv(&events);
    let (kind, contact) = (
        header.iter().position(|h| h == "kind").unwrap(),
        header.iter().position(|h| h == "contact").unwrap(),
    );
    let impacts: Vec<(f64, f64)> = rows
        .iter()
        .filter(|r| r[kind] == "impact")
        .map(|r| {
            let c = if r[contact] == "K1" { 0.0 } else { 1.0 };
            (r[0].parse().unwrap(), c)
        })
        .collect();
    assert!(
        impacts.len() > 10,
        "the run hops: {} impacts",
        impacts.len()
    );
    let (it, ic) = (
        data["events"]["impacts"]["t"].as_array().unwrap(),
        data["events"]["impacts"]["contact"].as_array().unwrap(),
    );
    assert_eq!(it.len(), impacts.len());
    for ((t, c), (want_t, want_c)) in it.iter().zip(ic).zip(&impacts) {
        assert!((t.as_f64().unwrap() - want_t).abs() <= 0.5e-6);
        assert_eq!(c.as_f64(), Some(*want_c));
    }
}

#[test]
fn a_60_s_run_stays_under_the_documented_size() {
    let page = scratch("sixty.html");
    let r = travel("60", &page, None);
    assert_eq!(r.status, 0, "{}", r.stderr);
    let size = std::fs::metadata(&page).unwrap().len();
    assert!(
        size < SIZE_60_S,
        "{size} bytes for 60 s, documented: under {SIZE_60_S}"
    );
    let data = embedded(&std::fs::read_to_string(&page).unwrap());
    assert_eq!(data["frames"].as_u64(), Some(30_001));
}

/// The reference machine open loop at 12 V for `t_end` s with `extra` options.
fn open_loop(t_end: &str, extra: &[&str]) -> common::Run {
    let mut args = vec!["--open-loop", "12,12", "--t-end", t_end];
    args.extend_from_slice(extra);
    run_machine("run", &args)
}

#[test]
fn a_refused_run_writes_nothing() {
    // Too long for an animation: refused before the run, naming the limit.
    let (page, out) = (scratch("long.html"), scratch("long.csv"));
    let (page_arg, out_arg) = (page.to_str().unwrap(), out.to_str().unwrap());
    let r = open_loop("601", &["--animate", page_arg, "--out", out_arg]);
    r.refused("error: --animate: --t-end 601: an animation holds at most 600 s");
    assert!(!page.exists() && !out.exists());

    // A bad option: nothing written.
    let r = open_loop("0.1", &["--speed", "3000", "--animate", page_arg]);
    r.refused("--speed and --offset go with --command");
    assert!(!page.exists());

    // An animation that cannot be written: the other outputs are not written
    // either.
    let dir = scratch("a-directory.html");
    std::fs::create_dir_all(&dir).unwrap();
    let r = open_loop(
        "0.1",
        &["--out", out_arg, "--animate", dir.to_str().unwrap()],
    );
    r.refused("is a directory");
    assert!(!out.exists());
}

/// `host-sim scenario file --animate page`.
fn animate_scenario(file: &Path, page: &Path) -> common::Run {
    let [file, page] = [file, page].map(|p| p.to_str().unwrap());
    run(&["scenario", file, "--animate", page])
}

#[test]
fn scenario_animate_writes_the_scenario_run() {
    // The shortest shipped scenario (2.5 s): an over-current fault at 2 s.
    let file = root().join("tests/scenarios/current-offset.toml");
    let page = scratch("scenario.html");
    let r = animate_scenario(&file, &page);
    assert_eq!(r.status, 0, "{}{}", r.stdout, r.stderr);
    let text = std::fs::read_to_string(&page).unwrap();
    assert!(!text.contains("http://") && !text.contains("https://"));
    let data = embedded(&text);
    assert_eq!(data["frames"].as_u64(), Some(1251), "2.5 s / 2 ms + 1");
    // The controller's events are there: the fault it latched.
    let controller = data["events"]["controller"].as_array().unwrap();
    assert!(
        controller
            .iter()
            .any(|e| e[1] == "fault" && e[2] == "over_current"),
        "{controller:?}"
    );

    // A scenario too long to animate is refused, nothing written.
    let long = scratch("long-scenario.toml");
    let body = std::fs::read_to_string(&file)
        .unwrap()
        .replace("t_end = 2.5", "t_end = 700")
        .replace(
            "../../examples/vibro-driver.toml",
            common::machine().to_str().unwrap(),
        );
    assert!(body.contains("t_end = 700"), "the scenario's t_end is 2.5");
    std::fs::write(&long, body).unwrap();
    let page = scratch("long-scenario.html");
    let r = animate_scenario(&long, &page);
    r.refused("an animation holds at most 600 s");
    assert!(!page.exists());
}
