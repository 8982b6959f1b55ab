//! The capture's own controller, run again: a controller built as the board's
//! (its machine file, the capture's tuning table) stepped on the capture's
//! recorded inputs, tick by tick. It gives what the board's controller computed
//! and did not record (its filtered speeds, the measured phase offset), and it
//! checks the capture: a controller that, given the same inputs, does not write
//! the recorded duties, state and faults is not the one that recorded it (the
//! wrong machine file, another table, a capture edited with its checksum
//! recomputed), and the replay stops there.

use shared::capture::{duty_raw, Record};
use shared::controller::{Command, Controller, Outputs, Params, ResetCause};

use crate::capture::CaptureFile;

/// How far a duty recomputed on the host may be from the recorded one, in
/// units of 1/32767: the board's `f32` arithmetic and the host's are both IEEE
/// binary32, but the compilers may order operations apart, which moves a duty
/// by an ulp or so, seen here as one unit at most after rounding.
pub const DUTY_UNITS: i32 = 2;

/// The inputs of tick `k` of `capture`: the record's, with its command, and at
/// the first tick the index latches the board's controller knew before the
/// capture (`start_index`), for a rotor whose first record has none.
pub fn inputs_at(capture: &CaptureFile, k: usize) -> shared::controller::Inputs {
    let record = &capture.records[k];
    let mut inputs = record.inputs(capture.commands[k]);
    if k == 0 {
        for r in 0..2 {
            if inputs.index[r].is_none() {
                inputs.index[r] = capture.header.start.index[r];
            }
        }
    }
    inputs
}

/// Start what the link started before tick `k`'s step.
pub fn start_procedures(controller: &mut Controller, record: &Record) {
    if record.self_test_started {
        controller.start_self_test();
    }
    if record.identify_started {
        controller.start_identify();
    }
}

/// Where the re-run first differs from the record, for the message.
#[derive(Clone, Debug, PartialEq)]
pub struct Mismatch {
    /// The tick.
    pub tick: usize,
    /// What the board recorded and what the controller wrote, for people.
    pub recorded: String,
    /// What the controller built from the files wrote.
    pub recomputed: String,
}

/// The controller of `params` stepped on every tick of `capture`; `Err` at the
/// first tick whose outputs differ from the record.
pub fn rerun(params: &Params, capture: &CaptureFile) -> Result<Vec<Outputs>, Mismatch> {
    let mut controller = Controller::new(params, ResetCause::PowerOn);
    let dt = capture.header.tick_s as f32;
    let mut outs = Vec::with_capacity(capture.records.len());
    for (k, record) in capture.records.iter().enumerate() {
        start_procedures(&mut controller, record);
        let out = controller.step(&inputs_at(capture, k), dt);
        let duty = out.bridges.map(duty_raw);
        let close = (0..2).all(|r| match (duty[r], record.duty_raw[r]) {
            (None, None) => true,
            (Some(a), Some(b)) => (i32::from(a) - i32::from(b)).abs() <= DUTY_UNITS,
            _ => false,
        });
        if !close || out.state != record.state || out.faults != record.faults {
            return Err(Mismatch {
                tick: k,
                recorded: outputs_text(record.state.name(), record.faults, record.duty()),
                recomputed: outputs_text(out.state.name(), out.faults, duty_of(&out)),
            });
        }
        outs.push(out);
    }
    Ok(outs)
}

fn duty_of(out: &Outputs) -> [Option<f32>; 2] {
    out.bridges.map(|b| b.is_driven().then_some(b.duty()))
}

fn outputs_text(state: &str, faults: shared::controller::Faults, duty: [Option<f32>; 2]) -> String {
    let d = duty.map(|d| d.map_or("off".to_string(), |d| format!("{d:.5}")));
    format!("state {state}, faults {faults}, duties {} {}", d[0], d[1])
}

/// The command of a tick, for the twin's port.
pub fn command_at(capture: &CaptureFile, k: usize) -> Option<Command> {
    capture.commands.get(k).copied().flatten()
}
