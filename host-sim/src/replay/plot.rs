//! The replay's plot: speeds, phase offset, currents and duties against time,
//! recorded (solid) and simulated (dashed) in the same panel, rotor 1 blue,
//! rotor 2 orange.

use std::fmt::Write;

use crate::output::svg::{escape, nice_step, open_document, tick_label, ticks, value_grid_line};

use super::residual::Sample;
use super::Replay;

const WIDTH: f64 = 900.0;
const PANEL: f64 = 170.0;
const GAP: f64 = 40.0;
const LEFT: f64 = 80.0;
const RIGHT: f64 = 20.0;
const TOP: f64 = 50.0;
const COLOURS: [&str; 2] = ["#1f77b4", "#ff7f0e"];

/// One line: its rotor (index), dashed (simulated), its (t, value) points.
type Series = (usize, bool, Vec<(f64, f64)>);

/// One panel: its title and its lines.
struct Panel {
    title: &'static str,
    series: Vec<Series>,
}

fn points(
    samples: &[Sample],
    tick_s: f64,
    value: impl Fn(&Sample) -> Option<f64>,
) -> Vec<(f64, f64)> {
    samples
        .iter()
        .enumerate()
        .filter_map(|(k, s)| {
            value(s)
                .filter(|v| v.is_finite())
                .map(|v| (k as f64 * tick_s, v))
        })
        .collect()
}

fn panels(r: &Replay, rotors: usize) -> Vec<Panel> {
    let both = |title, f: &dyn Fn(&Sample, usize) -> Option<f64>| {
        let mut series = Vec::new();
        for k in 0..rotors {
            series.push((k, false, points(&r.recorded, r.tick_s, |s| f(s, k))));
            series.push((k, true, points(&r.simulated, r.tick_s, |s| f(s, k))));
        }
        Panel { title, series }
    };
    let mut out = vec![both("rotor speed, rpm", &|s, k| Some(s.speed_rpm[k]))];
    if rotors == 2 {
        out.push(Panel {
            title: "phase offset, deg",
            series: vec![
                (0, false, points(&r.recorded, r.tick_s, |s| s.phase_deg)),
                (0, true, points(&r.simulated, r.tick_s, |s| s.phase_deg)),
            ],
        });
    }
    out.push(both("winding current, A", &|s, k| Some(s.current_a[k])));
    out.push(both("duty", &|s, k| Some(s.duty[k])));
    out
}

/// The SVG document.
pub fn svg(r: &Replay, title: &str) -> String {
    let rotors = r
        .residuals
        .iter()
        .filter_map(|x| x.rotor)
        .max()
        .unwrap_or(1);
    let panels = panels(r, rotors);
    let height = TOP + panels.len() as f64 * (PANEL + GAP) + 20.0;
    let mut svg = String::new();
    open_document(&mut svg, WIDTH, height, title, LEFT, 28.0);
    let _ = writeln!(
        svg,
        r#"<text x="{}" y="44" font-size="12" text-anchor="end">solid: recorded on the board; dashed: the twin; rotor 1 blue, rotor 2 orange</text>"#,
        WIDTH - RIGHT
    );
    let t_end = (r.ticks as f64 * r.tick_s).max(r.tick_s);
    for (i, p) in panels.iter().enumerate() {
        let top = TOP + i as f64 * (PANEL + GAP) + 20.0;
        draw(&mut svg, p, top, t_end, i + 1 == panels.len());
    }
    svg.push_str("</svg>\n");
    svg
}

fn draw(svg: &mut String, p: &Panel, top: f64, t_end: f64, last: bool) {
    let (left, right) = (LEFT, WIDTH - RIGHT);
    let all = p
        .series
        .iter()
        .flat_map(|(_, _, pts)| pts.iter().map(|(_, v)| *v));
    let (mut lo, mut hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() {
        (lo, hi) = (0.0, 1.0);
    }
    if hi - lo < 1e-9 {
        (lo, hi) = (lo - 0.5, hi + 0.5);
    }
    let step = nice_step(hi - lo, 4.0);
    lo = (lo / step).floor() * step;
    hi = (hi / step).ceil() * step;
    let y = |v: f64| top + PANEL * (1.0 - (v - lo) / (hi - lo));
    let x = |t: f64| left + (right - left) * t / t_end;
    let _ = writeln!(
        svg,
        r#"<text x="{left}" y="{:.1}" font-size="13" font-weight="bold">{}</text>"#,
        top - 6.0,
        escape(p.title)
    );
    for v in ticks(lo, hi, step) {
        value_grid_line(svg, (left, right), y(v), "#ddd", &tick_label(v, step));
    }
    let t_step = nice_step(t_end, 8.0);
    for t in ticks(0.0, t_end, t_step) {
        let _ = writeln!(
            svg,
            r##"<line x1="{0:.1}" y1="{top:.1}" x2="{0:.1}" y2="{1:.1}" stroke="#eee"/>"##,
            x(t),
            top + PANEL
        );
        if last {
            let _ = writeln!(
                svg,
                r#"<text x="{:.1}" y="{:.1}" font-size="11" text-anchor="middle">{}</text>"#,
                x(t),
                top + PANEL + 16.0,
                tick_label(t, t_step)
            );
        }
    }
    if last {
        let _ = writeln!(
            svg,
            r#"<text x="{:.1}" y="{:.1}" font-size="12" text-anchor="middle">t, s (from the capture's first tick)</text>"#,
            (left + right) / 2.0,
            top + PANEL + 32.0
        );
    }
    for (rotor, dashed, pts) in &p.series {
        if pts.is_empty() {
            continue;
        }
        // At most two points a pixel column: the plot stays small.
        let every = (pts.len() / (2 * (right - left) as usize)).max(1);
        let path: Vec<String> = pts
            .iter()
            .step_by(every)
            .map(|(t, v)| format!("{:.1},{:.1}", x(*t), y(*v)))
            .collect();
        let _ = writeln!(
            svg,
            r#"<polyline fill="none" stroke="{}" stroke-width="1.3"{} points="{}"/>"#,
            COLOURS[*rotor % 2],
            if *dashed {
                r#" stroke-dasharray="5,3""#
            } else {
                ""
            },
            path.join(" ")
        );
    }
}
