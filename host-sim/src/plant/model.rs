//! The constant model of the simulated machine (MuJoCo's `mjModel`): the machine
//! file turned into platform-frame geometry. The changing state lives in
//! [`super::dynamics::State`].

use shared::impact::{ContactLaw, ImpactLaw};

use crate::machine::{Machine, MotorParams};

/// Number of generalized coordinates: `(x, y, theta, phi_1, phi_2)`.
pub const DOF: usize = 5;

/// Size of the integrated state: `q` (5), `q'` (5), winding currents (2).
pub const NY: usize = 2 * DOF + 2;

/// An unbalance rotor, in the platform frame.
#[derive(Clone, Debug)]
pub struct RotorModel {
    /// Axis position relative to the platform's centre of mass, platform frame, m.
    pub axis: [f64; 2],
    /// Eccentric mass, kg.
    pub mass: f64,
    /// Eccentricity, m.
    pub eccentricity: f64,
    /// Inertia about the axis without the eccentric mass, kg m^2.
    pub inertia: f64,
    /// `+1` ccw, `-1` cw: the driven sense.
    pub sense: f64,
    /// Eccentric angle of the index pulse, rad.
    pub index_angle: f64,
    /// Its motor.
    pub motor: MotorParams,
}

/// A contact point, in the platform frame.
#[derive(Clone, Debug)]
pub struct ContactPoint {
    /// Name (K1, K2, ...).
    pub name: String,
    /// Position relative to the platform's centre of mass, platform frame, m.
    pub point: [f64; 2],
    /// Restitution, friction and weight.
    pub law: ContactLaw<f64>,
}

/// The machine, ready to simulate.
#[derive(Clone, Debug)]
pub struct PlantModel {
    /// Platform mass without the eccentric masses, kg.
    pub platform_mass: f64,
    /// Platform inertia about its centre of mass, kg m^2.
    pub platform_inertia: f64,
    /// Rotor 1 and rotor 2.
    pub rotors: [RotorModel; 2],
    /// The contact points.
    pub contacts: Vec<ContactPoint>,
    /// A point of the fundament line, m.
    pub ground_point: [f64; 2],
    /// Unit normal of the fundament, towards the platform.
    pub normal: [f64; 2],
    /// Unit tangent `t = (-n_y, n_x)`.
    pub tangent: [f64; 2],
    /// Gravity, m/s^2.
    pub gravity: [f64; 2],
    /// The impact law.
    pub law: ImpactLaw,
    /// Supply voltage of the motor driver, V.
    pub supply_voltage: f64,
    /// The H-bridges as wired (`[drive] decay`, `pwm_hz`).
    pub bridge: shared::drive::BridgeConfig,
}

/// `R(-angle) v`: a world vector in the platform frame.
fn to_platform(angle: f64, v: [f64; 2]) -> [f64; 2] {
    let (s, c) = angle.sin_cos();
    [c * v[0] + s * v[1], -s * v[0] + c * v[1]]
}

impl PlantModel {
    /// The model of a checked machine file.
    pub fn new(m: &Machine) -> Self {
        let c0 = m.platform.position;
        let a0 = m.platform.angle;
        let local = |p: [f64; 2]| to_platform(a0, [p[0] - c0[0], p[1] - c0[1]]);
        let rotors = [0, 1].map(|k| {
            let r = &m.rotors[k];
            RotorModel {
                axis: local(r.axis),
                mass: r.eccentric_mass,
                eccentricity: r.eccentricity,
                inertia: r.inertia,
                sense: r.sense.sign(),
                index_angle: r.index_angle,
                motor: r.motor.clone(),
            }
        });
        let contacts = m
            .contacts
            .iter()
            .map(|c| ContactPoint {
                name: c.name.clone(),
                point: local(c.point),
                law: ContactLaw {
                    restitution: c.restitution,
                    friction: c.friction,
                    weight: c.weight,
                },
            })
            .collect();
        let n = m.fundament.normal;
        PlantModel {
            platform_mass: m.platform.mass,
            platform_inertia: m.platform.inertia,
            rotors,
            contacts,
            ground_point: m.fundament.point,
            normal: n,
            tangent: [-n[1], n[0]],
            gravity: m.fundament.gravity,
            law: m.law,
            supply_voltage: m.drive.supply_voltage,
            bridge: m.drive.bridge,
        }
    }

    /// Total mass: platform and eccentric masses, kg.
    pub fn total_mass(&self) -> f64 {
        self.platform_mass + self.rotors[0].mass + self.rotors[1].mass
    }
}

/// The state at `t = 0` of a machine file: the platform's position, angle and
/// velocities, the rotors' eccentric angles, rotors at rest relative to the
/// platform, no current. Layout of [`NY`]:
/// `(x, y, theta, phi_1, phi_2, x', y', theta', phi_1', phi_2', i_1, i_2)`.
pub fn initial_state(m: &Machine) -> [f64; NY] {
    let p = &m.platform;
    let mut y = [0.0; NY];
    y[0] = p.position[0];
    y[1] = p.position[1];
    y[2] = p.angle;
    y[3] = m.rotors[0].angle;
    y[4] = m.rotors[1].angle;
    y[5] = p.velocity[0];
    y[6] = p.velocity[1];
    y[7] = p.angular_velocity;
    y
}
