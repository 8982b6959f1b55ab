//! `host-sim device tune --write`: the tuning table made from a measured file's
//! rows, with `host-sim tune`'s peak fit ([`crate::sweep::best`]).
//!
//! Per speed, the rows at one offset are averaged (weighted mean
//! `v = sum(w_i v_i) / sum(w_i)`); then, as `tune` does, the best offset each way is
//! the extreme of the mean velocities, refined by the vertex of the parabola
//! through it and its two neighbours in offset (circularly when the offsets go
//! round the turn), rounded to 0.1 degree; a degenerate fit keeps the measured
//! extreme. Unlike `tune`, no run checks the vertex: it is the fit's, not a
//! measurement (measure it with `--resume FILE --offsets X` and write again).

use std::fmt::Write as _;
use std::path::Path;

use crate::machine::tuning_file;
use crate::measured::{Row, SAME_POINT};
use crate::numbers;
use crate::numbers::count;
use crate::sweep::best::{candidates, mm_s, no_travel, Way};
use crate::sweep::{Grid, RunOutcome};
use shared::controller::angle::{wrap_deg_f64, wrap_deg_signed_f64};

/// Fewest offsets at a speed for the peak fit: the extreme and its two
/// neighbours.
pub const MIN_OFFSETS: usize = 3;

/// The best offset one way at one speed.
#[derive(Clone, Debug, PartialEq)]
pub struct Pick {
    /// The offset for the table, degrees in [0, 360).
    pub offset_deg: f64,
    /// The measured extreme: offset, degrees, and mean velocity, m/s.
    pub grid: (f64, f64),
    /// Why the fit kept the measured extreme, if it did.
    pub degenerate: Option<String>,
}

/// One speed's measurements averaged per offset (offsets in [0, 360),
/// ascending) and its picks.
#[derive(Clone, Debug, PartialEq)]
pub struct SpeedFit {
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// The offsets measured, ascending.
    pub points: Vec<OffsetMean>,
    /// Best rightward offset.
    pub right: Pick,
    /// Best leftward offset.
    pub left: Pick,
}

/// One offset's measurements at a speed: (offset, degrees in [0, 360); mean
/// velocity, m/s; rows averaged).
pub type OffsetMean = (f64, f64, usize);

/// The rows of one offset at a speed: (offset, degrees in [0, 360); their
/// velocities, m/s, and weights).
type Group = (f64, Vec<(f64, f64)>);

/// The weighted mean `sum(w_i v_i) / sum(w_i)` of `(v, w)` pairs, the weights
/// first divided by the largest (the mean is the same, and no sum can overflow
/// whatever weights the file holds: each term is at most `|v|`, the sum of
/// weights at most the number of rows).
pub fn weighted_mean(rows: &[(f64, f64)]) -> f64 {
    let most = rows.iter().fold(0.0f64, |m, r| m.max(r.1));
    let (mut wv, mut w) = (0.0, 0.0);
    for &(v, weight) in rows {
        let u = weight / most;
        wv += u * v;
        w += u;
    }
    wv / w
}

/// The rows grouped by speed (ascending) and, within a speed, by offset
/// (wrapped to [0, 360), ascending), each group averaged by weight
/// ([`weighted_mean`]).
pub fn averages(rows: &[Row]) -> Vec<(f64, Vec<OffsetMean>)> {
    let mut speeds: Vec<(f64, Vec<Group>)> = Vec::new();
    for r in rows {
        let i = match speeds
            .iter()
            .position(|(s, _)| (s - r.speed_rpm).abs() <= SAME_POINT)
        {
            Some(i) => i,
            None => {
                speeds.push((r.speed_rpm, Vec::new()));
                speeds.len() - 1
            }
        };
        let offsets = &mut speeds[i].1;
        let measured = (r.velocity_mps, r.weight);
        match offsets
            .iter_mut()
            .find(|(o, _)| wrap_deg_signed_f64(o - r.offset_deg).abs() <= SAME_POINT)
        {
            Some(g) => g.1.push(measured),
            None => offsets.push((wrap_deg_f64(r.offset_deg) + 0.0, vec![measured])),
        }
    }
    speeds.sort_by(|a, b| a.0.total_cmp(&b.0));
    speeds
        .into_iter()
        .map(|(s, mut offsets)| {
            offsets.sort_by(|a, b| a.0.total_cmp(&b.0));
            (
                s,
                offsets
                    .into_iter()
                    .map(|(o, runs)| (o, weighted_mean(&runs), runs.len()))
                    .collect(),
            )
        })
        .collect()
}

/// The peak fit of one speed's averaged `points` (at least [`MIN_OFFSETS`]).
fn fit(speed_rpm: f64, points: Vec<OffsetMean>) -> SpeedFit {
    let grid = Grid {
        speeds_rpm: vec![speed_rpm],
        offsets_deg: points.iter().map(|p| p.0).collect(),
        t_end: f64::NAN,
    };
    let runs: Vec<RunOutcome> = points
        .iter()
        .map(|&(offset_deg, mean_velocity, _)| RunOutcome {
            speed_rpm,
            offset_deg,
            mean_velocity,
            not_held: None,
            not_a_travel: None,
            plant_warnings: Vec::new(),
        })
        .collect();
    let pick = |way: Way| {
        // Every velocity is finite (the file's rows are), so there is one.
        let c = candidates(&grid, &runs, way).into_iter().next();
        let (i, vertex) = c.map_or((0, Err(String::new())), |c| (c.grid_index, c.vertex));
        let at = (runs[i].offset_deg, runs[i].mean_velocity);
        match vertex {
            Ok(x) => Pick {
                offset_deg: x,
                grid: at,
                degenerate: None,
            },
            Err(why) => Pick {
                offset_deg: at.0,
                grid: at,
                degenerate: Some(why),
            },
        }
    };
    SpeedFit {
        speed_rpm,
        right: pick(Way::Right),
        left: pick(Way::Left),
        points,
    }
}

/// The fits of every speed of `rows`, or the speeds with too few offsets.
pub fn fits(rows: &[Row]) -> Result<Vec<SpeedFit>, Vec<String>> {
    let mut problems = Vec::new();
    let mut out = Vec::new();
    for (speed, points) in averages(rows) {
        if points.len() < MIN_OFFSETS {
            let offsets: Vec<String> = points.iter().map(|p| numbers::sig(p.0)).collect();
            problems.push(format!(
                "{} rpm has {} ({} deg): the peak fit needs at least {MIN_OFFSETS} (the best and its two neighbours)",
                numbers::sig(speed),
                count(points.len(), "offset"),
                offsets.join(", ")
            ));
        } else {
            out.push(fit(speed, points));
        }
    }
    if out.is_empty() && problems.is_empty() {
        problems.push("no measurement in the file".into());
    }
    if problems.is_empty() {
        Ok(out)
    } else {
        Err(problems)
    }
}

/// The speeds where no offset measured travels one way faster than
/// [`crate::sweep::best::MIN_TRAVEL_MPS`] (as `tune` warns): the table's offset that way is the
/// least bad, and drives the platform the other way or hardly at all.
pub fn warnings(fits: &[SpeedFit]) -> Vec<String> {
    let mut out = Vec::new();
    for f in fits {
        for (pick, way) in [(&f.right, Way::Right), (&f.left, Way::Left)] {
            if !way.travels(pick.grid.1) {
                out.push(no_travel(f.speed_rpm, way, pick.grid.0, pick.grid.1));
            }
        }
    }
    out
}

/// How a pick was found, for the file's header.
fn describe(p: &Pick) -> String {
    match &p.degenerate {
        None => format!(
            "vertex of the fit (measured best {} deg: {} mm/s)",
            numbers::sig(p.grid.0),
            mm_s(p.grid.1)
        ),
        Some(why) => format!("measured best, {} mm/s ({why})", mm_s(p.grid.1)),
    }
}

/// The tuning table file of `fits`, made from the measured file `source`: a
/// header saying how, and a row per speed. Refused (the reason) when the
/// controller would not take it: more rows than it holds, speeds that print
/// alike at the file's 0.1 rpm.
pub fn table_file(fits: &[SpeedFit], source: &Path, rows: usize) -> Result<String, String> {
    let mut header = format!(
        "Tuning table: the best phase offset for rightward and leftward travel per rotor speed.\n\
         Made by `host-sim device tune --write` (see docs/cli-device.md) from the\n\
         {} measured on the machine in {}: per speed, the\n\
         best mean velocity each way refined by the vertex of the parabola through it and\n\
         its two neighbours in offset (the fit of `host-sim tune`, not checked by a run).\n",
        count(rows, "run"),
        source.display()
    );
    for f in fits {
        let _ = writeln!(
            header,
            "  {} rpm: right {:.1} deg, {}; left {:.1} deg, {}",
            numbers::sig(f.speed_rpm),
            f.right.offset_deg,
            describe(&f.right),
            f.left.offset_deg,
            describe(&f.left)
        );
    }
    let table: Vec<tuning_file::Row> = fits
        .iter()
        .map(|f| (f.speed_rpm, f.right.offset_deg, f.left.offset_deg))
        .collect();
    let written: Vec<String> = table.iter().map(|r| format!("{:.1}", r.0)).collect();
    if let Some(w) = written.windows(2).find(|w| w[0] == w[1]) {
        return Err(format!(
            "two measured speeds are written alike at the table's 0.1 rpm ({} rpm)",
            w[0]
        ));
    }
    tuning_file::table(&table).map_err(|e| e.to_string())?;
    Ok(tuning_file::write(&table, header.trim_end()))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(speed_rpm: f64, offset_deg: f64, velocity_mps: f64, weight: f64) -> Row {
        Row {
            line: 0,
            speed_rpm,
            offset_deg,
            velocity_mps,
            weight,
        }
    }

    #[test]
    fn repeated_rows_average_by_weight_and_offsets_wrap() {
        let a = averages(&[
            row(3000.0, 90.0, 0.03, 1.0),
            row(2500.0, 0.0, 0.01, 1.0),
            row(3000.0, -270.0, 0.06, 2.0),
            row(3000.0, 360.0, 0.02, 1.0),
        ]);
        assert_eq!(a.len(), 2);
        assert_eq!(a[0], (2500.0, vec![(0.0, 0.01, 1)]));
        // (0.03 + 2 x 0.06) / 3 = 0.05.
        assert_eq!(a[1].1.len(), 2);
        assert_eq!((a[1].1[0].0, a[1].1[0].2), (0.0, 1));
        assert_eq!((a[1].1[1].0, a[1].1[1].2), (90.0, 2));
        assert!((a[1].1[1].1 - 0.05).abs() < 1e-15);
    }

    /// The weights are divided by the largest before they are summed: rows of
    /// weight 1e308 (beyond the reader's bound, so only built here) average as
    /// rows of weight 1 do, not to infinity over infinity.
    #[test]
    fn the_weighted_mean_does_not_overflow() {
        let a = averages(&[
            row(3000.0, 90.0, 0.030, 1e308),
            row(3000.0, 90.0, 0.0303, 1e308),
            row(3000.0, 90.0, 0.1, 1e-300),
        ]);
        let mean = a[0].1[0].1;
        assert!((mean - 0.03015).abs() < 1e-15, "{mean}");
        assert_eq!(
            weighted_mean(&[(0.03, 1.0), (0.06, 2.0)]),
            weighted_mean(&[(0.03, 1e-6), (0.06, 2e-6)])
        );
    }

    #[test]
    fn the_fit_is_the_parabola_through_the_best_and_its_neighbours() {
        // 12, 30, -6 mm/s at 0, 90, 180 deg: by hand, d01 = 0.2, d12 = -0.4
        // (mm/s per deg), a = -0.6 / 180, b = d01 + 90 a = -0.1, vertex
        // 90 - b / (2 a) = 75 deg. Left: the most negative is at the end of a
        // range that does not go round: kept.
        let rows = [
            row(3000.0, 0.0, 0.012, 1.0),
            row(3000.0, 90.0, 0.030, 1.0),
            row(3000.0, 180.0, -0.006, 1.0),
        ];
        let f = fits(&rows).unwrap();
        assert_eq!(f.len(), 1);
        assert!(
            (f[0].right.offset_deg - 75.0).abs() < 1e-9,
            "{:?}",
            f[0].right
        );
        assert_eq!(f[0].right.grid, (90.0, 0.030));
        assert_eq!(f[0].left.offset_deg, 180.0);
        assert!(f[0].left.degenerate.is_some());
        assert!(warnings(&f).is_empty());
        let text = table_file(&f, Path::new("m.csv"), 3).unwrap();
        let read = tuning_file::parse("t", &text).unwrap();
        assert_eq!(read, vec![(3000.0, 75.0, 180.0)]);
    }

    #[test]
    fn too_few_offsets_are_refused_by_speed() {
        let e = fits(&[
            row(3000.0, 0.0, 0.01, 1.0),
            row(3000.0, 90.0, 0.02, 1.0),
            row(2500.0, 0.0, 0.01, 1.0),
            row(2500.0, 90.0, 0.02, 1.0),
            row(2500.0, 180.0, 0.01, 1.0),
        ])
        .unwrap_err();
        assert_eq!(
            e,
            vec!["3000 rpm has 2 offsets (0, 90 deg): the peak fit needs at least 3 (the best and its two neighbours)"]
        );
    }

    /// A speed where every offset measured travels right: its left pick travels
    /// right too, and is said so.
    #[test]
    fn a_way_no_offset_travels_is_a_warning() {
        let rows = [
            row(3000.0, 0.0, 0.012, 1.0),
            row(3000.0, 90.0, 0.030, 1.0),
            row(3000.0, 180.0, 0.006, 1.0),
        ];
        let f = fits(&rows).unwrap();
        assert_eq!(
            warnings(&f),
            ["3000 rpm: no offset travels left faster than 0.5 mm/s: the best is 180 deg at +6.0 mm/s"]
        );
    }

    /// Measured speeds below `MIN_TRAVEL_MPS` either way are no travel
    /// (issue 23: a best left of -3.4e-6 m/s was written without a word).
    #[test]
    fn a_speed_below_the_threshold_is_no_travel() {
        let rows = [
            row(3000.0, 0.0, 0.0004, 1.0),
            row(3000.0, 90.0, 0.0001, 1.0),
            row(3000.0, 180.0, -3.4e-6, 1.0),
            row(3000.0, 270.0, -0.0002, 1.0),
        ];
        let f = fits(&rows).unwrap();
        assert_eq!(
            warnings(&f),
            [
                "3000 rpm: no offset travels right faster than 0.5 mm/s: the best is 0 deg at +0.4 mm/s",
                "3000 rpm: no offset travels left faster than 0.5 mm/s: the best is 270 deg at -0.2 mm/s"
            ]
        );
        // Just above the threshold is travel.
        let rows = [
            row(3000.0, 0.0, 0.0006, 1.0),
            row(3000.0, 90.0, 0.0001, 1.0),
            row(3000.0, 180.0, -0.0006, 1.0),
        ];
        assert!(warnings(&fits(&rows).unwrap()).is_empty());
    }
}
