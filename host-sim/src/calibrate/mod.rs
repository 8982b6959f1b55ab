//! `host-sim calibrate MACHINE --measured FILE.csv --fit KEY[,KEY...]
//! [--write OUT.toml] [--format table|json] [--t-end T] [--set KEY=VALUE]...
//! [--shard I/N [--out-part FILE.json]]`, or with `--capture CAPTURE.csv
//! [--firmware-machine FW.toml]` in place of `--measured` ([`capture`]).
//!
//! Fits keys of the machine file to the travel speeds measured on the real
//! machine (docs/calibration.md): by least squares
//! on the mean travel velocity of each measured run, within each key's range;
//! or motor keys to a capture of the board, by least squares on the replay's
//! residuals, tick by tick ([`capture`]).
//!
//! Stages of [`run`] with `--measured`:
//! 1. read and check, every problem at once (exit 2) before any run: the machine
//!    file with the `--set`s (as `tune` runs it: two rotors, no tuning table), the
//!    fitted keys and their ranges ([`keys`]), the measured file ([`measured`],
//!    read row by row into its distinct points, [`points`]), `--t-end`, the output
//!    file (opened, staged); then the planned cost on stderr ([`plan`]);
//! 2. the fit ([`fit`]): one evaluation is one closed-loop run per distinct
//!    `(speed, offset)` of the measured file (`tune`'s [`run_point`], holding the
//!    offset from `t = 0`), all the runs of a batch of points in parallel; a run
//!    that does not hold its offset gives its point the residual
//!    [`points::NOT_HELD_RESIDUAL_MPS`];
//! 3. the simulator's numerical noise at the fit: every point run again at other
//!    tolerances ([`numerical`]); the standard errors, the measurements' scatter
//!    and that noise both in them, and the keys not identified ([`precision`]);
//! 4. the outputs ([`report`]): `--write` (the machine file with the fitted values,
//!    nothing else changed, checked to read back), then the result on stdout as a
//!    table or JSON, the residual of each of the first [`points::ROWS_SHOWN`] rows
//!    in both; one summary line on stderr.

pub mod capture;
pub mod fit;
pub mod keys;
pub mod levenberg;
pub mod numerical;
pub mod part;
pub mod plan;
pub mod points;
pub mod precision;
pub mod report;
pub mod serial;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::{ArgGroup, Args};
use rayon::prelude::*;

use crate::args::{FormatArg, MachineArg, SetArgs, TEndArg};
use crate::failure::{Console, Failure, Kind, Reason};
use crate::help::epilogue;
use crate::measured;
use crate::numbers::count;
use crate::numbers::warning_count;
use crate::output::file::Staged;
use crate::parts::{read_machine_file, sha256_hex, Shard};
use crate::simulation::closed_loop;
use crate::simulation::limits;
use crate::sweep::{load_machine, progress_bar, DEFAULT_T_END};
use crate::sweep::{run_point, RunOutcome};
use fit::Settings;
use keys::FitKey;
use points::{Gathered, Point, MAX_POINTS};

/// Arguments of `host-sim calibrate`.
#[derive(Debug, Args)]
#[command(mut_arg("t_end", |a| a.help("End time of each simulated run, s; the mean velocity is over the second half, as `tune`'s [default: 5]")))]
#[command(mut_arg("format", |a| a.help("Output format of the result")))]
#[command(after_help = epilogue(
    &[
        "host-sim device --port /dev/ttyUSB0 tune --speeds 3000 --offsets 0:180:30 --for 4 --out measured.csv",
        "host-sim calibrate examples/vibro-driver.toml --measured measured.csv --fit 'contacts.*.restitution'",
        "host-sim calibrate examples/vibro-driver.toml --measured measured.csv --fit 'contacts.*.restitution' --write calibrated.toml",
        "host-sim device --port /dev/ttyUSB0 capture --for 2 --travel right --speed 3000 --out capture.csv",
        "host-sim calibrate examples/vibro-driver.toml --capture capture.csv --fit 'rotors.*.motor.resistance,rotors.*.motor.torque_constant'",
    ],
    &[],
    &["docs/calibration.md"],
))]
#[command(group(ArgGroup::new("measurement").required(true).multiple(false)))]
pub struct CalibrateArgs {
    /// The machine file.
    #[command(flatten)]
    pub machine: MachineArg,
    /// The measured travel: CSV `speed_rpm,offset_deg,velocity_mps[,weight]`, one
    /// row per run on the real machine (see docs/calibration.md).
    #[arg(long, value_name = "FILE.csv", group = "measurement")]
    pub measured: Option<PathBuf>,
    /// A capture of the board (`host-sim device capture`): fit motor keys
    /// (resistance, torque constant, friction, inertia) to its replay, tick by
    /// tick (see docs/calibration.md, "Motor keys from a capture").
    #[arg(long, value_name = "CAPTURE.csv", group = "measurement", conflicts_with_all = ["t_end", "shard"])]
    pub capture: Option<PathBuf>,
    /// The machine file the board's firmware was built for: the replay's
    /// controller is built from it, as the board's was (default: MACHINE).
    #[arg(long, value_name = "FW.toml", conflicts_with = "measured")]
    pub firmware_machine: Option<PathBuf>,
    /// The keys to fit, `--set` keys with `*` for every element together, e.g.
    /// `contacts.*.restitution,contacts.*.friction`.
    #[arg(
        long,
        value_name = "KEY[,KEY...]",
        value_delimiter = ',',
        required = true
    )]
    pub fit: Vec<String>,
    /// Write the machine file with the fitted values (everything else as it was).
    #[arg(long, value_name = "OUT.toml")]
    pub write: Option<PathBuf>,
    /// Output format.
    #[command(flatten)]
    pub format: FormatArg,
    /// End time.
    #[command(flatten)]
    pub t_end: TEndArg,
    /// Overrides.
    #[command(flatten)]
    pub set: SetArgs,
    /// Evaluate only part I of N of the multistart's starts (the starts k with
    /// k % N == I - 1) and write a partial result for `host-sim merge` instead of
    /// the outputs (see docs/scale-out.md).
    #[arg(long, value_name = "I/N", value_parser = crate::parts::parse_shard, conflicts_with_all = ["write", "format"])]
    pub shard: Option<Shard>,
    /// Where `--shard` writes its partial result, written whole (`-`: stdout)
    /// [default: -].
    #[arg(long, value_name = "FILE.json", requires = "shard")]
    pub out_part: Option<PathBuf>,
}

/// What was read in stage 1.
pub struct Inputs {
    /// The machine file's text, as checked.
    pub text: String,
    /// The fitted keys.
    pub keys: Vec<FitKey>,
    /// The measured rows, gathered by their distinct points.
    pub data: Gathered,
    /// SHA-256 of the measured file's text, as read.
    pub measured_sha256: String,
    /// End time of each run, s.
    pub t_end: f64,
}

impl CalibrateArgs {
    /// The measured travel file (`--measured`; the argument parser requires it
    /// where `--capture` is not given).
    pub fn measured_file(&self) -> &Path {
        self.measured
            .as_deref()
            .expect("--measured or --capture, one of them required by the parser")
    }
}

/// Stage 1 (without the output).
pub(crate) fn read_options(args: &CalibrateArgs) -> Result<Inputs, Failure> {
    let path = &args.machine.path;
    let (text, _) = read_machine_file(path)?;
    let machine = load_machine(path, &text, &args.set.keys)?;
    let mut problems = Vec::new();
    let keys = keys::resolve(path, &text, &args.set.keys, &args.fit)
        .map_err(|f| problems.extend(f.into_reasons()))
        .ok();
    let speeds = closed_loop::speed_range_rpm(&machine);
    let mut data = Gathered::default();
    let mut measured_sha256 = String::new();
    let measured_file = args.measured_file();
    let rows = measured::read_bounded(measured_file)
        .map_err(Failure::from)
        .and_then(|text| {
            measured_sha256 = sha256_hex(text.as_bytes());
            let file = measured_file.display().to_string();
            measured::parse_each(&file, &text, Some(speeds), &mut |r| data.add(r))
        })
        .and_then(|_| {
            let file = measured_file.display();
            // A file with a header alone (a sweep stopped before its first
            // answer) is well formed, but there is nothing to fit.
            if data.rows == 0 {
                Err(Failure::usage(format!(
                    "{file}: no rows after the header: one row per measured run"
                )))
            } else if data.rows_beyond > 0 {
                Err(Failure::usage(format!(
                    "{file}: more than {MAX_POINTS} distinct (speed, offset) points ({} beyond the first {MAX_POINTS} points): one evaluation of the fit runs each point, and a fit takes some 80 evaluations (docs/calibration.md, \"Cost\"); measure fewer points (a point repeated costs no run)",
                    count(data.rows_beyond, "row")
                )))
            } else {
                Ok(())
            }
        })
        .map_err(|f| problems.extend(f.into_reasons()))
        .ok();
    let t_end = args.t_end.seconds.unwrap_or(DEFAULT_T_END);
    if !(t_end.is_finite() && t_end > 0.0) {
        problems.push(Reason::new(format!(
            "--t-end {t_end}: must be a positive number of seconds"
        )));
    }
    problems.extend(
        limits::check(&machine, t_end, "--t-end")
            .into_iter()
            .map(Reason::new),
    );
    match (keys, rows) {
        (Some(keys), Some(())) if problems.is_empty() => Ok(Inputs {
            text,
            keys,
            data,
            measured_sha256,
            t_end,
        }),
        _ => Err(Failure::new(Kind::Usage, problems)),
    }
}

/// What stages 2 and 3 found, for the outputs.
pub struct Calibration {
    /// The fitted keys.
    pub keys: Vec<FitKey>,
    /// The measured rows, gathered by their distinct points.
    pub data: Gathered,
    /// The weighted sum of squares over the rows at the fit, `S`, m^2/s^2 (the
    /// search's over the points and the scatter within them).
    pub ssr: f64,
    /// The fitted value of each key (rounded as written).
    pub fitted: Vec<f64>,
    /// Each key's standard error, in its units.
    pub std_error: Vec<Option<f64>>,
    /// Its part from the measurements' scatter, in the key's units.
    pub std_error_measurement: Vec<Option<f64>>,
    /// Its part from the simulator's numerical noise, in the key's units.
    pub std_error_numerical: Vec<Option<f64>>,
    /// The runs at the other tolerances and the numerical noise of each point.
    pub noise: numerical::Noise,
    /// How far each key's fit may lie from the least-squares point by the
    /// search's last step, in its units.
    pub resolution: Vec<Option<f64>>,
    /// The search.
    pub fit: fit::Fit,
    /// The estimates behind the standard errors.
    pub precision: precision::Precision,
    /// Each point's simulated run at the fit.
    pub simulated: Vec<RunOutcome>,
    /// End time of each run, s.
    pub t_end: f64,
    /// Closed-loop runs made.
    pub runs: usize,
    /// What a user must know: keys not identified, runs not held, points refused.
    pub warnings: Vec<String>,
}

/// Runs the command (stages of the module doc); with `--shard`, its part of
/// the starts ([`part`]).
pub fn run(args: &CalibrateArgs, console: &mut Console<'_>) -> Result<(), Failure> {
    if let Some(capture) = &args.capture {
        return capture::run(args, capture, console);
    }
    if let Some(shard) = args.shard {
        return part::run_shard(args, shard, console);
    }
    let inputs = read_options(args)?;
    fit_and_report(args, inputs, HashMap::new(), console)
}

/// Stages 2 to 4 on the checked `inputs`, the trial points `preset` evaluated
/// already (by the parts of a fit in parts).
pub(crate) fn fit_and_report(
    args: &CalibrateArgs,
    inputs: Inputs,
    preset: HashMap<Vec<u64>, Evaluated>,
    console: &mut Console<'_>,
) -> Result<(), Failure> {
    // 1. The output before any run; then what the fit will cost.
    let mut staged = Staged::new();
    let out = staged.add_optional("--write", args.write.as_deref())?;
    let settings = Settings::for_keys(inputs.keys.len());
    // What the parts evaluated already: the plan and the closing line say so.
    let in_parts = (!preset.is_empty()).then(|| plan::InParts {
        evaluations: preset.len(),
        runs: preset
            .values()
            .map(|e| e.as_ref().map_or(0, Vec::len))
            .sum(),
    });
    let plan = plan::plan(args, &inputs, &settings, in_parts);
    console.note(&plan.render(rayon::current_num_threads()));

    // 2. and 3. The fit, with a progress bar on stderr (on a terminal).
    let started = Instant::now();
    let mut calibration = calibrate(args, inputs, &settings, preset)?;
    calibration.warnings.extend(plan.warnings);
    let seconds = started.elapsed().as_secs_f64();

    // 4. The file, then the result: printed whether or not the file could be
    // written (the fit is not thrown away), its error after it.
    let mut file = || -> Result<(), Failure> {
        if let (Some(i), Some(path)) = (out, &args.write) {
            let (text, _) = read_machine_file(&args.machine.path)?;
            let written = report::machine_file(&args.machine.path, &text, &calibration, path)?;
            staged.write(i, &written)?;
        }
        Ok(())
    };
    let written = file().and_then(|()| staged.commit());
    console.print(&match args.format.format {
        crate::args::Format::Json => report::json(&calibration, args),
        crate::args::Format::Table => report::table(&calibration, args),
    });
    written?;
    // Of a merge, the runs the parts made are not the seconds': said apart.
    let here = match in_parts {
        Some(done) => format!(
            ", {} of them ({}) made in the parts, the other {}",
            count(done.evaluations, "evaluation"),
            count(done.runs, "run"),
            count(calibration.runs.saturating_sub(done.runs), "run")
        ),
        None => String::new(),
    };
    console.note(&format!(
        "calibrate: {} ({}){here} in {:.1} s on {}{}\n",
        count(calibration.fit.evaluations, "evaluation"),
        count(calibration.runs, "run"),
        seconds,
        count(rayon::current_num_threads(), "thread"),
        warning_count(&calibration.warnings)
    ));
    Ok(())
}

/// The runs of the fit: for a batch of trial points (normalised), the machines
/// with their values and one run per measured point on each, all in parallel.
struct Trials<'a> {
    args: &'a CalibrateArgs,
    inputs: &'a Inputs,
    /// The measured points' speeds and offsets.
    points: Vec<(f64, f64)>,
    progress: crate::output::progress::Progress,
    /// The runs of every point evaluated, by the bits of its coordinates.
    outcomes: HashMap<Vec<u64>, Vec<RunOutcome>>,
    /// Trial points evaluated already (by the parts of a fit in parts, `merge`):
    /// their runs, or the reader's refusal, by the bits of their coordinates.
    preset: HashMap<Vec<u64>, Evaluated>,
    /// The reader's refusal of each trial point it refused.
    refused: Vec<String>,
    /// Runs made.
    runs: usize,
}

/// One trial point's evaluation: a run per measured point, in their order, or
/// the machine reader's refusal of its values.
pub type Evaluated = Result<Vec<RunOutcome>, String>;

/// The machine reader's refusal of a trial point as the user reads it, every
/// `error: ` line of it: the warning quotes it, and a part records it so.
pub fn refusal(f: &Failure) -> String {
    f.message().trim_end().to_string()
}

/// The key of a point in [`Trials::outcomes`].
fn bits(u: &[f64]) -> Vec<u64> {
    u.iter().map(|x| x.to_bits()).collect()
}

impl Trials<'_> {
    /// The runs of every trial point of `batch` (those in [`Trials::preset`]
    /// taken from there), in order; `Err` on Ctrl-C.
    fn evaluate(&mut self, batch: &[Vec<f64>]) -> Result<Vec<Evaluated>, Failure> {
        let Inputs {
            text, keys, t_end, ..
        } = self.inputs;
        let points = &self.points;
        // The machines, in order (a point evaluated already or refused has none).
        let mut done: Vec<Option<Evaluated>> = Vec::new();
        let mut machines = Vec::new();
        for u in batch {
            if let Some(e) = self.preset.remove(&bits(u)) {
                self.runs += e.as_ref().map_or(0, Vec::len);
                done.push(Some(e));
                machines.push(None);
                continue;
            }
            let mut sets = self.args.set.keys.clone();
            sets.extend(keys::sets_at(keys, u));
            match load_machine(&self.args.machine.path, text, &sets) {
                Ok(m) => {
                    done.push(None);
                    machines.push(Some(m));
                }
                Err(e) => {
                    done.push(Some(Err(refusal(&e))));
                    machines.push(None);
                }
            }
        }
        // Their runs, in parallel, collected in order.
        let jobs: Vec<(usize, usize)> = (0..batch.len())
            .filter(|&c| machines[c].is_some())
            .flat_map(|c| (0..points.len()).map(move |k| (c, k)))
            .collect();
        let progress = &self.progress;
        let ran: Vec<RunOutcome> = jobs
            .par_iter()
            .map(|&(c, k)| {
                let (speed, offset) = points[k];
                let machine = machines[c].as_ref().expect("jobs have machines");
                let o = run_point(machine, speed, offset, *t_end);
                progress.inc(1);
                o
            })
            .collect();
        self.runs += ran.len();
        if crate::interrupt::interrupted() {
            return Err(Failure::run(format!(
                "calibrate: {}: the fit is incomplete, nothing written",
                crate::interrupt::interruption()
            )));
        }
        let mut ran = ran.into_iter();
        Ok(done
            .into_iter()
            .map(|e| e.unwrap_or_else(|| Ok(ran.by_ref().take(points.len()).collect())))
            .collect())
    }

    /// The weighted residuals of every trial point of `batch`, one per measured
    /// point (not numbers for a trial point the reader refuses); `Err` on Ctrl-C.
    fn residuals(&mut self, batch: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, Failure> {
        let evaluated = self.evaluate(batch)?;
        let data = &self.inputs.data;
        let mut out = Vec::new();
        for (u, e) in batch.iter().zip(evaluated) {
            match e {
                Ok(sims) => {
                    out.push(point_residuals(&data.points, &sims));
                    self.outcomes.insert(bits(u), sims);
                }
                Err(refusal) => {
                    self.refused.push(refusal);
                    out.push(vec![f64::NAN; self.points.len()]);
                }
            }
        }
        Ok(out)
    }
}

/// The start given to the multistart: the machine file's values of `keys`,
/// normalised.
pub fn nominal_start(keys: &[FitKey]) -> Vec<f64> {
    keys.iter().map(|k| k.u_of(k.nominal)).collect()
}

/// Stages 2 and 3 on checked inputs, with the search's `settings`.
pub fn calibrate(
    args: &CalibrateArgs,
    inputs: Inputs,
    settings: &Settings,
    preset: HashMap<Vec<u64>, Evaluated>,
) -> Result<Calibration, Failure> {
    let keys = &inputs.keys;
    let p = keys.len();
    let points = inputs.data.speeds_offsets();
    let mut trials = Trials {
        args,
        inputs: &inputs,
        // The search's most runs and the numerical noise's at the fit
        // ([`most_evaluations`]): the total is fixed from the start (the search
        // may end early).
        progress: progress_bar("calibrate", most_evaluations(settings, p) * points.len()),
        points,
        outcomes: HashMap::new(),
        preset,
        refused: Vec::new(),
        runs: 0,
    };
    let found = fit::fit(p, &[nominal_start(keys)], settings, &mut |b| {
        trials.residuals(b)
    });
    let found = found.inspect_err(|_| trials.progress.finish_and_clear())?;

    // The runs at the fit, point by point.
    let simulated = trials.outcomes.remove(&bits(&found.u)).unwrap_or_default();
    if simulated.len() != inputs.data.points.len() {
        trials.progress.finish_and_clear();
        return Err(Failure::run(
            "calibrate: no point of the search ran (every one refused by the machine reader); nothing written",
        ));
    }

    // 3. The numerical noise at the fit (its machine loaded: the search ran it).
    let mut sets = args.set.keys.clone();
    sets.extend(keys::sets_at(keys, &found.u));
    let machine =
        load_machine(&args.machine.path, &inputs.text, &sets).map_err(|f| f.of_kind(Kind::Run))?;
    let progress = &trials.progress;
    let noise = numerical::noise(
        &machine,
        &inputs.data.points,
        inputs.t_end,
        &simulated,
        &|| progress.inc(1),
    );
    trials.progress.finish_and_clear();
    crate::sweep::refuse_interrupted("calibrate", "the fit is incomplete")?;
    let runs = trials.runs + numerical::DIVISORS.len() * trials.points.len();

    // Standard errors and resolution, in the keys' units.
    let n = inputs.data.rows;
    let ssr = found.ssr + inputs.data.scatter();
    let numerical: Vec<f64> = inputs
        .data
        .points
        .iter()
        .zip(&noise.sd)
        .map(|(point, tau)| point.weight * tau * tau)
        .collect();
    let precision = precision::precision(
        &found.jacobian,
        ssr,
        n,
        settings.last_step,
        &precision::Numerical {
            variance: numerical,
            indifference: noise.gain() + noise.ssr_sd(),
        },
    );
    let in_units = |normalised: &[Option<f64>]| -> Vec<Option<f64>> {
        keys.iter()
            .zip(normalised)
            .map(|(k, s)| s.map(|s| s * k.width()))
            .collect()
    };
    let std_error = in_units(&precision.std_error_u);
    let std_error_measurement = in_units(&precision.measurement_u);
    let std_error_numerical = in_units(&precision.numerical_u);
    let resolution = in_units(&precision.resolution_u);
    let mut warnings = report::warnings(
        keys,
        &found,
        n,
        &precision,
        &std_error,
        &simulated,
        &trials.refused,
    );
    warnings.extend(report::numerical_warnings(
        keys,
        &std_error_measurement,
        &std_error_numerical,
        &inputs.data.points,
        &noise,
    ));
    Ok(Calibration {
        fitted: keys
            .iter()
            .zip(&found.u)
            .map(|(k, u)| k.value_at(*u))
            .collect(),
        keys: inputs.keys.clone(),
        ssr,
        std_error,
        std_error_measurement,
        std_error_numerical,
        noise,
        resolution,
        fit: found,
        precision,
        simulated,
        t_end: inputs.t_end,
        runs,
        warnings,
        data: inputs.data,
    })
}

/// The most evaluations of a fit of `p` keys with `settings`: the search's and
/// the runs again at the other tolerances ([`numerical::DIVISORS`]).
pub fn most_evaluations(settings: &Settings, p: usize) -> usize {
    settings.most_evaluations(1, p) + numerical::DIVISORS.len()
}

/// The weighted residuals of the measured `points` (the simulated run of point
/// `k` in `sims[k]`), m/s ([`Point::residual`]).
pub fn point_residuals(points: &[Point], sims: &[RunOutcome]) -> Vec<f64> {
    points
        .iter()
        .zip(sims)
        .map(|(p, o)| p.residual(o.velocity()))
        .collect()
}
