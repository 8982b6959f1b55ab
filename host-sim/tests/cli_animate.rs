//! `--animate FILE.html` of `host-sim run` and `host-sim scenario` through the real
//! binary: the page is written whole, self-contained and byte-identical for the same
//! run; its frames are the trace's rows (to the page's rounding) every 2 ms with
//! every impact; a 60 s run stays under the documented size; a refused run writes
//! nothing. In a headless chromium (`browser`): no console error, the clock
//! advancing by the rate while playing and standing when paused, the slider
//! showing the traced pose (at frames, an impact, between frames) and moving the
//! drawing, the fragment's settings; screenshots in `target/browser/animation-*.png`.

use std::path::{Path, PathBuf};
use std::time::Duration;

use serde_json::{json, Value};

mod browser;
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
/// writing the animation to `page` and the trace and events when given. The
/// machine file is named from the repository root, as the page's title shows it.
fn travel(t_end: &str, page: &Path, trace: Option<(&Path, &Path)>) -> common::Run {
    let mut extra = Vec::new();
    if let Some((out, events)) = trace {
        extra.extend(["--out", out.to_str().unwrap()]);
        extra.extend(["--events", events.to_str().unwrap()]);
    }
    travel_with(t_end, page, &extra)
}

/// [`travel`] with the options `extra`.
fn travel_with(t_end: &str, page: &Path, extra: &[&str]) -> common::Run {
    let mut args = vec![
        "run",
        "examples/vibro-driver.toml",
        "--command",
        "right",
        "--t-end",
        t_end,
        "--set",
        "simulation.rtol=1e-3",
        "--animate",
        page.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    run(&args)
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

    // The outline drawn is the one the fundament check follows
    // (`host_sim::plant::outline`): the convex hull of the feet and the
    // eccentric circles, not a box.
    let data = embedded(&page);
    let machine = host_sim::machine::Machine::load(&root().join("examples/vibro-driver.toml"), &[])
        .expect("the reference machine");
    let polygon = &host_sim::plant::outline::outlines(&machine)[0].polygon;
    assert_eq!(data["scene"]["bodies"][0]["outline"], json!(polygon));
    assert!(polygon.len() > 4, "{polygon:?}");

    // The frames: the trace's rows every 2 ms (the 1 ms output step's every
    // second row), the run's end included.
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
    r.refused(&format!(
        "error: --animate: cannot write {}: is a directory",
        dir.display()
    ));
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

// --- in a real browser ---------------------------------------------------------

/// The platform's pose columns of the trace, with their rates (for the bound on
/// interpolating between frames).
const POSE: [(&str, &str); 3] = [("x", "vx"), ("y", "vy"), ("angle", "omega")];

/// The trace as rows of numbers, with the index of each column name.
struct Trace {
    header: Vec<String>,
    rows: Vec<Vec<f64>>,
}

impl Trace {
    fn read(path: &Path) -> Trace {
        let (header, rows) = read_csv(path);
        let rows = rows
            .iter()
            .map(|r| r.iter().map(|v| v.parse().unwrap()).collect())
            .collect();
        Trace { header, rows }
    }

    fn col(&self, name: &str) -> usize {
        self.header.iter().position(|h| h == name).unwrap()
    }

    /// The first row at or after `t`, with the page's nanosecond of slack (the
    /// row of the frame at `t` when `t` is a multiple of 2 ms): a row at `t`.
    fn at(&self, t: f64) -> &[f64] {
        let row = self
            .rows
            .iter()
            .find(|r| r[0] >= t - 1e-9)
            .unwrap_or_else(|| panic!("no trace row after {t}"));
        assert!(
            (row[0] - t).abs() <= 1e-9,
            "no trace row at {t}: {}",
            row[0]
        );
        row
    }

    /// The time of the highest hop (the largest |y - y(0)|) within 50 ms of
    /// `around`, among the rows at whole milliseconds: even ones (a frame's time)
    /// when `frame`, else odd ones (halfway between two frames).
    fn hop_top(&self, around: f64, frame: bool) -> f64 {
        let y = self.col("y");
        let y0 = self.rows[0][y];
        let ms = self
            .rows
            .iter()
            .filter(|r| (r[0] - around).abs() <= 0.05)
            .filter(|r| {
                let ms = r[0] * 1e3;
                (ms - ms.round()).abs() < 1e-6 && (ms.round() as i64 % 2 == 0) == frame
            })
            .max_by(|p, q| (p[y] - y0).abs().total_cmp(&(q[y] - y0).abs()))
            .map(|r| (r[0] * 1e3).round())
            .unwrap_or_else(|| panic!("no rows near {around} s"));
        ms / 1e3
    }

    /// The largest |value| of column `name` over the run.
    fn max_abs(&self, name: &str) -> f64 {
        let c = self.col(name);
        self.rows.iter().map(|r| r[c].abs()).fold(0.0, f64::max)
    }
}

/// The canvas `id`'s pixels as a data URL (to compare two drawings).
fn canvas(id: &str) -> String {
    format!("document.getElementById('{id}').toDataURL()")
}

/// Move the time slider to `t` as a user does: its value set, an `input` event.
fn slide(b: &mut browser::Browser, t: f64) {
    b.eval(&format!(
        "(() => {{ const s = document.getElementById('time'); s.value = '{t}';
          s.dispatchEvent(new Event('input', {{ bubbles: true }})); }})()"
    ));
}

/// A screenshot `name` in the browser tests' folder.
fn shoot(b: &mut browser::Browser, name: &str) {
    let png = browser::output_dir().join(name);
    b.screenshot(&png);
    let bytes = std::fs::read(&png).unwrap();
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "not a PNG");
}

#[test]
fn the_page_in_a_browser_plays_and_its_slider_shows_the_traced_pose() {
    let Some(mut b) = browser::Browser::launch() else {
        return;
    };
    let (page, out, events) = (
        scratch("browser.html"),
        scratch("browser.csv"),
        scratch("browser-events.csv"),
    );
    let r = travel("3", &page, Some((&out, &events)));
    assert_eq!(r.status, 0, "{}", r.stderr);
    let trace = Trace::read(&out);
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    b.navigate(&url);
    b.wait_for("window.vibro !== undefined", Duration::from_secs(10));
    assert_eq!(b.console_errors(), Vec::<String>::new(), "after loading");

    // The run's span: frames every 2 ms from the first row to the last.
    let (t0, t1) = (trace.rows[0][0], trace.rows.last().unwrap()[0]);
    let duration = b.eval("vibro.duration").as_f64().unwrap();
    assert!((duration - t1).abs() <= 0.5e-6, "{duration} s, traced {t1}");
    let frames = ((t1 - t0) / FRAME_STEP + 1e-9).floor() as u64 + 1;
    assert_eq!(b.eval("vibro.frames").as_u64(), Some(frames));

    // Playing advances the clock by the rate times the wall-clock time. A probe
    // counts the animation frames: the player moves the time at each by the wall
    // time since the one before, so what it can miss is the time from play to
    // its first frame and from its last to the reading, each at most the
    // largest gap G between frames the probe saw (play and reading included).
    let probe = "(() => { const g = window.probe = { max: 0, n: 0, last: performance.now() };
        (function f(ts) { g.max = Math.max(g.max, ts - g.last); g.last = ts; g.n++;
          if (!g.stop) requestAnimationFrame(f); })(g.last); })()";
    b.eval(probe);
    // The play button clicked in the same script as the clock is read.
    let before = b.eval(
        "(() => { const read = [performance.now(), vibro.t()];
           document.getElementById('play').click(); return read; })()",
    );
    assert_eq!(b.eval("vibro.playing()"), json!(true));
    std::thread::sleep(Duration::from_secs(1));
    let after = b.eval(
        "(() => { probe.stop = true;
           const now = performance.now();
           return [now, vibro.t(), Math.max(probe.max, now - probe.last), probe.n]; })()",
    );
    b.click("#play");
    assert_eq!(b.eval("vibro.playing()"), json!(false));
    let rate = b.eval("vibro.rate()").as_f64().unwrap();
    assert_eq!(
        b.eval("Number(document.getElementById('rate').value)")
            .as_f64(),
        Some(rate),
        "the rate shown"
    );
    let f = |v: &Value, k: usize| v[k].as_f64().unwrap();
    let wall = (f(&after, 0) - f(&before, 0)) / 1e3;
    let gap = f(&after, 2) / 1e3;
    let advanced = f(&after, 1) - f(&before, 1);
    assert!(advanced > 0.0, "the clock stood while playing");
    assert!(
        (advanced - rate * wall).abs() <= rate * 2.0 * gap,
        "{advanced} s in {wall} s at rate {rate}; frames up to {gap} s apart ({} frames)",
        after[3]
    );
    // Paused, the clock stands.
    let paused = b.eval("vibro.t()");
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(b.eval("vibro.t()"), paused, "the clock moved while paused");

    // The slider shows the traced pose, at the top of a hop (the platform aloft,
    // pitched) near 0.75, 1.25 and 2.25 s, at an impact, and at a hop's top
    // halfway between two frames near 2.75 s. At a frame's time (a multiple of
    // 2 ms): that frame, the trace's row to the page's rounding (half of 1e-9 m
    // or rad, relative 1e-12 for reading both files' decimals). Between frames:
    // the trace's two frames interpolated, to the same rounding; and the trace's
    // own row at that time within what linear interpolation over a frame can
    // miss, |f(t) - L(t)| <= 2 V min(t - a, b - t) for f of slope at most V
    // between frames a and b, V the run's largest rate of that coordinate in the
    // trace (its rows every 1 ms and at every event).
    let (header, rows) = read_csv(&events);
    let kind = header.iter().position(|h| h == "kind").unwrap();
    let impact: f64 = rows
        .iter()
        .filter(|r| r[kind] == "impact")
        .map(|r| r[0].parse().unwrap())
        .find(|&t: &f64| t > 1.6)
        .expect("an impact after 1.6 s");
    let mut drawn = Vec::new();
    let times = [
        trace.hop_top(0.75, true),
        trace.hop_top(1.25, true),
        impact,
        trace.hop_top(2.25, true),
        trace.hop_top(2.75, false),
    ];
    for t in times {
        slide(&mut b, t);
        // Chromium's range input keeps 15 significant digits of its value.
        let now = b.eval("vibro.t()").as_f64().unwrap();
        assert!((now - t).abs() <= 1e-14 * t, "the slider at {t}: {now}");
        let pose = b.eval("vibro.pose()");
        // The frames either side: a = the last multiple of 2 ms at or before t.
        let k = (t / FRAME_STEP + 1e-9).floor();
        let (a, b_) = (k * FRAME_STEP, (k + 1.0) * FRAME_STEP);
        let s = (t - a) / FRAME_STEP;
        for (name, rate) in POSE {
            let c = trace.col(name);
            let shown = pose[name].as_f64().unwrap();
            let (fa, fb) = (trace.at(a)[c], trace.at(b_)[c]);
            let framed = if s < 1e-9 { fa } else { fa + (fb - fa) * s };
            assert!(
                (shown - framed).abs() <= 0.5e-9 + 1e-12 * framed.abs(),
                "t = {t}: {name} {shown} shown, {framed} from the trace's frames"
            );
            let traced = trace.at(t)[c];
            let miss = 2.0 * trace.max_abs(rate) * (t - a).min(b_ - t);
            assert!(
                (shown - traced).abs() <= miss + 0.5e-9 + 1e-12 * traced.abs(),
                "t = {t}: {name} {shown} shown, {traced} traced (interpolation: {miss})"
            );
        }
        drawn.push(b.eval(&canvas("scene")));
    }
    // The picture moves with the slider, not only the numbers.
    for w in drawn.windows(2) {
        assert_ne!(w[0], w[1], "the scene did not change");
    }

    // Screenshots at a few times, magnified (the page's first choice, on the
    // scene and in its menu).
    let mag = b.eval("vibro.magnification()").as_f64().unwrap();
    assert!(mag > 1.0, "magnification {mag}");
    assert_eq!(
        b.eval("Number(document.getElementById('mag').value)")
            .as_f64(),
        Some(mag)
    );
    for t in [0.75, 1.5] {
        slide(&mut b, t);
        shoot(&mut b, &format!("animation-t{t}.png"));
    }
    // The address's fragment sets the start: reopened with one, the page shows
    // that time, magnification, rate and span of the traces.
    b.navigate("about:blank");
    b.navigate(&format!("{url}#t=2.514&mag=100&rate=0.1&span=0.1"));
    let settings = b.eval(
        "[vibro.t(), vibro.magnification(), vibro.rate(),
          Number(document.getElementById('span').value)]",
    );
    assert_eq!(settings, json!([2.514, 100, 0.1, 0.1]));
    shoot(&mut b, "animation-t2.514.png");
    assert_eq!(b.console_errors(), Vec::<String>::new());
}

/// The reference machine travelling right for 3 s at rtol 1e-3, writing the
/// animation to `page` and the events to `events`: its JSON summary.
fn travel_with_summary(page: &Path, events: &Path) -> Value {
    let events = events.to_str().unwrap();
    let r = travel_with("3", page, &["--events", events, "--format", "json"]);
    assert_eq!(r.status, 0, "{}", r.stderr);
    serde_json::from_str(&r.stdout).expect("the summary")
}

/// Issue 23: the page counted 14 112 impacts (one per foot at each impact) where
/// the summary counted 9 402 (one per instant). Its data now carries the
/// summary's count at every impact; the impulses at each foot are the events'.
#[test]
fn the_page_counts_impacts_as_the_summary_does() {
    let (page, events) = (scratch("count.html"), scratch("count-events.csv"));
    let summary = travel_with_summary(&page, &events);
    let data = embedded(&std::fs::read_to_string(&page).unwrap());
    let instants: Vec<u64> = data["events"]["impacts"]["instant"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    let (header, rows) = read_csv(&events);
    let kind = header.iter().position(|h| h == "kind").unwrap();
    let rows: Vec<&Vec<String>> = rows.iter().filter(|r| r[kind] == "impact").collect();
    // One entry per impulse at a foot; the last carries the summary's count,
    // fewer: the feet of one instant count once.
    assert_eq!(instants.len(), rows.len());
    assert_eq!(instants.last().copied(), summary["impacts"].as_u64());
    assert!(
        instants.len() as u64 > instants[instants.len() - 1],
        "{}",
        instants.len()
    );
    // Counted by the events' exact times: a new instant where the time changes.
    for (k, w) in rows.windows(2).enumerate() {
        let new = u64::from(w[1][0] != w[0][0]);
        assert_eq!(instants[k + 1], instants[k] + new, "impact {}", k + 1);
    }
}

#[test]
fn the_page_in_a_browser_shows_the_summary_count_and_true_shapes_magnified() {
    let Some(mut b) = browser::Browser::launch() else {
        return;
    };
    let (page, events) = (scratch("mag.html"), scratch("mag-events.csv"));
    let summary = travel_with_summary(&page, &events);
    let data = embedded(&std::fs::read_to_string(&page).unwrap());
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    b.navigate(&url);
    b.wait_for("window.vibro !== undefined", Duration::from_secs(10));
    assert_eq!(b.console_errors(), Vec::<String>::new(), "after loading");

    // At the end: the summary's impacts, and the events' impulses by foot.
    b.eval("vibro.seek(vibro.duration)");
    let (header, rows) = read_csv(&events);
    let (kind, contact) = (
        header.iter().position(|h| h == "kind").unwrap(),
        header.iter().position(|h| h == "contact").unwrap(),
    );
    let by_foot = |name: &str| {
        rows.iter()
            .filter(|r| r[kind] == "impact" && r[contact] == name)
            .count()
    };
    assert_eq!(
        b.eval("vibro.impacts()"),
        json!({"instants": summary["impacts"], "impulses": {"K1": by_foot("K1"), "K2": by_foot("K2")}})
    );
    let note = b.eval("document.getElementById('note').textContent");
    let said = format!(
        "; {} impacts (instants, as the run's summary counts them)",
        summary["impacts"]
    );
    assert!(note.as_str().unwrap().contains(&said), "{note}");

    // Each magnification's largest change of a drawn shape's size, from the
    // page's own frames: |A| - 1 with A = 1 - M + M e^(i (angle - angle_0)); the
    // ones beyond 5 % not offered (disabled in the menu).
    let angle = column(&data, "angle");
    let mags = b.eval("vibro.magnifications()");
    let mags = mags.as_array().unwrap();
    assert_eq!(mags.len(), 7);
    let mut largest = 1.0;
    for (k, g) in mags.iter().enumerate() {
        let m = g["mag"].as_f64().unwrap();
        let err = angle
            .iter()
            .map(|a| {
                let d = a - angle[0];
                ((1.0 - m + m * d.cos()).hypot(m * d.sin()) - 1.0).abs()
            })
            .fold(0.0, f64::max);
        let shown = g["size_error"].as_f64().unwrap();
        assert!((shown - err).abs() <= 1e-12, "x{m}: {shown} vs {err}");
        let offered = err <= 0.05;
        assert_eq!(g["offered"], json!(offered), "x{m}: {err}");
        let disabled = b.eval(&format!(
            "document.getElementById('mag').options[{k}].disabled"
        ));
        assert_eq!(disabled, json!(!offered), "x{m}");
        if offered {
            largest = m;
        }
    }
    // This run's pitch (some 0.03 degrees) puts x1000 beyond 5 % and x300
    // within it.
    assert_eq!(largest, 300.0, "{mags:?}");
    // The fragment cannot ask for one not offered: the page keeps its choice.
    b.navigate("about:blank");
    b.navigate(&format!("{url}#mag=1000"));
    let first = b.eval("vibro.magnification()").as_f64().unwrap();
    assert!((1.0..1000.0).contains(&first), "{first}");
    b.navigate("about:blank");
    b.navigate(&format!("{url}#mag=300"));
    assert_eq!(b.eval("vibro.magnification()"), json!(300));

    // Magnified x300, every point's displacement from its start (the travel
    // taken out) is multiplied: a foot on the floor is drawn on it, a foot in
    // the air 300 times as high as it is. Its true height from the page's frame:
    // y + R(angle) p along the normal (the floor y = 0), p = [+-0.08, -0.03] from
    // the centre of mass.
    let (t, y, fns) = (
        column(&data, "t"),
        column(&data, "y"),
        [column(&data, "fn_K1"), column(&data, "fn_K2")],
    );
    let foot = [[-0.08, -0.03], [0.08, -0.03]];
    let (mut on, mut off) = (0, 0);
    for i in (t.len() / 2..t.len()).step_by(7) {
        b.eval(&format!("vibro.seek({})", t[i]));
        let drawn = b.eval("vibro.feet()");
        for (c, p) in foot.iter().enumerate() {
            let (s, co) = angle[i].sin_cos();
            let h = y[i] + s * p[0] + co * p[1];
            let shown = drawn[c]["h"].as_f64().unwrap();
            // The page's rounding (1e-9 m and rad) magnified.
            let slack = 300.0 * 1.5e-9;
            if fns[c][i] > 0.5 {
                assert!(
                    shown.abs() <= slack,
                    "t = {}: {} on the floor drawn {shown} m up",
                    t[i],
                    c
                );
                on += 1;
            } else if h > 2e-6 {
                assert!(
                    (shown - 300.0 * h).abs() <= slack,
                    "t = {}: foot {c} {h} m up drawn {shown}",
                    t[i]
                );
                off += 1;
            }
        }
    }
    assert!(
        on > 20 && off > 20,
        "feet on the floor {on}, in the air {off}"
    );
    shoot(&mut b, "animation-x300.png");

    // The floor's ticks: numbered in true mm at x1 only; magnified, their true
    // spacing drawn M times as far apart (the legend says so).
    let ticks = b.eval("vibro.ticks()");
    assert_eq!(ticks["numbered"], json!(false));
    let (step, apart) = (
        ticks["step"].as_f64().unwrap(),
        ticks["apart"].as_f64().unwrap(),
    );
    assert!((apart - 300.0 * step).abs() <= 1e-12 * apart, "{ticks}");
    b.eval(
        "(() => { const m = document.getElementById('mag'); m.value = '1';
        m.dispatchEvent(new Event('change')); })()",
    );
    assert_eq!(b.eval("vibro.magnification()"), json!(1));
    assert_eq!(b.eval("vibro.ticks().numbered"), json!(true));
    // At true scale the platform's outline is drawn where the frame's pose puts
    // the scene's polygon: every vertex p at height y + R(angle) p along the
    // normal, each foot's vertex on the floor while it presses on it.
    let outline: Vec<[f64; 2]> =
        serde_json::from_value(data["scene"]["bodies"][0]["outline"].clone())
            .expect("the outline's vertices");
    for i in (0..t.len()).step_by(97) {
        b.eval(&format!("vibro.seek({})", t[i]));
        let drawn = b.eval("vibro.outlines()[0]");
        let drawn = drawn.as_array().unwrap();
        assert_eq!(drawn.len(), outline.len());
        let (s, co) = angle[i].sin_cos();
        for (v, p) in drawn.iter().zip(&outline) {
            let h = y[i] + s * p[0] + co * p[1];
            let shown = v["h"].as_f64().unwrap();
            assert!(
                (shown - h).abs() <= 1.5e-9,
                "t = {}: vertex {p:?} at {h} m drawn at {shown}",
                t[i]
            );
        }
    }
    shoot(&mut b, "animation-x1.png");
    assert_eq!(b.console_errors(), Vec::<String>::new());
}
