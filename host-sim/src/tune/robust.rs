//! `host-sim tune MACHINE --robust [--samples N] [--seed S]`: the sweep over the
//! machines the file's `[uncertainty]` allows (docs/tuning.md,
//! "Robust tuning").
//!
//! Every grid point runs on `N` machines (the nominal one, then `N - 1` of a Latin
//! hypercube of the ranges, [`Uncertainty::draw`]) from [`STARTS`] initial
//! conditions each (the platform at rest; rotor 1's start angle turned by 0, 120
//! and 240 degrees from the file's), so on `3 N` runs. Per point: the nominal run
//! (the nominal machine from the file's start, the plain sweep's number), the mean,
//! the 10th and 90th percentiles (nearest rank), the extremes, and the share of runs
//! travelling each way (faster than [`MIN_TRAVEL_MPS`]). The best offset at a
//! speed is, rightward, the one with the highest 10th percentile among the points
//! whose every run travels right (leftward: the lowest 90th percentile among those
//! whose every run travels left). A speed with no such point gets the least bad
//! one: the point whose runs travel that way most often, less those travelling
//! the other way (runs not held or no travel count for neither), then by the same
//! percentile; marked as not travelling that way on every run and warned of: so
//! `--write` writes what travels, as the plain sweep writes its least bad offset
//! with a warning. A point whose runs on one machine,
//! from its different starts, settle at speeds further apart than
//! [`multistable_margin`] is **multistable** there, flagged with the speeds found.
//!
//! The best offsets are grid offsets: the plain sweep's parabola through three
//! neighbours does not apply to a percentile of a gait that can change from one
//! offset to the next.

use std::fmt::Write as _;
use std::path::Path;

use rayon::prelude::*;

use super::plot;
use super::{Report, Request, TuneArgs};
use crate::args::Format;
use crate::failure::{Console, Failure};
use crate::machine::tuning_file;
use crate::machine::uncertainty::Uncertainty;
use crate::machine::Machine;
use crate::numbers;
use crate::numbers::count;
use crate::output::progress::Progress;
use crate::sweep::best::{mm_s, Best, Refinement, Tuning, Way, MIN_TRAVEL_MPS};
use crate::sweep::load_machine;
use crate::sweep::{run_point, Grid, RunOutcome};

/// Default `--samples`: the nominal machine and seven drawn (24 runs a point with
/// the three starts).
pub const DEFAULT_SAMPLES: usize = 8;
/// Most `--samples`.
pub const MAX_SAMPLES: usize = 1000;
/// Default `--seed`.
pub const DEFAULT_SEED: u64 = 1;
/// Initial conditions per machine: rotor 1's start angle turned by `k 360 / STARTS`
/// degrees from the file's (the offset the controller starts from, which decides
/// a multistable gait).
pub const STARTS: usize = 3;

/// How far apart the speeds from different starts on one machine may settle before
/// the point is multistable there, m/s: 1 mm/s plus 10 % of the faster (a gait
/// change, issue 14's 45 against 20 mm/s, is far beyond; the mean over the
/// second half of a run wanders by less on a stable gait).
pub fn multistable_margin(speeds: &[f64]) -> f64 {
    let fastest = speeds.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    1e-3 + 0.1 * fastest
}

/// One grid point over every machine and start.
#[derive(Clone, Debug, PartialEq)]
pub struct PointStats {
    /// Rotor speed, rpm.
    pub speed_rpm: f64,
    /// Phase offset, degrees.
    pub offset_deg: f64,
    /// The nominal machine from the file's start, m/s.
    pub nominal: f64,
    /// Mean over the runs, m/s.
    pub mean: f64,
    /// 10th percentile (nearest rank), m/s.
    pub p10: f64,
    /// 90th percentile (nearest rank), m/s.
    pub p90: f64,
    /// Slowest (most leftward) run, m/s.
    pub min: f64,
    /// Fastest (most rightward) run, m/s.
    pub max: f64,
    /// Share of runs travelling left (`v < -MIN_TRAVEL_MPS`).
    pub left_share: f64,
    /// Share of runs travelling right (`v > MIN_TRAVEL_MPS`).
    pub right_share: f64,
    /// Runs that did not hold their offset (not counted as travelling either way).
    pub not_held: usize,
    /// Runs that were no travel (a body through the fundament or tipped over; not
    /// counted as travelling either way).
    pub not_a_travel: usize,
    /// Machines (0: nominal) on which the starts settled apart: the speeds, m/s.
    pub multistable: Vec<(usize, Vec<f64>)>,
    /// Every run's mean velocity, machine by machine and start by start within
    /// (`NaN` where the offset was not held or the run was no travel), m/s.
    pub speeds: Vec<f64>,
}

/// A best offset at one speed, one way.
#[derive(Clone, Debug, PartialEq)]
pub struct RobustBest {
    /// The point's statistics.
    pub point: PointStats,
    /// The percentile it was chosen by, m/s: the 10th rightward, the 90th leftward.
    pub by: f64,
    /// Whether every run travels its way there; `false` for the least bad
    /// offset of a speed where none does (warned of).
    pub every_run: bool,
}

impl PointStats {
    /// The share of runs travelling `way`.
    fn share(&self, way: Way) -> f64 {
        match way {
            Way::Right => self.right_share,
            Way::Left => self.left_share,
        }
    }

    /// The runs travelling `way` less those travelling the other way (runs not
    /// held or no travel count for neither), a whole number: every run where
    /// every run travels `way`; a point that goes the wrong way more often than
    /// the right one ranks below one that does not move.
    fn net_runs(&self, way: Way) -> i64 {
        let n = self.speeds.len() as f64;
        let net = match way {
            Way::Right => self.right_share - self.left_share,
            Way::Left => self.left_share - self.right_share,
        };
        (net * n).round() as i64
    }

    /// The percentile `way` is judged by, turned so that larger is better: the
    /// 10th rightward, minus the 90th leftward.
    fn score(&self, way: Way) -> f64 {
        match way {
            Way::Right => self.p10,
            Way::Left => -self.p90,
        }
    }
}

/// The best offset `way` among one speed's points `at` (those with a
/// percentile: a run that held its offset and travelled), ranked by
/// [`PointStats::net_runs`] first, then by the percentile
/// ([`PointStats::score`]): the best percentile among the points whose every
/// run travels `way`, else the least bad, the point travelling
/// `way` on the most runs, against those travelling the other way; `None` when
/// no point has a percentile.
fn pick(at: &[&PointStats], way: Way) -> Option<RobustBest> {
    let point = at
        .iter()
        .filter(|s| s.score(way).is_finite())
        .max_by(|a, b| {
            (a.net_runs(way).cmp(&b.net_runs(way))).then(a.score(way).total_cmp(&b.score(way)))
        })
        .map(|s| (*s).clone())?;
    let every_run = point.share(way) == 1.0;
    Some(RobustBest {
        by: match way {
            Way::Right => point.p10,
            Way::Left => point.p90,
        },
        point,
        every_run,
    })
}

/// The whole robust sweep.
#[derive(Clone, Debug)]
pub struct Robust {
    /// The grid.
    pub grid: Grid,
    /// The ranges the machines were drawn from.
    pub uncertainty: Uncertainty,
    /// Machines drawn (the nominal one included).
    pub samples: usize,
    /// Seed of the draw.
    pub seed: u64,
    /// Per grid point, in [`Grid::points`] order.
    pub points: Vec<PointStats>,
    /// Best rightward offset per speed that has one.
    pub right: Vec<RobustBest>,
    /// Best leftward offset per speed that has one.
    pub left: Vec<RobustBest>,
    /// What the sweep found that a user must know.
    pub warnings: Vec<String>,
}

/// The machines of a robust sweep: `(sample, start, machine)`, sample by sample
/// (0: the nominal machine), its starts next to each other.
pub type Machines = Vec<(usize, usize, Machine)>;

/// The machines a robust sweep runs ([`Machines`]), with the ranges they come from.
pub fn machines(
    path: &Path,
    text: &str,
    sets: &[String],
    samples: usize,
    seed: u64,
) -> Result<(Uncertainty, Machines), Failure> {
    let dir = path.parent().unwrap_or(Path::new(""));
    let file = path.display().to_string();
    let uncertainty = Uncertainty::from_text(&file, text, dir, sets)?;
    if uncertainty.ranges.is_empty() {
        return Err(Failure::usage(format!(
            "{file}: tune --robust: the machine file has no [uncertainty] ranges to draw machines from; add e.g."
        ))
        .with_detail("  [uncertainty]")
        .with_detail("  \"contacts.*.restitution\" = [0.2, 0.45]")
        .with_detail("(docs/machine-file.md)"));
    }
    let nominal = load_machine(path, text, sets)?;
    let angle0 = nominal.rotors[0].angle;
    let mut out = Vec::new();
    for (i, drawn) in uncertainty.draw(samples, seed).into_iter().enumerate() {
        for s in 0..STARTS {
            let mut all = sets.to_vec();
            all.extend(drawn.iter().cloned());
            let turn = s as f64 * std::f64::consts::TAU / STARTS as f64;
            if s > 0 {
                all.push(format!("rotors.0.angle={:?}", angle0 + turn));
            }
            out.push((i, s, load_machine(path, text, &all)?));
        }
    }
    Ok((uncertainty, out))
}

/// Runs every grid point on every machine, in parallel; the outcomes by machine,
/// then by point.
pub fn sweep(
    machines: &[(usize, usize, Machine)],
    grid: &Grid,
    progress: &Progress,
) -> Vec<Vec<RunOutcome>> {
    let points = grid.points();
    let jobs: Vec<(usize, usize)> = (0..machines.len())
        .flat_map(|m| (0..points.len()).map(move |p| (m, p)))
        .collect();
    let outcomes: Vec<RunOutcome> = jobs
        .par_iter()
        .map(|&(m, p)| {
            let (speed, offset) = points[p];
            let o = run_point(&machines[m].2, speed, offset, grid.t_end);
            progress.inc(1);
            o
        })
        .collect();
    outcomes.chunks(points.len()).map(<[_]>::to_vec).collect()
}

/// The value at nearest rank `ceil(q n)` of the sorted `v` (`q` in (0, 1]).
fn nearest_rank(sorted: &[f64], q: f64) -> f64 {
    let n = sorted.len();
    let rank = ((q * n as f64).ceil() as usize).clamp(1, n);
    sorted[rank - 1]
}

/// The statistics of point `p` over every machine's outcomes `runs` (machine by
/// machine, `sample[m]` the drawn machine that machine `m` is, its starts next to
/// each other).
fn point_stats(sample: &[usize], runs: &[Vec<RunOutcome>], p: usize) -> PointStats {
    let first = &runs[0][p];
    let held: Vec<f64> = runs.iter().filter_map(|r| r[p].velocity()).collect();
    let not_a_travel = runs.iter().filter(|r| r[p].not_a_travel.is_some()).count();
    let n = runs.len();
    let mut sorted = held.clone();
    sorted.sort_by(f64::total_cmp);
    let (mean, p10, p90, min, max) = if sorted.is_empty() {
        (f64::NAN, f64::NAN, f64::NAN, f64::NAN, f64::NAN)
    } else {
        (
            sorted.iter().sum::<f64>() / sorted.len() as f64,
            nearest_rank(&sorted, 0.1),
            nearest_rank(&sorted, 0.9),
            sorted[0],
            sorted[sorted.len() - 1],
        )
    };
    // Multistable: the starts of one machine apart.
    let mut multistable = Vec::new();
    let mut i = 0;
    while i < sample.len() {
        let this = sample[i];
        let mut speeds = Vec::new();
        while i < sample.len() && sample[i] == this {
            if let Some(v) = runs[i][p].velocity() {
                speeds.push(v);
            }
            i += 1;
        }
        let lo = speeds.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = speeds.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        if speeds.len() > 1 && hi - lo > multistable_margin(&speeds) {
            multistable.push((this, speeds));
        }
    }
    PointStats {
        speed_rpm: first.speed_rpm,
        offset_deg: first.offset_deg,
        nominal: first.mean_velocity,
        mean,
        p10,
        p90,
        min,
        max,
        left_share: held.iter().filter(|v| Way::Left.travels(**v)).count() as f64 / n as f64,
        right_share: held.iter().filter(|v| Way::Right.travels(**v)).count() as f64 / n as f64,
        not_held: n - held.len() - not_a_travel,
        not_a_travel,
        multistable,
        speeds: runs
            .iter()
            .map(|r| r[p].velocity().unwrap_or(f64::NAN))
            .collect(),
    }
}

/// The statistics, the best offsets and the warnings of a robust sweep.
pub fn conclude(
    grid: Grid,
    uncertainty: Uncertainty,
    seed: u64,
    machines: &[(usize, usize, Machine)],
    runs: &[Vec<RunOutcome>],
) -> Robust {
    let samples = machines.len() / STARTS;
    let sample: Vec<usize> = machines.iter().map(|m| m.0).collect();
    let points: Vec<PointStats> = (0..grid.points().len())
        .map(|p| point_stats(&sample, runs, p))
        .collect();
    let mut right = Vec::new();
    let mut left = Vec::new();
    let mut warnings = Vec::new();
    for &speed in &grid.speeds_rpm {
        let at: Vec<&PointStats> = points.iter().filter(|s| s.speed_rpm == speed).collect();
        for (way, list) in [(Way::Right, &mut right), (Way::Left, &mut left)] {
            let every = format!(
                "{} rpm: no offset travels {} faster than {} mm/s on every machine from every start",
                numbers::sig(speed),
                way.name(),
                numbers::sig(MIN_TRAVEL_MPS * 1e3)
            );
            match pick(&at, way) {
                Some(b) if b.every_run => list.push(b),
                Some(b) => {
                    warnings.push(format!(
                        "{every}: the least bad is {} deg, {} percentile {} mm/s, {} of {} runs travelling {}",
                        numbers::sig(b.point.offset_deg),
                        match way {
                            Way::Right => "10th",
                            Way::Left => "90th",
                        },
                        mm_s(b.by),
                        (b.point.share(way) * b.point.speeds.len() as f64).round(),
                        b.point.speeds.len(),
                        way.name()
                    ));
                    list.push(b);
                }
                None => warnings.push(format!(
                    "{every}: no run held its offset and travelled, no best offset"
                )),
            }
        }
    }
    let multistable = points.iter().filter(|s| !s.multistable.is_empty()).count();
    if multistable > 0 {
        let (what, verb) = if multistable == 1 {
            ("point", "is")
        } else {
            ("points", "are")
        };
        warnings.push(format!(
            "{multistable} {what} {verb} multistable: runs from different starts on one machine settle apart (see the multistable points)"
        ));
    }
    Robust {
        grid,
        uncertainty,
        samples,
        seed,
        points,
        right,
        left,
        warnings,
    }
}

/// `tune --robust` on the machines of [`machines`] (the ranges `uncertainty`
/// they were drawn from): the sweep, then the outputs ([`finish`]).
pub fn run(
    args: &TuneArgs,
    uncertainty: Uncertainty,
    machines: &Machines,
    grid: Grid,
    request: &Request,
    console: &mut Console<'_>,
) -> Result<(), Failure> {
    let seed = args.seed.unwrap_or(DEFAULT_SEED);
    // The output files, checked and opened before the sweep, as the plain one's.
    let report = Report::open(&args.output)?;
    let started = std::time::Instant::now();
    let progress =
        crate::sweep::progress_bar("tune --robust", machines.len() * grid.points().len());
    let runs = sweep(machines, &grid, &progress);
    progress.finish_and_clear();
    crate::sweep::refuse_interrupted("tune", "the sweep is incomplete")?;
    let robust = conclude(grid, uncertainty, seed, machines, &runs);
    finish(&robust, &runs[0], report, request, console)?;
    console.note(&format!(
        "tune --robust: {} runs ({} x {STARTS} starts x {}) in {:.1} s on {}{}\n",
        machines.len() * robust.points.len(),
        count(robust.samples, "machine"),
        count(robust.points.len(), "point"),
        started.elapsed().as_secs_f64(),
        count(rayon::current_num_threads(), "thread"),
        crate::numbers::warning_count(&robust.warnings)
    ));
    Ok(())
}

/// The outputs of a robust sweep (`nominal`: the nominal machine's runs from the
/// file's start), for `tune --robust` and for `merge` of its parts alike: the
/// files of `report` (all or none), then the result on stdout, printed whether
/// or not they could be written (the runs are not thrown away; their error comes
/// after it). The outputs name the machine file as `request` does.
pub fn finish(
    robust: &Robust,
    nominal: &[RunOutcome],
    report: Report,
    request: &Request,
    console: &mut Console<'_>,
) -> Result<(), Failure> {
    let Report {
        mut staged,
        table: write,
        plot,
        format,
    } = report;
    let path = &request.machine_path;
    let result = match format {
        Format::Json => json(robust),
        Format::Table => table(robust, path),
    };
    let mut files = || -> Result<(), Failure> {
        if let Some((i, p)) = &write {
            let Some(text) = table_file(robust, request, p) else {
                return Err(Failure::run(
                    "--write: no speed has a best offset both ways (no run there held its offset and travelled; see the warnings): nothing written; the sweep is above",
                ));
            };
            staged.write(*i, &text)?;
        }
        if let Some(i) = plot {
            let title = format!("host-sim tune --robust {}", path.display());
            staged.write(i, &plot_svg(robust, nominal, &title))?;
        }
        Ok(())
    };
    let written = files().and_then(|()| staged.commit());
    console.print(&result);
    written
}

/// `--plot`: the plain sweep's figure of the nominal runs (`nominal`, the nominal
/// machine from the file's start), the robust best offsets marked, over the band
/// from each point's 10th to its 90th percentile.
pub fn plot_svg(r: &Robust, nominal: &[RunOutcome], title: &str) -> String {
    let best = |b: &RobustBest| Best {
        speed_rpm: b.point.speed_rpm,
        offset_deg: b.point.offset_deg,
        mean_velocity: b.point.nominal,
        grid_offset_deg: b.point.offset_deg,
        grid_mean_velocity: b.point.nominal,
        refinement: Refinement::Degenerate("a robust best offset is a grid offset".into()),
    };
    let tuning = Tuning {
        grid: r.grid.clone(),
        runs: nominal.to_vec(),
        right: r.right.iter().map(best).collect(),
        left: r.left.iter().map(best).collect(),
        warnings: r.warnings.clone(),
        run_count: r.points.len() * r.samples * STARTS,
    };
    let range: Vec<(f64, f64)> = r.points.iter().map(|s| (s.p10, s.p90)).collect();
    let multistable: Vec<bool> = r.points.iter().map(|s| !s.multistable.is_empty()).collect();
    let band = plot::Band {
        range: &range,
        multistable: &multistable,
    };
    plot::plot_with_band(&tuning, title, Some(&band))
}

/// The speeds with a best offset both ways.
fn rows(r: &Robust) -> Vec<(&RobustBest, &RobustBest)> {
    r.right
        .iter()
        .filter_map(|a| {
            r.left
                .iter()
                .find(|b| b.point.speed_rpm == a.point.speed_rpm)
                .map(|b| (a, b))
        })
        .collect()
}

/// The tuning table file (`--write`), `None` when no speed has a best offset both
/// ways (robust or the least bad: no point held its offset and travelled on a run).
pub fn table_file(r: &Robust, request: &Request, write: &Path) -> Option<String> {
    let both = rows(r);
    if both.is_empty() {
        return None;
    }
    let mut command = format!(
        "host-sim tune {} --speeds {} --offsets {} --t-end {} --robust --samples {} --seed {}",
        request.machine_path.display(),
        request.speeds_text,
        request.offsets_text,
        numbers::sig(r.grid.t_end),
        r.samples,
        r.seed
    );
    for s in &request.set {
        let _ = write!(command, " --set {s}");
    }
    let _ = write!(command, " --write {}", write.display());
    let mut header = format!(
        "Tuning table: the best phase offset for rightward and leftward travel per rotor speed,\n\
         robust over the machine file's [uncertainty]. Written by `host-sim tune --robust`\n\
         (see docs/tuning.md); regenerate with\n  {command}\n\
         Each offset travels its way on all {} machines from all {STARTS} starts and has the best\n\
         10th percentile of the speed there (90th leftward), or is the least bad where none does.\n\
         10th (90th) percentile (mean), m/s:\n",
        r.samples
    );
    for (a, b) in &both {
        let _ = writeln!(
            header,
            "  {} rpm: right {:.1} deg {} ({}), left {:.1} deg {} ({})",
            numbers::sig(a.point.speed_rpm),
            a.point.offset_deg,
            numbers::signed(a.by),
            numbers::signed(a.point.mean),
            b.point.offset_deg,
            numbers::signed(b.by),
            numbers::signed(b.point.mean)
        );
    }
    let least_bad: Vec<String> = both
        .iter()
        .flat_map(|(a, b)| [(a, Way::Right), (b, Way::Left)])
        .filter(|(b, _)| !b.every_run)
        .map(|(b, way)| format!("{} rpm {}", numbers::sig(b.point.speed_rpm), way.name()))
        .collect();
    if !least_bad.is_empty() {
        let _ = writeln!(
            header,
            "Not travelling its way on every run (the least bad; see the warnings): {}.",
            least_bad.join(", ")
        );
    }
    let flagged: Vec<String> = both
        .iter()
        .flat_map(|(a, b)| [&a.point, &b.point])
        .filter(|p| !p.multistable.is_empty())
        .map(|p| format!("{} rpm {:.1} deg", numbers::sig(p.speed_rpm), p.offset_deg))
        .collect();
    if !flagged.is_empty() {
        let _ = writeln!(
            header,
            "Multistable (runs from different starts on one machine settle apart): {}.",
            flagged.join(", ")
        );
    }
    let rows: Vec<tuning_file::Row> = both
        .iter()
        .map(|(a, b)| (a.point.speed_rpm, a.point.offset_deg, b.point.offset_deg))
        .collect();
    Some(tuning_file::write(&rows, header.trim_end()))
}

/// `--format table`.
pub fn table(r: &Robust, path: &Path) -> String {
    let mut out = format!(
        "tune --robust {}: {} machines (the nominal, then a Latin hypercube, seed {}) x {STARTS} starts, {} s runs\n",
        path.display(),
        r.samples,
        r.seed,
        numbers::sig(r.grid.t_end)
    );
    for range in &r.uncertainty.ranges {
        let _ = writeln!(
            out,
            "  {} in [{}, {}]",
            range.key,
            numbers::sig(range.low),
            numbers::sig(range.high)
        );
    }
    out.push_str(
        "\nbest offsets (every run travelling that way, else the least bad: marked), mm/s:\n",
    );
    out.push_str("speed_rpm  way    offset_deg  p10/p90    mean     nominal\n");
    for &speed in &r.grid.speeds_rpm {
        for (way, list) in [("right", &r.right), ("left", &r.left)] {
            match list.iter().find(|b| b.point.speed_rpm == speed) {
                Some(b) => {
                    let _ = writeln!(
                        out,
                        "{:<10} {:<6} {:<11.1} {:<10} {:<8} {}{}",
                        numbers::sig(speed),
                        way,
                        b.point.offset_deg,
                        numbers::fixed(b.by * 1e3, 3),
                        numbers::fixed(b.point.mean * 1e3, 3),
                        numbers::fixed(b.point.nominal * 1e3, 3),
                        if b.every_run {
                            ""
                        } else {
                            "  least bad: not every run travels this way"
                        }
                    );
                }
                None => {
                    let _ = writeln!(out, "{:<10} {:<6} none", numbers::sig(speed), way);
                }
            }
        }
    }
    let flagged: Vec<&PointStats> = r
        .points
        .iter()
        .filter(|s| !s.multistable.is_empty())
        .collect();
    if !flagged.is_empty() {
        out.push_str("\nmultistable points (machine: speeds from the starts, mm/s):\n");
        for s in flagged {
            let machines: Vec<String> = s
                .multistable
                .iter()
                .map(|(m, v)| {
                    let v: Vec<String> = v.iter().map(|x| format!("{:+.2}", x * 1e3)).collect();
                    format!("{m}: {}", v.join(" "))
                })
                .collect();
            let _ = writeln!(
                out,
                "  {} rpm {:.1} deg: {}",
                numbers::sig(s.speed_rpm),
                s.offset_deg,
                machines.join("; ")
            );
        }
    }
    for w in &r.warnings {
        let _ = writeln!(out, "warning: {w}");
    }
    out
}

/// `--format json`: the plain sweep's `grid` and `best` (the nominal run's speed as
/// `mean_velocity`) with the robust statistics added.
pub fn json(r: &Robust) -> String {
    use serde_json::{json, Value};
    let stats = |s: &PointStats| {
        json!({
            "mean": s.mean, "p10": s.p10, "p90": s.p90, "min": s.min, "max": s.max,
            "right_share": s.right_share, "left_share": s.left_share,
            "not_held": s.not_held, "not_a_travel": s.not_a_travel,
            "speeds": s.speeds.iter().map(|v| if v.is_finite() { json!(v) } else { Value::Null }).collect::<Vec<Value>>(),
            "multistable": s.multistable.iter().map(|(m, v)| json!({"machine": m, "speeds": v})).collect::<Vec<Value>>(),
        })
    };
    let grid: Vec<Value> = r
        .points
        .iter()
        .map(|s| {
            json!({"speed_rpm": s.speed_rpm, "offset_deg": s.offset_deg,
                   "mean_velocity": s.nominal, "robust": stats(s)})
        })
        .collect();
    let best = |list: &[RobustBest]| -> Vec<Value> {
        list.iter()
            .map(|b| {
                json!({"speed_rpm": b.point.speed_rpm, "offset_deg": b.point.offset_deg,
                       "mean_velocity": b.point.nominal, "by": b.by, "every_run": b.every_run,
                       "robust": stats(&b.point)})
            })
            .collect()
    };
    let ranges: Vec<Value> = r
        .uncertainty
        .ranges
        .iter()
        .map(|x| json!({"key": x.key, "low": x.low, "high": x.high}))
        .collect();
    let doc = json!({
        "grid": grid,
        "best": {"right": best(&r.right), "left": best(&r.left)},
        "robust": {"samples": r.samples, "seed": r.seed, "starts": STARTS, "ranges": ranges},
        "warnings": r.warnings,
    });
    let mut s = serde_json::to_string_pretty(&doc).unwrap_or_default();
    s.push('\n');
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(v: f64) -> RunOutcome {
        RunOutcome {
            speed_rpm: 3000.0,
            offset_deg: 90.0,
            mean_velocity: v,
            not_held: None,
            not_a_travel: None,
            plant_warnings: Vec::new(),
        }
    }

    /// Two machines of three starts each at one point: the statistics by hand.
    #[test]
    fn statistics_of_one_point() {
        let speeds = [0.030, 0.031, 0.032, 0.010, 0.011, 0.045];
        let runs: Vec<Vec<RunOutcome>> = speeds.iter().map(|v| vec![outcome(*v)]).collect();
        let s = point_stats(&[0, 0, 0, 1, 1, 1], &runs, 0);
        assert_eq!(s.nominal, 0.030);
        assert!((s.mean - 0.159 / 6.0).abs() < 1e-15);
        // Nearest rank: ceil(0.1 * 6) = 1st and ceil(0.9 * 6) = 6th of the sorted.
        assert_eq!((s.p10, s.p90, s.min, s.max), (0.010, 0.045, 0.010, 0.045));
        assert_eq!((s.right_share, s.left_share, s.not_held), (1.0, 0.0, 0));
        // Machine 0's starts agree within 1 mm/s + 10 %; machine 1's do not.
        assert_eq!(s.multistable, vec![(1, vec![0.010, 0.011, 0.045])]);
        assert_eq!(s.speeds, speeds.to_vec());
    }

    /// A run that did not hold its offset counts for neither way and keeps the
    /// point out of the best offsets; one going the other way shows in the shares.
    #[test]
    fn runs_not_held_and_the_wrong_way() {
        let mut runs: Vec<Vec<RunOutcome>> = [0.02, -0.001, 0.02]
            .iter()
            .map(|v| vec![outcome(*v)])
            .collect();
        runs[2][0].not_held = Some("fault".into());
        let s = point_stats(&[0, 0, 0], &runs, 0);
        assert_eq!((s.not_held, s.not_a_travel), (1, 0));
        assert!((s.right_share - 1.0 / 3.0).abs() < 1e-15);
        assert!((s.left_share - 1.0 / 3.0).abs() < 1e-15);
        assert!(s.speeds[2].is_nan());
        assert_eq!((s.min, s.max), (-0.001, 0.02));
        // A run through the floor: no travel, counted as such, not as not held.
        runs[0][0].not_a_travel = Some("platform went through the fundament".into());
        runs[0][0].mean_velocity = f64::NAN;
        let s = point_stats(&[0, 0, 0], &runs, 0);
        assert_eq!((s.not_held, s.not_a_travel), (1, 1));
        assert_eq!((s.right_share, s.left_share), (0.0, 1.0 / 3.0));
        assert!(s.speeds[0].is_nan());
    }

    /// The statistics of one point at `offset_deg` whose three runs (one
    /// machine) went at `speeds`, m/s.
    fn point(offset_deg: f64, speeds: [f64; 3]) -> PointStats {
        let runs: Vec<Vec<RunOutcome>> = speeds.iter().map(|v| vec![outcome(*v)]).collect();
        PointStats {
            offset_deg,
            ..point_stats(&[0, 0, 0], &runs, 0)
        }
    }

    /// Speeds below `MIN_TRAVEL_MPS` are no travel: a point whose runs all
    /// went left by 1e-5 m/s does not travel left on every run (issue 23).
    /// Where no point travels a way on every run, the least bad by the same
    /// percentile is picked, marked so (issue 23: the sweep was thrown away).
    #[test]
    fn a_way_without_travel_on_every_run_gets_the_least_bad_marked() {
        let right = point(90.0, [0.030, 0.031, 0.029]);
        let noise = point(0.0, [-1e-5, -2e-5, -3e-6]);
        let back = point(180.0, [0.004, -0.001, 0.002]);
        assert_eq!((noise.left_share, noise.right_share), (0.0, 0.0));
        assert!((back.left_share - 1.0 / 3.0).abs() < 1e-15);
        let at = [&right, &noise, &back];
        let r = pick(&at, Way::Right).unwrap();
        assert_eq!((r.point.offset_deg, r.by, r.every_run), (90.0, 0.029, true));
        // Left: none travels on every run. 180 degrees travels left on one run
        // of three but right on two: worse than the noise, which travels
        // neither way; of those two with no net share, the lowest 90th
        // percentile is the noise's, -3e-6 m/s (the third of three).
        let l = pick(&at, Way::Left).unwrap();
        assert_eq!((l.point.offset_deg, l.by, l.every_run), (0.0, -3e-6, false));
        // No percentile anywhere: nothing to pick.
        let none = point(0.0, [f64::NAN; 3]);
        assert_eq!(pick(&[&none], Way::Right), None);
    }

    /// Issue 23: with frictionless feet (`--samples 2 --offsets 0:360:90 --t-end
    /// 2`) no offset travels right on every run; 0 degrees was written, held on
    /// every run and travelling on none, while 90 degrees travelled +33 mm/s on
    /// the two runs of the drawn machine that held it. The least bad is the
    /// point travelling its way on the most runs (against the other way), then
    /// by the percentile.
    #[test]
    fn the_least_bad_travels_its_way_on_the_most_runs() {
        let stats = |offset_deg: f64, speeds: [f64; 6]| {
            let runs: Vec<Vec<RunOutcome>> = speeds
                .iter()
                .map(|v| {
                    let mut o = outcome(*v);
                    if v.is_nan() {
                        o.not_held = Some("phase error".into());
                    }
                    vec![o]
                })
                .collect();
            PointStats {
                offset_deg,
                ..point_stats(&[0, 0, 0, 1, 1, 1], &runs, 0)
            }
        };
        let still = stats(0.0, [8.5e-9, -3.8e-10, -7.2e-10, 1.0e-5, 7.3e-5, -6.7e-5]);
        let some = stats(90.0, [8.8e-7, -4.0e-7, f64::NAN, 0.0329, 0.0329, f64::NAN]);
        assert_eq!((still.not_held, some.not_held), (0, 2));
        let r = pick(&[&still, &some], Way::Right).unwrap();
        assert_eq!((r.point.offset_deg, r.every_run), (90.0, false));
        // Its percentile is over the runs that held: -4e-7 m/s.
        assert_eq!(r.by, -4.0e-7);
        // Of two that travel on as many runs, the better percentile.
        let more = stats(180.0, [3e-4, 2e-4, f64::NAN, 0.0329, 0.0329, f64::NAN]);
        assert_eq!(more.right_share, some.right_share);
        let r = pick(&[&still, &some, &more], Way::Right).unwrap();
        assert_eq!(r.point.offset_deg, 180.0);
        // Travelling every run wins over any percentile.
        let all = stats(270.0, [0.0006; 6]);
        let r = pick(&[&some, &more, &all], Way::Right).unwrap();
        assert_eq!((r.point.offset_deg, r.every_run), (270.0, true));
    }

    #[test]
    fn the_margin_of_multistability() {
        assert!((multistable_margin(&[0.0, 0.0]) - 1e-3).abs() < 1e-15);
        assert!((multistable_margin(&[0.02, -0.045]) - 5.5e-3).abs() < 1e-15);
    }
}
