//! The measured rows of `host-sim calibrate` gathered by their distinct (speed,
//! offset) point: one simulated run serves every row at a point, and the weighted
//! sum of squares over the rows is a sum over the points (docs/calibration.md,
//! "Method"). Nothing is kept row by row but the first [`ROWS_SHOWN`] rows, for
//! the report: a million rows at a few points cost no more than the points.
//!
//! For the rows `r` at one point, with weights `w_r` and measured speeds `v_r`,
//! their total weight `W = sum w_r`, weighted mean `vbar = sum w_r v_r / W` and
//! scatter `Q = sum w_r (v_r - vbar)^2`, and any simulated speed `g`:
//!
//! ```text
//! sum_r w_r (g - v_r)^2 = W (g - vbar)^2 + Q
//! ```
//!
//! (the cross term `2 (g - vbar) sum w_r (vbar - v_r)` is zero). So the point's
//! residual `sqrt(W) (g - vbar)` with the constant `sum Q` gives the rows' `S`
//! exactly, and its derivative `sqrt(W) dg/du` gives the rows' `J^T J` (each row's
//! `w_r (dg/du)^2`, summed): the fit and its standard errors are those of the
//! rows. `vbar` and `Q` are accumulated row by row by West's update (D. H. D.
//! West, *Communications of the ACM* 22, 1979, "Updating mean and variance
//! estimates: an improved method"), without the cancellation of `sum w v^2 - W
//! vbar^2`.

use std::collections::HashMap;

use crate::measured::Row;

/// Rows listed one by one in the outputs (the first ones of the file); the rest
/// are counted. Their points are all in the outputs' fit.
pub const ROWS_SHOWN: usize = 1000;

/// The most distinct points `calibrate` takes: one evaluation runs each, and a
/// fit is some 80 evaluations (docs/calibration.md, "Cost").
pub const MAX_POINTS: usize = 10_000;

/// From this many distinct points on, a warning before the fit says what it costs.
pub const MANY_POINTS: usize = 500;

/// The residual of a point whose simulated run did not hold its offset (from its
/// rows' weighted mean), m/s: twice the reference machine's fastest travel (50
/// mm/s at 3500 rpm), so that a fit holding every offset always scores better
/// than one that does not.
pub const NOT_HELD_RESIDUAL_MPS: f64 = 0.1;

/// One distinct (speed, offset) of the measured rows.
#[derive(Clone, Debug, PartialEq)]
pub struct Point {
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// Phase offset, degrees in [0, 360).
    pub offset_deg: f64,
    /// Rows at it.
    pub rows: usize,
    /// Their total weight `W`.
    pub weight: f64,
    /// Their weighted mean measured velocity `vbar`, m/s.
    pub mean_mps: f64,
    /// Their scatter `Q = sum w (v - vbar)^2`, m^2/s^2: what no simulated speed fits.
    pub scatter: f64,
}

impl Point {
    /// The weighted residual `sqrt(W) (g - vbar)` of the point at the simulated
    /// speed `g`, m/s (`None`: the run did not hold its offset, and the residual
    /// is `sqrt(W)` [`NOT_HELD_RESIDUAL_MPS`]). With the scatter within the
    /// points, the squares give the rows' `S` (module doc).
    pub fn residual(&self, simulated: Option<f64>) -> f64 {
        let e = match simulated {
            Some(g) => g - self.mean_mps,
            None => NOT_HELD_RESIDUAL_MPS,
        };
        self.weight.sqrt() * e
    }
}

/// The measured file, gathered.
#[derive(Debug, Default)]
pub struct Gathered {
    /// The distinct points in the order first met (at most [`MAX_POINTS`]).
    pub points: Vec<Point>,
    /// Every row read.
    pub rows: usize,
    /// Rows at points beyond the first [`MAX_POINTS`], not gathered (nor their
    /// points remembered: memory stays bounded).
    pub rows_beyond: usize,
    /// The first [`ROWS_SHOWN`] rows, each with its point's index.
    pub shown: Vec<(Row, usize)>,
    /// Each point's index, by the bits of its speed and offset.
    index: HashMap<(u64, u64), usize>,
}

impl Gathered {
    /// Adds a row to its point (a new point when none has its speed and offset,
    /// bit for bit).
    pub fn add(&mut self, row: Row) {
        self.rows += 1;
        let key = (row.speed_rpm.to_bits(), row.offset_deg.to_bits());
        let k = match self.index.get(&key) {
            Some(&k) => k,
            None if self.points.len() >= MAX_POINTS => {
                self.rows_beyond += 1;
                return;
            }
            None => {
                self.index.insert(key, self.points.len());
                self.points.push(Point {
                    speed_rpm: row.speed_rpm,
                    offset_deg: row.offset_deg,
                    rows: 0,
                    weight: 0.0,
                    mean_mps: 0.0,
                    scatter: 0.0,
                });
                self.points.len() - 1
            }
        };
        // West's update: W' = W + w, vbar' = vbar + (w / W') (v - vbar),
        // Q' = Q + w (v - vbar) (v - vbar').
        let p = &mut self.points[k];
        let (w, v) = (row.weight, row.velocity_mps);
        p.rows += 1;
        p.weight += w;
        let delta = v - p.mean_mps;
        p.mean_mps += w / p.weight * delta;
        p.scatter += w * delta * (v - p.mean_mps);
        if self.shown.len() < ROWS_SHOWN {
            self.shown.push((row, k));
        }
    }

    /// The scatter within the points, `sum Q`, m^2/s^2: the part of `S` no fit
    /// changes.
    pub fn scatter(&self) -> f64 {
        self.points.iter().map(|p| p.scatter).sum()
    }

    /// The distinct points' speeds and offsets, for the runs.
    pub fn speeds_offsets(&self) -> Vec<(f64, f64)> {
        self.points
            .iter()
            .map(|p| (p.speed_rpm, p.offset_deg))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(line: usize, speed_rpm: f64, offset_deg: f64, velocity_mps: f64, weight: f64) -> Row {
        Row {
            line,
            speed_rpm,
            offset_deg,
            velocity_mps,
            weight,
        }
    }

    /// Repeated rows share one point; its sums give the rows' weighted sum of
    /// squares for any simulated speed, as the module doc's identity says.
    #[test]
    fn the_points_sums_give_the_rows_sum_of_squares() {
        let rows = [
            row(2, 3000.0, 90.0, 0.031, 1.0),
            row(3, 3000.0, 0.0, 0.010, 2.0),
            row(4, 3000.0, 90.0, 0.0295, 3.0),
            row(5, 3000.0, 90.0, 0.0302, 0.5),
        ];
        let mut g = Gathered::default();
        for r in &rows {
            g.add(r.clone());
        }
        assert_eq!(g.rows, 4);
        assert_eq!(g.speeds_offsets(), vec![(3000.0, 90.0), (3000.0, 0.0)]);
        assert_eq!(
            g.shown.iter().map(|(_, k)| *k).collect::<Vec<_>>(),
            [0, 1, 0, 0]
        );
        let p = &g.points[0];
        assert_eq!((p.rows, p.weight), (3, 4.5));
        for sim in [0.0, 0.03, -0.01] {
            let by_rows: f64 = rows
                .iter()
                .filter(|r| r.offset_deg == 90.0)
                .map(|r| r.weight * (sim - r.velocity_mps).powi(2))
                .sum();
            let by_point = p.weight * (sim - p.mean_mps).powi(2) + p.scatter;
            assert!(
                (by_rows - by_point).abs() <= 1e-15 * by_rows,
                "{by_rows} {by_point}"
            );
        }
        assert_eq!(g.points[1].scatter, 0.0);
    }

    /// Past the first rows, none is kept; past the most points, none is gathered
    /// but each is counted.
    #[test]
    fn rows_and_points_are_bounded() {
        let mut g = Gathered::default();
        for i in 0..ROWS_SHOWN + 10 {
            g.add(row(i + 2, 3000.0, 90.0, 0.03, 1.0));
        }
        assert_eq!(
            (g.rows, g.shown.len(), g.points.len()),
            (ROWS_SHOWN + 10, ROWS_SHOWN, 1)
        );
        for i in 0..MAX_POINTS + 2 {
            g.add(row(i, 2000.0, i as f64 * 1e-3, 0.03, 1.0));
        }
        assert_eq!((g.points.len(), g.rows_beyond), (MAX_POINTS, 3));
    }
}
