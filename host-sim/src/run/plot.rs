//! `host-sim run --plot`: the run as a self-contained SVG figure for people.
//!
//! Stacked panels share the time axis (labelled under the last one):
//! 1. horizontal position `x` of the platform's centre of mass, mm;
//! 2. its height `y`, mm (a panel of its own: the hops are millimetres while the
//!    travel may be metres, and on one axis they would vanish);
//! 3. its velocity `vx`, `vy`, m/s, with a tick at the foot of the panel for every
//!    impact instant and their count in the legend;
//! 4. the pitch angle, degrees;
//! 5. the rotor speeds in their driven senses, rpm;
//! 6. the phase offset `theta_1 - theta_2` (docs/machine-file.md, "Conventions"),
//!    degrees in [0, 360): a line that wraps continues from the opposite edge instead
//!    of crossing the panel.
//!
//! Every panel has a title with its legend, an axis label with the unit, and ticks
//! at "nice" values (1, 2, 2.5 or 5 times a power of ten). A line of more than
//! [`MAX_POINTS`] points is thinned to the first, lowest, highest and last point of
//! each pixel column, so peaks stay. Values that are not finite break the line and
//! are never written. Text uses the generic `sans-serif` family: nothing to load.

use std::fmt::Write as _;

use crate::event::EventRow;
use crate::machine::Machine;
use crate::output::svg::{
    escape, nice_step, open_document, tick_label, ticks, value_grid_line, PALETTE,
};
use crate::simulation::summary::{impact_times, phase_offset_deg};
use crate::simulation::trace::TraceRow;

/// Most points drawn for one line before it is thinned.
pub const MAX_POINTS: usize = 4000;

/// Figure width, px.
const WIDTH: f64 = 1100.0;
/// Left margin: tick labels and the rotated axis label.
const LEFT: f64 = 92.0;
/// Right margin.
const RIGHT: f64 = 24.0;
/// Top margin: the title and the subtitle.
const TOP: f64 = 62.0;
/// Height of a panel's head (its title and legend), above its plot area.
const HEAD: f64 = 24.0;
/// Height of a panel's plot area.
const PLOT: f64 = 128.0;
/// Space after a panel.
const GAP: f64 = 14.0;
/// Bottom margin: time tick labels and the time axis label.
const BOTTOM: f64 = 50.0;

/// Colours from the palette: first line, second line, single line, phase, impacts.
const BLUE: &str = PALETTE[0];
const ORANGE: &str = PALETTE[1];
const GREEN: &str = PALETTE[2];
const PURPLE: &str = PALETTE[4];
const RED: &str = PALETTE[3];

/// rad/s to rpm.
const RPM_PER_RAD_S: f64 = 60.0 / (2.0 * std::f64::consts::PI);

/// One line of a panel.
struct Series {
    /// Legend text.
    label: String,
    /// Stroke colour.
    color: &'static str,
    /// `(t, value)` in the panel's unit.
    points: Vec<(f64, f64)>,
    /// Dashed (`stroke-dasharray`), so that a line drawn over another shows both.
    dashed: bool,
}

/// One panel: its lines, how its value axis is scaled, and optional event marks.
struct Panel {
    /// Title above the plot area.
    title: &'static str,
    /// Value axis label, with the unit.
    axis: &'static str,
    /// The lines.
    series: Vec<Series>,
    /// A fixed value range and tick step, and the period at which values wrap.
    fixed: Option<Fixed>,
    /// Times marked by ticks at the panel's foot, with their legend text.
    marks: Option<(Vec<f64>, String)>,
}

/// A fixed value axis.
struct Fixed {
    /// Lowest and highest value.
    range: (f64, f64),
    /// Tick step.
    step: f64,
    /// Values are modulo this (a line wrapping past an edge continues at the other).
    period: f64,
}

/// A linear map from values to pixels.
#[derive(Clone, Copy)]
struct Scale {
    /// Value range.
    from: (f64, f64),
    /// Pixel range.
    to: (f64, f64),
}

impl Scale {
    /// The pixel of value `v`, clamped to a band around the figure so that an
    /// absurd value cannot write an absurdly long number.
    fn at(&self, v: f64) -> f64 {
        let (a, b) = self.from;
        let (p, q) = self.to;
        (p + (v - a) / (b - a) * (q - p)).clamp(-1e5, 1e5)
    }
}

/// The lowest and highest finite value of a panel's lines, if any.
fn extent<'a>(values: impl Iterator<Item = &'a f64>) -> Option<(f64, f64)> {
    values
        .filter(|v| v.is_finite())
        .fold(None, |acc, &v| match acc {
            None => Some((v, v)),
            Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
        })
}

/// A value axis for `(lo, hi)`: bounds widened to whole ticks, and the tick step.
/// An empty or single-valued range is widened first so that it has a span.
fn value_axis(data: Option<(f64, f64)>) -> ((f64, f64), f64) {
    let (mut lo, mut hi) = data.unwrap_or((0.0, 1.0));
    if !(hi - lo).is_finite() {
        // Beyond f64's range: nothing sensible to scale, so a unit axis.
        (lo, hi) = (0.0, 1.0);
    }
    if hi - lo <= hi.abs().max(lo.abs()) * 1e-12 {
        let half = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        (lo, hi) = (lo - half, hi + half);
    }
    let step = nice_step(hi - lo, 4.0);
    (
        (((lo / step).floor()) * step, ((hi / step).ceil()) * step),
        step,
    )
}

/// A line's points split into runs to draw: a non-finite point ends a run; with a
/// `period`, a jump of more than half of it is a wrap, and the run is carried to
/// the edge it left by and a new one starts at the opposite edge.
fn runs(points: &[(f64, f64)], period: Option<f64>) -> Vec<Vec<(f64, f64)>> {
    let mut out: Vec<Vec<(f64, f64)>> = Vec::new();
    let mut run: Vec<(f64, f64)> = Vec::new();
    for &(t, v) in points {
        if !(t.is_finite() && v.is_finite()) {
            if !run.is_empty() {
                out.push(std::mem::take(&mut run));
            }
            continue;
        }
        if let (Some(p), Some(&(t0, v0))) = (period, run.last()) {
            if (v - v0).abs() > p / 2.0 {
                // Unwrap v next to v0, find where the line crosses the edge.
                let (unwrapped, edge, other) = if v < v0 {
                    (v + p, p, 0.0)
                } else {
                    (v - p, 0.0, p)
                };
                let f = (edge - v0) / (unwrapped - v0);
                let tc = t0 + f * (t - t0);
                run.push((tc, edge));
                out.push(std::mem::take(&mut run));
                run.push((tc, other));
            }
        }
        run.push((t, v));
    }
    if !run.is_empty() {
        out.push(run);
    }
    out
}

/// A run thinned to the first, lowest, highest and last point of each of
/// `columns` equal time columns over `t_range`, in time order.
fn thin(run: &[(f64, f64)], t_range: (f64, f64), columns: usize) -> Vec<(f64, f64)> {
    let (t0, t1) = t_range;
    let column = |t: f64| (((t - t0) / (t1 - t0)) * columns as f64).floor() as i64;
    let mut out = Vec::new();
    let mut start = 0;
    while start < run.len() {
        // The points of one column: consecutive, as t ascends.
        let c = column(run[start].0);
        let end = start + run[start..].iter().take_while(|p| column(p.0) == c).count();
        let part = &run[start..end];
        let by_value = |a: &usize, b: &usize| part[*a].1.total_cmp(&part[*b].1);
        let lowest = (0..part.len()).min_by(by_value).unwrap_or(0);
        let highest = (0..part.len()).max_by(by_value).unwrap_or(0);
        let mut keep = vec![0, lowest, highest, part.len() - 1];
        keep.sort_unstable();
        keep.dedup();
        out.extend(keep.into_iter().map(|i| part[i]));
        start = end;
    }
    out
}

/// The dash attribute of a dashed line, else nothing.
fn dash(s: &Series) -> &'static str {
    if s.dashed {
        r#" stroke-dasharray="6 3""#
    } else {
        ""
    }
}

/// Writes one `<polyline>` per run of a line.
fn draw_series(svg: &mut String, s: &Series, x: Scale, y: Scale, period: Option<f64>) {
    let mut parts = runs(&s.points, period);
    let total: usize = parts.iter().map(Vec::len).sum();
    if total > MAX_POINTS {
        let columns = (x.to.1 - x.to.0).round().max(1.0) as usize;
        parts = parts.iter().map(|r| thin(r, x.from, columns)).collect();
    }
    for run in parts {
        if run.len() == 1 {
            let (t, v) = run[0];
            let _ = writeln!(
                svg,
                r#"<circle cx="{:.1}" cy="{:.1}" r="1.5" fill="{}"/>"#,
                x.at(t),
                y.at(v),
                s.color
            );
            continue;
        }
        let mut pts = String::with_capacity(run.len() * 12);
        for (i, (t, v)) in run.iter().enumerate() {
            if i > 0 {
                pts.push(' ');
            }
            let _ = write!(pts, "{:.1},{:.1}", x.at(*t), y.at(*v));
        }
        let _ = writeln!(
            svg,
            r#"<polyline points="{pts}" fill="none" stroke="{}" stroke-width="1.3" stroke-linejoin="round"{}/>"#,
            s.color,
            dash(s)
        );
    }
}

/// Approximate width of text in the figure's sans-serif at `size` px.
fn text_width(s: &str, size: f64) -> f64 {
    s.chars().count() as f64 * size * 0.56
}

/// Writes one panel with its top at `top`; `last` puts the time labels under it.
fn draw_panel(svg: &mut String, panel: &Panel, top: f64, time: (Scale, f64), last: bool) {
    let (x, t_step) = time;
    let (left, right) = x.to;
    let plot_top = top + HEAD;
    let plot_bottom = plot_top + PLOT;

    // The value axis: fixed, or from the data.
    let ((lo, hi), step) = match &panel.fixed {
        Some(f) => (f.range, f.step),
        None => value_axis(extent(
            panel
                .series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| &p.1)),
        )),
    };
    let y = Scale {
        from: (lo, hi),
        to: (plot_bottom, plot_top),
    };

    // Head: the title, then the legend.
    let _ = writeln!(
        svg,
        r#"<text x="{left:.1}" y="{:.1}" font-size="13" font-weight="bold">{}</text>"#,
        top + 16.0,
        escape(panel.title)
    );
    let mut lx = left + text_width(panel.title, 13.0) + 28.0;
    let ly = top + 16.0;
    for s in &panel.series {
        let _ = writeln!(
            svg,
            r#"<line x1="{lx:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{}" stroke-width="2.5"{}/><text x="{:.1}" y="{ly:.1}" font-size="12">{}</text>"#,
            ly - 4.0,
            lx + 18.0,
            ly - 4.0,
            s.color,
            dash(s),
            lx + 23.0,
            escape(&s.label)
        );
        lx += 23.0 + text_width(&s.label, 12.0) + 20.0;
    }
    if let Some((_, label)) = &panel.marks {
        let _ = writeln!(
            svg,
            r#"<line x1="{lx:.1}" y1="{:.1}" x2="{lx:.1}" y2="{:.1}" stroke="{RED}" stroke-width="1.5"/><text x="{:.1}" y="{ly:.1}" font-size="12">{}</text>"#,
            ly - 10.0,
            ly + 1.0,
            lx + 6.0,
            escape(label)
        );
    }

    // The frame, the grid and the value ticks.
    let _ = writeln!(
        svg,
        r##"<rect x="{left:.1}" y="{plot_top:.1}" width="{:.1}" height="{PLOT:.1}" fill="#fbfbfb" stroke="#999" stroke-width="1"/>"##,
        right - left
    );
    for v in ticks(lo, hi, step) {
        let py = y.at(v);
        // The zero line is darker: it separates signs.
        let colour = if v.abs() < step * 1e-9 && lo < 0.0 && hi > 0.0 {
            "#aaa"
        } else {
            "#e3e3e3"
        };
        value_grid_line(
            svg,
            (left, right),
            py,
            colour,
            &escape(&tick_label(v, step)),
        );
    }
    for t in ticks(x.from.0, x.from.1, t_step) {
        let px = x.at(t);
        let _ = writeln!(
            svg,
            r##"<line x1="{px:.1}" y1="{plot_top:.1}" x2="{px:.1}" y2="{plot_bottom:.1}" stroke="#e3e3e3" stroke-width="1"/>"##
        );
        if last {
            let _ = writeln!(
                svg,
                r#"<text x="{px:.1}" y="{:.1}" font-size="11" text-anchor="middle">{}</text>"#,
                plot_bottom + 16.0,
                escape(&tick_label(t, t_step))
            );
        }
    }
    let mid = (plot_top + plot_bottom) / 2.0;
    let _ = writeln!(
        svg,
        r#"<text x="22" y="{mid:.1}" font-size="12" text-anchor="middle" transform="rotate(-90 22 {mid:.1})">{}</text>"#,
        escape(panel.axis)
    );

    // The lines, then the marks on top at the panel's foot.
    let period = panel.fixed.as_ref().map(|f| f.period);
    for s in &panel.series {
        draw_series(svg, s, x, y, period);
    }
    if let Some((times, _)) = &panel.marks {
        let mut path = String::new();
        for &t in times.iter().filter(|t| t.is_finite()) {
            let px = x.at(t);
            if px >= left - 0.5 && px <= right + 0.5 {
                let _ = write!(path, "M{px:.1} {plot_bottom:.1}v-10");
            }
        }
        if !path.is_empty() {
            let _ = writeln!(
                svg,
                r#"<path d="{path}" stroke="{RED}" stroke-width="1" stroke-opacity="0.8" fill="none"/>"#
            );
        }
    }
    if last {
        let _ = writeln!(
            svg,
            r#"<text x="{:.1}" y="{:.1}" font-size="12" text-anchor="middle">time (s)</text>"#,
            (left + right) / 2.0,
            plot_bottom + 36.0
        );
    }
}

/// A rotor's legend text: `rotor 1 "left" (ccw)`.
fn rotor_label(k: usize, machine: &Machine) -> String {
    let r = &machine.rotors[k];
    format!("rotor {} \"{}\" ({})", k + 1, r.name, r.sense.name())
}

/// The panels of a run's figure.
fn panels(rows: &[TraceRow], events: &[EventRow], machine: &Machine) -> Vec<Panel> {
    let line = |label: &str, color, f: &dyn Fn(&TraceRow) -> f64| Series {
        label: label.to_string(),
        color,
        points: rows.iter().map(|r| (r.t, f(r))).collect(),
        dashed: false,
    };
    let s1 = machine.rotors.rotor1().sense.sign();
    let impacts = impact_times(events);
    let count = impacts.len();
    let impact_label = format!("{count} impact{}", if count == 1 { "" } else { "s" });
    let mut panels = vec![
        Panel {
            title: "Platform position x",
            axis: "x (mm)",
            series: vec![line("x of the centre of mass", BLUE, &|r| r.x * 1e3)],
            fixed: None,
            marks: None,
        },
        Panel {
            title: "Platform height y",
            axis: "y (mm)",
            series: vec![line("y of the centre of mass", ORANGE, &|r| r.y * 1e3)],
            fixed: None,
            marks: None,
        },
        Panel {
            title: "Platform velocity",
            axis: "velocity (m/s)",
            series: vec![line("vx", BLUE, &|r| r.vx), line("vy", ORANGE, &|r| r.vy)],
            fixed: None,
            marks: Some((impacts, impact_label)),
        },
        Panel {
            title: "Pitch",
            axis: "angle (deg)",
            series: vec![line("pitch angle, ccw +", GREEN, &|r| r.angle.to_degrees())],
            fixed: None,
            marks: None,
        },
    ];
    // Rotor 1's speed, and on two rotors rotor 2's and their phase offset.
    let mut speeds = vec![line(&rotor_label(0, machine), BLUE, &|r| {
        s1 * r.omega1 * RPM_PER_RAD_S
    })];
    if let Some(r2) = machine.rotors.rotor2() {
        let s2 = r2.sense.sign();
        speeds.push(Series {
            dashed: true,
            ..line(&rotor_label(1, machine), ORANGE, &|r| {
                s2 * r.omega2 * RPM_PER_RAD_S
            })
        });
    }
    panels.push(Panel {
        title: if speeds.len() == 1 {
            "Rotor speed (driven sense)"
        } else {
            "Rotor speeds (driven sense)"
        },
        axis: "speed (rpm)",
        series: speeds,
        fixed: None,
        marks: None,
    });
    if machine.rotors.rotor2().is_some() {
        panels.push(Panel {
            title: "Phase offset",
            axis: "offset (deg)",
            series: vec![line("theta1 - theta2, wrapped to [0, 360)", PURPLE, &|r| {
                phase_offset_deg(r.phi1, r.phi2, machine).unwrap_or(f64::NAN)
            })],
            fixed: Some(Fixed {
                range: (0.0, 360.0),
                step: 90.0,
                period: 360.0,
            }),
            marks: None,
        });
    }
    panels
}

/// The figure of a run: its trace `rows` (times ascending), its `events` (impacts
/// marked) and its `machine` (rotor names and senses, the phase convention), with
/// `title` on top. Returns a complete SVG document.
pub fn plot_svg(rows: &[TraceRow], events: &[EventRow], machine: &Machine, title: &str) -> String {
    let panels = panels(rows, events, machine);
    let height = TOP + panels.len() as f64 * (HEAD + PLOT + GAP) - GAP + BOTTOM;

    // The shared time axis: the trace's span, or a unit span when it has none.
    let (mut t0, mut t1) = extent(rows.iter().map(|r| &r.t)).unwrap_or((0.0, 1.0));
    if t1 - t0 <= 0.0 || !(t1 - t0).is_finite() {
        (t0, t1) = if t0.is_finite() {
            (t0, t0 + 1.0)
        } else {
            (0.0, 1.0)
        };
    }
    let x = Scale {
        from: (t0, t1),
        to: (LEFT, WIDTH - RIGHT),
    };
    let t_step = nice_step(t1 - t0, 10.0);

    let mut svg = String::new();
    open_document(&mut svg, WIDTH, height, title, LEFT, 24.0);
    let rotors = match machine.rotors.rotor2() {
        Some(r2) => format!(
            "rotor 1 \"{}\", rotor 2 \"{}\"; phase offset theta_k = s_k (phi_k - index_angle_k)",
            machine.rotors.rotor1().name,
            r2.name
        ),
        None => format!(
            "one rotor, \"{}\": no phase offset",
            machine.rotors.rotor1().name
        ),
    };
    let subtitle = format!(
        "{} rows from t = {} s to {} s; {rotors}",
        rows.len(),
        crate::numbers::sig(t0),
        crate::numbers::sig(t1),
    );
    let _ = writeln!(
        svg,
        r##"<text x="{LEFT}" y="44" font-size="12" fill="#555">{}</text>"##,
        escape(&subtitle)
    );

    let mut top = TOP;
    let n = panels.len();
    for (i, panel) in panels.iter().enumerate() {
        draw_panel(&mut svg, panel, top, (x, t_step), i + 1 == n);
        top += HEAD + PLOT + GAP;
    }
    svg.push_str("</svg>\n");
    svg
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::simulation::summary::tests::{impact, machine};
    use std::f64::consts::PI;

    /// A platform hopping right: 50 hops a second (one per revolution of rotors at
    /// 3000 rpm), `y` in arcs of 1.5 mm, `x` creeping at 5 cm/s, the rotors
    /// spinning up from rest, their offset settling from 300 through 360 to about
    /// 90 deg, the pitch rocking half a degree. Two rows at each impact.
    fn hopping(t_end: f64) -> (Vec<TraceRow>, Vec<EventRow>) {
        let m = machine([0.0, 0.0]);
        let dt = 1e-3;
        let hop = 0.02;
        let mut rows = Vec::new();
        let mut events = Vec::new();
        let w_full = 2.0 * PI * 50.0;
        let tau = 0.4;
        let row = |t: f64| {
            // Rotor speed w(t) = w_full (1 - exp(-t/tau)); phi its integral.
            let w = w_full * (1.0 - (-t / tau).exp());
            let angle = w_full * (t - tau * (1.0 - (-t / tau).exp()));
            // The offset (deg) settles from 300 to 450 = 90 (mod 360), with ripple.
            let offset = 450.0 - 150.0 * (-t / 0.5).exp() + 3.0 * (2.0 * PI * 3.0 * t).sin();
            // (The nudge keeps t = k hop at the start of hop k despite rounding.)
            let phase = (t / hop + 1e-9).fract();
            let height = 4.0 * 1.5e-3 * phase * (1.0 - phase);
            let vy = 4.0 * 1.5e-3 * (1.0 - 2.0 * phase) / hop;
            TraceRow {
                t,
                x: 0.05 * t + 2e-4 * (2.0 * PI * t / hop).sin(),
                y: 0.03 + height,
                angle: 0.5f64.to_radians() * (2.0 * PI * t / hop).cos(),
                vx: 0.05 + 2e-4 * 2.0 * PI / hop * (2.0 * PI * t / hop).cos(),
                vy,
                omega: 0.0,
                phi1: angle + offset.to_radians(),
                phi2: -angle,
                omega1: w,
                omega2: -w * (1.0 + 0.01 * (2.0 * PI * t / hop).sin()),
                i1: 0.5,
                i2: 0.5,
                duty1: 0.5,
                duty2: 0.5,
                ..TraceRow::default()
            }
        };
        let n = (t_end / dt).round() as usize;
        let mut k = 1;
        for i in 0..=n {
            let t = i as f64 * dt;
            while (k as f64 * hop) < t {
                let next_impact = k as f64 * hop;
                // The rows just before and after the impact: vy flips sign.
                let mut before = row(next_impact);
                before.vy = -before.vy.abs();
                rows.push(before);
                rows.push(row(next_impact));
                events.push(impact(next_impact, "K1"));
                events.push(impact(next_impact, "K2"));
                k += 1;
            }
            rows.push(row(t));
        }
        assert_eq!(m.rotors[0].name, "left");
        (rows, events)
    }

    #[test]
    fn the_figure_is_well_formed_and_has_its_panels() {
        let (rows, events) = hopping(1.0);
        let svg = plot_svg(&rows, &events, &machine([0.0; 2]), "hopping <right> & co");
        let doc = roxmltree::Document::parse(&svg).expect("well-formed XML");
        assert_eq!(doc.root_element().tag_name().name(), "svg");
        for label in [
            "Platform position x",
            "Platform height y",
            "Platform velocity",
            "Pitch",
            "Rotor speeds (driven sense)",
            "Phase offset",
            "x (mm)",
            "velocity (m/s)",
            "speed (rpm)",
            "offset (deg)",
            "time (s)",
            "49 impacts",
            "rotor 1 &quot;left&quot; (ccw)",
            "hopping &lt;right&gt; &amp; co",
        ] {
            assert!(svg.contains(label), "no {label}");
        }
        // The phase offset wraps once (300 -> 360 = 0 -> 90): two runs of its line.
        let purple = svg
            .lines()
            .filter(|l| l.starts_with("<polyline") && l.contains(PURPLE))
            .count();
        assert_eq!(purple, 2);
    }

    #[test]
    fn long_traces_are_thinned_and_keep_their_peaks() {
        let (rows, events) = hopping(10.0);
        assert!(rows.len() > 10_000);
        let svg = plot_svg(&rows, &events, &machine([0.0; 2]), "long");
        roxmltree::Document::parse(&svg).expect("well-formed XML");
        for line in svg.lines().filter(|l| l.starts_with("<polyline")) {
            assert!(line.matches(',').count() <= MAX_POINTS, "a line too long");
        }
        // Thinning keeps each column's extremes.
        let run: Vec<(f64, f64)> = (0..10_000)
            .map(|i| (i as f64, if i == 4321 { 9.0 } else { (i % 7) as f64 }))
            .collect();
        let thinned = thin(&run, (0.0, 10_000.0), 100);
        assert!(thinned.len() <= 400);
        assert!(thinned.contains(&(4321.0, 9.0)));
        assert!(thinned.windows(2).all(|w| w[0].0 < w[1].0));
    }

    #[test]
    fn empty_and_one_row_traces_do_not_panic() {
        let m = machine([0.0; 2]);
        for rows in [vec![], vec![TraceRow::default()]] {
            let svg = plot_svg(&rows, &[], &m, "tiny");
            roxmltree::Document::parse(&svg).expect("well-formed XML");
            assert!(svg.contains("0 impacts"));
        }
    }

    #[test]
    fn non_finite_values_are_skipped_not_written() {
        let m = machine([0.0; 2]);
        let mut rows: Vec<TraceRow> = (0..50)
            .map(|i| TraceRow {
                t: i as f64 * 0.01,
                x: i as f64 * 1e-3,
                y: 0.03,
                ..TraceRow::default()
            })
            .collect();
        rows[10].x = f64::NAN;
        rows[20].vy = f64::INFINITY;
        rows[30].phi1 = f64::NAN;
        rows[40].t = f64::NAN;
        let mut all_nan = rows.clone();
        for r in &mut all_nan {
            r.omega1 = f64::NAN;
        }
        for rows in [rows, all_nan] {
            let svg = plot_svg(&rows, &[impact(f64::NAN, "K1")], &m, "gaps");
            roxmltree::Document::parse(&svg).expect("well-formed XML");
            for bad in ["NaN", "nan", "inf"] {
                assert!(!svg.contains(bad), "{bad} written");
            }
        }
    }

    #[test]
    fn wraps_continue_at_the_opposite_edge() {
        let r = runs(&[(0.0, 350.0), (1.0, 10.0), (2.0, 20.0)], Some(360.0));
        assert_eq!(r.len(), 2);
        assert_eq!(r[0], [(0.0, 350.0), (0.5, 360.0)]);
        assert_eq!(r[1], [(0.5, 0.0), (1.0, 10.0), (2.0, 20.0)]);
        let r = runs(&[(0.0, 10.0), (1.0, 350.0)], Some(360.0));
        assert_eq!(r[0], [(0.0, 10.0), (0.5, 0.0)]);
        assert_eq!(r[1], [(0.5, 360.0), (1.0, 350.0)]);
        let r = runs(&[(0.0, 1.0), (1.0, f64::NAN), (2.0, 2.0)], None);
        assert_eq!(r, [vec![(0.0, 1.0)], vec![(2.0, 2.0)]]);
    }

    #[test]
    fn nice_ticks() {
        assert_eq!(nice_step(10.0, 10.0), 1.0);
        assert_eq!(nice_step(2.003, 10.0), 0.25);
        assert_eq!(nice_step(0.7, 4.0), 0.2);
        assert_eq!(value_axis(Some((28.1, 31.4))), ((28.0, 32.0), 1.0));
        assert_eq!(value_axis(Some((0.0, 0.0))), ((-1.0, 1.0), 0.5));
        assert_eq!(value_axis(None), ((0.0, 1.0), 0.25));
        assert_eq!(ticks(0.0, 1.0, 0.25), [0.0, 0.25, 0.5, 0.75, 1.0]);
        assert_eq!(tick_label(0.25, 0.25), "0.25");
        assert_eq!(tick_label(3000.0, 500.0), "3000");
        assert_eq!(tick_label(-1e-17, 0.1), "0.0");
        assert_eq!(tick_label(-0.5, 0.5), "-0.5");
    }

    /// Writes the sample figures for a person to look at:
    /// `cargo test -p host-sim plot::tests::sample -- --ignored`, then open
    /// `$TMPDIR/host-sim-sample-plot-{1,10}s.svg`.
    #[test]
    #[ignore]
    fn sample() {
        for t_end in [1.0, 10.0] {
            let (rows, events) = hopping(t_end);
            let svg = plot_svg(
                &rows,
                &events,
                &machine([0.0; 2]),
                "host-sim run: synthetic hopping platform (--command right)",
            );
            let path = std::env::temp_dir().join(format!("host-sim-sample-plot-{t_end}s.svg"));
            std::fs::write(&path, svg).unwrap();
            println!("{}", path.display());
        }
    }
}
