//! What the controller reads and writes each tick: [`Inputs`], [`Command`],
//! [`Outputs`], [`Telemetry`], and the names of its [`State`]s.
//!
//! Rotor 1 is index 0 of every pair, rotor 2 index 1, in the machine file's order
//! (`[[rotors]]`). On a machine with one rotor ([`super::RotorCount::One`]) the pairs
//! keep two entries: rotor 2's inputs are not read, and its outputs and telemetry
//! (duty, speed, reference, current) are 0. Every angle, speed, current and duty is signed in the rotor's
//! *driven sense* (the `sense` of the machine file): positive is the way the rotor
//! turns when driven forward, whichever way that is in the platform frame.

use super::faults::Faults;

/// Travel direction along the platform's x axis.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Direction {
    /// Towards +x (offsets near 90 degrees for the reference machine).
    Right,
    /// Towards -x (offsets near 270 degrees).
    Left,
}

/// Both ways, named as scenario files and outputs write them.
impl crate::Enumerated for Direction {
    const ALL: &'static [Direction] = &[Direction::Right, Direction::Left];

    fn name(self) -> &'static str {
        match self {
            Direction::Right => "right",
            Direction::Left => "left",
        }
    }
}

/// A command from the host (or the firmware's own panel), at most one per tick.
///
/// Any command, [`Command::Heartbeat`] included, proves the link alive
/// ([`super::FaultLimits::link_timeout_s`]).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Command {
    /// Ramp both rotors down to rest, then go idle (motors off).
    Stop,
    /// Run both rotors at `speed_rpm` with the phase offset the tuning table gives
    /// for `direction` at that speed.
    Travel {
        /// Which way to travel.
        direction: Direction,
        /// Rotor speed, rpm, in the driven sense; within
        /// [`super::Params::min_speed_rpm`, `max_speed_rpm`] or the command is refused.
        speed_rpm: f32,
    },
    /// Run both rotors at `speed_rpm` and hold the phase offset `offset_deg`.
    HoldOffset {
        /// Rotor speed, rpm, as for [`Command::Travel`].
        speed_rpm: f32,
        /// Phase offset `theta_1 - theta_2`, degrees, finite (wrapped to [0, 360)).
        offset_deg: f32,
    },
    /// Clear the latched faults whose cause is gone; back to [`State::Idle`] when
    /// none is left. Never starts the motors.
    ResetFaults,
    /// Nothing but "the link is alive".
    Heartbeat,
}

/// Why the processor started: the controller is built once per start.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ResetCause {
    /// Power-on, a reset pin or a deliberate software reset: start idle.
    PowerOn,
    /// The independent watchdog fired: start in [`State::Fault`] with
    /// [`Faults::WATCHDOG_RESET`] latched, so a crash never restarts the motors on
    /// its own.
    Watchdog,
}

/// The sampled inputs of one control tick.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Inputs {
    /// Encoder counters, counts after x4 decoding, wrapping at `2^32`; they increase
    /// when the rotor turns in its driven sense. Travel between ticks is
    /// `now.wrapping_sub(before) as i32`.
    pub encoder: [u32; 2],
    /// The counter value latched at an index pulse since the previous tick, `None`
    /// when there was none. The index marks `theta = 0`
    /// (`theta = s (phi - index_angle)`: docs/machine-file.md, "Conventions"), so the
    /// controller's angle is `theta = 2 pi (count - index_count) / N`.
    pub index: [Option<u32>; 2],
    /// Winding currents, A, measured, positive when driving the rotor forward:
    /// each the mean over the tick just ended (the firmware averages its ADC
    /// conversions, one per PWM update, over the tick; host-sim integrates the
    /// plant's current over the tick), not a sample at some point of the ripple.
    /// The two are the same in slow decay, where the current's ripple is linear
    /// about its mean at the sampling instant (`shared::drive`); in fast decay with
    /// the current dying in each period they are not, so the firmware's build
    /// refuses fast decay until its ADC averages the period.
    pub current: [f32; 2],
    /// Motor supply (DC bus) voltage, V, measured.
    pub supply_voltage: f32,
    /// `true` when the E-stop circuit is open (pressed, or a wire broken).
    pub estop: bool,
    /// A command received since the previous tick.
    pub command: Option<Command>,
    /// When this tick started and how long the previous one worked, as the
    /// firmware measured them (a lockstep simulation's ticks are on time: zero,
    /// unless a scenario injects lateness).
    pub timing: TickTiming,
}

/// The timing of the control loop as the firmware measures it (its cycle
/// counter): what the deadline check ([`super::Faults::DEADLINE`]) looks at.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct TickTiming {
    /// How long after its nominal time this tick started, s (0 or more).
    pub late_s: f32,
    /// How long the previous tick's work took, from its start to its end, s.
    pub busy_s: f32,
}

impl Default for Inputs {
    /// Counters at 0, no index, no current, 0 V, E-stop closed, no command.
    fn default() -> Self {
        Inputs {
            encoder: [0; 2],
            index: [None; 2],
            current: [0.0; 2],
            supply_voltage: 0.0,
            estop: false,
            command: None,
            timing: TickTiming::default(),
        }
    }
}

/// The controller's state (the sequence of a run).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum State {
    /// Motors off (driver disabled, windings open), waiting for a run command.
    Idle,
    /// Soft start: the speed ramps up to the commanded speed (fast through the
    /// resonance band); the phase loop joins once both index pulses have been seen
    /// and the speed is above [`super::Params::phase_loop_min_rpm`].
    Starting,
    /// At the commanded speed with the phase loop holding the offset; speed and
    /// offset changes still ramp.
    Running,
    /// Ramping down to rest after [`Command::Stop`]; then [`State::Idle`].
    Stopping,
    /// A fault is latched: motors off until [`Command::ResetFaults`] clears it.
    Fault,
    /// The first-run self-test drives the motors, one at a time, gently and open
    /// loop ([`super::self_test`]); then [`State::Idle`]. [`Command::Stop`] aborts it
    /// (idle), a fault too ([`State::Fault`]); run commands are refused meanwhile.
    SelfTest,
    /// The motor identification drives the motors, one at a time, open loop
    /// ([`super::identify`]); then [`State::Idle`]. Aborted as the self-test is.
    Identify,
}

impl State {
    /// `idle`, `starting`, `running`, `stopping`, `fault`, `self_test` or
    /// `identify`.
    pub fn name(self) -> &'static str {
        match self {
            State::Idle => "idle",
            State::Starting => "starting",
            State::Running => "running",
            State::Stopping => "stopping",
            State::Fault => "fault",
            State::SelfTest => "self_test",
            State::Identify => "identify",
        }
    }

    /// Every state, in wire-code order.
    pub const ALL: [State; 7] = [
        State::Idle,
        State::Starting,
        State::Running,
        State::Stopping,
        State::Fault,
        State::SelfTest,
        State::Identify,
    ];

    /// The state's code on the wire and in a capture: 0 idle, 1 starting,
    /// 2 running, 3 stopping, 4 fault, 5 self-test, 6 identify.
    pub fn code(self) -> u8 {
        match self {
            State::Idle => 0,
            State::Starting => 1,
            State::Running => 2,
            State::Stopping => 3,
            State::Fault => 4,
            State::SelfTest => 5,
            State::Identify => 6,
        }
    }

    /// The state of wire code `b`, if there is one.
    pub fn from_code(b: u8) -> Option<State> {
        State::ALL.into_iter().find(|s| s.code() == b)
    }

    /// The state named `name` ([`State::name`]), if there is one.
    pub fn from_name(name: &str) -> Option<State> {
        State::ALL.into_iter().find(|s| s.name() == name)
    }

    /// Whether the motors are driven in this state (before the fault override).
    pub fn drives(self) -> bool {
        matches!(
            self,
            State::Starting | State::Running | State::Stopping | State::SelfTest | State::Identify
        )
    }
}

/// Measurements and internal references of one tick, for logs and plots.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Telemetry {
    /// Filtered rotor speeds, rpm, in the driven sense.
    pub speed_rpm: [f32; 2],
    /// Speed references of the speed loops, rpm: the ramp plus and minus half the
    /// phase loop's trim (0 when not driving).
    pub speed_ref_rpm: [f32; 2],
    /// Whether the phase offset is measured: both index pulses seen.
    pub phase_valid: bool,
    /// Measured phase offset `theta_1 - theta_2`, degrees in [0, 360) (0 until
    /// `phase_valid`).
    pub phase_offset_deg: f32,
    /// Whether the phase loop is closed this tick.
    pub phase_loop_closed: bool,
    /// The offset reference the phase loop follows (the ramped one), degrees in
    /// [0, 360); meaningful while `phase_loop_closed` (otherwise the last one).
    pub commanded_offset_deg: f32,
    /// Where the offset reference is heading: the table's offset at the current
    /// speed reference, or the held offset, degrees in [0, 360); meaningful while
    /// `phase_loop_closed`.
    pub target_offset_deg: f32,
    /// Phase error `commanded - measured`, degrees in (-180, 180] (0 while the phase
    /// loop is open).
    pub phase_error_deg: f32,
    /// Measured winding currents, A (as read; NaN passes through); rotor 2's 0 on a
    /// one-rotor machine, whose rotor 2 current is not read.
    pub current: [f32; 2],
    /// Measured supply voltage, V (as read).
    pub supply_voltage: f32,
    /// The duties written, in [-1, 1] (equal to [`Outputs::duties`]: 0 for a bridge
    /// off).
    pub duty: [f32; 2],
    /// The command of this tick was refused: out-of-range values, or a run command
    /// while a fault is latched or a self-test runs.
    pub command_rejected: bool,
    /// How late this tick started, us (the input, saturating at 65535).
    pub tick_late_us: u16,
    /// How long the previous tick's work took, us (the input, saturating).
    pub tick_busy_us: u16,
    /// Ticks that missed their deadline since the start, in any state (saturating).
    pub overruns: u16,
}

/// What one H-bridge does in a tick.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Bridge {
    /// Off (the default, the safe state): both inputs low, every switch open; the
    /// winding is open and the motor coasts.
    #[default]
    Off,
    /// Driven at a signed duty in [-1, 1]: `duty x supply` on the winding, positive
    /// driving the rotor forward (its driven sense). Driven at 0 shorts the winding
    /// in slow decay (the rotor brakes), which off does not.
    Driven(f32),
}

impl Bridge {
    /// `Driven(duty)` when `on`, otherwise `Off`.
    pub(crate) fn driven_if(on: bool, duty: f32) -> Bridge {
        if on {
            Bridge::Driven(duty)
        } else {
            Bridge::Off
        }
    }

    /// The duty, in [-1, 1]; 0 when off.
    pub fn duty(self) -> f32 {
        match self {
            Bridge::Off => 0.0,
            Bridge::Driven(duty) => duty,
        }
    }

    /// Whether the bridge is driven (at any duty, 0 included).
    pub fn is_driven(self) -> bool {
        matches!(self, Bridge::Driven(_))
    }
}

/// What the controller writes each tick. Built afresh every tick, so a value from an
/// earlier tick can never pass through.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Outputs {
    /// The H-bridges of rotor 1 and rotor 2: driven at a duty while the state
    /// drives the motors (both on two rotors; rotor 1's alone on one,
    /// [`super::RotorCount::bridges_on`]), otherwise off. Every bridge off is the
    /// safe state (driver disabled, windings open). What the firmware and the
    /// simulation put on the bridges, decided here once.
    pub bridges: [Bridge; 2],
    /// The state after this tick.
    pub state: State,
    /// Latched faults after this tick (empty unless `state` is [`State::Fault`]).
    pub faults: Faults,
    /// Measurements and references of this tick.
    pub telemetry: Telemetry,
}

impl Outputs {
    /// The duties of rotor 1's and rotor 2's bridges, in [-1, 1]; 0 for a bridge
    /// off.
    pub fn duties(&self) -> [f32; 2] {
        [self.bridges[0].duty(), self.bridges[1].duty()]
    }

    /// Whether any bridge is driven (the driver enabled); `false` is the safe
    /// state, every winding open.
    pub fn drives(&self) -> bool {
        self.bridges[0].is_driven() || self.bridges[1].is_driven()
    }
}
