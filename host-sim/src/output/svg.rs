//! Small pieces shared by the hand-written SVG figures ([`crate::run::plot`],
//! [`crate::tune::plot`]): the document's opening, text escaping and "nice" axis
//! ticks.

/// The common categorical palette (matplotlib's "tab10"), in its order: one colour
/// per line in turn.
pub const PALETTE: [&str; 10] = [
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf",
];

/// Text with `&`, `<`, `>`, `"`, `'` escaped for XML.
pub fn escape(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&apos;"),
            // XML 1.0 forbids most control characters outright.
            c if (c as u32) < 0x20 && !matches!(c, '\t' | '\n' | '\r') => out.push(' '),
            c => out.push(c),
        }
    }
    out
}

/// A tick step near `span / target` that is 1, 2, 2.5 or 5 times a power of ten.
pub fn nice_step(span: f64, target: f64) -> f64 {
    let raw = span / target;
    let magnitude = 10f64.powf(raw.log10().floor());
    let f = raw / magnitude;
    let nice = if f <= 1.0 {
        1.0
    } else if f <= 2.0 {
        2.0
    } else if f <= 2.5 {
        2.5
    } else if f <= 5.0 {
        5.0
    } else {
        10.0
    };
    nice * magnitude
}

/// The values `lo, lo + step, ...` up to `hi`, at most 100.
pub fn ticks(lo: f64, hi: f64, step: f64) -> Vec<f64> {
    let first = (lo / step - 1e-9).ceil();
    (0..100)
        .map(|i| (first + i as f64) * step)
        .take_while(|v| *v <= hi + step * 1e-9)
        .collect()
}

/// A tick label: as many decimals as the step needs, never `-0`.
pub fn tick_label(v: f64, step: f64) -> String {
    if v.abs() >= 1e6 || step < 1e-6 {
        return crate::numbers::sig(v);
    }
    let decimals = (0..=6usize)
        .find(|d| {
            let scaled = step * 10f64.powi(*d as i32);
            (scaled - scaled.round()).abs() < 1e-6 * scaled.max(1.0)
        })
        .unwrap_or(6);
    let s = format!("{v:.decimals$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// Opens an SVG document of `width x height` px on white, with `title` as its
/// `<title>` and as a bold heading at (`x`, `y`).
pub fn open_document(svg: &mut String, width: f64, height: f64, title: &str, x: f64, y: f64) {
    use std::fmt::Write;
    let _ = writeln!(
        svg,
        r##"<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" viewBox="0 0 {width} {height}" font-family="sans-serif" fill="#222">"##
    );
    let _ = writeln!(svg, "<title>{}</title>", escape(title));
    let _ = writeln!(svg, r#"<rect width="100%" height="100%" fill="white"/>"#);
    let _ = writeln!(
        svg,
        r#"<text x="{x}" y="{y}" font-size="17" font-weight="bold">{}</text>"#,
        escape(title)
    );
}

/// A horizontal grid line at `py` from `left` to `right` in `colour`, with the
/// value tick's `label` (written as given) at its left end.
pub fn value_grid_line(
    svg: &mut String,
    (left, right): (f64, f64),
    py: f64,
    colour: &str,
    label: &str,
) {
    use std::fmt::Write;
    let _ = writeln!(
        svg,
        r#"<line x1="{left:.1}" y1="{py:.1}" x2="{right:.1}" y2="{py:.1}" stroke="{colour}" stroke-width="1"/><text x="{:.1}" y="{:.1}" font-size="11" text-anchor="end">{}</text>"#,
        left - 6.0,
        py + 4.0,
        label
    );
}
