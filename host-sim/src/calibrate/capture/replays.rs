//! The replays of `calibrate --capture`'s fit ([`super`]): the machine with a
//! trial point's values, one replay of the capture on it, its weighted
//! residuals ([`super::residuals`]); a batch of trial points in parallel.

use std::path::Path;

use rayon::prelude::*;

use super::inputs::Inputs;
use super::{residuals, start};
use crate::calibrate::keys;
use crate::calibrate::CalibrateArgs;
use crate::failure::{Failure, Kind};
use crate::machine::Machine;
use crate::output::progress::Progress;
use crate::replay::{self, Replay};

/// The replays of the fit: for a batch of trial points (normalised), the
/// machines with their values and one replay of the capture on each, all in
/// parallel.
pub struct Replays<'a> {
    /// The command's arguments.
    pub args: &'a CalibrateArgs,
    /// What stage 1 read.
    pub inputs: &'a Inputs,
    /// The progress bar, told of every replay.
    pub progress: Progress,
    /// Why each trial point refused was refused (the machine reader, or the
    /// twin's stop).
    pub refused: Vec<String>,
    /// Replays made.
    pub replays: usize,
}

impl Replays<'_> {
    /// The machine with the trial values `u`.
    pub fn machine(&self, u: &[f64]) -> Result<Machine, Failure> {
        let path = &self.args.machine.path;
        let mut sets = self.args.set.keys.clone();
        sets.extend(keys::sets_at(&self.inputs.keys, u));
        let dir = path.parent().unwrap_or(Path::new(""));
        Ok(Machine::from_text(
            &path.display().to_string(),
            &self.inputs.text,
            dir,
            &sets,
        )?)
    }

    /// The replay of the capture with the trial values `u`.
    pub fn replay(&self, u: &[f64]) -> Result<Replay, Failure> {
        let i = self.inputs;
        replay::replay(&i.capture, &self.machine(u)?, &i.params, Vec::new())
    }

    /// The weighted residuals at `u` from elsewhere in the start counts
    /// ([`start::WITHIN`]), in parallel; `Err` where one does not replay (a
    /// run failure: the replay from the middle did), or on Ctrl-C.
    pub fn within_counts(&mut self, u: &[f64]) -> Result<Vec<Vec<f64>>, Failure> {
        let i = self.inputs;
        let machine = self.machine(u).map_err(|f| f.of_kind(Kind::Run))?;
        let progress = &self.progress;
        let others: Vec<Result<Vec<f64>, Failure>> = start::WITHIN
            .par_iter()
            .map(|within| {
                let r = replay::replay_within(&i.capture, &machine, &i.params, Vec::new(), *within)
                    .map(|r| residuals::weighted(&r, &i.scales, i.rotors, i.window));
                progress.inc(1);
                r
            })
            .collect();
        self.replays += start::WITHIN.len();
        crate::sweep::refuse_interrupted("calibrate", "the fit is incomplete")?;
        others
            .into_iter()
            .map(|r| r.map_err(|f| f.of_kind(Kind::Run)))
            .collect()
    }

    /// The weighted residuals of every trial point of `batch` (not numbers for
    /// one refused); `Err` on Ctrl-C.
    pub fn residuals(&mut self, batch: &[Vec<f64>]) -> Result<Vec<Vec<f64>>, Failure> {
        let i = self.inputs;
        let windows = i.capture.records.len().div_ceil(i.window);
        let n = windows * residuals::per_window(i.rotors);
        let progress = &self.progress;
        let got: Vec<Result<Vec<f64>, String>> = batch
            .par_iter()
            .map(|u| {
                let r = self
                    .replay(u)
                    .map(|r| residuals::weighted(&r, &i.scales, i.rotors, i.window))
                    .map_err(|f| crate::calibrate::refusal(&f));
                progress.inc(1);
                r
            })
            .collect();
        self.replays += batch.len();
        if crate::interrupt::interrupted() {
            return Err(Failure::run(format!(
                "calibrate: {}: the fit is incomplete, nothing written",
                crate::interrupt::interruption()
            )));
        }
        Ok(got
            .into_iter()
            .map(|r| {
                r.unwrap_or_else(|why| {
                    self.refused.push(why);
                    vec![f64::NAN; n]
                })
            })
            .collect())
    }
}
