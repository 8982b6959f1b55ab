//! `machine-file`: the machine file and the tuning file read and checked, for
//! host-sim and for the firmware's build script: one path from the files to the
//! controller's constants, so the firmware compiles in exactly what the simulator
//! runs and tunes.
//!
//! - [`Machine::load`]: the machine file (`docs/machine-file.md`), the vibro
//!   driver that host-sim simulates, checked into plain values. All positions are
//!   world coordinates at `t = 0`, SI units, radians; the doc lists every key,
//!   default and message;
//! - [`set`]: the `--set KEY=VALUE` overrides;
//! - [`tuning_file`]: the tuning table file, read with the controller's own rule for
//!   its rows, and written;
//! - [`machine_constants`]: the controller's constants of a machine, by `shared`'s
//!   formulas ([`MachineConstants::from_physics`]);
//! - [`input`]: the checked TOML reader the files (and host-sim's other input files)
//!   are read with: every problem with its file and key path;
//! - [`kind`]: which input file a table is, so a file given to the wrong command
//!   is refused in one line naming the command that reads it.
//!
//! Reading a machine file (see [`Machine::load`]):
//! 1. read and parse the TOML ([`input`]); a file recognisably of another kind (an
//!    impact case, a scenario, a tuning table) is one problem saying so ([`kind`]);
//! 2. apply the `--set KEY=VALUE` overrides to the parsed table
//!    ([`set`]), so overridden values meet the same checks;
//! 3. every key on its own: types, NaN and infinities, ranges, unknown keys with a
//!    "did you mean"; the optional sections take their defaults;
//! 4. each rotor's motor: the machine's `[motor]`, with any key the rotor's own
//!    `[rotors.motor]` gives replaced (partial override);
//! 5. the contacts and rotors as a whole: 1 to [`MAX_CONTACTS`](shared::impact::MAX_CONTACTS) contacts, one or two
//!    rotors ([`Rotors`]), unique names;
//! 6. the geometry at `t = 0`: no contact below the fundament,
//!    `gap = n . (K - P) >= 0`;
//! 7. every problem at once; a problem in a value a `--set` gave names that `--set`.
//!
//! Its dependencies stay few (`shared`, `toml`, `serde`, `strsim`): the firmware's
//! build compiles it for the host.
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod bodies;
pub mod input;
pub mod joint_limits;
pub mod kind;
pub mod rotors;
pub mod set;
pub mod tuning_file;
pub mod uncertainty;

use std::path::{Path, PathBuf};

use shared::controller::{MachineConstants, MachinePhysics, RotorCount, RotorPhysics};
use shared::drive::{BridgeConfig, Decay};
use shared::impact::ImpactLaw;
use shared::Enumerated;
use toml::Table;

use bodies::{Body, ContactEnds, Joint};
use input::{
    check_names, number, read_name, vector, Limit, Location, Named, Need, Problem, Problems,
    Section,
};
use rotors::Rotors;
use set::Override;

/// The obstacle line the platform strikes, and gravity.
#[derive(Clone, Debug, PartialEq)]
pub struct Fundament {
    /// A point of the line, m.
    pub point: [f64; 2],
    /// Unit normal, from the fundament towards the platform.
    pub normal: [f64; 2],
    /// Gravity, m/s^2.
    pub gravity: [f64; 2],
}

/// The moving platform, without the rotors' eccentric masses.
#[derive(Clone, Debug, PartialEq)]
pub struct Platform {
    /// Mass, kg.
    pub mass: f64,
    /// Moment of inertia about its centre of mass, kg m^2.
    pub inertia: f64,
    /// Centre of mass at t = 0, m.
    pub position: [f64; 2],
    /// Angle at t = 0, rad.
    pub angle: f64,
    /// Velocity of the centre of mass at t = 0, m/s.
    pub velocity: [f64; 2],
    /// Angular velocity at t = 0, rad/s.
    pub angular_velocity: f64,
}

/// A point of the platform that strikes the fundament.
#[derive(Clone, Debug, PartialEq)]
pub struct MachineContact {
    /// Name (K1, K2, ...).
    pub name: String,
    /// World position at t = 0, m.
    pub point: [f64; 2],
    /// Restitution coefficient of the impact law, in [0, 1].
    pub restitution: f64,
    /// Coulomb friction coefficient, >= 0.
    pub friction: f64,
    /// Relative stiffness, > 0.
    pub weight: f64,
    /// The bodies it is between: the platform against the fundament unless
    /// `body`, `against`, `face` and `normal` say otherwise ([`bodies`]).
    pub ends: ContactEnds,
}

/// The sense a rotor turns when driven forward.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sense {
    /// Counter-clockwise: `s = +1`.
    Ccw,
    /// Clockwise: `s = -1`.
    Cw,
}

impl Sense {
    /// `+1` for ccw, `-1` for cw.
    pub fn sign(self) -> f64 {
        match self {
            Sense::Ccw => 1.0,
            Sense::Cw => -1.0,
        }
    }
}

/// The senses a rotor may turn, as written in the file.
impl Enumerated for Sense {
    const ALL: &'static [Sense] = &[Sense::Ccw, Sense::Cw];

    fn name(self) -> &'static str {
        match self {
            Sense::Ccw => "ccw",
            Sense::Cw => "cw",
        }
    }
}

/// A brushed DC motor.
#[derive(Clone, Debug, PartialEq)]
pub struct MotorParams {
    /// Winding resistance, ohm.
    pub resistance: f64,
    /// Winding inductance, H.
    pub inductance: f64,
    /// Torque constant, N m / A (= back-EMF constant, V s / rad).
    pub torque_constant: f64,
    /// Coulomb friction torque, N m.
    pub coulomb_friction: f64,
    /// Viscous friction, N m s.
    pub viscous_friction: f64,
    /// The driver's current limit, A (the winding current stays within +-this).
    pub current_limit: f64,
}

/// An unbalance rotor on the platform.
#[derive(Clone, Debug, PartialEq)]
pub struct Rotor {
    /// Name.
    pub name: String,
    /// World position of the axis at t = 0, m (fixed on the platform).
    pub axis: [f64; 2],
    /// Eccentric mass, kg (0 allowed).
    pub eccentric_mass: f64,
    /// Distance of the eccentric mass from the axis, m.
    pub eccentricity: f64,
    /// Inertia about the axis without the eccentric mass, kg m^2.
    pub inertia: f64,
    /// The sense it turns when driven forward.
    pub sense: Sense,
    /// Eccentric angle phi in the platform frame at t = 0, rad.
    pub angle: f64,
    /// Eccentric angle at which the index pulse fires, rad.
    pub index_angle: f64,
    /// Its motor (the machine's `[motor]` unless the rotor has its own).
    pub motor: MotorParams,
    /// The body that carries it: `platform` unless `body` says otherwise.
    pub body: String,
}

/// The motor drivers: the H-bridges as wired (`shared::drive`).
#[derive(Clone, Debug, PartialEq)]
pub struct Drive {
    /// Supply voltage, V; in slow decay a duty d in [-1, 1] puts a mean d x supply
    /// on the winding.
    pub supply_voltage: f64,
    /// The H-bridges as wired (`shared::drive`): `decay` (`"slow"`, the default:
    /// drive, then brake; or `"fast"`: drive, then coast) and `pwm_hz` (default
    /// 20000).
    pub bridge: BridgeConfig,
}

/// The range of `[drive] pwm_hz`, Hz: a DRV8871-class bridge switches up to 200 kHz;
/// below 1 kHz the PWM period would be as long as a control tick.
pub const PWM_HZ_RANGE: [u32; 2] = [1_000, 200_000];

/// The sensors.
#[derive(Clone, Debug, PartialEq)]
pub struct Sensors {
    /// Counter increments per revolution (after x4 decoding).
    pub encoder_counts: u32,
    /// Standard deviation of the current measurement noise, A.
    pub current_noise: f64,
    /// Standard deviation of the encoder edge timing jitter, s.
    pub encoder_jitter: f64,
}

/// The controller's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct ControllerSettings {
    /// Control tick, Hz (the firmware uses the same value).
    pub rate_hz: f64,
    /// Default rotor speed for `--command`, rpm.
    pub speed_rpm: f64,
    /// The tuning table file, resolved relative to the machine file.
    pub tuning_table: Option<PathBuf>,
}

/// The simulation's settings.
#[derive(Clone, Debug, PartialEq)]
pub struct Simulation {
    /// End time, s.
    pub t_end: f64,
    /// Time between rows of `--out`, s.
    pub output_step: f64,
    /// Seed of every noise source.
    pub seed: u64,
    /// The integrator's relative tolerance (docs/plant-model.md, "Integration").
    pub rtol: f64,
    /// How far a free body (the platform, a body not hinged to anything) may turn
    /// from its angle at t = 0 before the run says it tipped over, rad.
    pub max_tilt: f64,
    /// The progress guard: the most integrator steps and events the plant may
    /// take within one millisecond of simulated time before it ends the run
    /// (docs/plant-model.md, "The progress guard").
    pub progress_budget: u64,
}

/// A checked machine file.
#[derive(Clone, Debug, PartialEq)]
pub struct Machine {
    /// The fundament and gravity.
    pub fundament: Fundament,
    /// The platform.
    pub platform: Platform,
    /// The further bodies, `[[bodies]]` ([`bodies`]).
    pub bodies: Vec<Body>,
    /// The joints between bodies, `[[joints]]`.
    pub joints: Vec<Joint>,
    /// The contact points, K1, K2, ...
    pub contacts: Vec<MachineContact>,
    /// Rotor 1, then rotor 2 if the machine has two: one or two rotors, never
    /// another count ([`Rotors`]).
    pub rotors: Rotors,
    /// The motor driver.
    pub drive: Drive,
    /// The sensors.
    pub sensors: Sensors,
    /// The controller's settings.
    pub controller: ControllerSettings,
    /// The impact law.
    pub law: ImpactLaw,
    /// The simulation's settings.
    pub simulation: Simulation,
}

impl Sense {
    /// `ccw` or `cw`, as written in the file.
    pub fn name(self) -> &'static str {
        match self {
            Sense::Ccw => "ccw",
            Sense::Cw => "cw",
        }
    }
}

impl Machine {
    /// Reads and checks the machine file at `path`, with the `--set KEY=VALUE`
    /// overrides `sets` applied before checking (the stages of the module doc).
    /// Every problem is returned at once: those of the overrides first, then those of
    /// the file. A relative `[controller].tuning_table` is resolved against the
    /// file's directory.
    pub fn load(path: &Path, sets: &[String]) -> Result<Machine, Vec<Problem>> {
        Machine::load_overridden(path, &Override::command_line(sets))
    }

    /// [`Machine::load`] with overrides given anywhere (a scenario's `set`),
    /// each refused one said where it was given.
    pub fn load_overridden(path: &Path, overrides: &[Override]) -> Result<Machine, Vec<Problem>> {
        let text = input::read_text(path).map_err(|p| vec![p])?;
        let dir = path.parent().unwrap_or(Path::new(""));
        Machine::from_text_overridden(&path.display().to_string(), &text, dir, overrides)
    }

    /// Checks the text of a machine file named `file` (for messages), with
    /// `tuning_table` resolved against `dir`, as [`Machine::load`] does.
    pub fn from_text(
        file: &str,
        text: &str,
        dir: &Path,
        sets: &[String],
    ) -> Result<Machine, Vec<Problem>> {
        Machine::from_text_overridden(file, text, dir, &Override::command_line(sets))
    }

    /// [`Machine::from_text`] with overrides given anywhere (a scenario's `set`),
    /// each refused one said where it was given.
    pub fn from_text_overridden(
        file: &str,
        text: &str,
        dir: &Path,
        overrides: &[Override],
    ) -> Result<Machine, Vec<Problem>> {
        // Stage 1: TOML. Overrides that are not `KEY=VALUE` are reported even when
        // the file does not parse.
        let mut table = match input::parse(file, text) {
            Ok(t) => t,
            Err(p) => {
                let mut problems = set::not_key_value(overrides);
                problems.push(p);
                return Err(problems);
            }
        };
        // Another kind of file (an impact case, a scenario): said in one line.
        if let Some(p) = kind::wrong_kind(file, &table, kind::FileKind::Machine) {
            return Err(vec![p]);
        }
        // Stage 2: the overrides.
        let (applied, set_problems) = set::apply(&mut table, overrides);
        // Stages 3 to 6.
        let problems = Problems::new(file);
        let machine = check(&table, &problems, dir);
        // Stage 6b: `[uncertainty]`, each range's ends against the whole machine.
        if machine.is_some() && problems.is_empty() {
            uncertainty::check(&table, &problems, dir);
        }
        match problems.into_result(machine) {
            Ok(m) if set_problems.is_empty() => Ok(m),
            Ok(_) => Err(set_problems),
            Err(file_problems) => {
                // Stage 7: say which value an override wrote.
                let mut all = set_problems;
                all.extend(file_problems.into_iter().map(|p| blame_set(p, &applied)));
                Err(all)
            }
        }
    }

    /// Every number of the machine file `file` (its `text` with the `--set`s
    /// `sets`, which must pass every check, as [`Machine::from_text`]) as the
    /// reader read it: its key path, value (or default) and the range it was
    /// checked against. The valid range of a key, for callers that vary it
    /// (`host-sim calibrate`), from the one place that declares it.
    pub fn numbers(
        file: &str,
        text: &str,
        dir: &Path,
        sets: &[String],
    ) -> Result<Vec<input::NumberRead>, Vec<Problem>> {
        Machine::from_text(file, text, dir, sets)?;
        let mut table = input::parse(file, text).map_err(|p| vec![p])?;
        let _ = set::apply(&mut table, &Override::command_line(sets));
        let problems = Problems::new(file);
        let _ = check(&table, &problems, dir);
        Ok(problems.numbers())
    }

    /// What the machine asks beyond a single platform on the fundament (further
    /// bodies, joints, contacts between bodies, rotors elsewhere), one item a
    /// line: what the firmware's build refuses (its controller constants are a
    /// single platform's); empty for a single platform.
    pub fn beyond_the_platform(&self) -> Vec<String> {
        let ends: Vec<ContactEnds> = self.contacts.iter().map(|c| c.ends.clone()).collect();
        let rotor_bodies: Vec<String> = self.rotors.iter().map(|r| r.body.clone()).collect();
        bodies::beyond_the_platform(&self.bodies, &self.joints, &ends, &rotor_bodies)
    }

    /// Platform mass plus the eccentric masses, kg: the mass that moves.
    pub fn total_mass(&self) -> f64 {
        self.physics().total_mass_kg()
    }

    /// The values the controller's constants depend on, key by key: `[controller]
    /// rate_hz`, `[sensors] encoder_counts`, `[drive]` (supply, decay, PWM),
    /// `[platform] mass`, `[fundament] gravity`, and each rotor's eccentric mass,
    /// eccentricity and inertia with its motor's resistance, torque constant, Coulomb
    /// friction and current limit; one rotor or two (with one, rotor 1's values
    /// stand in rotor 2's place, which [`MachinePhysics`] then ignores).
    pub fn physics(&self) -> MachinePhysics {
        let rotor = |r: &Rotor| RotorPhysics {
            resistance_ohm: r.motor.resistance,
            torque_constant: r.motor.torque_constant,
            inertia_kg_m2: r.inertia,
            eccentric_mass_kg: r.eccentric_mass,
            eccentricity_m: r.eccentricity,
            coulomb_friction_nm: r.motor.coulomb_friction,
            current_limit_a: r.motor.current_limit,
        };
        MachinePhysics {
            rate_hz: self.controller.rate_hz,
            encoder_counts: self.sensors.encoder_counts,
            supply_voltage_v: self.drive.supply_voltage,
            platform_mass_kg: self.platform.mass,
            gravity_m_s2: self.fundament.gravity,
            rotor_count: self.rotors.count(),
            rotors: [
                rotor(self.rotors.rotor1()),
                rotor(self.rotors.rotor2().unwrap_or(self.rotors.rotor1())),
            ],
            bridge: self.drive.bridge,
        }
    }
}

/// The controller's constants for a machine: its [`Machine::physics`] through
/// `shared`'s formulas ([`MachineConstants::from_physics`]), as the firmware's build
/// script compiles them in.
pub fn machine_constants(m: &Machine) -> MachineConstants {
    MachineConstants::from_physics(&m.physics())
}

/// Reads every table of an array of tables with `read` (an element that is not a
/// table was reported and reads as nothing).
fn read_all<T>(list: Vec<Option<Section>>, read: fn(usize, &Section) -> Named<T>) -> Vec<Named<T>> {
    list.iter()
        .enumerate()
        .map(|(i, s)| match s {
            Some(s) => read(i, s),
            None => refused_element(),
        })
        .collect()
}

/// Appends `(from --set KEY=VALUE)` to a problem in a key (or an element of it) that
/// the last override of that key gave, from the command line or a scenario's `set`
/// alike (docs/scenarios.md shows the scenario's case).
fn blame_set(mut problem: Problem, applied: &[set::Applied]) -> Problem {
    if let Location::Key(key) = &problem.location {
        let from = applied.iter().rev().find(|a| {
            key == &a.key_path
                || key.starts_with(&format!("{}[", a.key_path))
                || key.starts_with(&format!("{}.", a.key_path))
        });
        if let Some(a) = from {
            problem.message = format!("{} (from --set {})", problem.message, a.arg);
        }
    }
    problem
}

/// Default `[fundament].point`: the floor passes through the origin.
pub const DEFAULT_FUNDAMENT_POINT: [f64; 2] = [0.0, 0.0];
/// Default `[fundament].normal`: a horizontal floor, the line `y = 0`
/// (docs/machine-file.md, "Keys").
pub const DEFAULT_FUNDAMENT_NORMAL: [f64; 2] = [0.0, 1.0];
/// Default `[fundament].gravity`, m/s^2: standard gravity, 9.80665 rounded as
/// docs/machine-file.md gives it, pointing down.
pub const DEFAULT_GRAVITY: [f64; 2] = [0.0, -9.81];
/// Default `[sensors].encoder_counts`: a 1024-line encoder decoded x4, a common
/// choice for small motors.
pub const DEFAULT_ENCODER_COUNTS: i64 = 4096;
/// Default `[controller].rate_hz`: 1 kHz, the usual speed-loop rate of small motor
/// drives, well above the rotors' mechanical bandwidth (tens of Hz).
pub const DEFAULT_RATE_HZ: f64 = 1000.0;
/// The highest `[controller].rate_hz`, Hz: 100 kHz leaves the firmware's 168 MHz core
/// 1680 cycles a tick, and each tick costs the simulator a lockstep.
pub const MAX_RATE_HZ: f64 = 100_000.0;
/// Default `[controller].speed_rpm`: the reference machine's working speed.
pub const DEFAULT_SPEED_RPM: f64 = 3000.0;
/// Default `[simulation].t_end`, s: long enough for the rotors to reach speed
/// (time constant about 0.05 s) and the travel to settle.
pub const DEFAULT_T_END: f64 = 10.0;
/// Default `[simulation].output_step`, s: 1 ms, one row per control tick at the
/// default rate, about 20 rows per revolution at 3000 rpm.
pub const DEFAULT_OUTPUT_STEP: f64 = 1.0e-3;
/// Default `[simulation].seed`.
pub const DEFAULT_SEED: i64 = 1;
/// Default `[simulation].rtol`: the integrator's relative tolerance.
pub const DEFAULT_RTOL: f64 = 1.0e-8;
/// Default `[simulation].max_tilt`, rad: 60 degrees. A gait rocks a platform by
/// hundredths of a degree; the reference machine's centre of mass passes over a
/// foot at `atan(0.08 m / 0.03 m)` = 69 degrees, so a platform turned by 60 has
/// tipped over or is about to.
pub const DEFAULT_MAX_TILT: f64 = std::f64::consts::FRAC_PI_3;
/// Default `[simulation].progress_budget`: integrator steps (accepted or
/// rejected) and events within one millisecond of simulated time. The most any
/// run took (benchmarks/plant.md, "The progress guard"): 902 for the Fig. 8
/// machine at its defaults, 8 606 for the reference machine with fast decay, PWM
/// and control ticks at 50 kHz and rtol 1e-11; 100 000 is 11 times that. A run
/// that stops advancing (steps of 1e-10 s) spends it in about 0.2 s of CPU.
pub const DEFAULT_PROGRESS_BUDGET: u64 = 100_000;
/// The range of `[simulation].rtol`: below 1e-12 the positions' absolute
/// tolerance (1e-3 rtol m) nears the rounding of f64 coordinates; up to 1e-3 the
/// reference machine's tuning sweep gives the same table and every grid point's
/// travel speed within 1e-4 mm/s (median) of 1e-8's, except where the gait is
/// chaotic and differs as much between 1e-11 and 1e-8 (benchmarks/plant.md,
/// "The integrator's tolerance up to 1e-3"); above it, not measured.
pub const RTOL_RANGE: (f64, f64) = (1.0e-12, 1.0e-3);
/// How far below the fundament a contact point may lie at `t = 0`, m: far above the
/// rounding of positions a generator computes on a tilted fundament (1e-17 m at
/// these sizes), far below any real mistake.
pub const FUNDAMENT_GAP_TOLERANCE: f64 = 1.0e-12;

/// A key read on its own: absent, present but refused (reported), or a value.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Read<T> {
    Absent,
    Refused,
    Value(T),
}

/// The motor's keys with their limits and units, in [`MotorParams`] order.
const MOTOR: [(&str, Limit, &str); 6] = [
    ("resistance", Limit::Positive, "ohm"),
    ("inductance", Limit::Positive, "H"),
    ("torque_constant", Limit::Positive, "N m / A"),
    ("coulomb_friction", Limit::NonNegative, "N m"),
    ("viscous_friction", Limit::NonNegative, "N m s"),
    ("current_limit", Limit::Positive, "A"),
];

/// A motor table's keys as read (`[motor]` or a rotor's own `[rotors.motor]`).
type MotorKeys = [Read<f64>; 6];

/// A rotor's keys as read, its motor not yet merged.
struct RotorKeys {
    /// Everything but the motor (whose value is a placeholder here).
    rotor: Option<Rotor>,
    /// The rotor's own `[rotors.motor]` keys (all absent without one); `None` when
    /// `motor` is there but not a table (reported).
    own_motor: Option<MotorKeys>,
}

/// Stages 3 to 6; `None` when some problem was recorded.
pub(crate) fn check(table: &Table, problems: &Problems, dir: &Path) -> Option<Machine> {
    let root = Section::root(table, problems);
    // An omitted optional section reads as this empty table: every key takes its
    // default from the same `Need::Default` a present section uses.
    let empty = Table::new();

    // Stage 3: every key on its own, section by section as docs/machine-file.md lists
    // them ("Keys"), the bodies and joints ("Several bodies") after the rotors.
    let fundament = optional(&root, "fundament", &empty).and_then(|s| read_fundament(&s));
    let platform = root
        .section("platform", Need::Required)
        .and_then(|s| read_platform(&s));
    let contacts = root
        .sections("contacts")
        .map(|list| read_all(list, read_contact));
    let rotors = root
        .sections("rotors")
        .map(|list| read_all(list, read_rotor));
    let further = root
        .sections("bodies")
        .map(|list| read_all(list, bodies::read_body));
    let joints = root
        .sections("joints")
        .map(|list| read_all(list, bodies::read_joint));
    let has_motor = root.has("motor");
    let motor = match root.section("motor", Need::Optional) {
        Some(s) => Some(read_motor(&s)),
        None if has_motor => None, // not a table, reported
        None => Some([Read::Absent; 6]),
    };
    let drive = root.section("drive", Need::Required).and_then(|s| {
        let supply_voltage = s.number("supply_voltage", Need::Required, Limit::Positive);
        let decay = s.one_of("decay", Need::Default(Decay::Slow));
        let pwm_hz = s.integer(
            "pwm_hz",
            Need::Default(i64::from(BridgeConfig::DEFAULT.pwm_hz)),
            Limit::Between(f64::from(PWM_HZ_RANGE[0]), f64::from(PWM_HZ_RANGE[1])),
        );
        s.finish();
        Some(Drive {
            supply_voltage: supply_voltage?,
            bridge: BridgeConfig {
                decay: decay?,
                pwm_hz: u32::try_from(pwm_hz?).ok()?,
            },
        })
    });
    let sensors = optional(&root, "sensors", &empty).and_then(|s| read_sensors(&s));
    let controller = optional(&root, "controller", &empty).and_then(|s| read_controller(&s, dir));
    let law = optional(&root, "impact", &empty).and_then(|s| {
        let law = s.one_of("law", Need::Default(ImpactLaw::Poisson));
        s.finish();
        law
    });
    let simulation = optional(&root, "simulation", &empty).and_then(|s| read_simulation(&s));
    // `[uncertainty]` is checked against the whole machine once it passed
    // (`uncertainty::check`, from `Machine::from_text`).
    root.has(uncertainty::SECTION);
    root.finish();

    // Stage 4: each rotor's motor, `[motor]` with the rotor's own keys over it.
    let rotors = rotors.map(|list| merge_motors(&root, list, motor.as_ref(), has_motor));

    // Stage 5: contacts and rotors as a whole.
    let contacts = contacts.and_then(|list| check_contacts(&root, list));
    let rotors = rotors.and_then(|list| check_rotors(&root, list));

    // Stage 6: the geometry at t = 0 against the fundament; the bridges against
    // the control rate; the bodies, joints and contact ends together. Each check
    // runs whatever else is wrong, so that every problem is reported at once.
    let fundament = fundament?;
    let contacts = contacts?;
    check_gaps(&root, &fundament, &contacts);
    if let (Some(d), Some(c)) = (&drive, &controller) {
        check_update_rate(&root, d.bridge, c.rate_hz);
    }
    let (further, joints) = (further?, joints?);
    let rotors = rotors?;
    let rotor_bodies: Vec<String> = rotors.iter().map(|r| r.body.clone()).collect();
    let bodies_ok = bodies::check(&root, &further, &joints, &contacts, &rotor_bodies)
        && bodies::check_size_and_motion(&root, platform.as_ref(), &further, &joints, rotors.len());
    let rigid = |name: &str| match name {
        bodies::PLATFORM => platform.as_ref(),
        _ => further
            .iter()
            .filter_map(|b| b.value.as_ref())
            .find(|b| b.name == name)
            .map(|b| &b.rigid),
    };
    let bodies_ok = joint_limits::check(&root, &joints, rigid) && bodies_ok;

    let further = further
        .into_iter()
        .map(|b| b.value)
        .collect::<Option<Vec<_>>>()?;
    let joints = joints
        .into_iter()
        .map(|j| j.value)
        .collect::<Option<Vec<_>>>()?;
    if !bodies_ok {
        return None;
    }
    let machine = Machine {
        fundament,
        platform: platform?,
        bodies: further,
        joints,
        contacts,
        rotors,
        drive: drive?,
        sensors: sensors?,
        controller: controller?,
        law: law?,
        simulation: simulation?,
    };
    problems.is_empty().then_some(machine)
}

/// The timer must take a new duty at least once per control tick: its update
/// rate, `pwm_hz / periods_per_update` (`shared::drive`), at least the control
/// rate (the firmware also samples the currents at each update).
fn check_update_rate(root: &Section, bridge: BridgeConfig, rate_hz: f64) {
    let updates_hz = f64::from(bridge.pwm_hz) / f64::from(bridge.periods_per_update());
    if updates_hz < rate_hz {
        root.problem(
            "drive.pwm_hz",
            format!(
                "{} Hz gives {} duty updates a second, fewer than [controller] rate_hz = {} control ticks: \
                 must give at least one update per tick (pwm_hz >= rate_hz up to 50 kHz)",
                bridge.pwm_hz, updates_hz, rate_hz
            ),
        );
    }
}

/// An optional section: the table when present, the empty table when omitted,
/// `None` when present but not a table (reported).
fn optional<'a>(root: &Section<'a>, key: &'static str, empty: &'a Table) -> Option<Section<'a>> {
    match root.section(key, Need::Optional) {
        Some(s) => Some(s),
        None if root.has(key) => None,
        // Key paths of this stand-in are never shown: an empty table has no unknown
        // key, and every key read from it has a default.
        None => Some(Section::root(empty, root.problems())),
    }
}

/// An element of an array of tables that is not a table (reported).
fn refused_element<T>() -> Named<T> {
    Named {
        given: false,
        name: None,
        value: None,
    }
}

/// `[fundament]`: point, normal (non-zero, normalised here), gravity.
fn read_fundament(s: &Section) -> Option<Fundament> {
    let point = s.vec2("point", Need::Default(DEFAULT_FUNDAMENT_POINT), Limit::Any);
    let normal = s
        .vec2(
            "normal",
            Need::Default(DEFAULT_FUNDAMENT_NORMAL),
            Limit::Any,
        )
        .and_then(|n| {
            s.unit_vector(
                "normal",
                n,
                "the direction from the fundament towards the platform",
            )
        });
    let gravity = s.vec2("gravity", Need::Default(DEFAULT_GRAVITY), Limit::Any);
    s.finish();
    Some(Fundament {
        point: point?,
        normal: normal?,
        gravity: gravity?,
    })
}

/// `[platform]`: mass and inertia > 0, position, angle (default 0), velocity
/// (default [0, 0]), angular velocity (default 0).
pub(crate) fn read_platform(s: &Section) -> Option<Platform> {
    let mass = s.number("mass", Need::Required, Limit::Positive);
    let inertia = s.number("inertia", Need::Required, Limit::Positive);
    let position = s.vec2("position", Need::Required, Limit::Any);
    let angle = s.number("angle", Need::Default(0.0), Limit::Any);
    let velocity = s.vec2("velocity", Need::Default([0.0, 0.0]), Limit::Any);
    let angular_velocity = s.number("angular_velocity", Need::Default(0.0), Limit::Any);
    s.finish();
    Some(Platform {
        mass: mass?,
        inertia: inertia?,
        position: position?,
        angle: angle?,
        velocity: velocity?,
        angular_velocity: angular_velocity?,
    })
}

/// One `[[contacts]]` table: name (default `K{i+1}`), point, restitution in
/// [0, 1], friction >= 0, weight > 0 (default 1).
fn read_contact(index: usize, s: &Section) -> Named<MachineContact> {
    let (given, name) = read_name(s, index, "K");
    let point = s.vec2("point", Need::Required, Limit::Any);
    let restitution = s.number("restitution", Need::Required, Limit::Between(0.0, 1.0));
    let friction = s.number("friction", Need::Required, Limit::NonNegative);
    let weight = s.number("weight", Need::Default(1.0), Limit::Positive);
    let ends = bodies::read_ends(s);
    s.finish();
    let value = (|| {
        let (point, mut ends) = (point?, ends?);
        // Against a body, the face passes through the point unless given.
        if ends.against != bodies::FUNDAMENT {
            ends.face.get_or_insert(point);
        }
        Some(MachineContact {
            name: name.clone()?,
            point,
            restitution: restitution?,
            friction: friction?,
            weight: weight?,
            ends,
        })
    })();
    Named { given, name, value }
}

/// One `[[rotors]]` table: name (default `R{i+1}`), axis, eccentric mass >= 0,
/// eccentricity >= 0 (> 0 with an eccentric mass), inertia > 0, sense, angle and
/// index angle (default 0), and its own `[rotors.motor]` keys if any.
fn read_rotor(index: usize, s: &Section) -> Named<RotorKeys> {
    let (given, name) = read_name(s, index, "R");
    let axis = s.vec2("axis", Need::Required, Limit::Any);
    let eccentric_mass = s.number("eccentric_mass", Need::Required, Limit::NonNegative);
    let eccentricity = s.number("eccentricity", Need::Required, Limit::NonNegative);
    let inertia = s.number("inertia", Need::Required, Limit::Positive);
    let sense = s.one_of("sense", Need::Required);
    let angle = s.number("angle", Need::Default(0.0), Limit::Any);
    let index_angle = s.number("index_angle", Need::Default(0.0), Limit::Any);
    let body = s.string("body", Need::Default(bodies::PLATFORM.to_string()));
    let own_motor = match s.section("motor", Need::Optional) {
        Some(m) => Some(read_motor(&m)),
        None if s.has("motor") => None, // not a table, reported
        None => Some([Read::Absent; 6]),
    };
    s.finish();
    // An eccentric mass needs an arm: m > 0 at e = 0 is a mistake, not a plain rotor.
    if let (Some(m), Some(e)) = (eccentric_mass, eccentricity) {
        if m > 0.0 && e == 0.0 {
            s.problem(
                "eccentricity",
                format!(
                    "must be > 0 when eccentric_mass > 0 (got 0 with eccentric_mass {}); for a plain rotor set eccentric_mass = 0",
                    number(m)
                ),
            );
        }
    }
    let eccentric_ok =
        matches!((eccentric_mass, eccentricity), (Some(m), Some(e)) if !(m > 0.0 && e == 0.0));
    let rotor = (|| {
        Some(Rotor {
            name: name.clone()?,
            axis: axis?,
            eccentric_mass: eccentric_mass.filter(|_| eccentric_ok)?,
            eccentricity: eccentricity?,
            inertia: inertia?,
            sense: sense?,
            angle: angle?,
            index_angle: index_angle?,
            // A placeholder until stage 4 merges the motor.
            motor: MotorParams {
                resistance: 0.0,
                inductance: 0.0,
                torque_constant: 0.0,
                coulomb_friction: 0.0,
                viscous_friction: 0.0,
                current_limit: 0.0,
            },
            body: body?,
        })
    })();
    Named {
        given,
        name,
        value: Some(RotorKeys { rotor, own_motor }),
    }
}

/// A motor table: every key optional here (stage 4 says what is missing), each
/// checked against its limit.
fn read_motor(s: &Section) -> MotorKeys {
    let mut keys = [Read::Absent; 6];
    for (slot, (key, limit, _)) in keys.iter_mut().zip(MOTOR) {
        if s.has(key) {
            *slot = match s.number(key, Need::Required, limit) {
                Some(x) => Read::Value(x),
                None => Read::Refused,
            };
        }
    }
    s.finish();
    keys
}

/// `[sensors]`: encoder counts (an integer >= 4, a multiple of 4), current noise and
/// encoder jitter >= 0.
fn read_sensors(s: &Section) -> Option<Sensors> {
    let counts = s.integer(
        "encoder_counts",
        Need::Default(DEFAULT_ENCODER_COUNTS),
        Limit::Between(4.0, f64::from(u32::MAX)),
    );
    // x4 decoding counts every edge of both channels: 4 increments per line.
    let counts = counts.and_then(|c| {
        if c % 4 == 0 {
            u32::try_from(c).ok()
        } else {
            s.problem(
                "encoder_counts",
                format!(
                    "must be a multiple of 4: increments per revolution after x4 decoding, 4 x the encoder's lines (got {c})"
                ),
            );
            None
        }
    });
    let current_noise = s.number("current_noise", Need::Default(0.0), Limit::NonNegative);
    let encoder_jitter = s.number("encoder_jitter", Need::Default(0.0), Limit::NonNegative);
    s.finish();
    Some(Sensors {
        encoder_counts: counts?,
        current_noise: current_noise?,
        encoder_jitter: encoder_jitter?,
    })
}

/// `[controller]`: rate in (0, [`MAX_RATE_HZ`]] Hz, speed > 0 rpm, tuning table path
/// (optional, non-empty, resolved against `dir`; not read here).
fn read_controller(s: &Section, dir: &Path) -> Option<ControllerSettings> {
    let rate_hz = s
        .number("rate_hz", Need::Default(DEFAULT_RATE_HZ), Limit::Positive)
        .and_then(|r| {
            if r <= MAX_RATE_HZ {
                Some(r)
            } else {
                s.problem(
                    "rate_hz",
                    format!(
                        "must be in (0, {}] Hz, the control tick the firmware can run (got {})",
                        number(MAX_RATE_HZ),
                        number(r)
                    ),
                );
                None
            }
        });
    let speed_rpm = s.number(
        "speed_rpm",
        Need::Default(DEFAULT_SPEED_RPM),
        Limit::Positive,
    );
    let has_table = s.has("tuning_table");
    let tuning_table = match s.string("tuning_table", Need::Optional) {
        Some(t) if t.is_empty() => {
            s.problem(
                "tuning_table",
                "must not be empty: a file name relative to the machine file (or omit the key)",
            );
            None
        }
        Some(t) => Some(Some(dir.join(t))),
        None if has_table => None, // not a string, reported
        None => Some(None),
    };
    s.finish();
    Some(ControllerSettings {
        rate_hz: rate_hz?,
        speed_rpm: speed_rpm?,
        tuning_table: tuning_table?,
    })
}

/// `[simulation]`: t_end > 0, output step > 0, seed a non-negative integer, rtol
/// within [`RTOL_RANGE`], max_tilt > 0, progress_budget a positive integer.
fn read_simulation(s: &Section) -> Option<Simulation> {
    let t_end = s.number("t_end", Need::Default(DEFAULT_T_END), Limit::Positive);
    let output_step = s.number(
        "output_step",
        Need::Default(DEFAULT_OUTPUT_STEP),
        Limit::Positive,
    );
    let seed = s.integer("seed", Need::Default(DEFAULT_SEED), Limit::NonNegative);
    let rtol = s.number(
        "rtol",
        Need::Default(DEFAULT_RTOL),
        Limit::Between(RTOL_RANGE.0, RTOL_RANGE.1),
    );
    let max_tilt = s.number("max_tilt", Need::Default(DEFAULT_MAX_TILT), Limit::Positive);
    let progress_budget = s.integer(
        "progress_budget",
        // Far below i64::MAX: the cast is exact.
        Need::Default(DEFAULT_PROGRESS_BUDGET as i64),
        Limit::Positive,
    );
    s.finish();
    Some(Simulation {
        t_end: t_end?,
        output_step: output_step?,
        // An i64 >= 0 always fits a u64.
        seed: u64::try_from(seed?).ok()?,
        rtol: rtol?,
        max_tilt: max_tilt?,
        // An i64 > 0 always fits a u64.
        progress_budget: u64::try_from(progress_budget?).ok()?,
    })
}

/// Stage 4: each rotor's motor is `[motor]` with every key the rotor's own
/// `[rotors.motor]` gives in its place. A key neither gives is reported once for the
/// machine: at `motor` when the file has no `[motor]`, else at `motor.KEY`.
fn merge_motors(
    root: &Section,
    list: Vec<Named<RotorKeys>>,
    machine: Option<&MotorKeys>,
    has_motor: bool,
) -> Vec<Named<Rotor>> {
    let mut missing = [false; 6];
    let rotors = list
        .into_iter()
        .map(|named| {
            let value = named.value.and_then(|keys| {
                let own = keys.own_motor?;
                let base = machine?;
                let mut values = [0.0; 6];
                let mut ok = true;
                for k in 0..6 {
                    let read = match own[k] {
                        Read::Absent => base[k],
                        other => other,
                    };
                    match read {
                        Read::Value(x) => values[k] = x,
                        Read::Refused => ok = false,
                        Read::Absent => {
                            missing[k] = true;
                            ok = false;
                        }
                    }
                }
                let mut rotor = keys.rotor?;
                rotor.motor = MotorParams {
                    resistance: values[0],
                    inductance: values[1],
                    torque_constant: values[2],
                    coulomb_friction: values[3],
                    viscous_friction: values[4],
                    current_limit: values[5],
                };
                ok.then_some(rotor)
            });
            Named {
                given: named.given,
                name: named.name,
                value,
            }
        })
        .collect();
    let missing_keys: Vec<&str> = MOTOR
        .iter()
        .zip(missing)
        .filter(|(_, m)| *m)
        .map(|((key, _, _), _)| *key)
        .collect();
    if !has_motor && !missing_keys.is_empty() {
        root.problem(
            "motor",
            format!(
                "missing; required: a table [motor], the rotors' brushed DC motor (a rotor's own [rotors.motor] may replace any of its keys; missing for some rotor: {})",
                missing_keys.join(", ")
            ),
        );
    } else {
        for ((key, limit, unit), _) in MOTOR.iter().zip(missing).filter(|(_, m)| *m) {
            let range = match limit {
                Limit::Positive => "> 0",
                _ => ">= 0",
            };
            root.problem(
                &format!("motor.{key}"),
                format!(
                    "missing; required: a number {range} ({unit}), here or in the [rotors.motor] of every rotor"
                ),
            );
        }
    }
    rotors
}

/// 1 to [`MAX_CONTACTS`](shared::impact::MAX_CONTACTS) contacts (the impact solver's limit), names unique.
fn check_contacts(root: &Section, list: Vec<Named<MachineContact>>) -> Option<Vec<MachineContact>> {
    input::check_contact_list(root, list, "(the impact solver's limit)")
        .map(|named| named.into_iter().map(|(_, c)| c).collect())
}

/// One or two rotors ([`Rotors::COUNTS`]), names unique.
fn check_rotors(root: &Section, list: Vec<Named<Rotor>>) -> Option<Rotors> {
    let ok = check_names(root, "rotors", "rotor", &list);
    if RotorCount::from_count(list.len()).is_none() {
        root.problem(
            "rotors",
            format!(
                "one or two [[rotors]] tables are required (got {}): rotor 1, then rotor 2 if the machine has two",
                list.len()
            ),
        );
        return None;
    }
    let rotors = list
        .into_iter()
        .map(|r| r.value)
        .collect::<Option<Vec<_>>>()?;
    Rotors::new(rotors).ok().filter(|_| ok)
}

/// Stage 6: every contact on or above the fundament at `t = 0`:
/// `gap = n . (K - P) >= 0` with `P` the fundament's point and `n` its unit normal
/// (within [`FUNDAMENT_GAP_TOLERANCE`]).
fn check_gaps(root: &Section, fundament: &Fundament, contacts: &[MachineContact]) {
    let (p, n) = (fundament.point, fundament.normal);
    for (i, c) in contacts.iter().enumerate() {
        if c.ends.against != bodies::FUNDAMENT {
            continue;
        }
        let gap = n[0] * (c.point[0] - p[0]) + n[1] * (c.point[1] - p[1]);
        if gap < -FUNDAMENT_GAP_TOLERANCE {
            root.problem(
                &format!("contacts[{i}].point"),
                format!(
                    "contact {} is below the fundament at t = 0: gap n . (K - P) = {} m (K = {}, fundament point P = {}, normal n = {}); it must be >= 0, on or above the fundament",
                    c.name,
                    number(gap),
                    vector(c.point),
                    vector(p),
                    vector(n)
                ),
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::set::{Node, SCHEMA};

    const REFERENCE: &str = include_str!("../../../examples/vibro-driver.toml");

    /// A table of the schema: how to reach it in the TOML (keys, and `0` for the
    /// first element of an array), the reader's key path, and its keys.
    fn schema_tables() -> Vec<(Vec<&'static str>, String, Vec<&'static str>)> {
        fn walk(
            steps: Vec<&'static str>,
            path: String,
            keys: &'static [(&'static str, Node)],
            out: &mut Vec<(Vec<&'static str>, String, Vec<&'static str>)>,
        ) {
            out.push((
                steps.clone(),
                path.clone(),
                keys.iter().map(|k| k.0).collect(),
            ));
            let join = |p: &str, k: &str| {
                if p.is_empty() {
                    k.to_string()
                } else {
                    format!("{p}.{k}")
                }
            };
            for (key, node) in keys {
                let mut next = steps.clone();
                next.push(key);
                match node {
                    Node::Value => {}
                    Node::Table(inner) => walk(next, join(&path, key), inner, out),
                    Node::Array { keys: inner, .. } => {
                        next.push("0");
                        walk(next, format!("{}[0]", join(&path, key)), inner, out);
                    }
                }
            }
        }
        let mut out = Vec::new();
        walk(Vec::new(), String::new(), SCHEMA, &mut out);
        out
    }

    /// The table at `steps` (an array stands for its first element), created where
    /// absent.
    fn table_at<'t>(mut t: &'t mut Table, steps: &[&str]) -> &'t mut Table {
        for step in steps {
            let v = t
                .entry(step.to_string())
                .or_insert_with(|| toml::Value::Table(Table::new()));
            t = match v {
                toml::Value::Table(inner) => inner,
                toml::Value::Array(items) => match &mut items[0] {
                    toml::Value::Table(inner) => inner,
                    _ => unreachable!("the reference's arrays hold tables"),
                },
                _ => unreachable!("the reference's sections are tables"),
            };
        }
        t
    }

    #[test]
    fn the_reader_reads_exactly_the_schema_keys() {
        // An unknown key in every table of the schema: the reader's "allowed here"
        // list, the keys it read, must be the schema's (which --set uses).
        // The reference machine with one further body on a joint, so that every
        // array of the schema has a table.
        let text = format!(
            "{REFERENCE}\n[[bodies]]\nname = \"B\"\nmass = 1.0\ninertia = 0.01\nposition = [0.0, 0.5]\n\n[[joints]]\nkind = \"revolute\"\nbodies = [\"platform\", \"B\"]\npoint = [0.0, 0.5]\n"
        );
        for (steps, path, keys) in schema_tables() {
            let mut table: Table = toml::from_str(&text).unwrap();
            let steps: Vec<&str> = steps.into_iter().filter(|s| *s != "0").collect();
            table_at(&mut table, &steps).insert("zzz".into(), toml::Value::Integer(1));
            let problems = Problems::new("m.toml");
            assert!(check(&table, &problems, Path::new("")).is_none());
            let key = if path.is_empty() {
                "zzz".to_string()
            } else {
                format!("{path}.zzz")
            };
            let list = problems.into_vec();
            let p = list
                .iter()
                .find(|p| p.location == Location::Key(key.clone()))
                .unwrap_or_else(|| panic!("no problem at {key}: {list:?}"));
            let allowed = p.message.split("allowed here: ").nth(1).unwrap();
            let mut read: Vec<&str> = allowed.trim_end_matches(')').split(", ").collect();
            if path.is_empty() {
                // `[uncertainty]` holds ranges of the other keys, not a key of its
                // own that --set could set.
                read.retain(|k| *k != uncertainty::SECTION);
            }
            let mut keys = keys;
            read.sort_unstable();
            keys.sort_unstable();
            assert_eq!(read, keys, "at {path:?}");
        }
    }

    #[test]
    fn the_reference_machine_reads() {
        let m = Machine::from_text("m.toml", REFERENCE, Path::new("examples"), &[]).unwrap();
        assert_eq!(m.rotors[0].sense, Sense::Ccw);
        assert_eq!(m.rotors[1].sense, Sense::Cw);
        assert_eq!(m.rotors[1].motor, m.rotors[0].motor);
        assert_eq!(
            m.controller.tuning_table,
            Some(Path::new("examples").join("vibro-driver.tuning.toml"))
        );
        assert!((m.total_mass() - 2.02).abs() < 1e-12);
    }

    #[test]
    fn numbers_come_with_the_limits_the_reader_checked() {
        let sets = ["contacts.K2.friction=0.5".to_string()];
        let numbers = Machine::numbers("m.toml", REFERENCE, Path::new(""), &sets).unwrap();
        let at = |k: &str| numbers.iter().find(|n| n.key_path == k).unwrap();
        assert_eq!(
            at("contacts[0].restitution").limit,
            Limit::Between(0.0, 1.0)
        );
        assert_eq!(at("contacts[0].restitution").value, 0.3);
        assert_eq!(at("contacts[1].friction").limit, Limit::NonNegative);
        assert_eq!(at("contacts[1].friction").value, 0.5);
        assert_eq!(at("motor.resistance").limit, Limit::Positive);
        assert_eq!(
            at("simulation.rtol").limit,
            Limit::Between(RTOL_RANGE.0, RTOL_RANGE.1)
        );
        // A default counts as read.
        assert_eq!(at("simulation.rtol").value, DEFAULT_RTOL);
        // A file the reader refuses gives its problems.
        let bad = ["contacts.K2.friction=-1".to_string()];
        assert!(Machine::numbers("m.toml", REFERENCE, Path::new(""), &bad).is_err());
    }

    /// A value, key or name of 3 MB is quoted cut in its message, with its
    /// length ([`input::cut`]): it gave a 3 MB line.
    #[test]
    fn long_values_are_cut_in_messages() {
        let long = "q".repeat(3_000_000);
        let cases = [
            // A choice, its value unknown.
            REFERENCE.replacen("sense = \"ccw\"", &format!("sense = \"{long}\""), 1),
            // An unknown key, and a name the file does not have.
            REFERENCE.replacen("[controller]\n", &format!("[controller]\n{long} = 1\n"), 1),
            REFERENCE.replacen(
                "name = \"K1\"",
                &format!("name = \"K1\"\nbody = \"{long}\""),
                1,
            ),
            // A range of [uncertainty] on a key that is not one.
            format!("{REFERENCE}\"{long}\" = [0.1, 0.2]\n"),
        ];
        for text in cases {
            let e = Machine::from_text("m.toml", &text, Path::new(""), &[]).unwrap_err();
            let rendered = input::render(&e);
            assert!(
                rendered.contains("... (3000000 bytes)"),
                "{}",
                input::cut(&rendered, 1000)
            );
            assert!(
                rendered.len() < 2000,
                "{} bytes: {}",
                rendered.len(),
                input::cut(&rendered, 3000)
            );
        }
        // A file name no file can have (a tuning_table of 3 MB): cut after the
        // longest path a file can be opened by.
        let e = tuning_file::read(Path::new(&long)).unwrap_err();
        let rendered = input::render(&e);
        assert!(
            rendered.len() < input::MAX_PATH_SHOWN + 200,
            "{} bytes",
            rendered.len()
        );
        assert!(
            rendered.contains("... (3000000 bytes): cannot read the file"),
            "{}",
            input::cut(&rendered, 200)
        );
    }

    #[test]
    fn problems_in_set_values_name_the_set() {
        let sets = ["contacts.K1.friction=-1".to_string()];
        let e = Machine::from_text("m.toml", REFERENCE, Path::new(""), &sets).unwrap_err();
        assert_eq!(
            input::render(&e),
            "error: m.toml: contacts[0].friction: must be >= 0 (got -1) (from --set contacts.K1.friction=-1)\n"
        );
    }
}
