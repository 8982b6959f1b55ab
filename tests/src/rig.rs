//! A machine described in the test, written as a machine file, and the mechanics
//! of its state computed from the geometry with formulas written here (never the
//! plant's own mass matrix, energy or forces): the independent side of the plant's
//! reference tests. Plane-vector arithmetic is `shared::vec2`'s, whose own tests
//! check each operation against its meaning.
//!
//! Conventions: world `x` right, `y` up, the fundament `y = 0` with normal
//! `n = (0, 1)` and tangent `t = (-n_y, n_x) = (-1, 0)`; gravity `(0, -G)`; state
//! layout `(x, y, theta, phi1, phi2, x', y', theta', phi1', phi2', i1, i2)`.

use crate::initial_state;
use crate::machine::TestMachine;

use host_sim::machine::Machine;
use host_sim::plant::model::PlantModel;
use host_sim::plant::model::NY;
use host_sim::plant::simulator::{Holds, Plant, Settings};
use shared::vec2::{add, cross, rotate, spin, sub};

/// Gravity, m/s^2 (the machine file's default, `[0, -9.81]`).
pub const G: f64 = 9.81;

// ---------------------------------------------------------------------------------
// The machine under test, described here and written as a machine file
// ---------------------------------------------------------------------------------

/// A foot, in the platform frame relative to the platform's centre of mass.
#[derive(Clone, Debug)]
pub struct Foot {
    pub local: [f64; 2],
    pub restitution: f64,
    pub friction: f64,
}

/// A rotor, its axis in the platform frame relative to the platform's centre of mass.
#[derive(Clone, Debug)]
pub struct RotorSpec {
    pub axis: [f64; 2],
    pub mass: f64,
    pub eccentricity: f64,
    pub inertia: f64,
    pub ccw: bool,
    /// Eccentric angle phi in the platform frame at t = 0, rad.
    pub angle: f64,
}

/// The motor of both rotors.
#[derive(Clone, Debug)]
pub struct MotorSpec {
    pub resistance: f64,
    pub inductance: f64,
    pub torque_constant: f64,
    pub coulomb_friction: f64,
    pub viscous_friction: f64,
    pub current_limit: f64,
}

/// Everything a test varies; [`Rig::reference`] is `examples/vibro-driver.toml` with
/// frictionless motors.
#[derive(Clone, Debug)]
pub struct Rig {
    pub platform_mass: f64,
    pub platform_inertia: f64,
    /// Platform centre of mass at t = 0, world, m.
    pub position: [f64; 2],
    pub angle: f64,
    pub velocity: [f64; 2],
    pub angular_velocity: f64,
    pub feet: Vec<Foot>,
    pub rotors: [RotorSpec; 2],
    pub motor: MotorSpec,
    pub law: &'static str,
}

impl Rig {
    /// The reference machine standing on the floor, motor friction 0.
    pub fn reference() -> Self {
        let foot = |x: f64| Foot {
            local: [x, -0.03],
            restitution: 0.3,
            friction: 0.4,
        };
        let rotor = |x: f64, ccw: bool| RotorSpec {
            axis: [x, 0.0],
            mass: 0.01,
            eccentricity: 0.02,
            inertia: 6.0e-6,
            ccw,
            angle: 0.0,
        };
        Rig {
            platform_mass: 2.0,
            platform_inertia: 7.3e-3,
            position: [0.0, 0.03],
            angle: 0.0,
            velocity: [0.0, 0.0],
            angular_velocity: 0.0,
            feet: vec![foot(-0.08), foot(0.08)],
            rotors: [rotor(-0.03, true), rotor(0.03, false)],
            motor: MotorSpec {
                resistance: 2.0,
                inductance: 0.5e-3,
                torque_constant: 0.02,
                coulomb_friction: 0.0,
                viscous_friction: 0.0,
                current_limit: 2.0,
            },
            law: "poisson",
        }
    }

    /// Total mass: platform and both eccentric masses, kg.
    pub fn total_mass(&self) -> f64 {
        self.platform_mass + self.rotors[0].mass + self.rotors[1].mass
    }

    /// World position of a platform-frame point at t = 0.
    pub fn world(&self, local: [f64; 2]) -> [f64; 2] {
        let r = rot(self.angle, local);
        [self.position[0] + r[0], self.position[1] + r[1]]
    }

    /// The machine file.
    pub fn toml(&self) -> String {
        let v = |a: [f64; 2]| format!("[{:?}, {:?}]", a[0], a[1]);
        let mut s = format!(
            "[platform]\nmass = {:?}\ninertia = {:?}\nposition = {}\nangle = {:?}\n\
             velocity = {}\nangular_velocity = {:?}\n\n",
            self.platform_mass,
            self.platform_inertia,
            v(self.position),
            self.angle,
            v(self.velocity),
            self.angular_velocity
        );
        for (i, f) in self.feet.iter().enumerate() {
            s += &format!(
                "[[contacts]]\nname = \"K{}\"\npoint = {}\nrestitution = {:?}\nfriction = {:?}\n\n",
                i + 1,
                v(self.world(f.local)),
                f.restitution,
                f.friction
            );
        }
        for (i, r) in self.rotors.iter().enumerate() {
            s += &format!(
                "[[rotors]]\nname = \"R{}\"\naxis = {}\neccentric_mass = {:?}\neccentricity = {:?}\n\
                 inertia = {:?}\nsense = \"{}\"\nangle = {:?}\nindex_angle = 0.0\n\n",
                i + 1,
                v(self.world(r.axis)),
                r.mass,
                r.eccentricity,
                r.inertia,
                if r.ccw { "ccw" } else { "cw" },
                r.angle
            );
        }
        let m = &self.motor;
        s += &format!(
            "[motor]\nresistance = {:?}\ninductance = {:?}\ntorque_constant = {:?}\n\
             coulomb_friction = {:?}\nviscous_friction = {:?}\ncurrent_limit = {:?}\n\n\
             [drive]\nsupply_voltage = 24.0\n\n[impact]\nlaw = \"{}\"\n",
            m.resistance,
            m.inductance,
            m.torque_constant,
            m.coulomb_friction,
            m.viscous_friction,
            m.current_limit,
            self.law
        );
        s
    }

    /// The checked machine.
    pub fn machine(&self) -> Machine {
        let text = self.toml();
        TestMachine::new("plant_references.toml")
            .with(&text)
            .machine()
    }

    /// The plant at t = 0, after `edit` changed the initial state.
    pub fn plant(
        &self,
        settings: Settings,
        holds: Holds,
        edit: impl FnOnce(&mut [f64; NY]),
    ) -> Plant {
        let m = self.machine();
        let mut y = initial_state(&m);
        edit(&mut y);
        Plant::new(PlantModel::new(&m), y, settings, holds)
    }
}

/// `R(angle) v`, the angle in rad ([`rotate`] of its sine and cosine).
pub fn rot(angle: f64, v: [f64; 2]) -> [f64; 2] {
    rotate(angle.sin_cos(), v)
}

/// Asserts `|got - expected| <= tol`.
pub fn check(what: &str, got: f64, expected: f64, tol: f64) {
    assert!(
        (got - expected).abs() <= tol,
        "{what}: got {got:.15e}, expected {expected:.15e}, |diff| {:.3e} > tol {tol:.3e}",
        (got - expected).abs()
    );
}

// ---------------------------------------------------------------------------------
// Mechanics of the state, written here from the geometry (not the plant's matrices)
// ---------------------------------------------------------------------------------

/// Positions and velocities of the bodies at state `y`.
///
/// The platform's centre of mass `C = (x, y)`, velocity `v_C = (x', y')`. Rotor `k`'s
/// axis `A_k = C + R(theta) a_k`; its eccentric point mass at `P_k = A_k + eps_k` with
/// `eps_k = e_k (cos(theta + phi_k), sin(theta + phi_k))`; velocities
/// `v_A = v_C + theta' x (A_k - C)`, `v_P = v_A + (theta' + phi_k') x eps_k`. The
/// rotor's own inertia `I_k` (about its axis) turns at `theta' + phi_k'`.
pub struct Kinematics {
    pub c: [f64; 2],
    pub v_c: [f64; 2],
    pub theta_dot: f64,
    /// Eccentric masses' positions and velocities.
    pub p: [[f64; 2]; 2],
    pub v_p: [[f64; 2]; 2],
    /// Absolute rotor angular velocities `theta' + phi_k'`.
    pub w_rotor: [f64; 2],
}

pub fn kinematics(rig: &Rig, y: &[f64; NY]) -> Kinematics {
    let c = [y[0], y[1]];
    let v_c = [y[5], y[6]];
    let (theta, theta_dot) = (y[2], y[7]);
    let mut p = [[0.0; 2]; 2];
    let mut v_p = [[0.0; 2]; 2];
    let mut w_rotor = [0.0; 2];
    for k in 0..2 {
        let r = &rig.rotors[k];
        let rho = rot(theta, r.axis);
        let a = theta + y[3 + k];
        let eps = [r.eccentricity * a.cos(), r.eccentricity * a.sin()];
        w_rotor[k] = theta_dot + y[8 + k];
        p[k] = add(add(c, rho), eps);
        v_p[k] = add(add(v_c, spin(theta_dot, rho)), spin(w_rotor[k], eps));
    }
    Kinematics {
        c,
        v_c,
        theta_dot,
        p,
        v_p,
        w_rotor,
    }
}

/// Kinetic plus gravity's potential energy, J:
/// `m_p |v_C|^2 / 2 + J_p theta'^2 / 2 + sum_k (m_k |v_P|^2 / 2 + I_k (theta' + phi_k')^2 / 2)
///  + G (m_p y_C + sum_k m_k y_P)`.
pub fn energy(rig: &Rig, y: &[f64; NY]) -> f64 {
    let k = kinematics(rig, y);
    let sq = |a: [f64; 2]| a[0] * a[0] + a[1] * a[1];
    let mut e = 0.5 * rig.platform_mass * sq(k.v_c)
        + 0.5 * rig.platform_inertia * k.theta_dot * k.theta_dot
        + G * rig.platform_mass * k.c[1];
    for j in 0..2 {
        let r = &rig.rotors[j];
        e += 0.5 * r.mass * sq(k.v_p[j])
            + 0.5 * r.inertia * k.w_rotor[j] * k.w_rotor[j]
            + G * r.mass * k.p[j][1];
    }
    e
}

/// Linear momentum of the whole system, kg m/s.
pub fn momentum(rig: &Rig, y: &[f64; NY]) -> [f64; 2] {
    let k = kinematics(rig, y);
    let mut p = [rig.platform_mass * k.v_c[0], rig.platform_mass * k.v_c[1]];
    for j in 0..2 {
        p[0] += rig.rotors[j].mass * k.v_p[j][0];
        p[1] += rig.rotors[j].mass * k.v_p[j][1];
    }
    p
}

/// Angular momentum of the whole system about the fixed point `o`, kg m^2/s, and the
/// sum of its terms' magnitudes (the scale of its rounding):
/// `H_O = m_p (C - O) x v_C + J_p theta'
///      + sum_k [m_k (P_k - O) x v_P + I_k (theta' + phi_k')]`.
pub fn angular_momentum(rig: &Rig, y: &[f64; NY], o: [f64; 2]) -> (f64, f64) {
    let k = kinematics(rig, y);
    let mut terms = vec![
        rig.platform_mass * cross(sub(k.c, o), k.v_c),
        rig.platform_inertia * k.theta_dot,
    ];
    for j in 0..2 {
        let r = &rig.rotors[j];
        terms.push(r.mass * cross(sub(k.p[j], o), k.v_p[j]));
        terms.push(r.inertia * k.w_rotor[j]);
    }
    (terms.iter().sum(), terms.iter().map(|t| t.abs()).sum())
}

/// World position of foot `j` at state `y`.
pub fn foot(rig: &Rig, y: &[f64; NY], j: usize) -> [f64; 2] {
    add([y[0], y[1]], rot(y[2], rig.feet[j].local))
}

/// The integrator's per-step error allowance for a scalar function `f` of the state.
///
/// The plant's Dormand-Prince controller (`simulator.rs`, `tolerance`) accepts a step
/// when `sqrt(mean_i (e_i / sc_i)^2) <= 1`, `sc_i = atol_i + rtol |y_i|`, with
/// `atol = 1e-3 rtol` on positions and angles and `rtol` on everything else. Then
/// `sum_i (e_i / sc_i)^2 <= n` over the single platform's [`STATE_LEN`] components,
/// and by Cauchy-Schwarz the error the step puts into `f` is at most
/// `sqrt(n) |grad f o sc|_2`. The gradient is taken here by central differences
/// (`f` is smooth).
pub fn step_allowance(f: &dyn Fn(&[f64; NY]) -> f64, y: &[f64; NY], rtol: f64) -> f64 {
    let mut sum = 0.0;
    for i in 0..STATE_LEN {
        let atol = if i < 5 { 1e-3 * rtol } else { rtol };
        let sc = atol + rtol * y[i].abs();
        let h = 1e-6 * (1.0 + y[i].abs());
        let (mut up, mut down) = (*y, *y);
        up[i] += h;
        down[i] -= h;
        let g = (f(&up) - f(&down)) / (2.0 * h);
        sum += (g * sc) * (g * sc);
    }
    (STATE_LEN as f64).sqrt() * sum.sqrt()
}

/// The components of the single platform's state `(q, q', i)`: 5 + 5 + 2 (the
/// plant's state array holds up to [`NY`] for larger machines; the rest stay zero
/// and take no part in the integrator's error norm).
pub const STATE_LEN: usize = 12;
