//! What a fit will cost, said on stderr before it starts (docs/calibration.md,
//! "Cost"): the most runs it can make, from the search's settings and the
//! measured file's distinct points, and the time they take at the cost of one run
//! measured first (the file's values at the first point, the chosen `--t-end`):
//!
//! ```text
//! runs <= (most evaluations of the search) x (distinct points)
//! time ~= runs x (seconds of the run timed) / threads
//! ```
//!
//! The most evaluations count the two of the numerical noise's runs at the other
//! tolerances ([`super::numerical`]), which cost a little more than the others.
//! An upper bound on the runs (the search usually stops at 70 to 80 % of its
//! budget) and a rough one on the time (runs differ in cost by their gait).

use std::time::Instant;

use super::fit::Settings;
use super::points::MANY_POINTS;
use super::{CalibrateArgs, Inputs};
use crate::numbers;
use crate::numbers::count;
use crate::sweep::load_machine;
use crate::sweep::run_point;

/// What the fit will cost.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// The most evaluations of the search.
    pub evaluations: usize,
    /// Distinct measured points: runs an evaluation.
    pub points: usize,
    /// End time of each run, s.
    pub t_end: f64,
    /// Seconds one run took (the run timed), if it ran.
    pub seconds_per_run: Option<f64>,
    /// Warnings for the result too: a file of very many points.
    pub warnings: Vec<String>,
    /// The evaluations and runs the parts of a fit in parts made already
    /// (`merge`): the merge makes the rest.
    pub in_parts: Option<InParts>,
}

/// What the parts of a fit in parts evaluated before the merge: the starts.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InParts {
    /// Evaluations (the starts the parts ran or the reader refused).
    pub evaluations: usize,
    /// Their runs (none for a refused start).
    pub runs: usize,
}

impl Plan {
    /// The most runs.
    pub fn runs(&self) -> usize {
        self.evaluations * self.points
    }

    /// The planned cost, one line, then the warnings: for stderr. Of a merge,
    /// the evaluations the parts made are named, and the time is the rest's.
    pub fn render(&self, threads: usize) -> String {
        let (parts, left) = match self.in_parts {
            Some(done) => (
                format!(
                    ", {} of them ({}) made in the parts",
                    count(done.evaluations, "evaluation"),
                    count(done.runs, "run")
                ),
                Some(self.runs().saturating_sub(done.runs)),
            ),
            None => (String::new(), None),
        };
        let time = match self.seconds_per_run {
            Some(s) => format!(
                "; one took {} s, so up to about {} on {}{}",
                numbers::sig(round2(s)),
                duration(left.unwrap_or(self.runs()) as f64 * s / threads.max(1) as f64),
                count(threads, "thread"),
                left.map_or(String::new(), |n| format!(
                    " for the other {}",
                    count(n, "run")
                ))
            ),
            None => String::new(),
        };
        let mut out = format!(
            "calibrate: up to {} x {} = {} of {} s{parts}{time}\n",
            count(self.evaluations, "evaluation"),
            count(self.points, "point"),
            count(self.runs(), "run"),
            numbers::sig(self.t_end)
        );
        for w in &self.warnings {
            out += &format!("warning: {w}\n");
        }
        out
    }
}

/// The plan of a fit with `settings` on `inputs`, one run timed; `in_parts`,
/// what the parts of a fit in parts evaluated already.
pub fn plan(
    args: &CalibrateArgs,
    inputs: &Inputs,
    settings: &Settings,
    in_parts: Option<InParts>,
) -> Plan {
    let p = inputs.keys.len();
    let points = inputs.data.points.len();
    let seconds_per_run = inputs.data.points.first().and_then(|first| {
        let machine = load_machine(&args.machine.path, &inputs.text, &args.set.keys).ok()?;
        let started = Instant::now();
        run_point(&machine, first.speed_rpm, first.offset_deg, inputs.t_end);
        Some(started.elapsed().as_secs_f64())
    });
    let evaluations = super::most_evaluations(settings, p);
    let mut warnings = Vec::new();
    if points >= MANY_POINTS {
        warnings.push(format!(
            "{} measured: every evaluation of the fit runs each of them, up to {} in all; fewer points, each measured more than once (a repeated point costs no run), take a fraction of the time (docs/calibration.md, \"Cost\")",
            count(points, "distinct point"),
            count(evaluations * points, "run")
        ));
    }
    Plan {
        evaluations,
        points,
        t_end: inputs.t_end,
        seconds_per_run,
        warnings,
        in_parts,
    }
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

/// A time for people: `40 s`, `12 min`, `3.5 h`.
pub fn duration(seconds: f64) -> String {
    if seconds < 100.0 {
        format!("{} s", numbers::sig(round2(seconds.max(0.0))))
    } else if seconds < 6000.0 {
        format!("{} min", numbers::sig(round2(seconds / 60.0)))
    } else {
        format!("{} h", numbers::sig(round2(seconds / 3600.0)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_line_states_runs_and_time() {
        let plan = Plan {
            evaluations: 96,
            points: 15,
            t_end: 5.0,
            seconds_per_run: Some(0.0912),
            warnings: vec!["many".into()],
            in_parts: None,
        };
        // 1440 runs x 0.0912 s / 2 threads = 65.7 s.
        assert_eq!(
            plan.render(2),
            "calibrate: up to 96 evaluations x 15 points = 1440 runs of 5 s; one took 0.091 s, so up to about 66 s on 2 threads\nwarning: many\n"
        );
        // A merge: 7 evaluations (14 runs) made in the parts, the time of the
        // other 1426 runs: 1426 x 0.0912 s / 2 = 65.0 s.
        let merge = Plan {
            in_parts: Some(InParts {
                evaluations: 7,
                runs: 14,
            }),
            warnings: vec![],
            ..plan
        };
        assert_eq!(
            merge.render(2),
            "calibrate: up to 96 evaluations x 15 points = 1440 runs of 5 s, 7 evaluations of them (14 runs) made in the parts; one took 0.091 s, so up to about 65 s on 2 threads for the other 1426 runs\n"
        );
        assert_eq!(duration(4000.0), "67 min");
        assert_eq!(duration(36000.0), "10 h");
    }
}
