//! What one run may ask: bounds, so that a typo
//! (`--t-end 1e300`, `simulation.output_step=1e-300`) is refused with the key and
//! the limit instead of running forever or filling the memory.
//!
//! - [`MAX_T_END_S`]: one hour of simulated time. The reference machine runs at
//!   20 to 40 times real time on one core, so the longest run takes about 1.5 to 3
//!   minutes; longer studies are several runs.
//! - [`MAX_TRACE_ROWS`]: the regular trace rows of one run, `t_end / output_step`
//!   (events add two rows each). Every row is computed whether or not it is
//!   written, and the summary keeps 16 bytes of each row of the second half, so
//!   10^7 rows are at most 80 MB and about 2 GB of CSV.

use crate::machine::Machine;
use crate::numbers::sig;

/// Longest simulated time of one run, s.
pub const MAX_T_END_S: f64 = 3600.0;

/// Most regular trace rows of one run (`t_end / output_step`).
pub const MAX_TRACE_ROWS: f64 = 1.0e7;

/// The limits as lines for people (`run --help`), from the constants above.
pub fn describe() -> Vec<String> {
    vec![
        format!(
            "--t-end (or simulation.t_end): at most {} s of simulated time in one run",
            sig(MAX_T_END_S)
        ),
        format!("trace rows, t_end / simulation.output_step: at most {MAX_TRACE_ROWS:.0e}"),
    ]
}

/// The problems of a run of `machine` to `t_end`, s, whose end
/// time was given as `t_end_key` (`--t-end`, `simulation.t_end`, `FILE: t_end`):
/// one text each, as a [`crate::failure::Failure`]'s reasons say them.
pub fn check(machine: &Machine, t_end: f64, t_end_key: &str) -> Vec<String> {
    let mut problems = Vec::new();
    if !(t_end.is_finite() && t_end > 0.0) {
        // The caller's own check says what a valid end time is.
        return problems;
    }
    if t_end > MAX_T_END_S {
        problems.push(format!(
            "{t_end_key} {}: at most {} s of simulated time in one run (split a longer study into runs)",
            sig(t_end),
            sig(MAX_T_END_S)
        ));
        return problems;
    }
    let step = machine.simulation.output_step;
    let rows = t_end / step;
    if rows > MAX_TRACE_ROWS {
        problems.push(format!(
            "simulation.output_step {}: {} trace rows over {} s, at most {:.0e}: make output_step at least {} s",
            sig(step),
            sig(rows.floor()),
            sig(t_end),
            MAX_TRACE_ROWS,
            sig(t_end / MAX_TRACE_ROWS)
        ));
    }
    problems
}
