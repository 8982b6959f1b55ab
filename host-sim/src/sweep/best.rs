//! Best offsets from a sweep: per speed and direction the grid's extreme, refined by
//! a parabola through it and its two neighbours and checked by one more run
//! ([`best_offsets`]); warnings for offsets not held and speeds without travel.

use super::{run_points, Grid, RunOutcome, OFFSET_RESOLUTION_DEG};
use crate::machine::Machine;
use crate::numbers;
use crate::output::progress::Progress;
use shared::controller::angle::wrap_deg_f64;

/// How a best offset was found.
#[derive(Clone, Debug, PartialEq)]
pub enum Refinement {
    /// The parabola's vertex, checked by a run that travelled at least as fast.
    Parabola,
    /// The grid point, because the parabola is degenerate (the reason).
    Degenerate(String),
    /// The grid point, because the run at the vertex (offset, mean velocity)
    /// travelled slower or did not hold its offset.
    Slower(f64, f64),
}

/// The best offset for one direction at one speed.
#[derive(Clone, Debug, PartialEq)]
pub struct Best {
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// The best offset, degrees in [0, 360).
    pub offset_deg: f64,
    /// The mean velocity measured at that offset, m/s.
    pub mean_velocity: f64,
    /// The best grid offset, degrees.
    pub grid_offset_deg: f64,
    /// The mean velocity at the best grid offset, m/s.
    pub grid_mean_velocity: f64,
    /// How `offset_deg` was found.
    pub refinement: Refinement,
}

/// The slowest mean velocity that counts as travel, m/s: a best offset slower
/// than this one way (or going the other way) "travels no way" there, with a
/// warning, in `tune`, `tune --robust` and `device tune --write` alike.
///
/// Why 0.5 mm/s. A machine that cannot travel still shows a mean velocity: with
/// frictionless feet (nothing to push on) the reference machine's runs give up
/// to 0.15 mm/s at the default `--t-end` of 5 s, and up to 0.33 mm/s at
/// `--t-end 2`, either sign (`host-sim tune examples/vibro-driver.toml --set
/// contacts.K1.friction=0 --set contacts.K2.friction=0 --offsets 0:360:30`):
/// the platform sways sideways with the eccentrics (about 0.2 mm), and a second
/// half that is not a whole number of turns keeps part of a sway in
/// `x(T) - x(T/2)`. Where it is a whole number (3000 rpm: 125 turns) what is
/// left is 1e-6 m/s and less. The reference machine's best offsets travel 21 to
/// 50 mm/s, 40 to 100 times this; an operator's marks 1 mm apart over a 10 s
/// hold are 0.1 mm/s.
pub const MIN_TRAVEL_MPS: f64 = 0.5e-3;

/// The warning for a speed where no offset travels `way`: the best found,
/// `offset_deg` at `velocity` m/s, does not reach [`MIN_TRAVEL_MPS`] that way.
pub fn no_travel(speed_rpm: f64, way: Way, offset_deg: f64, velocity: f64) -> String {
    format!(
        "{} rpm: no offset travels {} faster than {} mm/s: the best is {} deg at {} mm/s",
        numbers::sig(speed_rpm),
        way.name(),
        numbers::sig(MIN_TRAVEL_MPS * 1e3),
        numbers::sig(offset_deg),
        mm_s(velocity)
    )
}

/// Travel direction, for the search of the extreme.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Way {
    /// Rightward: the largest mean velocity.
    Right,
    /// Leftward: the most negative mean velocity.
    Left,
}

impl Way {
    /// `right` or `left`.
    pub fn name(self) -> &'static str {
        match self {
            Way::Right => "right",
            Way::Left => "left",
        }
    }

    /// The velocity turned so that larger is better.
    fn score(self, v: f64) -> f64 {
        match self {
            Way::Right => v,
            Way::Left => -v,
        }
    }

    /// Whether a mean velocity `v`, m/s, travels this way: faster than
    /// [`MIN_TRAVEL_MPS`] (NaN does not).
    pub fn travels(self, v: f64) -> bool {
        self.score(v) > MIN_TRAVEL_MPS
    }
}

/// The result of a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Tuning {
    /// What was swept.
    pub grid: Grid,
    /// One outcome per grid point, in [`Grid::points`] order.
    pub runs: Vec<RunOutcome>,
    /// Best rightward offset per speed (speeds with a finite velocity).
    pub right: Vec<Best>,
    /// Best leftward offset per speed.
    pub left: Vec<Best>,
    /// Warnings: runs that did not hold their offset, speeds without travel one
    /// way, plant warnings.
    pub warnings: Vec<String>,
    /// Runs made: the grid's and the checks of refined offsets.
    pub run_count: usize,
}

/// The vertex of the parabola through `(x[i], v[i])`, `x` ascending: its abscissa
/// and value, when the parabola opens downwards (`way` right: a maximum) or
/// upwards (left: a minimum). Otherwise the reason it is degenerate.
///
/// With the divided differences `d01 = (v1 - v0) / (x1 - x0)`,
/// `d12 = (v2 - v1) / (x2 - x1)` and `a = (d12 - d01) / (x2 - x0)` (half the
/// second derivative), the parabola is `p(x) = v1 + b (x - x1) + a (x - x1)^2`
/// with `b = d01 + a (x1 - x0)`, and its vertex is at `x* = x1 - b / (2 a)`,
/// `p(x*) = v1 - b^2 / (4 a)`: Newton's divided differences, the same vertex as
/// Press et al., Numerical Recipes, 3rd ed., section 10.3, eq. (10.3.1).
pub fn parabola_vertex(x: [f64; 3], v: [f64; 3], way: Way) -> Result<(f64, f64), String> {
    if !x.iter().chain(&v).all(|z| z.is_finite()) {
        return Err("a neighbour's velocity is not a number".into());
    }
    if !(x[0] < x[1] && x[1] < x[2]) {
        return Err("the three offsets are not distinct".into());
    }
    let d01 = (v[1] - v[0]) / (x[1] - x[0]);
    let d12 = (v[2] - v[1]) / (x[2] - x[1]);
    let a = (d12 - d01) / (x[2] - x[0]);
    let opens_right_way = match way {
        Way::Right => a < 0.0,
        Way::Left => a > 0.0,
    };
    if !opens_right_way {
        return Err(format!(
            "the three velocities are not a {} (flat or curving the wrong way)",
            match way {
                Way::Right => "peak",
                Way::Left => "trough",
            }
        ));
    }
    let b = d01 + a * (x[1] - x[0]);
    let vertex = x[1] - b / (2.0 * a);
    let value = v[1] - b * b / (4.0 * a);
    if !(vertex.is_finite() && value.is_finite()) || vertex < x[0] || vertex > x[2] {
        return Err("the vertex lies outside the three offsets".into());
    }
    Ok((vertex, value))
}

/// The refinement planned for one speed and direction: the best grid point and
/// the rounded vertex to check, or why there is none.
#[derive(Clone, Debug, PartialEq)]
pub(crate) struct Candidate {
    pub(crate) speed_rpm: f64,
    /// Index of the best grid point in the tuning's runs.
    pub(crate) grid_index: usize,
    /// The vertex, rounded and wrapped, if the fit is not degenerate.
    pub(crate) vertex: Result<f64, String>,
}

/// The best grid point for `way` among the runs of one speed (`runs`, offsets
/// ascending): the extreme among the runs that gave a speed (held their offset
/// and travelled), else among those with a mean velocity (offsets not held), the
/// first of equals; `None` when no velocity is finite (a run that was no travel
/// has none).
fn extreme(runs: &[RunOutcome], way: Way) -> Option<usize> {
    let any_held = runs.iter().any(|r| r.velocity().is_some());
    let mut best: Option<usize> = None;
    for (i, r) in runs.iter().enumerate() {
        if !r.mean_velocity.is_finite() || (any_held && r.velocity().is_none()) {
            continue;
        }
        if best.is_none_or(|b| way.score(r.mean_velocity) > way.score(runs[b].mean_velocity)) {
            best = Some(i);
        }
    }
    best
}

/// Stage 3, planning: for each speed and direction the best grid point and the
/// vertex of the parabola through it and its neighbours in offset (circularly
/// when the offsets go round the turn).
pub(crate) fn candidates(grid: &Grid, runs: &[RunOutcome], way: Way) -> Vec<Candidate> {
    let n = grid.offsets_deg.len();
    let circular = grid.circular();
    let mut out = Vec::new();
    for (k, &speed) in grid.speeds_rpm.iter().enumerate() {
        let row = &runs[k * n..(k + 1) * n];
        let Some(i) = extreme(row, way) else { continue };
        let o = &grid.offsets_deg;
        // The neighbours' offsets, unwrapped around the best one.
        let neighbours = if circular {
            let (p, q) = ((i + n - 1) % n, (i + 1) % n);
            Some((
                p,
                o[i] - (o[i] - o[p]).rem_euclid(360.0),
                q,
                o[i] + (o[q] - o[i]).rem_euclid(360.0),
            ))
        } else if i > 0 && i + 1 < n {
            Some((i - 1, o[i - 1], i + 1, o[i + 1]))
        } else {
            None
        };
        let vertex = match neighbours {
            None => Err("the best offset is at an end of the offset range".to_string()),
            Some((p, xp, q, xq)) => parabola_vertex(
                [xp, o[i], xq],
                [
                    row[p].mean_velocity,
                    row[i].mean_velocity,
                    row[q].mean_velocity,
                ],
                way,
            )
            .map(|(x, _)| {
                wrap_deg_f64((x / OFFSET_RESOLUTION_DEG).round() * OFFSET_RESOLUTION_DEG) + 0.0
            }),
        };
        out.push(Candidate {
            speed_rpm: speed,
            grid_index: k * n + i,
            vertex,
        });
    }
    out
}

/// Most check runs of `grid`'s best offsets: one per speed and direction. A
/// sweep's progress counts them all from the start; [`best_offsets`] counts
/// those it does not need as done.
pub fn most_checks(grid: &Grid) -> usize {
    2 * grid.speeds_rpm.len()
}

/// Stage 3: the best offsets of both directions, checking each refined offset by
/// a run (in parallel). A refined offset is kept when its run held the offset and
/// travelled at least as fast as the best grid point; otherwise the grid point
/// is. Returns (right, left, the check runs made).
pub fn best_offsets(
    machine: &Machine,
    grid: &Grid,
    runs: &[RunOutcome],
    progress: &Progress,
) -> (Vec<Best>, Vec<Best>, usize) {
    let plans: Vec<(Way, Candidate)> = [Way::Right, Way::Left]
        .into_iter()
        .flat_map(|w| candidates(grid, runs, w).into_iter().map(move |c| (w, c)))
        .collect();

    // The check runs: vertices that differ from their grid offset.
    let checks: Vec<(f64, f64)> = plans
        .iter()
        .filter_map(|(_, c)| match c.vertex {
            Ok(x) if x != runs[c.grid_index].offset_deg => Some((c.speed_rpm, x)),
            _ => None,
        })
        .collect();
    progress.inc(most_checks(grid).saturating_sub(checks.len()) as u64);
    let checked = run_points(machine, &checks, grid.t_end, progress);
    let mut checked = checked.into_iter();

    let (mut right, mut left) = (Vec::new(), Vec::new());
    for (way, c) in plans {
        let at = &runs[c.grid_index];
        let mut best = Best {
            speed_rpm: c.speed_rpm,
            offset_deg: at.offset_deg,
            mean_velocity: at.mean_velocity,
            grid_offset_deg: at.offset_deg,
            grid_mean_velocity: at.mean_velocity,
            refinement: Refinement::Parabola,
        };
        match c.vertex {
            Err(why) => best.refinement = Refinement::Degenerate(why),
            // The vertex is the grid point itself: nothing to check.
            Ok(x) if x == at.offset_deg => {}
            Ok(x) => {
                // In `checks` order: the same filter, the same sequence.
                if let Some(r) = checked.next() {
                    let faster = way.score(r.mean_velocity) >= way.score(at.mean_velocity);
                    if r.velocity().is_some() && faster {
                        best.offset_deg = x;
                        best.mean_velocity = r.mean_velocity;
                    } else {
                        best.refinement = Refinement::Slower(x, r.mean_velocity);
                    }
                }
            }
        }
        match way {
            Way::Right => right.push(best),
            Way::Left => left.push(best),
        }
    }
    (right, left, checks.len())
}

/// Stage 4: the warnings, in grid order, then by speed.
pub(crate) fn warnings(
    grid: &Grid,
    runs: &[RunOutcome],
    right: &[Best],
    left: &[Best],
) -> Vec<String> {
    let mut out = Vec::new();
    for r in runs {
        let at = format!(
            "{} rpm, {} deg",
            numbers::sig(r.speed_rpm),
            numbers::sig(r.offset_deg)
        );
        if let Some(why) = r.no_speed() {
            out.push(format!("{at}: {why}"));
        }
        for w in &r.plant_warnings {
            out.push(format!("{at}: {w}"));
        }
    }
    for &speed in &grid.speeds_rpm {
        let has = |list: &[Best]| list.iter().any(|b| b.speed_rpm == speed);
        if !has(right) || !has(left) {
            out.push(format!(
                "{} rpm: no run gave a mean velocity: no best offset",
                numbers::sig(speed)
            ));
        }
    }
    for (list, way) in [(right, Way::Right), (left, Way::Left)] {
        for b in list {
            if !way.travels(b.mean_velocity) {
                out.push(no_travel(b.speed_rpm, way, b.offset_deg, b.mean_velocity));
            }
        }
    }
    out
}

/// A velocity in mm/s with a sign and one decimal: `+29.2`, `-0.4`, `0.0`.
pub(crate) fn mm_s(v: f64) -> String {
    if !v.is_finite() {
        return "nan".into();
    }
    let s = format!("{:+.1}", v * 1e3);
    if s == "+0.0" || s == "-0.0" {
        "0.0".into()
    } else {
        s
    }
}
