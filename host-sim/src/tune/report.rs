//! A [`Tuning`] as a table for people, as JSON, and as the tuning file `--write`
//! writes.

use std::fmt::Write as _;
use std::path::Path;

use serde_json::{Map, Value};

use super::Request;
use crate::machine::tuning_file;
use crate::numbers;
use crate::numbers::count;
use crate::output::text::{Align, Table};
use crate::sweep::best::mm_s;
use crate::sweep::best::Best;
use crate::sweep::best::Refinement;
use crate::sweep::best::Tuning;

/// A JSON number, `null` when not finite.
fn number(x: f64) -> Value {
    Value::from(x)
}

/// `{"speed_rpm", "offset_deg", "mean_velocity"}`.
fn point_value(speed: f64, offset: f64, velocity: f64) -> Map<String, Value> {
    let mut m = Map::new();
    m.insert("speed_rpm".into(), number(speed));
    m.insert("offset_deg".into(), number(offset));
    m.insert("mean_velocity".into(), number(velocity));
    m
}

/// The JSON document of docs/tuning.md ("Output"), `{"grid": [...], "best":
/// {"right": [...], "left": [...]}, "warnings": [...]}`, pretty-printed.
pub fn tuning_json(t: &Tuning) -> String {
    let mut doc = Map::new();
    doc.insert(
        "grid".into(),
        Value::Array(
            t.runs
                .iter()
                .map(|r| {
                    let mut m = point_value(r.speed_rpm, r.offset_deg, r.mean_velocity);
                    m.insert("not_held".into(), Value::from(r.not_held.clone()));
                    m.insert("not_a_travel".into(), Value::from(r.not_a_travel.clone()));
                    Value::Object(m)
                })
                .collect(),
        ),
    );
    let list = |bests: &[Best]| {
        Value::Array(
            bests
                .iter()
                .map(|b| Value::Object(point_value(b.speed_rpm, b.offset_deg, b.mean_velocity)))
                .collect(),
        )
    };
    let mut best = Map::new();
    best.insert("right".into(), list(&t.right));
    best.insert("left".into(), list(&t.left));
    doc.insert("best".into(), Value::Object(best));
    doc.insert(
        "warnings".into(),
        Value::Array(t.warnings.iter().map(|w| Value::from(w.as_str())).collect()),
    );
    let mut text = serde_json::to_string_pretty(&Value::Object(doc))
        .unwrap_or_else(|e| format!("{{\"error\": \"{e}\"}}"));
    text.push('\n');
    text
}

/// How a best offset was found, for people.
fn describe(b: &Best) -> String {
    match &b.refinement {
        Refinement::Parabola if b.offset_deg == b.grid_offset_deg => {
            "grid (the vertex is the grid point)".into()
        }
        Refinement::Parabola => format!(
            "vertex (grid {} deg: {} mm/s)",
            numbers::sig(b.grid_offset_deg),
            mm_s(b.grid_mean_velocity)
        ),
        Refinement::Degenerate(why) => format!("grid ({why})"),
        Refinement::Slower(x, v) => {
            format!("grid (vertex {} deg: {} mm/s)", numbers::sig(*x), mm_s(*v))
        }
    }
}

/// The result for people: the grid of mean velocities (speeds as rows, offsets
/// as columns, mm/s; `*` marks a run that did not hold its offset, `!` one that
/// was no travel), the best offsets, and the warnings.
pub fn tuning_table(t: &Tuning, machine_path: &Path) -> String {
    let g = &t.grid;
    let mut out = format!(
        "tune {}: {} x {}, runs of {} s holding the offset from t = 0; mean velocity over the second half, mm/s\n\n",
        machine_path.display(),
        count(g.speeds_rpm.len(), "speed"),
        count(g.offsets_deg.len(), "offset"),
        numbers::sig(g.t_end)
    );

    // The grid.
    let titles: Vec<String> = std::iter::once("rpm \\ deg".to_string())
        .chain(g.offsets_deg.iter().map(|o| numbers::sig(*o)))
        .collect();
    let columns: Vec<(&str, Align)> = titles
        .iter()
        .enumerate()
        .map(|(i, s)| (s.as_str(), if i == 0 { Align::Left } else { Align::Right }))
        .collect();
    let mut grid = Table::new(&columns);
    let n = g.offsets_deg.len();
    let (mut not_held, mut not_a_travel) = (false, false);
    for (k, speed) in g.speeds_rpm.iter().enumerate() {
        let mut cells = vec![numbers::sig(*speed)];
        for r in &t.runs[k * n..(k + 1) * n] {
            let mark = if r.not_a_travel.is_some() {
                "!"
            } else if r.not_held.is_some() {
                "*"
            } else {
                ""
            };
            not_held |= r.not_held.is_some();
            not_a_travel |= r.not_a_travel.is_some();
            cells.push(format!("{}{mark}", mm_s(r.mean_velocity)));
        }
        grid.row(cells);
    }
    out.push_str(&grid.render());
    if not_held {
        out.push_str("* the offset was not held in this run (see the warnings)\n");
    }
    if not_a_travel {
        out.push_str("! not a travel in this run: no mean velocity (see the warnings)\n");
    }

    // The best offsets.
    out.push_str("\nbest offsets (parabola through the best grid point and its neighbours, checked by a run)\n");
    let mut best = Table::new(&[
        ("speed (rpm)", Align::Right),
        ("right (deg)", Align::Right),
        ("mm/s", Align::Right),
        ("left (deg)", Align::Right),
        ("mm/s", Align::Right),
        ("right from", Align::Left),
        ("left from", Align::Left),
    ]);
    for speed in &g.speeds_rpm {
        let find = |list: &[Best]| list.iter().find(|b| b.speed_rpm == *speed).cloned();
        let (r, l) = (find(&t.right), find(&t.left));
        let cell = |b: &Option<Best>, f: &dyn Fn(&Best) -> String| b.as_ref().map_or("-".into(), f);
        best.row(vec![
            numbers::sig(*speed),
            cell(&r, &|b| numbers::sig(b.offset_deg)),
            cell(&r, &|b| mm_s(b.mean_velocity)),
            cell(&l, &|b| numbers::sig(b.offset_deg)),
            cell(&l, &|b| mm_s(b.mean_velocity)),
            cell(&r, &describe),
            cell(&l, &describe),
        ]);
    }
    out.push_str(&best.render());

    // Warnings.
    if t.warnings.is_empty() {
        out.push_str("\nwarnings: none\n");
    } else {
        out.push_str("\nwarnings:\n");
        for w in &t.warnings {
            let _ = writeln!(out, "  - {w}");
        }
    }
    out
}

/// The tuning table file for `--write FILE` (`write`): a header that says how it
/// was made (no date, so the same sweep writes the same file) and one row per speed
/// with a best offset both ways.
pub fn table_file(t: &Tuning, request: &Request, write: &Path) -> String {
    let g = &t.grid;
    let mut command = format!(
        "host-sim tune {} --speeds {} --offsets {} --t-end {}",
        request.machine_path.display(),
        request.speeds_text,
        request.offsets_text,
        numbers::sig(g.t_end)
    );
    for s in &request.set {
        let _ = write!(command, " --set {s}");
    }
    let _ = write!(command, " --write {}", write.display());
    let mut header = format!(
        "Tuning table: the best phase offset for rightward and leftward travel per rotor speed.\n\
         Written by `host-sim tune` (see docs/tuning.md); regenerate with\n  {command}\n\
         Grid: {} x {} ({}), runs of {} s holding each offset from t = 0,\n\
         mean velocity over the second half. The best grid offset is refined by a parabola\n\
         through it and its two neighbours and kept when a run there is at least as fast.\n\
         Measured mean velocities, m/s:\n",
        count(g.speeds_rpm.len(), "speed"),
        count(g.offsets_deg.len(), "offset"),
        if g.circular() {
            "around the turn"
        } else {
            "part of the turn"
        },
        numbers::sig(g.t_end)
    );
    for (r, l) in table_rows_bests(t) {
        let _ = writeln!(
            header,
            "  {} rpm: right {:.1} deg {}, left {:.1} deg {}",
            numbers::sig(r.speed_rpm),
            r.offset_deg,
            numbers::signed(r.mean_velocity),
            l.offset_deg,
            numbers::signed(l.mean_velocity)
        );
    }
    if !t.warnings.is_empty() {
        let _ = writeln!(
            header,
            "The sweep gave {}: see the output of the command above.",
            count(t.warnings.len(), "warning")
        );
    }
    let rows: Vec<tuning_file::Row> = table_rows_bests(t)
        .iter()
        .map(|(r, l)| (r.speed_rpm, r.offset_deg, l.offset_deg))
        .collect();
    tuning_file::write(&rows, header.trim_end())
}

/// The speeds with a best offset both ways, as (right, left) pairs.
fn table_rows_bests(t: &Tuning) -> Vec<(Best, Best)> {
    t.right
        .iter()
        .filter_map(|r| {
            t.left
                .iter()
                .find(|l| l.speed_rpm == r.speed_rpm)
                .map(|l| (r.clone(), l.clone()))
        })
        .collect()
}
