//! The outputs of `host-sim calibrate`: the warnings, the table and the JSON
//! document (the fitted keys with their standard errors, the search, the residual
//! of each of the first [`ROWS_SHOWN`] rows and the count of the rows left out),
//! and the machine file with the fitted values (`--write`).

use std::fmt::Write as _;
use std::path::Path;

use serde_json::{json, Value};

use super::fit::Fit;
use super::keys::FitKey;
use super::numerical::Noise;
use super::points::NOT_HELD_RESIDUAL_MPS;
use super::points::{Point, ROWS_SHOWN};
use super::precision::{informative, Precision, MAX_CONDITION, UNIDENTIFIED_SHARE};
use super::{CalibrateArgs, Calibration};
use crate::failure::Failure;
use crate::numbers;
use crate::output::machine_edit::with_values;
use crate::output::text::{self, Align};
use crate::sweep::RunOutcome;

/// Whether key `i` is identified: a standard error, within
/// [`UNIDENTIFIED_SHARE`] of its range, and not in a near-singular direction.
pub fn identified(c: &Calibration, i: usize) -> bool {
    !c.precision.weak.contains(&i)
        && c.std_error[i].is_some_and(|s| s <= UNIDENTIFIED_SHARE * c.keys[i].width())
}

/// What a user must know of a fit to travel.
pub fn warnings(
    keys: &[FitKey],
    fit: &Fit,
    n: usize,
    precision: &Precision,
    std_error: &[Option<f64>],
    simulated: &[RunOutcome],
    refused: &[String],
) -> Vec<String> {
    let effect = Effect {
        changed: "simulated speed",
        on: "the speeds",
        step: super::fit::JACOBIAN_STEP,
        refused_by: "the machine reader",
    };
    let mut out = key_warnings(keys, fit, n, precision, std_error, &effect);
    // Runs not held, or no travel, at the fit.
    for o in simulated {
        let what = match (&o.not_a_travel, &o.not_held) {
            (Some(why), _) => format!("was no travel at the fit ({why})"),
            (None, Some(why)) => format!("did not hold its offset at the fit ({why})"),
            (None, None) => continue,
        };
        let w = format!(
            "{} rpm {} deg: the simulated run {what}; its rows count with the residual {} m/s from their mean",
            numbers::sig(o.speed_rpm),
            numbers::sig(o.offset_deg),
            numbers::sig(NOT_HELD_RESIDUAL_MPS)
        );
        if !out.contains(&w) {
            out.push(w);
        }
    }
    out.extend(budget_warning(fit));
    if let Some(first) = refused.first() {
        out.push(format!(
            "{} of the search refused by the machine reader (counted as infinitely bad); the first: {first}",
            super::count(refused.len(), "point")
        ));
    }
    out
}

/// What the fitted keys move, in the words of [`key_warnings`].
#[derive(Clone, Copy, Debug)]
pub struct Effect<'a> {
    /// What a key changes (`simulated speed`).
    pub changed: &'a str,
    /// What it acts on (`the speeds`).
    pub on: &'a str,
    /// The Jacobian's step, a share of each range.
    pub step: f64,
    /// Who refuses a trial value (`the machine reader`).
    pub refused_by: &'a str,
}

/// What a user must know of the fitted keys, whatever was measured: no degrees
/// of freedom, keys not identified, a fit at an end of a range.
pub fn key_warnings(
    keys: &[FitKey],
    fit: &Fit,
    n: usize,
    precision: &Precision,
    std_error: &[Option<f64>],
    effect: &Effect<'_>,
) -> Vec<String> {
    let step = format!("1/{}", (1.0 / effect.step).round());
    let mut out = Vec::new();
    if precision.dof <= 0 {
        out.push(format!(
            "{} for {}: no standard error (it needs more rows than keys)",
            super::count(n, "row"),
            super::count(keys.len(), "key")
        ));
    }
    // Keys the measurements do not move, or cannot tell apart.
    let zero: Vec<&str> = (0..keys.len())
        .filter(|&i| precision.column_norm[i] == 0.0)
        .map(|i| keys[i].key.as_str())
        .collect();
    for k in &zero {
        out.push(format!(
            "{k}: not identified: no {} changes over a step of {step} of its range (the measurements do not depend on it)",
            effect.changed
        ));
    }
    for i in (0..keys.len()).filter(|&i| {
        let norm = precision.column_norm[i];
        norm != 0.0 && !informative(norm)
    }) {
        out.push(format!(
            "{}: not identified: its effect on {} is unknown (a value {step} of its range from the fit was refused by {})",
            keys[i].key, effect.on, effect.refused_by
        ));
    }
    let tangled: Vec<&str> = precision
        .weak
        .iter()
        .filter(|&&i| informative(precision.column_norm[i]))
        .map(|&i| keys[i].key.as_str())
        .collect();
    if !tangled.is_empty() {
        out.push(format!(
            "{}: not identified apart: their effects on {} are nearly proportional (condition number {} of the scaled J^T J, above {})",
            tangled.join(", "),
            effect.on,
            numbers::sig(precision.condition),
            numbers::sig(MAX_CONDITION)
        ));
    }
    for (k, s) in keys.iter().zip(std_error) {
        if let Some(s) = s {
            if *s > UNIDENTIFIED_SHARE * k.width() {
                out.push(format!(
                    "{}: not identified: standard error {} is more than a quarter of its range [{}, {}]",
                    k.key,
                    numbers::sig(*s),
                    numbers::sig(k.low),
                    numbers::sig(k.high)
                ));
            }
        }
    }
    // A fit on a face of the box.
    for (k, u) in keys.iter().zip(&fit.u) {
        if *u <= 0.0 || *u >= 1.0 {
            out.push(format!(
                "{}: the fit lies at the {} end of its range ({}): the best value may lie beyond; the standard error assumes a minimum inside",
                k.key,
                if *u <= 0.0 { "low" } else { "high" },
                numbers::sig(k.value_at(*u))
            ));
        }
    }
    out
}

/// The warning of a fit whose search stopped at its budget (another search's
/// early stop is harmless: it ended higher).
pub fn budget_warning(fit: &Fit) -> Option<String> {
    let best = fit
        .searches
        .iter()
        .filter(|s| s.u == fit.u)
        .all(|s| !s.converged);
    (best && !fit.searches.is_empty()).then(|| {
        "the local search that gave the fit stopped at its budget of evaluations before its last step: the fit is coarser than its resolution".to_string()
    })
}

/// Points named in a warning of numerical noise, the noisiest first.
const NOISIEST_NAMED: usize = 3;

/// A warning for each key whose standard error the simulator's numerical noise
/// (`numerical`, in the key's units) makes more of than the measurements'
/// scatter (`measurement`): its precision is the simulator's, not the
/// measurements'. It names the points whose speed changes most with the
/// tolerance.
pub fn numerical_warnings(
    keys: &[FitKey],
    measurement: &[Option<f64>],
    numerical: &[Option<f64>],
    points: &[Point],
    noise: &Noise,
) -> Vec<String> {
    let mut order: Vec<usize> = (0..points.len()).filter(|&k| noise.sd[k] > 0.0).collect();
    order.sort_by(|&a, &b| noise.sd[b].total_cmp(&noise.sd[a]).then(a.cmp(&b)));
    let named: Vec<String> = order
        .iter()
        .take(NOISIEST_NAMED)
        .map(|&k| {
            format!(
                "{} rpm {} deg: {} mm/s",
                numbers::sig(points[k].speed_rpm),
                numbers::sig(points[k].offset_deg),
                numbers::sig(noise.sd[k] * 1e3)
            )
        })
        .collect();
    let rtols: Vec<String> = noise.rtols.iter().map(|r| numbers::sig(*r)).collect();
    // A finer tolerance is advice only where there is one: at the lowest the
    // file allows the runs went coarser.
    let finer = if noise.rtols[1] < noise.rtols[0] {
        " or a finer simulation.rtol"
    } else {
        ""
    };
    let mut out = Vec::new();
    for (i, k) in keys.iter().enumerate() {
        if let (Some(m), Some(x)) = (measurement[i], numerical[i]) {
            if x > m {
                out.push(format!(
                    "{}: the simulator's numerical noise makes more of its standard error ({}) than the measurements' scatter ({}): speeds change with the tolerance ({}) by up to {}; leaving such points out (a chaotic gait's speed changes at any tolerance){finer} narrows it (docs/calibration.md, \"Numerical noise\")",
                    k.key,
                    numbers::sig(x),
                    numbers::sig(m),
                    rtols.join(", "),
                    named.join(", ")
                ));
            }
        }
    }
    out
}

/// The cells of the rows shown, for the table and JSON: the measured and
/// simulated speeds and the residual (not weighted), m/s; `None` simulated where
/// the run gave no speed (not held, or no travel).
fn row_values(c: &Calibration) -> Vec<(f64, Option<f64>, f64)> {
    c.data
        .shown
        .iter()
        .map(|(r, k)| (r, &c.simulated[*k]))
        .map(|(r, o)| match o.velocity() {
            Some(v) => (r.velocity_mps, Some(v), v - r.velocity_mps),
            None => (r.velocity_mps, None, NOT_HELD_RESIDUAL_MPS),
        })
        .collect()
}

/// The columns of the fitted keys' table, the travel fit's and the capture
/// fit's alike: `part` is the one share of the standard error each states
/// apart (the simulator's numerical noise, the start angle's count).
pub struct KeyColumns<'a> {
    /// The keys, with their ranges and nominal values.
    pub keys: &'a [FitKey],
    /// The fitted values.
    pub fitted: &'a [f64],
    /// Their standard errors.
    pub std_error: &'a [Option<f64>],
    /// The share's column title and values.
    pub part: (&'a str, &'a [Option<f64>]),
    /// The smallest change each key's fit resolves.
    pub resolution: &'a [Option<f64>],
    /// Whether each key is identified.
    pub identified: &'a [bool],
}

/// The fitted keys as a table for people.
pub fn keys_table(k: &KeyColumns<'_>) -> String {
    let mut t = text::Table::new(&[
        ("key", Align::Left),
        ("range", Align::Left),
        ("from", Align::Left),
        ("nominal", Align::Right),
        ("fitted", Align::Right),
        ("std_error", Align::Right),
        (k.part.0, Align::Right),
        ("resolution", Align::Right),
        ("identified", Align::Left),
    ]);
    let sig = |v: Option<f64>| v.map_or("-".into(), numbers::sig);
    for (i, key) in k.keys.iter().enumerate() {
        t.row(vec![
            key.key.clone(),
            format!("[{}, {}]", numbers::sig(key.low), numbers::sig(key.high)),
            key.bound.name().into(),
            numbers::sig(key.nominal),
            numbers::sig(k.fitted[i]),
            sig(k.std_error[i]),
            sig(k.part.1[i]),
            sig(k.resolution[i]),
            if k.identified[i] { "yes" } else { "no" }.into(),
        ]);
    }
    t.render()
}

/// `--format table`.
pub fn table(c: &Calibration, args: &CalibrateArgs) -> String {
    let n = c.data.rows;
    let mut out = format!(
        "calibrate {}: {} from {}, {}, runs of {} s\n\n",
        args.machine.path.display(),
        super::count(n, "row"),
        args.measured_file().display(),
        super::count(c.keys.len(), "key"),
        numbers::sig(c.t_end)
    );
    let identified: Vec<bool> = (0..c.keys.len()).map(|i| identified(c, i)).collect();
    out.push_str(&keys_table(&KeyColumns {
        keys: &c.keys,
        fitted: &c.fitted,
        std_error: &c.std_error,
        part: ("numerical", &c.std_error_numerical),
        resolution: &c.resolution,
        identified: &identified,
    }));
    let p = &c.precision;
    let _ = writeln!(
        out,
        "\nfit: weighted sum of squares {} m^2/s^2 over {} at {} (n - p = {}), s = {} mm/s, condition number {}",
        numbers::sig(c.ssr),
        super::count(n, "row"),
        super::count(c.data.points.len(), "point"),
        p.dof,
        p.s2.map_or("-".into(), |s2| numbers::sig(s2.sqrt() * 1e3)),
        numbers::sig(p.condition)
    );
    let scatter = c.data.scatter();
    let from: Vec<String> = c
        .fit
        .searches
        .iter()
        .map(|s| {
            format!(
                "start {} ({} -> {} in {})",
                s.start,
                numbers::sig(s.from + scatter),
                numbers::sig(s.to + scatter),
                super::count(s.polls, "poll")
            )
        })
        .collect();
    let _ = writeln!(
        out,
        "search: {} (0: the file's values), local searches from {}; {}, {}",
        super::count(c.fit.starts.len(), "start"),
        from.join(", "),
        super::count(c.fit.evaluations, "evaluation"),
        super::count(c.runs, "run")
    );
    let others: Vec<String> = c.noise.rtols[1..]
        .iter()
        .map(|r| numbers::sig(*r))
        .collect();
    let _ = writeln!(
        out,
        "numerical noise: each point run again at rtol {}: the rows' numerical column is the standard deviation of its speeds over the {} tolerances, the keys' that noise's part of the standard error",
        match others.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} and {last}", rest.join(", ")),
            _ => others.join(""),
        },
        c.noise.rtols.len()
    );
    out.push_str("\nrows, mm/s (residual = simulated - measured):\n");
    let mut rows = text::Table::new(&[
        ("line", Align::Right),
        ("speed_rpm", Align::Right),
        ("offset_deg", Align::Right),
        ("weight", Align::Right),
        ("measured", Align::Right),
        ("simulated", Align::Right),
        ("residual", Align::Right),
        ("numerical", Align::Right),
    ]);
    for ((r, k), (m, s, e)) in c.data.shown.iter().zip(row_values(c)) {
        rows.row(vec![
            r.line.to_string(),
            numbers::sig(r.speed_rpm),
            numbers::sig(r.offset_deg),
            numbers::sig(r.weight),
            format!("{:.3}", m * 1e3),
            s.map_or_else(
                || {
                    if c.simulated[*k].not_a_travel.is_some() {
                        "no travel".into()
                    } else {
                        "not held".into()
                    }
                },
                |s| format!("{:.3}", s * 1e3),
            ),
            format!("{:+.3}", e * 1e3),
            format!("{:.3}", c.noise.sd[*k] * 1e3),
        ]);
    }
    out.push_str(&rows.render());
    if let Some(left_out) = rows_left_out(c) {
        let _ = writeln!(
            out,
            "... and {left_out} more row{} (the first {ROWS_SHOWN} are listed; all count in the fit)",
            if left_out == 1 { "" } else { "s" }
        );
    }
    for w in &c.warnings {
        let _ = writeln!(out, "warning: {w}");
    }
    out
}

/// `--format json`.
pub fn json(c: &Calibration, args: &CalibrateArgs) -> String {
    let finite = |x: f64| if x.is_finite() { json!(x) } else { Value::Null };
    let keys: Vec<Value> = c
        .keys
        .iter()
        .enumerate()
        .map(|(i, k)| {
            json!({
                "key": k.key, "targets": k.targets, "low": k.low, "high": k.high,
                "range_from": k.bound.name(), "nominal": k.nominal, "fitted": c.fitted[i],
                "std_error": c.std_error[i],
                "std_error_measurement": c.std_error_measurement[i],
                "std_error_numerical": c.std_error_numerical[i],
                "resolution": c.resolution[i],
                "identified": identified(c, i),
            })
        })
        .collect();
    let rows: Vec<Value> = c
        .data
        .shown
        .iter()
        .zip(row_values(c))
        .map(|((r, k), (m, s, e))| {
            let o = &c.simulated[*k];
            json!({
                "line": r.line, "speed_rpm": r.speed_rpm, "offset_deg": r.offset_deg,
                "weight": r.weight, "measured_mps": m, "simulated_mps": s,
                "residual_mps": e, "not_held": o.not_held, "not_a_travel": o.not_a_travel,
                "numerical_mps": c.noise.sd[*k],
            })
        })
        .collect();
    let points: Vec<Value> = c
        .data
        .points
        .iter()
        .zip(&c.simulated)
        .zip(c.noise.speeds.iter().zip(&c.noise.sd))
        .map(|((pt, o), (speeds, sd))| {
            json!({
                "speed_rpm": pt.speed_rpm, "offset_deg": pt.offset_deg, "rows": pt.rows,
                "weight": pt.weight, "measured_mps": pt.mean_mps,
                "simulated_mps": speeds.first().copied().flatten(),
                "not_held": o.not_held, "not_a_travel": o.not_a_travel,
                "speeds_mps": speeds, "numerical_mps": sd,
            })
        })
        .collect();
    let p = &c.precision;
    // The search's sums are over the points; the rows' add the scatter within them.
    let scatter = c.data.scatter();
    let doc = json!({
        "machine": args.machine.path.display().to_string(),
        "measured": args.measured_file().display().to_string(),
        "t_end": c.t_end,
        "keys": keys,
        "rows": rows,
        "rows_left_out": rows_left_out(c).unwrap_or(0),
        "points": points,
        "fit": {
            "ssr": c.ssr, "n": c.data.rows, "points": c.data.points.len(),
            "p": c.keys.len(), "dof": p.dof,
            "s": p.s2.map(f64::sqrt), "condition": finite(p.condition),
            "evaluations": c.fit.evaluations, "runs": c.runs,
            "rtols": c.noise.rtols,
            "starts": c.fit.starts.iter().map(|(u, s)| json!({"u": u, "ssr": finite(*s + scatter)})).collect::<Vec<Value>>(),
            "searches": c.fit.searches.iter().map(|s| json!({
                "start": s.start, "u": s.u, "from": s.from + scatter, "to": s.to + scatter,
                "polls": s.polls, "converged": s.converged})).collect::<Vec<Value>>(),
        },
        "warnings": c.warnings,
    });
    let mut s = serde_json::to_string_pretty(&doc).unwrap_or_default();
    s.push('\n');
    s
}

/// The rows not listed in the outputs, when some are not.
fn rows_left_out(c: &Calibration) -> Option<usize> {
    let left_out = c.data.rows - c.data.shown.len();
    (left_out > 0).then_some(left_out)
}

/// `--write`: the text of the machine file `path` (`text`) with every target of
/// every fitted key at its fitted value, each value's comment kept, nothing else
/// changed; checked to read back with those values (`out`: where it goes, whose
/// directory a relative tuning table is resolved against).
pub fn machine_file(
    path: &Path,
    text: &str,
    c: &Calibration,
    out: &Path,
) -> Result<String, Failure> {
    machine_file_with(path, text, &c.keys, &c.fitted, out)
}

/// [`machine_file()`] of the `keys` at their `fitted` values, whatever they were
/// fitted to.
pub fn machine_file_with(
    path: &Path,
    text: &str,
    keys: &[FitKey],
    fitted: &[f64],
    out: &Path,
) -> Result<String, Failure> {
    let values: Vec<(String, f64)> = keys
        .iter()
        .zip(fitted)
        .flat_map(|(k, x)| k.key_paths.iter().map(move |p| (p.clone(), *x)))
        .collect();
    with_values(path, text, &values, out).map_err(|why| {
        Failure::run(format!(
            "--write {}: {why} (an internal error)",
            out.display()
        ))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calibrate::keys::Bound;

    /// The noise warning advises a finer tolerance only where the noise runs
    /// went finer: at 1e-12, the lowest the file allows, they went coarser.
    #[test]
    fn a_finer_tolerance_is_advised_only_where_there_is_one() {
        let key = FitKey {
            key: "contacts.*.restitution".into(),
            targets: vec![],
            key_paths: vec![],
            low: 0.2,
            high: 0.6,
            bound: Bound::Uncertainty,
            nominal: 0.4,
        };
        let point = Point {
            speed_rpm: 3000.0,
            offset_deg: 90.0,
            rows: 1,
            weight: 1.0,
            mean_mps: 0.03,
            scatter: 0.0,
        };
        let warning = |rtols: Vec<f64>| {
            let noise = Noise {
                rtols,
                speeds: vec![vec![Some(0.03); 5]],
                sd: vec![1e-3],
                ssr: vec![0.0; 5],
            };
            numerical_warnings(
                std::slice::from_ref(&key),
                &[Some(1e-3)],
                &[Some(2e-3)],
                std::slice::from_ref(&point),
                &noise,
            )
        };
        let finer = warning(vec![1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5]);
        assert_eq!(finer.len(), 1);
        assert!(
            finer[0].contains(" or a finer simulation.rtol narrows it"),
            "{finer:?}"
        );
        let coarser = warning(vec![1e-12, 2e-12, 4e-12, 8e-12, 1.6e-11]);
        assert_eq!(coarser.len(), 1);
        assert!(!coarser[0].contains("finer"), "{coarser:?}");
    }
}
