//! The outputs of `host-sim calibrate --capture`: the planned cost, the
//! warnings, the table and the JSON document (the fitted keys with their
//! standard errors, the fit and the search, each quantity's RMS residual at
//! the file's values and at the fit).

use std::fmt::Write as _;
use std::path::Path;

use serde_json::{json, Value};

use super::super::fit::{Fit, Settings};
use super::super::keys::FitKey;
use super::super::plan::duration;
use super::super::precision::{Precision, UNIDENTIFIED_SHARE};
use super::super::report::{budget_warning, key_warnings, keys_table, Effect, KeyColumns};
use super::super::CalibrateArgs;
use super::residuals::QUANTITIES;
use super::{Calibration, Inputs};
use crate::numbers::{self, count};
use crate::output::text::{self, Align};
use crate::replay::residual::Residual;
use crate::replay::Replay;

/// The line before the fit (stderr): the most replays and their time at the
/// cost of the one timed.
pub fn plan(inputs: &Inputs, evaluations: usize, threads: usize) -> String {
    let ticks = inputs.capture.records.len();
    let s = inputs.seconds_per_replay;
    format!(
        "calibrate: up to {} of the capture's {} ({} s); one took {} s, so up to about {} on {}\n",
        count(evaluations, "replay"),
        count(ticks, "tick"),
        numbers::sig(ticks as f64 * inputs.capture.header.tick_s),
        numbers::sig(round2(s)),
        duration(evaluations as f64 * s / threads.max(1) as f64),
        count(threads, "thread"),
    )
}

/// `x` to 2 significant digits.
fn round2(x: f64) -> f64 {
    if x > 0.0 && x.is_finite() {
        let scale = 10f64.powi(1 - x.log10().floor() as i32);
        (x * scale).round() / scale
    } else {
        x
    }
}

/// What a user must know of a fit to a capture: the keys' warnings, a search
/// stopped by its budget, trial points refused, and the replay at the fit
/// where its states are not the board's or it warns.
pub fn warnings(
    keys: &[FitKey],
    fit: &Fit,
    precision: &Precision,
    std_error: &[Option<f64>],
    settings: &Settings,
    refused: &[String],
    at_fit: &Replay,
) -> Vec<String> {
    let effect = Effect {
        changed: "replayed signal",
        on: "the replayed signals",
        step: settings.jacobian_step,
        refused_by: "the machine reader or stopped the twin",
    };
    let n = fit.residuals.len();
    let mut out = key_warnings(keys, fit, n, precision, std_error, &effect);
    out.extend(budget_warning(fit));
    if let Some(first) = refused.first() {
        out.push(format!(
            "{} of the search refused by the machine reader or stopped before the capture's end (counted as infinitely bad); the first: {first}",
            count(refused.len(), "point")
        ));
    }
    let (differs, first) = at_fit.state_differs;
    if let Some(k) = first {
        out.push(format!(
            "at the fit the twin's state differs from the board's at {} (first at {} s): the replay does not do what the board did there, and its residuals there are the fit's",
            count(differs, "tick"),
            numbers::fixed(k as f64 * at_fit.tick_s, 3)
        ));
    }
    out.extend(
        at_fit
            .warnings
            .iter()
            .map(|w| format!("the replay at the fit: {w}")),
    );
    out
}

/// Whether key `i` is identified: a standard error, within
/// [`UNIDENTIFIED_SHARE`] of its range, and not in a near-singular direction.
pub fn identified(c: &Calibration, i: usize) -> bool {
    !c.precision.weak.contains(&i)
        && c.std_error[i].is_some_and(|s| s <= UNIDENTIFIED_SHARE * c.keys[i].width())
}

/// A quantity's scale, in its units.
fn scale_of(inputs: &Inputs, r: &Residual) -> Option<f64> {
    match (r.quantity, r.rotor) {
        ("speed_rpm", _) => Some(inputs.scales.speed_rpm),
        ("current_a", _) => Some(inputs.scales.current_a),
        ("duty", Some(j)) => inputs.scales.duty.get(j - 1).copied(),
        _ => None,
    }
}

/// A residual's value for people (`-` where no tick was compared).
fn value(r: &Residual, v: f64) -> String {
    if r.ticks == 0 {
        "-".into()
    } else {
        numbers::sig(v)
    }
}

/// The fitted signals, and what the weighted least squares is over.
fn fit_line(c: &Calibration, inputs: &Inputs) -> String {
    let p = &c.precision;
    let ticks = inputs.capture.records.len();
    format!(
        "fit: weighted sum of squares {} over {} ({} of {} x {} x {}, each over its scale), n - p = {}, s = {}, condition number {}; standard errors with the windows correlated over {} lags",
        numbers::sig(c.fit.ssr),
        count(c.fit.residuals.len(), "residual"),
        count(ticks.div_ceil(inputs.window.max(1)), "window"),
        count(inputs.window, "tick"),
        count(inputs.rotors, "rotor"),
        QUANTITIES.join(", "),
        p.dof,
        p.s2.map_or("-".into(), |s2| numbers::sig(s2.sqrt())),
        numbers::sig(p.condition),
        c.lags,
    )
}

/// `--format table`.
pub fn table(c: &Calibration, inputs: &Inputs, args: &CalibrateArgs, capture: &Path) -> String {
    let ticks = inputs.capture.records.len();
    let mut out = format!(
        "calibrate {}: capture {} ({}, {} s) with {}'s controller, {}\n\n",
        args.machine.path.display(),
        capture.display(),
        count(ticks, "tick"),
        numbers::sig(ticks as f64 * inputs.capture.header.tick_s),
        inputs.firmware.display(),
        count(c.keys.len(), "key"),
    );
    let identified: Vec<bool> = (0..c.keys.len()).map(|i| identified(c, i)).collect();
    out.push_str(&keys_table(&KeyColumns {
        keys: &c.keys,
        fitted: &c.fitted,
        std_error: &c.std_error,
        part: ("start", &c.std_error_start),
        resolution: &c.resolution,
        identified: &identified,
    }));
    let _ = writeln!(out, "\n{}", fit_line(c, inputs));
    let from: Vec<String> = c
        .fit
        .searches
        .iter()
        .map(|s| {
            format!(
                "start {} ({} -> {} in {})",
                s.start,
                numbers::sig(s.from),
                numbers::sig(s.to),
                count(s.polls, "iteration")
            )
        })
        .collect();
    let others: Vec<String> = c.spread.ssr[1..].iter().map(|s| numbers::sig(*s)).collect();
    let _ = writeln!(
        out,
        "start angles: from 1/8, 3/8, 5/8 and 7/8 of each start count, the fit's sum of squares is {} (from the middle {}): the keys' start column is that spread's part of the standard error",
        others.join(", "),
        numbers::sig(c.spread.ssr[0])
    );
    let _ = writeln!(
        out,
        "search: {} (0: the file's values), Levenberg-Marquardt from {}; {}, {}",
        count(c.fit.starts.len(), "start"),
        from.join(", "),
        count(c.fit.evaluations, "evaluation"),
        count(c.replays, "replay")
    );
    out.push_str("\nresiduals (replayed - recorded), RMS at the file's values and at the fit:\n");
    let mut rows = text::Table::new(&[
        ("quantity", Align::Left),
        ("rotor", Align::Right),
        ("scale", Align::Right),
        ("file", Align::Right),
        ("fit", Align::Right),
        ("fit/scale", Align::Right),
    ]);
    for (a, b) in inputs
        .nominal
        .residuals
        .iter()
        .zip(&c.fitted_replay.residuals)
    {
        let scale = scale_of(inputs, b);
        rows.row(vec![
            b.quantity.into(),
            b.rotor.map_or("-".into(), |r| r.to_string()),
            scale.map_or("-".into(), numbers::sig),
            value(a, a.rms),
            value(b, b.rms),
            match scale {
                Some(s) if b.ticks > 0 => numbers::fixed(b.rms / s, 2),
                _ => "-".into(),
            },
        ]);
    }
    out.push_str(&rows.render());
    for w in &c.warnings {
        let _ = writeln!(out, "warning: {w}");
    }
    out
}

/// `--format json`.
pub fn json(c: &Calibration, inputs: &Inputs, args: &CalibrateArgs, capture: &Path) -> String {
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
                "std_error_start": c.std_error_start[i],
                "resolution": c.resolution[i],
                "identified": identified(c, i),
            })
        })
        .collect();
    let rms = |r: &Residual, v: f64| (r.ticks > 0).then_some(v);
    let residuals: Vec<Value> = inputs
        .nominal
        .residuals
        .iter()
        .zip(&c.fitted_replay.residuals)
        .map(|(a, b)| {
            json!({
                "quantity": b.quantity, "rotor": b.rotor, "ticks": b.ticks,
                "scale": scale_of(inputs, b),
                "rms_nominal": rms(a, a.rms), "rms_fitted": rms(b, b.rms),
                "max_fitted": rms(b, b.max),
            })
        })
        .collect();
    let p = &c.precision;
    let doc = json!({
        "machine": args.machine.path.display().to_string(),
        "capture": capture.display().to_string(),
        "firmware_machine": inputs.firmware.display().to_string(),
        "ticks": inputs.capture.records.len(),
        "tick_s": inputs.capture.header.tick_s,
        "keys": keys,
        "residuals": residuals,
        "fit": {
            "ssr": c.fit.ssr, "n": c.fit.residuals.len(), "p": c.keys.len(), "dof": p.dof,
            "s": p.s2.map(f64::sqrt), "condition": finite(p.condition),
            "window_ticks": inputs.window, "lags": c.lags,
            "ssr_start_within": c.spread.ssr[1..],
            "evaluations": c.fit.evaluations, "replays": c.replays,
            "starts": c.fit.starts.iter().map(|(u, s)| json!({"u": u, "ssr": finite(*s)})).collect::<Vec<Value>>(),
            "searches": c.fit.searches.iter().map(|s| json!({
                "start": s.start, "u": s.u, "from": s.from, "to": s.to,
                "iterations": s.polls, "converged": s.converged})).collect::<Vec<Value>>(),
        },
        "state_differs_ticks": c.fitted_replay.state_differs.0,
        "warnings": c.warnings,
    });
    let mut s = serde_json::to_string_pretty(&doc).unwrap_or_default();
    s.push('\n');
    s
}
