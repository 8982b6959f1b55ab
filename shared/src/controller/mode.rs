//! The controller's mode: its [`State`] together with the data only that state
//! uses, so that a combination the state machine never reaches cannot be
//! written: a run carries its command, speed ramp and loops (starting, running,
//! stopping); the phase loop's integrator and error history exist only while the
//! loop is closed within a run; the self-test in progress exists only in the
//! self-test; latched faults only in `Fault`. (The identification's working
//! memory, 1.6 KB, is the controller's own field, kept apart from the mode for
//! the tick's sake.)

use super::faults::Faults;
use super::io::{Direction, State};
use super::phase_loop::PhaseLoop;
use super::self_test::SelfTestRun;
use super::speed_loop::SpeedLoop;

/// Where a run's phase offset comes from.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum OffsetSource {
    /// The tuning table's offset for this direction at the ramped speed.
    Table(Direction),
    /// A fixed offset, degrees in [0, 360).
    Fixed(f32),
}

/// What the run command in force asks for.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct RunTarget {
    /// Rotor speed, rpm.
    pub speed_rpm: f32,
    /// Where the phase offset comes from.
    pub offset: OffsetSource,
}

/// The phase error of a closed phase loop, unwrapped since the loop closed: a rotor
/// slipping whole turns keeps it growing, where the wrapped error would come back
/// through 0 every turn.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct UnwrappedError {
    /// The sum of the wrapped error's tick-to-tick changes since the loop closed,
    /// degrees.
    pub sum_deg: f32,
    /// The last wrapped error, degrees in (-180, 180].
    pub last_deg: f32,
}

/// The phase-lock loop of a run.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum PhaseLock {
    /// Open: the phase offset is not measured yet (an index pulse missing), or the
    /// ramped speed is below [`super::Params::phase_loop_min_rpm`]; both rotors get
    /// the ramp's speed reference.
    Open,
    /// Closed: the PI on the phase error splits a speed difference between the
    /// rotors' references.
    Closed {
        /// The PI's state (its integrator), empty when the loop closes.
        pi: PhaseLoop,
        /// The phase error since the loop closed, for the lock check; `None` until
        /// the first tick that measures it after closing.
        error: Option<UnwrappedError>,
    },
}

/// A run, from a run command in idle until a stop reaches rest or a fault
/// latches: what it asks for, and where its speed reference and loops are.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Run {
    /// The run command in force (while stopping, the one that was stopped: a
    /// phase loop closing during the stop heads for its offset).
    pub target: RunTarget,
    /// The ramped speed reference, rpm.
    pub ramp_rpm: f32,
    /// The phase-lock loop.
    pub phase: PhaseLock,
    /// The speed loops of rotor 1 and rotor 2.
    pub speed_loops: [SpeedLoop; 2],
}

impl Run {
    /// A run of `target`, its speed ramp from `ramp_rpm`, its phase loop open and
    /// its speed loops empty.
    pub fn new(target: RunTarget, ramp_rpm: f32) -> Run {
        Run {
            target,
            ramp_rpm,
            phase: PhaseLock::Open,
            speed_loops: [SpeedLoop::new(); 2],
        }
    }

    /// Whether the phase loop is closed.
    pub fn phase_closed(&self) -> bool {
        matches!(self.phase, PhaseLock::Closed { .. })
    }
}

/// The controller's state with its data. [`Mode::state`] names it as
/// [`State`] (telemetry, protocol, host output).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Mode {
    /// Motors off, waiting for a run command.
    Idle,
    /// The first-run self-test, in progress.
    SelfTest(SelfTestRun),
    /// The motor identification, in progress (its working memory is the
    /// controller's, kept apart for the tick's sake).
    Identify,
    /// The speed ramps up to the commanded speed; the phase loop closes on the
    /// way.
    Starting(Run),
    /// At the commanded speed with the phase loop closed (one rotor: no phase
    /// loop); speed and offset changes still ramp.
    Running(Run),
    /// Ramping down to rest after a stop command.
    Stopping {
        /// The run being stopped.
        run: Run,
        /// Time since the speed ramp reached 0, s: the stop ends when both rotors
        /// are slow, or after [`super::Params::stop_timeout_s`].
        ramp_at_zero_s: f32,
    },
    /// Faults latched (never empty): motors off until a reset clears them.
    Fault(Faults),
}

impl Mode {
    /// The state's name.
    pub fn state(&self) -> State {
        match self {
            Mode::Idle => State::Idle,
            Mode::SelfTest(_) => State::SelfTest,
            Mode::Identify => State::Identify,
            Mode::Starting(_) => State::Starting,
            Mode::Running(_) => State::Running,
            Mode::Stopping { .. } => State::Stopping,
            Mode::Fault(_) => State::Fault,
        }
    }

    /// The latched faults (none outside [`Mode::Fault`]).
    pub fn faults(&self) -> Faults {
        match self {
            Mode::Fault(faults) => *faults,
            _ => Faults::NONE,
        }
    }
}
