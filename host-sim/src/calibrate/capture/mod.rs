//! `host-sim calibrate MACHINE --capture CAPTURE.csv --fit KEY[,KEY...]
//! [--firmware-machine FW.toml] [--write OUT.toml] [--format table|json]
//! [--set KEY=VALUE]...`
//!
//! Fits motor keys of the machine file to a capture of the board
//! (docs/calibration.md, "Motor keys from a capture"): by weighted least
//! squares on the replay's residuals, the replayed speeds, currents and duties
//! against the recorded ones, tick by tick, each over its scale ([`scales`]),
//! summed over windows of some 50 ticks ([`residuals`]), within each key's
//! range.
//!
//! Stages of [`run`]:
//! 1. read and check ([`inputs`]), every problem at once (exit 2) before the
//!    fit: the machine file with the `--set`s, the fitted keys and their
//!    ranges ([`super::keys`]), each a key a capture measures ([`motor_key`]);
//!    the capture and its premises (`replay::controller_params`: the
//!    firmware's machine file, a start idle at rest, no table handed over);
//!    one replay at the file's values, timed (a capture whose outputs are not
//!    the controller's is refused there); then the output file (opened,
//!    staged) and the planned cost on stderr;
//! 2. the fit ([`super::fit`] with [`Settings::for_capture`]: the multistart,
//!    then Levenberg–Marquardt, [`super::levenberg`]): one evaluation is one
//!    replay of the whole capture on the twin with the trial values
//!    (`replay::replay`, [`replays`]), a batch of them in parallel; a trial value set the
//!    machine reader refuses, or whose twin stops before the capture's end,
//!    counts as infinitely bad;
//! 3. the replays at the fit from elsewhere in the start counts ([`start`]);
//!    the standard errors from the Jacobian at the fit, the residuals taken
//!    as correlated from window to window ([`super::serial`], over [`lags`]
//!    windows) and the start angles' part, and the keys not identified
//!    ([`super::precision`]);
//! 4. the outputs ([`report`]): `--write` (the machine file with the fitted
//!    values, checked to read back), then the result on stdout as a table or
//!    JSON: the keys, the fit, each quantity's RMS residual at the file's
//!    values and at the fit; one summary line on stderr.

pub mod inputs;
pub mod replays;
pub mod report;
pub mod residuals;
pub mod scales;
pub mod start;

use std::path::Path;
use std::time::Instant;

use super::fit::{self, Settings};
use super::keys::FitKey;
use super::precision::{self, Errors, Numerical, Precision};
use super::serial;
use super::CalibrateArgs;
use crate::failure::{Console, Failure, Kind};
use crate::numbers::{self, count, warning_count};
use crate::output::file::Staged;
use crate::output::progress::Progress;
use crate::replay::Replay;
pub use inputs::{motor_key, read_inputs, Inputs};
use replays::Replays;

/// What stages 2 and 3 found, for the outputs.
pub struct Calibration {
    /// The fitted keys.
    pub keys: Vec<FitKey>,
    /// The fitted value of each key (rounded as written).
    pub fitted: Vec<f64>,
    /// Each key's standard error, in its units: the root sum of squares of
    /// the next two.
    pub std_error: Vec<Option<f64>>,
    /// Its part from the residuals at the fit ([`super::serial`]).
    pub std_error_measurement: Vec<Option<f64>>,
    /// Its part from the start angles ([`start`]).
    pub std_error_start: Vec<Option<f64>>,
    /// The replays at the fit from the middle of the start counts and
    /// elsewhere in them: their sums of squares and Gauss–Newton steps.
    pub spread: start::Spread,
    /// How far each key's fit may lie from the least-squares point: the
    /// Gauss–Newton step left at the fit and half the rounding's last digit,
    /// in its units.
    pub resolution: Vec<Option<f64>>,
    /// The search.
    pub fit: fit::Fit,
    /// The estimates behind the standard errors.
    pub precision: Precision,
    /// Lags of the standard errors' long-run covariance, windows.
    pub lags: usize,
    /// The replay at the fit.
    pub fitted_replay: Replay,
    /// Replays made.
    pub replays: usize,
    /// What a user must know.
    pub warnings: Vec<String>,
}

/// The lags of the standard errors' long-run covariance ([`super::serial`]),
/// windows, for `windows` windows: Newey and West's rule,
/// `floor(4 (T / 100)^(2/9))` (Newey & West, *Review of Economic Studies* 61,
/// 1994, section 3: the lag that grows with the sample as the Bartlett
/// estimate's bias and variance balance); 3 for the 40 windows of a 2 s
/// capture at 50 ticks a window, 2 for 0.5 s. Less than the windows.
pub fn lags(windows: usize) -> usize {
    let l = (4.0 * (windows as f64 / 100.0).powf(2.0 / 9.0)).floor() as usize;
    l.min(windows.saturating_sub(1))
}

/// Stages 2 and 3 on checked inputs, with the search's `settings`.
pub fn calibrate(
    args: &CalibrateArgs,
    inputs: &Inputs,
    settings: &Settings,
) -> Result<Calibration, Failure> {
    let keys = &inputs.keys;
    let p = keys.len();
    let mut replays = Replays {
        args,
        inputs,
        progress: Progress::new("calibrate", most_replays(settings, p) as u64, "replays"),
        refused: Vec::new(),
        replays: 0,
    };
    let found = fit::fit(p, &[super::nominal_start(keys)], settings, &mut |b| {
        replays.residuals(b)
    });
    let found = found.inspect_err(|_| replays.progress.finish_and_clear())?;
    if !found.ssr.is_finite() {
        replays.progress.finish_and_clear();
        return Err(Failure::run(format!(
            "calibrate: no trial point of the search replayed (the first refused: {}); nothing written",
            replays.refused.first().map_or("-", String::as_str)
        )));
    }
    // The replay at the fit, for its residuals and warnings; the replays
    // from elsewhere in the start counts.
    let fitted_replay = replays.replay(&found.u).map_err(|f| f.of_kind(Kind::Run))?;
    replays.progress.inc(1);
    let mut from = vec![found.residuals.clone()];
    from.extend(replays.within_counts(&found.u)?);
    let spread = start::Spread::new(&found.jacobian, &from);
    replays.progress.finish_and_clear();
    crate::sweep::refuse_interrupted("calibrate", "the fit is incomplete")?;

    // 3. Standard errors, the windows' residuals correlated over `lags`
    // windows.
    let per_window = residuals::per_window(inputs.rotors);
    let windows = found.residuals.len() / per_window.max(1);
    let lags = lags(windows);
    let scores = serial::scores(&found.jacobian, &found.residuals, per_window);
    let middle = serial::newey_west(&scores, lags);
    let n = found.residuals.len();
    let precision = precision::with_errors(
        &found.jacobian,
        found.ssr,
        n,
        settings.last_step,
        &Numerical::default(),
        &Errors::Serial {
            middle,
            samples: windows,
        },
    );
    // How far the least-squares point may lie: the Gauss–Newton step left at
    // the fit (to the least-squares point of the linearised residuals), and
    // half the last of the 6 significant digits the value is rounded to.
    let left = spread.steps[0].clone();
    let in_units = |normalised: &[Option<f64>]| -> Vec<Option<f64>> {
        keys.iter()
            .zip(normalised)
            .map(|(k, s)| s.map(|s| s * k.width()))
            .collect()
    };
    // The standard errors: the residuals' part and the start angles', in
    // quadrature.
    let start_u: Vec<Option<f64>> = match spread.sd() {
        Some(sd) => sd.into_iter().map(Some).collect(),
        None => vec![None; p],
    };
    let std_error_measurement = in_units(&precision.measurement_u);
    let std_error_start = in_units(&start_u);
    let std_error: Vec<Option<f64>> = std_error_measurement
        .iter()
        .zip(&std_error_start)
        .map(|(m, s)| Some(m.as_ref()?.hypot(*s.as_ref()?)))
        .collect();
    let resolution: Vec<Option<f64>> = keys
        .iter()
        .enumerate()
        .map(|(i, k)| {
            let column = precision.column_norm[i];
            let rounding = 0.5 * numbers::last_digit(k.value_at(found.u[i]));
            left.as_ref()
                .filter(|_| precision::informative(column))
                .map(|d| d[i].abs() * k.width() + rounding)
        })
        .collect();
    let mut warnings = inputs.warnings.clone();
    warnings.extend(report::warnings(
        keys,
        &found,
        &precision,
        &std_error,
        settings,
        &replays.refused,
        &fitted_replay,
    ));
    Ok(Calibration {
        fitted: keys
            .iter()
            .zip(&found.u)
            .map(|(k, u)| k.value_at(*u))
            .collect(),
        keys: keys.clone(),
        std_error,
        std_error_measurement,
        std_error_start,
        spread,
        resolution,
        fit: found,
        precision,
        lags,
        fitted_replay,
        replays: replays.replays,
        warnings,
    })
}

/// The most replays of a fit of `p` keys with `settings`: the search's, the
/// one at the fit and those from elsewhere in the start counts.
pub fn most_replays(settings: &Settings, p: usize) -> usize {
    settings.most_evaluations(1, p) + 1 + start::WITHIN.len()
}

/// Runs `calibrate --capture` (stages of the module doc).
pub fn run(
    args: &CalibrateArgs,
    capture_path: &Path,
    console: &mut Console<'_>,
) -> Result<(), Failure> {
    // 1. The inputs and the output, before the fit; then what it will cost.
    let inputs = read_inputs(args, capture_path)?;
    let mut staged = Staged::new();
    let out = staged.add_optional("--write", args.write.as_deref())?;
    let settings = Settings::for_capture(inputs.keys.len());
    let most = most_replays(&settings, inputs.keys.len());
    let threads = rayon::current_num_threads();
    console.note(&report::plan(&inputs, most, threads));

    // 2. and 3.
    let started = Instant::now();
    let calibration = calibrate(args, &inputs, &settings)?;
    let seconds = started.elapsed().as_secs_f64();

    // 4. The file, then the result: printed whether or not the file could be
    // written (the fit is not thrown away), its error after it.
    let mut file = || -> Result<(), Failure> {
        if let (Some(i), Some(path)) = (out, &args.write) {
            let written = super::report::machine_file_with(
                &args.machine.path,
                &inputs.text,
                &calibration.keys,
                &calibration.fitted,
                path,
            )?;
            staged.write(i, &written)?;
        }
        Ok(())
    };
    let written = file().and_then(|()| staged.commit());
    console.print(&match args.format.format {
        crate::args::Format::Json => report::json(&calibration, &inputs, args, capture_path),
        crate::args::Format::Table => report::table(&calibration, &inputs, args, capture_path),
    });
    written?;
    console.note(&format!(
        "calibrate: {} ({}) in {:.1} s on {}{}\n",
        count(calibration.fit.evaluations, "evaluation"),
        count(calibration.replays, "replay"),
        seconds,
        count(threads, "thread"),
        warning_count(&calibration.warnings)
    ));
    Ok(())
}
