//! What the motor identification measured, and where it stands: the values the
//! controller produces. Their bytes (in a message and in the flash record) are
//! `crate::codec`'s business, not the controller's.

/// A measured value and its standard error, in the value's unit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Estimate {
    /// The value.
    pub value: f32,
    /// Its standard error (one standard deviation), >= 0.
    pub std_error: f32,
}

/// Where one rotor's identification stopped short, if it did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Shortfall {
    /// The rotor turned over under the smallest standstill duty (its eccentric
    /// and friction hold less than the machine file says), or fewer than two
    /// standstill levels each way held: the resistance is not measured.
    NoStandstill,
    /// The rotor did not come to rest within the settle timeout.
    NoRest,
    /// A speed level did not turn the rotor [`super::MIN_TURNS`] times within
    /// [`super::MAX_MEASURE_S`]: too weak a duty for this motor.
    NoSpeed,
    /// A rotor ran faster than the controller's top speed (a motor much unlike
    /// its machine file): its run ended there.
    TooFast,
    /// The spin-up from rest made no whole turn while the top speed level ran:
    /// the inertia is not measured.
    NoTurn,
    /// A fit's rows did not tell its unknowns apart, the resistance, the torque
    /// constant or the inertia came out not positive, or a value not finite.
    NoFit,
    /// A stop command, the E-stop or a fault ended the identification before this
    /// rotor was done.
    Aborted,
}

/// One rotor's motor, as the identification measured it (every value in the
/// rotor's driven sense, at the winding as the bridge drives it).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct RotorIdentity {
    /// `None`: every value below was measured; otherwise where it stopped, and the
    /// values are 0.
    pub shortfall: Option<Shortfall>,
    /// Winding resistance `R`, ohm, the bridge's switches included.
    pub resistance_ohm: Estimate,
    /// Torque (= back-EMF) constant `k`, N m/A.
    pub torque_constant: Estimate,
    /// Coulomb friction torque `T_c`, N m.
    pub coulomb_friction_nm: Estimate,
    /// Viscous friction `b`, N m s/rad.
    pub viscous_friction: Estimate,
    /// Inertia about the axis, the eccentric's `m e^2` included, kg m^2.
    pub inertia_kg_m2: Estimate,
    /// The voltage fit's constant term `c_0`, V: an offset of the current sense or
    /// of the supply reading, as a voltage.
    pub offset_v: Estimate,
    /// The voltage fit's drop against the current `c_1`, V: a constant drop of the
    /// bridge (diodes, a switch's threshold) across the winding.
    pub drop_v: Estimate,
    /// The voltage fit's root-mean-square residual, V.
    pub voltage_residual_v: f32,
    /// The friction fit's root-mean-square residual, N m.
    pub friction_residual_nm: f32,
    /// Standstill levels used (of [`super::HOLD_LEVELS`] each way).
    pub standstill_levels: u8,
    /// Speed levels used (of [`super::SPEED_LEVELS`]).
    pub speed_levels: u8,
}

impl RotorIdentity {
    /// Every value, standard error and residual finite, the errors and
    /// residuals not negative (what the bytes of a result allow).
    pub fn is_finite(&self) -> bool {
        let estimates = [
            self.resistance_ohm,
            self.torque_constant,
            self.coulomb_friction_nm,
            self.viscous_friction,
            self.inertia_kg_m2,
            self.offset_v,
            self.drop_v,
        ];
        estimates
            .iter()
            .all(|e| e.value.is_finite() && e.std_error.is_finite() && e.std_error >= 0.0)
            && [self.voltage_residual_v, self.friction_residual_nm]
                .iter()
                .all(|r| r.is_finite() && *r >= 0.0)
    }

    /// A rotor that stopped short at `shortfall`, nothing kept.
    pub fn short(shortfall: Shortfall) -> Self {
        RotorIdentity {
            shortfall: Some(shortfall),
            ..RotorIdentity::default()
        }
    }
}

/// Both rotors' identification. A rotor not identified (rotor 2 of a one-rotor
/// machine, or both before any identification) has `shortfall: None` and every
/// value 0, and [`Identity::rotors_run`] says how many were.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Identity {
    /// Rotor 1 and rotor 2.
    pub rotors: [RotorIdentity; 2],
    /// How many rotors were identified: 1 on a one-rotor machine, else 2; 0 in
    /// the default (none run).
    pub rotors_run: u8,
}

/// Where the identification stands.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum IdentifyStatus {
    /// Never run since the identity was last stored (or never).
    NotRun,
    /// Running now.
    Running,
    /// Finished: [`IdentifyReport::identity`] holds what it measured (a rotor may
    /// have stopped short: its `shortfall`).
    Done,
    /// Ended early by a stop command, the E-stop or a fault.
    Aborted,
}

/// How far an identification has come: its status and the rotors finished. Its
/// result changes only when this does, so a reader copies the result only then.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IdentifyProgress {
    /// Identifications started on this controller (wrapping): a new run is new
    /// progress even where it ends as the last one did.
    pub run: u16,
    /// Where it stands.
    pub status: IdentifyStatus,
    /// Rotors whose results are final.
    pub rotors_finished: u8,
}

/// The identification's status with its result (the last finished one, or what
/// the one running has measured so far).
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct IdentifyReport {
    /// Where it stands.
    pub status: IdentifyStatus,
    /// What it measured.
    pub identity: Identity,
}
