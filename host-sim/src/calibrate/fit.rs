//! The least-squares search of `host-sim calibrate`, on any residual function of
//! `p` box-normalised coordinates `u` in [0, 1]^p (docs/calibration.md, "Method").
//!
//! Objective: `S(u) = sum_r r_r(u)^2`, the residuals `r` weighted already
//! (`sqrt(w_r) (v_sim - v_meas)`); a residual that is not a number counts as an
//! infinite `S` (a machine the reader refuses).
//!
//! Stages of [`fit`]:
//! 1. multistart: the starts given (the file's values) and a Latin hypercube of
//!    [`Settings::starts`] points (`latin_hypercube`, seeded: deterministic),
//!    evaluated as one batch;
//! 2. local search from the best [`Settings::local_searches`] starts, by
//!    [`Settings::local`]:
//!    - [`Local::Compass`], for travel speeds: a compass (pattern) search,
//!      derivative-free and bounded (Kolda, Lewis & Torczon, *SIAM Review* 45,
//!      2003, section 3): poll `u +- h e_i` (clamped to the box, all `2p` points
//!      as one batch), move to the best poll point when it lowers `S`, else halve
//!      `h`; from [`Settings::first_step`] down to [`Settings::last_step`]. The
//!      travel speed is not smooth in the parameters (gait changes), so no
//!      gradient method;
//!    - [`Local::LevenbergMarquardt`], for a capture's residuals, which are
//!      smooth in the motor keys at the scale of the Jacobian's step
//!      ([`super::levenberg`]);
//!
//!    each at most [`Settings::budget`] new evaluations;
//! 3. the best point found, and the Jacobian of the residuals there by
//!    differences of step [`Settings::jacobian_step`] (central inside the box,
//!    one-sided at its faces): `2p` more evaluations.
//!
//! Every point is evaluated once (a memo); batches go to the residual function
//! whole, so it may run them in parallel.

use std::collections::HashMap;

use crate::failure::Failure;
use crate::machine::uncertainty::latin_hypercube;

/// Default step of the Jacobian's differences, normalised: 1/16 of each range,
/// four times the search's last step. The simulated speed is not smooth at that
/// last step: where the gait is chaotic it jumps by some 0.3 mm/s from one
/// parameter value to the next (the reference machine at 3250 rpm and 140
/// degrees, friction 0.290 to 0.306 in steps of 0.002), and a difference over
/// 1/64 of the friction's range [0.2, 0.6] would read such a jump as a slope of
/// 50 mm/s per unit, as large as the true one (36 to 57 mm/s per unit at 2750
/// rpm): a standard error several times too small. Over 1/16 the jump reads as
/// a quarter of that.
pub const JACOBIAN_STEP: f64 = 1.0 / 16.0;

/// The local search of stage 2.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Local {
    /// The compass search (module doc).
    Compass,
    /// Levenberg–Marquardt on differences of step [`Settings::jacobian_step`]
    /// ([`super::levenberg`]).
    LevenbergMarquardt,
}

/// How the search goes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    /// The local search.
    pub local: Local,
    /// Points of the Latin hypercube of starts (besides the given ones).
    pub starts: usize,
    /// Seed of the hypercube.
    pub seed: u64,
    /// Local searches, from the best starts.
    pub local_searches: usize,
    /// First poll step, normalised.
    pub first_step: f64,
    /// Last poll step, normalised: the search's resolution and the Jacobian's step.
    pub last_step: f64,
    /// Most new evaluations of one local search.
    pub budget: usize,
    /// Step of the Jacobian's differences, normalised.
    pub jacobian_step: f64,
}

impl Settings {
    /// The defaults for `p` keys: `4 p` starts (at least 6), two local searches
    /// from 1/8 of each range down to 1/64, at most `20 p` new evaluations each (a
    /// search from the far side of the box to a minimum inside takes about 9
    /// polls, `14 p` new points, on the unit tests' linear model). With two keys
    /// that is about 65 evaluations (benchmarks/tune.md, "Calibration cost on the
    /// reference machine").
    pub fn for_keys(p: usize) -> Settings {
        Settings {
            local: Local::Compass,
            starts: (4 * p).max(6),
            seed: 1,
            local_searches: 2,
            first_step: 1.0 / 8.0,
            last_step: 1.0 / 64.0,
            budget: 20 * p.max(1),
            jacobian_step: JACOBIAN_STEP,
        }
    }

    /// The defaults for `p` keys fitted to a capture (docs/calibration.md,
    /// "Motor keys from a capture"): the same starts; two Levenberg–Marquardt
    /// searches ([`super::levenberg`]) of at most 15 iterations each (a
    /// Jacobian of `p` differences and [`super::levenberg::DAMPINGS`] trial
    /// steps an iteration; the ten motor keys of the test's two rotors,
    /// `host-sim/tests/cli_calibrate_capture.rs`, take 6 to 9), stopping at a
    /// step below 1/1000 of every range; differences of 1/16 of each range. The
    /// replayed signals, summed over windows, move linearly with a motor key
    /// over a few percent of it (their sum of squares grows fourfold a
    /// doubling, `capture::residuals`), and the counts' rounding left in the
    /// windows jitters them by a fixed amount: the wider the step, the less a
    /// difference is that jitter. On four captures like the test's, each range
    /// half to one and a half times the file's value, the searches took 6 to 9
    /// iterations with differences of 1/16 of the range; on the first of them
    /// 11 and 16 with 1/32; with 1/64 all four stopped at 15 with the viscous
    /// frictions still 2 to 11 % off.
    pub fn for_capture(p: usize) -> Settings {
        let iterations = 15;
        let step = 1.0 / 16.0;
        Settings {
            local: Local::LevenbergMarquardt,
            starts: (4 * p).max(6),
            seed: 1,
            local_searches: 2,
            // A compass search's; the Levenberg–Marquardt steps are its own.
            first_step: step,
            last_step: 1.0e-3,
            budget: iterations * (p.max(1) + super::levenberg::DAMPINGS.len()),
            jacobian_step: step,
        }
    }

    /// Most evaluations [`fit`] makes with `given` starts (for a progress bar).
    pub fn most_evaluations(&self, given: usize, p: usize) -> usize {
        given + self.starts + self.local_searches * self.budget + 2 * p + 1
    }
}

/// A residual function: the residual vectors of a batch of points, in order.
/// `Err`: stop (Ctrl-C), with why.
pub type Residuals<'a> = dyn FnMut(&[Vec<f64>]) -> Result<Vec<Vec<f64>>, Failure> + 'a;

/// One local search.
#[derive(Clone, Debug, PartialEq)]
pub struct Search {
    /// The start it went from (index in [`Fit::starts`]).
    pub start: usize,
    /// Where it ended.
    pub u: Vec<f64>,
    /// `S` at the start and at the end.
    pub from: f64,
    /// `S` at the end.
    pub to: f64,
    /// Polls made (a Levenberg–Marquardt search: its Jacobians).
    pub polls: usize,
    /// Whether the step went down to the last one (not stopped by the budget).
    pub converged: bool,
}

/// What [`fit`] found.
#[derive(Clone, Debug, PartialEq)]
pub struct Fit {
    /// The best point.
    pub u: Vec<f64>,
    /// Its residuals.
    pub residuals: Vec<f64>,
    /// `S` there.
    pub ssr: f64,
    /// The starts and their `S`, the given ones first.
    pub starts: Vec<(Vec<f64>, f64)>,
    /// The local searches, best start first.
    pub searches: Vec<Search>,
    /// The Jacobian `d r_r / d u_i` at the best point, row by row (`n x p`).
    pub jacobian: Vec<Vec<f64>>,
    /// Points evaluated.
    pub evaluations: usize,
}

/// `S` of a residual vector; not a number counts as infinite.
pub fn ssr(r: &[f64]) -> f64 {
    let s: f64 = r.iter().map(|x| x * x).sum();
    if s.is_nan() {
        f64::INFINITY
    } else {
        s
    }
}

/// Every point evaluated once.
pub struct Memo<'a, 'b> {
    residuals: &'a mut Residuals<'b>,
    seen: HashMap<Vec<u64>, Vec<f64>>,
}

impl Memo<'_, '_> {
    /// Points evaluated so far.
    pub fn len(&self) -> usize {
        self.seen.len()
    }

    /// Whether no point was evaluated yet.
    pub fn is_empty(&self) -> bool {
        self.seen.is_empty()
    }

    /// The residuals of `batch`, the new points evaluated as one batch.
    pub fn get(&mut self, batch: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, Failure> {
        let key = |u: &Vec<f64>| u.iter().map(|x| x.to_bits()).collect::<Vec<u64>>();
        let mut new: Vec<Vec<f64>> = Vec::new();
        for u in batch {
            if !self.seen.contains_key(&key(u)) && !new.contains(u) {
                new.push(u.clone());
            }
        }
        if !new.is_empty() {
            let got = (self.residuals)(&new)?;
            for (u, r) in new.iter().zip(got) {
                self.seen.insert(key(u), r);
            }
        }
        Ok(batch.iter().map(|u| self.seen[&key(u)].clone()).collect())
    }
}

/// The starts of stage 1 in `p` dimensions: those `given`, then the Latin
/// hypercube of [`Settings::starts`] points (seeded: the same every time).
pub fn starts(p: usize, given: &[Vec<f64>], settings: &Settings) -> Vec<Vec<f64>> {
    let mut starts: Vec<Vec<f64>> = given.to_vec();
    starts.extend(latin_hypercube(settings.starts, p, settings.seed));
    starts
}

/// Stages 1 to 3 of the module doc in `p` dimensions from the starts `given`.
pub fn fit(
    p: usize,
    given: &[Vec<f64>],
    settings: &Settings,
    residuals: &mut Residuals<'_>,
) -> Result<Fit, Failure> {
    let mut memo = Memo {
        residuals,
        seen: HashMap::new(),
    };

    // 1. The starts.
    let starts = starts(p, given, settings);
    let values: Vec<f64> = memo.get(&starts)?.iter().map(|r| ssr(r)).collect();
    let mut order: Vec<usize> = (0..starts.len())
        .filter(|&i| values[i].is_finite())
        .collect();
    order.sort_by(|&a, &b| values[a].total_cmp(&values[b]).then(a.cmp(&b)));

    // 2. The local searches.
    let mut searches = Vec::new();
    for &s in order.iter().take(settings.local_searches) {
        searches.push(match settings.local {
            Local::Compass => compass(&mut memo, &starts[s], values[s], s, settings)?,
            Local::LevenbergMarquardt => {
                super::levenberg::search(&mut memo, &starts[s], values[s], s, settings)?
            }
        });
    }
    let best = searches
        .iter()
        .min_by(|a, b| a.to.total_cmp(&b.to))
        .map(|s| s.u.clone())
        .unwrap_or_else(|| starts[0].clone());

    // 3. The Jacobian there.
    let h = settings.jacobian_step;
    let mut pairs = Vec::new();
    for i in 0..p {
        let mut up = best.clone();
        let mut down = best.clone();
        up[i] = (best[i] + h).min(1.0);
        down[i] = (best[i] - h).max(0.0);
        pairs.push(up);
        pairs.push(down);
    }
    let mut batch = vec![best.clone()];
    batch.extend(pairs.iter().cloned());
    let got = memo.get(&batch)?;
    let residuals = got[0].clone();
    let n = residuals.len();
    let mut jacobian = vec![vec![0.0; p]; n];
    for i in 0..p {
        let (up, down) = (&got[1 + 2 * i], &got[2 + 2 * i]);
        let du = pairs[2 * i][i] - pairs[2 * i + 1][i];
        for (row, (a, b)) in jacobian.iter_mut().zip(up.iter().zip(down)) {
            row[i] = if du > 0.0 { (a - b) / du } else { 0.0 };
        }
    }
    Ok(Fit {
        ssr: ssr(&residuals),
        u: best,
        residuals,
        starts: starts.into_iter().zip(values).collect(),
        searches,
        jacobian,
        evaluations: memo.seen.len(),
    })
}

/// Stage 2 from start `index` (`u0`, where `S = f0`).
fn compass(
    memo: &mut Memo<'_, '_>,
    u0: &[f64],
    f0: f64,
    index: usize,
    settings: &Settings,
) -> Result<Search, Failure> {
    let (mut u, mut f) = (u0.to_vec(), f0);
    let mut h = settings.first_step;
    let before = memo.seen.len();
    let mut polls = 0;
    let converged = loop {
        if memo.seen.len() - before >= settings.budget {
            break false;
        }
        // Poll the neighbours along every axis, within the box.
        let mut poll = Vec::new();
        for i in 0..u.len() {
            for sign in [1.0, -1.0] {
                let mut v = u.clone();
                v[i] = (u[i] + sign * h).clamp(0.0, 1.0);
                if v[i] != u[i] {
                    poll.push(v);
                }
            }
        }
        polls += 1;
        let got = memo.get(&poll)?;
        let best = got
            .iter()
            .map(|r| ssr(r))
            .enumerate()
            .min_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        match best {
            Some((k, s)) if s < f => {
                u = poll[k].clone();
                f = s;
            }
            _ if h <= settings.last_step => break true,
            _ => h *= 0.5,
        }
    };
    Ok(Search {
        start: index,
        u,
        from: f0,
        to: f,
        polls,
        converged,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A linear model `r = A (u - u*)` with its minimum inside the box is found
    /// to the last step `h`, and its Jacobian is `A` (exact differences). Bound:
    /// where no poll lowers `S = |A (u - u*)|^2`, `|g_i| <= h (A^T A)_ii` for the
    /// gradient `g = 2 A^T A (u - u*)`, so `|u - u*| <= (A^T A)^-1 (h/2) diag`:
    /// here `(0.59 h, 0.55 h)`, within `h`.
    #[test]
    fn a_linear_model_is_solved_to_the_resolution() {
        let star = [0.3, 0.7];
        let a = [[1.0, 0.5], [0.2, 1.0], [1.0, -1.0]];
        let mut calls = 0;
        let mut f = |batch: &[Vec<f64>]| -> Result<Vec<Vec<f64>>, Failure> {
            calls += 1;
            Ok(batch
                .iter()
                .map(|u| {
                    a.iter()
                        .map(|row| row[0] * (u[0] - star[0]) + row[1] * (u[1] - star[1]))
                        .collect()
                })
                .collect())
        };
        let s = Settings::for_keys(2);
        let fit = fit(2, &[vec![0.5, 0.5]], &s, &mut f).unwrap();
        for i in 0..2 {
            assert!((fit.u[i] - star[i]).abs() <= s.last_step, "{:?}", fit.u);
            for (row, arow) in fit.jacobian.iter().zip(&a) {
                assert!((row[i] - arow[i]).abs() < 1e-12);
            }
        }
        assert!(fit.searches.iter().all(|s| s.converged));
        assert!(fit.evaluations <= s.most_evaluations(1, 2));
    }

    /// Two basins: the given start lies in the shallow one; the multistart finds
    /// the deep one.
    #[test]
    fn the_multistart_leaves_a_local_minimum() {
        let mut f = |batch: &[Vec<f64>]| -> Result<Vec<Vec<f64>>, Failure> {
            Ok(batch
                .iter()
                .map(|u| {
                    let d1 = (u[0] - 0.1).powi(2) + (u[1] - 0.1).powi(2);
                    let d2 = (u[0] - 0.8).powi(2) + (u[1] - 0.8).powi(2);
                    // S = min(0.05 + d1, d2) as one residual.
                    vec![(0.05 + d1).min(d2).sqrt()]
                })
                .collect())
        };
        let s = Settings::for_keys(2);
        let fit = fit(2, &[vec![0.1, 0.1]], &s, &mut f).unwrap();
        assert!((fit.u[0] - 0.8).abs() <= s.last_step && (fit.u[1] - 0.8).abs() <= s.last_step);
    }

    /// A minimum on a face of the box: the search stops there, the Jacobian is
    /// one-sided.
    #[test]
    fn the_box_holds() {
        let mut f = |batch: &[Vec<f64>]| -> Result<Vec<Vec<f64>>, Failure> {
            Ok(batch.iter().map(|u| vec![u[0] + 1.0]).collect())
        };
        let fit = fit(1, &[vec![0.5]], &Settings::for_keys(1), &mut f).unwrap();
        assert_eq!(fit.u, vec![0.0]);
        assert!((fit.jacobian[0][0] - 1.0).abs() < 1e-12);
    }

    /// A stop from the residual function ends the search with its reason.
    #[test]
    fn a_stop_stops() {
        let mut f =
            |_: &[Vec<f64>]| -> Result<Vec<Vec<f64>>, Failure> { Err(Failure::run("stop")) };
        assert_eq!(
            fit(1, &[vec![0.5]], &Settings::for_keys(1), &mut f),
            Err(Failure::run("stop"))
        );
    }
}
