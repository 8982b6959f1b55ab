//! The motor identification's bytes, the same in the flash record and in the
//! [`crate::protocol::Response::Identify`] payload: one rotor's result in
//! [`ROTOR_IDENTITY_LEN`] bytes, both rotors' in [`IDENTITY_LEN`], and the report
//! (status and result) in [`IDENTIFY_REPORT_LEN`].
//!
//! ```text
//!  one rotor (68 bytes)
//!  0   shortfall u8: 0 none, 1 no standstill, 2 no rest, 3 no speed,
//!      4 too fast, 5 no turn, 6 no fit, 7 aborted
//!  1   standstill levels u8
//!  2   speed levels u8
//!  3   1 reserved zero byte
//!  4   7 x (value f32, standard error f32): resistance (ohm), torque constant
//!      (N m/A), Coulomb friction (N m), viscous friction (N m s/rad), inertia
//!      (kg m^2, the eccentric's m e^2 included), offset (V), drop (V)
//!  60  voltage residual f32, V
//!  64  friction residual f32, N m
//!
//!  both rotors (140 bytes)
//!  0   rotors identified u8: 0 (none run), 1 or 2
//!  1   3 reserved zero bytes
//!  4   rotor 1, then rotor 2
//!
//!  report (144 bytes)
//!  0   status u8: 0 not run, 1 running, 2 done, 3 aborted
//!  1   3 reserved zero bytes
//!  4   both rotors
//! ```
//!
//! Every number read must be finite, and a standard error or a residual not
//! negative.

use crate::controller::identify::{
    Estimate, IdentifyReport, IdentifyStatus, Identity, RotorIdentity, Shortfall,
};

use super::wire::{Field, Reader, Writer};

/// Bytes of one rotor's identification.
pub const ROTOR_IDENTITY_LEN: usize = 68;
/// Bytes of both rotors' identification.
pub const IDENTITY_LEN: usize = 4 + 2 * ROTOR_IDENTITY_LEN;
/// Bytes of an identification report: status, reserved, both rotors.
pub const IDENTIFY_REPORT_LEN: usize = 4 + IDENTITY_LEN;

/// The statuses in code order, from 0.
const STATUSES: [IdentifyStatus; 4] = [
    IdentifyStatus::NotRun,
    IdentifyStatus::Running,
    IdentifyStatus::Done,
    IdentifyStatus::Aborted,
];

/// The shortfalls in code order, from 1 (0 is none).
const SHORTFALLS: [Shortfall; 7] = [
    Shortfall::NoStandstill,
    Shortfall::NoRest,
    Shortfall::NoSpeed,
    Shortfall::TooFast,
    Shortfall::NoTurn,
    Shortfall::NoFit,
    Shortfall::Aborted,
];

/// Code of a shortfall (the layout above).
fn shortfall_code(s: Option<Shortfall>) -> u8 {
    match s {
        None => 0,
        Some(s) => SHORTFALLS
            .iter()
            .position(|k| *k == s)
            .map_or(0, |i| i as u8 + 1),
    }
}

/// The shortfall of code `b`; `None` for a code that names none.
fn shortfall_from_code(b: u8) -> Option<Option<Shortfall>> {
    match b {
        0 => Some(None),
        _ => SHORTFALLS.get(usize::from(b) - 1).map(|s| Some(*s)),
    }
}

/// A finite number, or nothing.
fn finite(r: &mut Reader<'_>) -> Option<f32> {
    r.f32().filter(|v| v.is_finite())
}

/// A finite number at least 0, or nothing.
fn spread(r: &mut Reader<'_>) -> Option<f32> {
    finite(r).filter(|v| *v >= 0.0)
}

impl Field for Estimate {
    fn write(&self, w: &mut Writer<'_>) {
        w.f32(self.value);
        w.f32(self.std_error);
    }

    fn read(r: &mut Reader<'_>) -> Option<Self> {
        Some(Estimate {
            value: finite(r)?,
            std_error: spread(r)?,
        })
    }
}

impl Field for RotorIdentity {
    fn write(&self, w: &mut Writer<'_>) {
        w.u8(shortfall_code(self.shortfall));
        w.u8(self.standstill_levels);
        w.u8(self.speed_levels);
        w.zeros(1);
        for e in [
            &self.resistance_ohm,
            &self.torque_constant,
            &self.coulomb_friction_nm,
            &self.viscous_friction,
            &self.inertia_kg_m2,
            &self.offset_v,
            &self.drop_v,
        ] {
            e.write(w);
        }
        w.f32(self.voltage_residual_v);
        w.f32(self.friction_residual_nm);
    }

    fn read(r: &mut Reader<'_>) -> Option<Self> {
        let shortfall = shortfall_from_code(r.u8()?)?;
        let standstill_levels = r.u8()?;
        let speed_levels = r.u8()?;
        r.zeros(1)?;
        Some(RotorIdentity {
            shortfall,
            standstill_levels,
            speed_levels,
            resistance_ohm: Estimate::read(r)?,
            torque_constant: Estimate::read(r)?,
            coulomb_friction_nm: Estimate::read(r)?,
            viscous_friction: Estimate::read(r)?,
            inertia_kg_m2: Estimate::read(r)?,
            offset_v: Estimate::read(r)?,
            drop_v: Estimate::read(r)?,
            voltage_residual_v: spread(r)?,
            friction_residual_nm: spread(r)?,
        })
    }
}

impl Field for Identity {
    fn write(&self, w: &mut Writer<'_>) {
        w.u8(self.rotors_run);
        w.zeros(3);
        for rotor in &self.rotors {
            rotor.write(w);
        }
    }

    fn read(r: &mut Reader<'_>) -> Option<Self> {
        let rotors_run = r.u8().filter(|n| *n <= 2)?;
        r.zeros(3)?;
        Some(Identity {
            rotors_run,
            rotors: [RotorIdentity::read(r)?, RotorIdentity::read(r)?],
        })
    }
}

impl Field for IdentifyReport {
    fn write(&self, w: &mut Writer<'_>) {
        let code = STATUSES.iter().position(|s| *s == self.status).unwrap_or(0);
        w.u8(code as u8);
        w.zeros(3);
        self.identity.write(w);
    }

    fn read(r: &mut Reader<'_>) -> Option<Self> {
        let status = *STATUSES.get(usize::from(r.u8()?))?;
        r.zeros(3)?;
        Some(IdentifyReport {
            status,
            identity: Identity::read(r)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Identity {
        let e = |v: f32| Estimate {
            value: v,
            std_error: v.abs() * 0.01,
        };
        let rotor = RotorIdentity {
            shortfall: None,
            resistance_ohm: e(2.0),
            torque_constant: e(0.02),
            coulomb_friction_nm: e(1e-3),
            viscous_friction: e(1e-6),
            inertia_kg_m2: e(1e-5),
            offset_v: e(-0.01),
            drop_v: Estimate {
                value: 0.02,
                std_error: 0.0,
            },
            voltage_residual_v: 1e-4,
            friction_residual_nm: 2e-7,
            standstill_levels: 4,
            speed_levels: 3,
        };
        Identity {
            rotors: [rotor, RotorIdentity::short(Shortfall::TooFast)],
            rotors_run: 2,
        }
    }

    fn bytes(id: &Identity) -> [u8; IDENTITY_LEN] {
        let mut buf = [0u8; IDENTITY_LEN];
        let mut w = Writer::new(&mut buf);
        id.write(&mut w);
        assert_eq!(w.finish(), Some(IDENTITY_LEN));
        buf
    }

    #[test]
    fn round_trip_and_layout() {
        let id = sample();
        let buf = bytes(&id);
        assert_eq!(buf[0], 2);
        assert_eq!(buf[4 + ROTOR_IDENTITY_LEN], 4, "rotor 2: too fast");
        assert_eq!(
            &buf[4 + 4..4 + 8],
            &2.0f32.to_le_bytes(),
            "rotor 1's resistance"
        );
        let mut r = Reader::new(&buf);
        assert_eq!(Identity::read(&mut r), Some(id));
        assert!(r.is_empty());
        for s in SHORTFALLS {
            assert_eq!(shortfall_from_code(shortfall_code(Some(s))), Some(Some(s)));
        }
        for (code, status) in STATUSES.into_iter().enumerate() {
            let report = IdentifyReport {
                status,
                identity: sample(),
            };
            let mut buf = [0u8; IDENTIFY_REPORT_LEN];
            let mut w = Writer::new(&mut buf);
            report.write(&mut w);
            assert_eq!(w.finish(), Some(IDENTIFY_REPORT_LEN));
            assert_eq!(usize::from(buf[0]), code);
            assert_eq!(IdentifyReport::read(&mut Reader::new(&buf)), Some(report));
        }
    }

    /// A byte out of its domain, a non-finite value or a negative spread is
    /// refused wherever it stands.
    #[test]
    fn bad_bytes_are_refused() {
        let good = bytes(&sample());
        let refused = |edit: &dyn Fn(&mut [u8; IDENTITY_LEN])| {
            let mut buf = good;
            edit(&mut buf);
            Identity::read(&mut Reader::new(&buf)).is_none()
        };
        assert!(refused(&|b| b[0] = 3), "three rotors");
        assert!(refused(&|b| b[1] = 1), "reserved");
        assert!(refused(&|b| b[4] = 8), "an unknown shortfall");
        assert!(refused(&|b| b[7] = 1), "a rotor's reserved byte");
        assert!(refused(
            &|b| b[8..12].copy_from_slice(&f32::NAN.to_le_bytes())
        ));
        assert!(refused(
            &|b| b[12..16].copy_from_slice(&(-1.0f32).to_le_bytes())
        ));
        assert!(refused(
            &|b| b[64..68].copy_from_slice(&f32::INFINITY.to_le_bytes())
        ));
        assert!(
            !refused(&|b| b[8..12].copy_from_slice(&(-2.0f32).to_le_bytes())),
            "a value may be negative"
        );
    }
}
