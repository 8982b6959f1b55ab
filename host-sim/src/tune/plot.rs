//! `host-sim tune --plot`: the sweep as a self-contained SVG figure for people.
//!
//! One panel: mean velocity (mm/s) against phase offset (degrees, 0 to 360, ticks
//! every 45), one line per speed, in the style of `host-sim run --plot`
//! ([`crate::run::plot`]): sans-serif text, ticks at "nice" values, a darker zero line,
//! a legend. When the offsets go round the turn, each line is closed at 360 with
//! its value at 0. The best offsets are marked on their line's colour: a filled
//! triangle pointing up for rightward travel, an open one pointing down for
//! leftward travel; a run that did not hold its offset is drawn as a grey ring.
//! Values that are not finite break the line and are never written.

use std::fmt::Write as _;

use crate::output::svg::{
    escape, nice_step, open_document, tick_label, ticks, value_grid_line, PALETTE,
};
use crate::sweep::best::{Best, Tuning};

/// Figure width, px.
const WIDTH: f64 = 960.0;
/// Figure height, px.
const HEIGHT: f64 = 600.0;
/// Left margin: tick labels and the rotated axis label.
const LEFT: f64 = 86.0;
/// Right margin: the legend.
const RIGHT: f64 = 190.0;
/// Top margin: title and subtitle.
const TOP: f64 = 66.0;
/// Bottom margin: offset tick labels and the axis label.
const BOTTOM: f64 = 56.0;

/// Line colours, one per speed, in turn.
const COLORS: [&str; 10] = PALETTE;

/// The value axis for the finite values: bounds on whole ticks, always
/// including 0 (the sign of travel is the point), and the step.
fn value_axis(values: impl Iterator<Item = f64>) -> ((f64, f64), f64) {
    let (mut lo, mut hi) = values
        .filter(|v| v.is_finite())
        .fold((0.0f64, 0.0f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
    if !(hi - lo).is_finite() || hi - lo <= 0.0 {
        (lo, hi) = (-1.0, 1.0);
    }
    let step = nice_step(hi - lo, 6.0);
    (
        ((lo / step).floor() * step, (hi / step).ceil() * step),
        step,
    )
}

/// A linear map from `from` values to `to` pixels, clamped to a band around the
/// figure so that an absurd value cannot write an absurdly long number.
fn map(v: f64, from: (f64, f64), to: (f64, f64)) -> f64 {
    (to.0 + (v - from.0) / (from.1 - from.0) * (to.1 - to.0)).clamp(-1e5, 1e5)
}

/// `colour` (`#rrggbb`) a quarter of the way from white: a band's fill.
fn tint(colour: &str) -> String {
    let channel = |i: usize| {
        let c = colour
            .get(i..i + 2)
            .and_then(|h| u8::from_str_radix(h, 16).ok())
            .unwrap_or(0x80);
        255 - (255 - u16::from(c)) / 4
    };
    format!("#{:02x}{:02x}{:02x}", channel(1), channel(3), channel(5))
}

/// A diamond marker centred at `(x, y)`, 7 px from its centre to each corner.
fn diamond(x: f64, y: f64) -> String {
    format!(
        "{:.1},{:.1} {:.1},{:.1} {:.1},{:.1} {:.1},{:.1}",
        x,
        y - 7.0,
        x + 7.0,
        y,
        x,
        y + 7.0,
        x - 7.0,
        y
    )
}

/// A triangle marker centred at `(x, y)`: pointing up (`up`) or down.
fn triangle(x: f64, y: f64, up: bool) -> String {
    let (tip, base) = if up { (-6.0, 4.0) } else { (6.0, -4.0) };
    format!(
        "{:.1},{:.1} {:.1},{:.1} {:.1},{:.1}",
        x,
        y + tip,
        x - 5.5,
        y + base,
        x + 5.5,
        y + base
    )
}

/// The figure of a sweep, with `title` on top. Returns a complete SVG document.
pub fn plot_svg(t: &Tuning, title: &str) -> String {
    plot_with_band(t, title, None)
}

/// What `tune --robust` draws besides the plain sweep's figure, per grid point
/// ([`crate::sweep::Grid::points`] order).
pub struct Band<'a> {
    /// The band under the line, `(low, high)`, m/s: the 10th to 90th percentiles.
    pub range: &'a [(f64, f64)],
    /// Points flagged multistable: a dark red diamond around the point.
    pub multistable: &'a [bool],
}

/// [`plot_svg`] with, under each speed's line, the band of `band` and its
/// multistable points marked.
pub fn plot_with_band(t: &Tuning, title: &str, band: Option<&Band<'_>>) -> String {
    let flags = band.map(|b| b.multistable);
    let band = band.map(|b| b.range);
    let axes = Axes::new(t, band);

    let mut svg = String::new();
    write_heading(&mut svg, t, title);
    write_frame(&mut svg, &axes);

    // One line per speed, closed at 360 when the offsets go round the turn.
    let g = &t.grid;
    let circular = g.circular() && g.offsets_deg.first() == Some(&0.0);
    // The bands first, every line over them.
    if let Some(band) = band {
        write_bands(&mut svg, t, band, &axes, circular);
    }
    let mut rings = String::new();
    // The best offsets are drawn last, over every line.
    let mut bests = String::new();
    for k in 0..g.speeds_rpm.len() {
        write_speed_line(&mut svg, t, k, &axes, circular);
        write_speed_points(&mut svg, &mut rings, t, k, flags, &axes);
        write_best_marks(&mut bests, t, k, &axes);
    }
    svg.push_str(&rings);
    svg.push_str(&bests);

    write_legend(&mut svg, t, band.is_some(), flags);
    svg.push_str("</svg>\n");
    svg
}

/// The plot's area in the figure, px, and its two axes: phase offset, deg, along
/// x (0 to 360); mean velocity, mm/s, along y, from `lo` to `hi` in ticks of
/// `step`.
struct Axes {
    /// The plot area's left and right edges, px.
    left: f64,
    right: f64,
    /// The plot area's top and bottom edges, px.
    top: f64,
    bottom: f64,
    /// The value axis's bounds, mm/s.
    lo: f64,
    hi: f64,
    /// The value axis's tick step, mm/s.
    step: f64,
}

impl Axes {
    /// The axes of the sweep `t`: the value axis holds every run's and every best
    /// offset's mean velocity, and the band's edges if there is one.
    fn new(t: &Tuning, band: Option<&[(f64, f64)]>) -> Self {
        let values = t
            .runs
            .iter()
            .map(|r| r.mean_velocity)
            .chain(t.right.iter().chain(&t.left).map(|b| b.mean_velocity))
            .chain(band.unwrap_or(&[]).iter().flat_map(|(a, b)| [*a, *b]))
            .map(|v| v * 1e3);
        let ((lo, hi), step) = value_axis(values);
        Axes {
            left: LEFT,
            right: WIDTH - RIGHT,
            top: TOP,
            bottom: HEIGHT - BOTTOM,
            lo,
            hi,
            step,
        }
    }

    /// The x pixel of a phase offset, deg.
    fn x(&self, offset_deg: f64) -> f64 {
        map(offset_deg, (0.0, 360.0), (self.left, self.right))
    }

    /// The y pixel of a mean velocity, m/s (the axis is in mm/s).
    fn y(&self, velocity: f64) -> f64 {
        map(velocity * 1e3, (self.lo, self.hi), (self.bottom, self.top))
    }
}

/// The document's opening, the title and the subtitle (how many runs, how long,
/// what is measured).
fn write_heading(svg: &mut String, t: &Tuning, title: &str) {
    open_document(svg, WIDTH, HEIGHT, title, LEFT, 26.0);
    let subtitle = format!(
        "{} runs of {} s, each holding its offset from t = 0; mean velocity over the second half; positive = right",
        t.run_count,
        crate::numbers::sig(t.grid.t_end)
    );
    let _ = writeln!(
        svg,
        r##"<text x="{LEFT}" y="46" font-size="12" fill="#555">{}</text>"##,
        escape(&subtitle)
    );
}

/// The plot area's frame, the grid lines with their tick labels (the zero line
/// darker) and the two axis labels.
fn write_frame(svg: &mut String, a: &Axes) {
    let (left, right, top, bottom) = (a.left, a.right, a.top, a.bottom);
    let _ = writeln!(
        svg,
        r##"<rect x="{left:.1}" y="{top:.1}" width="{:.1}" height="{:.1}" fill="#fbfbfb" stroke="#999" stroke-width="1"/>"##,
        right - left,
        bottom - top
    );
    for v in ticks(a.lo, a.hi, a.step) {
        let py = map(v, (a.lo, a.hi), (bottom, top));
        let colour = if v.abs() < a.step * 1e-9 {
            "#888"
        } else {
            "#e3e3e3"
        };
        value_grid_line(svg, (left, right), py, colour, &tick_label(v, a.step));
    }
    for o in ticks(0.0, 360.0, 45.0) {
        let px = a.x(o);
        let _ = writeln!(
            svg,
            r##"<line x1="{px:.1}" y1="{top:.1}" x2="{px:.1}" y2="{bottom:.1}" stroke="#e3e3e3" stroke-width="1"/><text x="{px:.1}" y="{:.1}" font-size="11" text-anchor="middle">{}</text>"##,
            bottom + 16.0,
            tick_label(o, 45.0)
        );
    }
    let mid = (top + bottom) / 2.0;
    let _ = writeln!(
        svg,
        r#"<text x="22" y="{mid:.1}" font-size="12" text-anchor="middle" transform="rotate(-90 22 {mid:.1})">mean velocity (mm/s)</text>"#
    );
    let _ = writeln!(
        svg,
        r#"<text x="{:.1}" y="{:.1}" font-size="12" text-anchor="middle">phase offset theta1 - theta2 (deg)</text>"#,
        (left + right) / 2.0,
        bottom + 38.0
    );
}

/// The bands under the lines (`band`: per grid point, m/s), one per speed: each
/// its upper edge left to right, its lower edge back, in pieces where both edges
/// are finite, closed at 360 when `circular`; a light tint of the line's colour,
/// solid (the same in every SVG renderer).
fn write_bands(svg: &mut String, t: &Tuning, band: &[(f64, f64)], a: &Axes, circular: bool) {
    let n = t.grid.offsets_deg.len();
    for k in 0..t.grid.speeds_rpm.len() {
        let tint = tint(COLORS[k % COLORS.len()]);
        let row = &t.runs[k * n..(k + 1) * n];
        let mut edges: Vec<(f64, (f64, f64))> = row
            .iter()
            .zip(&band[k * n..(k + 1) * n])
            .map(|(r, b)| (r.offset_deg, *b))
            .collect();
        if circular {
            edges.push((360.0, band[k * n]));
        }
        for piece in edges.split(|(_, (a, b))| !(a.is_finite() && b.is_finite())) {
            if piece.len() < 2 {
                continue;
            }
            let mut pts = Vec::new();
            for (o, (_, hi)) in piece {
                pts.push(format!("{:.1},{:.1}", a.x(*o), a.y(*hi)));
            }
            for (o, (lo, _)) in piece.iter().rev() {
                pts.push(format!("{:.1},{:.1}", a.x(*o), a.y(*lo)));
            }
            let _ = writeln!(
                svg,
                r#"<polygon points="{}" fill="{tint}" stroke="none" class="band"/>"#,
                pts.join(" ")
            );
        }
    }
}

/// The `k`-th speed's colour, and its dash once the palette has gone round.
fn line_style(k: usize) -> (&'static str, &'static str) {
    let colour = COLORS[k % COLORS.len()];
    let dash = if k >= COLORS.len() {
        r#" stroke-dasharray="6 3""#
    } else {
        ""
    };
    (colour, dash)
}

/// The `k`-th speed's line through its runs' mean velocities, closed at 360 with
/// its value at 0 when `circular`, broken where a value is not finite.
fn write_speed_line(svg: &mut String, t: &Tuning, k: usize, a: &Axes, circular: bool) {
    let n = t.grid.offsets_deg.len();
    let (colour, dash) = line_style(k);
    let row = &t.runs[k * n..(k + 1) * n];
    let mut points: Vec<(f64, f64)> = row
        .iter()
        .map(|r| (r.offset_deg, r.mean_velocity))
        .collect();
    if circular {
        points.push((360.0, row[0].mean_velocity));
    }
    let mut runs: Vec<String> = vec![String::new()];
    for (o, v) in points {
        if !v.is_finite() {
            runs.push(String::new());
            continue;
        }
        if let Some(last) = runs.last_mut() {
            if !last.is_empty() {
                last.push(' ');
            }
            let _ = write!(last, "{:.1},{:.1}", a.x(o), a.y(v));
        }
    }
    for pts in runs.iter().filter(|p| !p.is_empty()) {
        let _ = writeln!(
            svg,
            r#"<polyline points="{pts}" fill="none" stroke="{colour}" stroke-width="1.6" stroke-linejoin="round"{dash}/>"#
        );
    }
}

/// The `k`-th speed's grid points with a finite value: a dot on the line for a
/// run that held its offset, else a grey ring; a dark red diamond around a point
/// flagged multistable (`flags`). Rings and diamonds go to `rings`, drawn over
/// every line.
fn write_speed_points(
    svg: &mut String,
    rings: &mut String,
    t: &Tuning,
    k: usize,
    flags: Option<&[bool]>,
    a: &Axes,
) {
    let n = t.grid.offsets_deg.len();
    let (colour, _) = line_style(k);
    let row = &t.runs[k * n..(k + 1) * n];
    for (i, r) in row.iter().enumerate() {
        if !r.mean_velocity.is_finite() {
            continue;
        }
        let (px, py) = (a.x(r.offset_deg), a.y(r.mean_velocity));
        if flags.is_some_and(|f| f[k * n + i]) {
            let _ = writeln!(
                rings,
                r##"<polygon points="{}" fill="none" stroke="#8b0000" stroke-width="1.5" class="multistable"/>"##,
                diamond(px, py)
            );
        }
        if r.not_held.is_some() {
            let _ = writeln!(
                rings,
                r##"<circle cx="{px:.1}" cy="{py:.1}" r="5" fill="none" stroke="#777" stroke-width="1.5"/>"##
            );
        } else {
            let _ = writeln!(
                svg,
                r#"<circle cx="{px:.1}" cy="{py:.1}" r="2" fill="{colour}"/>"#
            );
        }
    }
}

/// The best offsets of the `k`-th speed, on its line's colour: a filled triangle
/// pointing up for rightward travel, an open one pointing down for leftward
/// travel; a best offset or velocity that is not finite is not drawn.
fn write_best_marks(bests: &mut String, t: &Tuning, k: usize, a: &Axes) {
    let speed = t.grid.speeds_rpm[k];
    let (colour, _) = line_style(k);
    let marks = |list: &[Best], up: bool, svg: &mut String| {
        for b in list.iter().filter(|b| b.speed_rpm == speed) {
            if !(b.offset_deg.is_finite() && b.mean_velocity.is_finite()) {
                continue;
            }
            let fill = if up { colour } else { "white" };
            let _ = writeln!(
                svg,
                r#"<polygon points="{}" fill="{fill}" stroke="{colour}" stroke-width="1.5"/>"#,
                triangle(a.x(b.offset_deg), a.y(b.mean_velocity), up)
            );
        }
    };
    marks(&t.right, true, bests);
    marks(&t.left, false, bests);
}

/// The legend, right of the plot: one line per speed, the two best marks, and
/// the band (`banded`), the multistable diamond (when a point is flagged in
/// `flags`) and the ring of an offset not held (when a run did not hold it).
fn write_legend(svg: &mut String, t: &Tuning, banded: bool, flags: Option<&[bool]>) {
    let lx = WIDTH - RIGHT + 18.0;
    let mut ly = TOP + 12.0;
    for (k, speed) in t.grid.speeds_rpm.iter().enumerate() {
        let (colour, dash) = line_style(k);
        let _ = writeln!(
            svg,
            r#"<line x1="{lx:.1}" y1="{:.1}" x2="{:.1}" y2="{:.1}" stroke="{colour}" stroke-width="2.5"{dash}/><text x="{:.1}" y="{ly:.1}" font-size="12">{} rpm</text>"#,
            ly - 4.0,
            lx + 20.0,
            ly - 4.0,
            lx + 26.0,
            crate::numbers::sig(*speed)
        );
        ly += 18.0;
    }
    ly += 8.0;
    for (text, up) in [("best right", true), ("best left", false)] {
        let fill = if up { "#444" } else { "white" };
        let _ = writeln!(
            svg,
            r##"<polygon points="{}" fill="{fill}" stroke="#444" stroke-width="1.5"/><text x="{:.1}" y="{ly:.1}" font-size="12">{text}</text>"##,
            triangle(lx + 10.0, ly - 4.0, up),
            lx + 26.0
        );
        ly += 18.0;
    }
    if banded {
        let _ = writeln!(
            svg,
            r##"<rect x="{lx:.1}" y="{:.1}" width="20" height="10" fill="{}"/><text x="{:.1}" y="{ly:.1}" font-size="12">10th-90th percentile</text>"##,
            ly - 9.0,
            tint("#444444"),
            lx + 26.0
        );
        ly += 18.0;
    }
    if flags.is_some_and(|f| f.contains(&true)) {
        let _ = writeln!(
            svg,
            r##"<polygon points="{}" fill="none" stroke="#8b0000" stroke-width="1.5"/><text x="{:.1}" y="{ly:.1}" font-size="12">multistable</text>"##,
            diamond(lx + 10.0, ly - 4.0),
            lx + 26.0
        );
        ly += 18.0;
    }
    if t.runs.iter().any(|r| r.not_held.is_some()) {
        let _ = writeln!(
            svg,
            r##"<circle cx="{:.1}" cy="{:.1}" r="5" fill="none" stroke="#777" stroke-width="1.5"/><text x="{:.1}" y="{ly:.1}" font-size="12">offset not held</text>"##,
            lx + 10.0,
            ly - 4.0,
            lx + 26.0
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sweep::best::Refinement;
    use crate::sweep::{Grid, RunOutcome};

    fn tuning(v: impl Fn(f64, f64) -> f64) -> Tuning {
        let grid = Grid {
            speeds_rpm: vec![2500.0, 3000.0],
            offsets_deg: (0..8).map(|i| f64::from(i) * 45.0).collect(),
            t_end: 4.0,
        };
        let runs: Vec<RunOutcome> = grid
            .points()
            .into_iter()
            .map(|(s, o)| RunOutcome {
                speed_rpm: s,
                offset_deg: o,
                mean_velocity: v(s, o),
                not_held: (o == 180.0).then(|| "ended `fault`".to_string()),
                not_a_travel: None,
                plant_warnings: vec![],
            })
            .collect();
        let best = |o: f64| Best {
            speed_rpm: 3000.0,
            offset_deg: o,
            mean_velocity: v(3000.0, o),
            grid_offset_deg: o,
            grid_mean_velocity: v(3000.0, o),
            refinement: Refinement::Parabola,
        };
        Tuning {
            run_count: runs.len(),
            grid,
            runs,
            right: vec![best(90.0)],
            left: vec![best(270.0)],
            warnings: vec![],
        }
    }

    #[test]
    fn the_figure_is_well_formed_and_labelled() {
        let t = tuning(|s, o| s * 1e-5 * o.to_radians().sin());
        let svg = plot_svg(&t, "tune <reference> & co");
        let doc = roxmltree::Document::parse(&svg).expect("well-formed XML");
        assert_eq!(doc.root_element().tag_name().name(), "svg");
        for label in [
            "2500 rpm",
            "3000 rpm",
            "best right",
            "best left",
            "offset not held",
            "mean velocity (mm/s)",
            "phase offset theta1 - theta2 (deg)",
            "tune &lt;reference&gt; &amp; co",
        ] {
            assert!(svg.contains(label), "no {label}");
        }
        // One closed line per speed, two best marks plus two legend marks.
        assert_eq!(svg.matches("<polyline").count(), 2);
        assert_eq!(svg.matches("<polygon").count(), 4);
    }

    #[test]
    fn non_finite_values_break_lines_and_are_not_written() {
        let t = tuning(|_, o| if o == 90.0 { f64::NAN } else { 0.01 });
        let svg = plot_svg(&t, "gaps");
        roxmltree::Document::parse(&svg).expect("well-formed XML");
        for bad in ["NaN", "nan", "inf"] {
            assert!(!svg.contains(bad), "{bad} written");
        }
        let t = tuning(|_, _| f64::NAN);
        let svg = plot_svg(&t, "all gaps");
        roxmltree::Document::parse(&svg).expect("well-formed XML");
        assert!(!svg.contains("NaN"));
    }

    #[test]
    fn a_band_is_drawn_under_each_line_and_widens_the_axis() {
        let t = tuning(|s, o| s * 1e-5 * o.to_radians().sin());
        let band: Vec<(f64, f64)> = t
            .runs
            .iter()
            .map(|r| (r.mean_velocity - 0.05, r.mean_velocity + 0.05))
            .collect();
        let flags: Vec<bool> = (0..band.len()).map(|i| i == 3).collect();
        let svg = plot_with_band(
            &t,
            "band",
            Some(&Band {
                range: &band,
                multistable: &flags,
            }),
        );
        roxmltree::Document::parse(&svg).expect("well-formed XML");
        assert!(svg.contains("10th-90th percentile"));
        // Two bands, the four marks of plot_svg, one multistable point and its
        // legend.
        assert_eq!(svg.matches("<polygon").count(), 8);
        assert_eq!(svg.matches(r#"class="multistable""#).count(), 1);
        assert!(svg.contains(">multistable<"));
        assert_eq!(svg.matches(r#"class="band""#).count(), 2);
        assert_eq!(tint("#1f77b4"), "#c7dded");
        // The band reaches 80 mm/s: the axis goes there.
        let ((_, hi), step) = value_axis(band.iter().flat_map(|b| [b.0 * 1e3, b.1 * 1e3]));
        assert!(hi >= 80.0, "{hi}");
        assert!(
            svg.contains(&format!(">{}<", tick_label(hi, step))),
            "axis to {hi}"
        );
        // Without a band, the figure is plot_svg's.
        assert_eq!(plot_with_band(&t, "band", None), plot_svg(&t, "band"));
    }

    #[test]
    fn the_value_axis_includes_zero() {
        assert_eq!(value_axis([12.0, 31.0].into_iter()), ((0.0, 40.0), 10.0));
        assert_eq!(value_axis([-30.0, 30.0].into_iter()), ((-30.0, 30.0), 10.0));
        assert_eq!(value_axis(std::iter::empty()), ((-1.0, 1.0), 0.5));
        assert_eq!(tick_label(-1e-17, 0.5), "0.0");
    }
}
