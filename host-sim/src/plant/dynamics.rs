//! Equations of motion of the platform with its two unbalance rotors, in the
//! generalized coordinates `q = (x, y, theta, phi_1, phi_2)`: the platform's centre
//! of mass, its angle, and the eccentric angles in the platform frame.
//!
//! The eccentric mass `m_k` of rotor `k` sits at `r_k = rho_k + eps_k` from the
//! platform's centre of mass, with the axis `rho_k = R(theta) a_k` and the
//! eccentric `eps_k = e_k (cos(theta + phi_k), sin(theta + phi_k))`. Its velocity
//! is `v_k = J_k q'` with the Jacobian columns
//!
//! ```text
//!   d/dx = (1, 0),  d/dy = (0, 1),  d/dtheta = z x r_k,  d/dphi_k = z x eps_k
//! ```
//!
//! and its acceleration `J_k q'' + b_k` with the velocity-product term
//! `b_k = -theta'^2 rho_k - (theta' + phi_k')^2 eps_k`. The rotor (armature and hub,
//! inertia `I_k`) turns at `theta' + phi_k'`. Lagrange's equations
//! (Goldstein, *Classical Mechanics*, ch. 1; d'Alembert for point masses) give
//!
//! ```text
//!   M(q) q'' = Q_g + Q_motor + J_c^T lambda - sum_k m_k J_k^T b_k
//!   M = diag(m_p, m_p, J_p, 0, 0) + sum_k m_k J_k^T J_k + sum_k I_k (e_theta + e_phi_k)(e_theta + e_phi_k)^T
//! ```
//!
//! so the coupling is complete: the exciting force of an eccentric
//! `m e (phi'^2 cos phi + phi'' sin phi, ...)` is the `m_k J_k^T b_k` and `M` terms, and the
//! platform's acceleration and gravity act back on the rotors through the same
//! terms (Sommerfeld effect, self-synchronisation; Blekhman, *Vibrational
//! Mechanics*, 2000). A motor's torque acts between platform and rotor, so its
//! generalized force is on `phi_k` only.

use super::model::PlantModel;
pub use super::model::DOF;

/// The mechanical state.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct State {
    /// `(x, y, theta, phi_1, phi_2)`: m, m, rad, rad, rad.
    pub q: [f64; DOF],
    /// Their rates: m/s, m/s, rad/s, rad/s, rad/s.
    pub v: [f64; DOF],
}

/// `z x r = (-r_y, r_x)`.
#[inline]
pub fn perp(r: [f64; 2]) -> [f64; 2] {
    [-r[1], r[0]]
}

/// `a x b` (z component).
#[inline]
pub fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// `a . b`.
#[inline]
pub fn dot(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[0] + a[1] * b[1]
}

/// `R(angle) v`.
#[inline]
pub fn rotate(angle_cs: (f64, f64), v: [f64; 2]) -> [f64; 2] {
    let (s, c) = angle_cs;
    [c * v[0] - s * v[1], s * v[0] + c * v[1]]
}

/// A contact point's kinematics at a state.
#[derive(Clone, Copy, Debug, Default)]
pub struct ContactKinematics {
    /// Normal Jacobian row: `u_n = j_n . q'`.
    pub j_n: [f64; DOF],
    /// Tangential Jacobian row: `u_t = j_t . q'`.
    pub j_t: [f64; DOF],
    /// Gap to the fundament along its normal, m (negative: penetration).
    pub gap: f64,
    /// Normal velocity, m/s.
    pub u_n: f64,
    /// Tangential velocity, m/s.
    pub u_t: f64,
    /// Velocity-product part of the normal acceleration, `-theta'^2 n . r`, m/s^2.
    pub bias_n: f64,
    /// Velocity-product part of the tangential acceleration, m/s^2.
    pub bias_t: f64,
}

/// Everything that depends on the configuration: mass matrix (factored) and the
/// eccentric masses' geometry.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The mass matrix, kg / kg m / kg m^2.
    pub mass: [[f64; DOF]; DOF],
    /// Its Cholesky factor (lower), used when coordinates are held.
    chol: [[f64; DOF]; DOF],
    /// The platform block's Schur complement `S = A - B D^-1 B^T` (inverse, 3x3),
    /// used when nothing is held (see [`Frame::solve`]).
    schur_inv: [[f64; 3]; 3],
    /// Axis offsets `rho_k` (world), m.
    rho: [[f64; 2]; 2],
    /// Eccentric offsets `eps_k` (world), m.
    eps: [[f64; 2]; 2],
    /// `(sin theta, cos theta)`.
    cs: (f64, f64),
    /// Coordinates held still.
    locked: [bool; DOF],
    /// Some coordinate is held: solve with the Cholesky factor.
    any_locked: bool,
}

impl Frame {
    /// The configuration-dependent terms at `q`, with the coordinates marked in
    /// `locked` held (their rows and columns of the factored mass matrix replaced
    /// by the identity, so that no force or impulse moves them; [`Frame::mass`]
    /// stays the true mass matrix).
    pub fn locked(model: &PlantModel, q: &[f64; DOF], locked: &[bool; DOF]) -> Self {
        let mut f = Self::new(model, q);
        if locked.iter().any(|l| *l) {
            let mut m = f.mass;
            for i in 0..DOF {
                if locked[i] {
                    for j in 0..DOF {
                        m[i][j] = 0.0;
                        m[j][i] = 0.0;
                    }
                    m[i][i] = 1.0;
                }
            }
            f.chol = cholesky(&m);
            f.locked = *locked;
            f.any_locked = true;
        }
        f
    }

    /// The configuration-dependent terms at `q`.
    pub fn new(model: &PlantModel, q: &[f64; DOF]) -> Self {
        let cs = q[2].sin_cos();
        let mut rho = [[0.0; 2]; 2];
        let mut eps = [[0.0; 2]; 2];
        let mut m = [[0.0; DOF]; DOF];
        let total = model.total_mass();
        m[0][0] = total;
        m[1][1] = total;
        m[2][2] = model.platform_inertia;
        for k in 0..2 {
            let rot = &model.rotors[k];
            rho[k] = rotate(cs, rot.axis);
            let (s, c) = (q[2] + q[3 + k]).sin_cos();
            eps[k] = [rot.eccentricity * c, rot.eccentricity * s];
            let r = [rho[k][0] + eps[k][0], rho[k][1] + eps[k][1]];
            let (mk, ik) = (rot.mass, rot.inertia);
            // m_k J_k^T J_k with columns (1,0), (0,1), z x r, z x eps.
            m[0][2] += -mk * r[1];
            m[1][2] += mk * r[0];
            m[0][3 + k] = -mk * eps[k][1];
            m[1][3 + k] = mk * eps[k][0];
            m[2][2] += mk * dot(r, r) + ik;
            m[2][3 + k] = mk * dot(r, eps[k]) + ik;
            m[3 + k][3 + k] = mk * dot(eps[k], eps[k]) + ik;
        }
        for i in 0..DOF {
            for j in 0..i {
                m[i][j] = m[j][i];
            }
        }
        let schur_inv = schur_inverse(&m);
        Frame {
            mass: m,
            chol: [[0.0; DOF]; DOF],
            schur_inv,
            rho,
            eps,
            cs,
            locked: [false; DOF],
            any_locked: false,
        }
    }

    /// `M^-1 b` (held coordinates: zero).
    ///
    /// Nothing held: block elimination of the rotors, whose block `D` is diagonal
    /// (`M = [A B; B^T D]`, `A` the platform's 3x3 block):
    /// `x_p = S^-1 (b_p - B D^-1 b_r)`, `x_r = D^-1 (b_r - B^T x_p)`.
    pub fn solve(&self, b: &[f64; DOF]) -> [f64; DOF] {
        if !self.any_locked {
            let m = &self.mass;
            let br = [b[3] / m[3][3], b[4] / m[4][4]];
            let rhs = [
                b[0] - m[0][3] * br[0] - m[0][4] * br[1],
                b[1] - m[1][3] * br[0] - m[1][4] * br[1],
                b[2] - m[2][3] * br[0] - m[2][4] * br[1],
            ];
            let si = &self.schur_inv;
            let xp = [
                si[0][0] * rhs[0] + si[0][1] * rhs[1] + si[0][2] * rhs[2],
                si[1][0] * rhs[0] + si[1][1] * rhs[1] + si[1][2] * rhs[2],
                si[2][0] * rhs[0] + si[2][1] * rhs[1] + si[2][2] * rhs[2],
            ];
            let xr =
                |k: usize| (b[k] - m[0][k] * xp[0] - m[1][k] * xp[1] - m[2][k] * xp[2]) / m[k][k];
            return [xp[0], xp[1], xp[2], xr(3), xr(4)];
        }
        let l = &self.chol;
        let mut y = [0.0; DOF];
        for i in 0..DOF {
            let mut s = if self.locked[i] { 0.0 } else { b[i] };
            for k in 0..i {
                s -= l[i][k] * y[k];
            }
            y[i] = s / l[i][i];
        }
        let mut x = [0.0; DOF];
        for i in (0..DOF).rev() {
            let mut s = y[i];
            for k in (i + 1)..DOF {
                s -= l[k][i] * x[k];
            }
            x[i] = s / l[i][i];
        }
        x
    }

    /// Generalized forces without contacts: gravity, the rotors' generalized torques
    /// `tau` (on `phi_1`, `phi_2`, N m), minus the velocity-product terms.
    ///
    /// `Q = sum_masses J^T m g - sum_k m_k J_k^T b_k + (0, 0, 0, tau_1, tau_2)`
    pub fn forces(&self, model: &PlantModel, v: &[f64; DOF], tau: [f64; 2]) -> [f64; DOF] {
        let g = model.gravity;
        let mut f = [0.0; DOF];
        f[0] = model.total_mass() * g[0];
        f[1] = model.total_mass() * g[1];
        let w = v[2];
        for k in 0..2 {
            let mk = model.rotors[k].mass;
            let wk = w + v[3 + k];
            let (rho, eps) = (self.rho[k], self.eps[k]);
            // Force on the eccentric mass: m (g - b_k), b_k = -w^2 rho - wk^2 eps.
            let a = [
                g[0] + w * w * rho[0] + wk * wk * eps[0],
                g[1] + w * w * rho[1] + wk * wk * eps[1],
            ];
            let fk = [mk * a[0], mk * a[1]];
            let r = [rho[0] + eps[0], rho[1] + eps[1]];
            // Gravity's share on x, y is already in the total mass above.
            f[0] += fk[0] - mk * g[0];
            f[1] += fk[1] - mk * g[1];
            f[2] += cross(r, fk);
            f[3 + k] += cross(eps, fk) + tau[k];
        }
        f
    }

    /// Kinetic energy `q'^T M q' / 2`, J.
    pub fn kinetic_energy(&self, v: &[f64; DOF]) -> f64 {
        let mut e = 0.0;
        for i in 0..DOF {
            for j in 0..DOF {
                e += v[i] * self.mass[i][j] * v[j];
            }
        }
        0.5 * e
    }

    /// Potential energy of gravity, `-sum m g . r`, J (zero at the origin).
    pub fn potential_energy(&self, model: &PlantModel, q: &[f64; DOF]) -> f64 {
        let g = model.gravity;
        let mut e = -model.platform_mass * (g[0] * q[0] + g[1] * q[1]);
        for k in 0..2 {
            let mk = model.rotors[k].mass;
            let p = [
                q[0] + self.rho[k][0] + self.eps[k][0],
                q[1] + self.rho[k][1] + self.eps[k][1],
            ];
            e -= mk * dot(g, p);
        }
        e
    }

    /// The kinematics of contact point `j` at state `(q, v)`.
    pub fn contact(
        &self,
        model: &PlantModel,
        j: usize,
        q: &[f64; DOF],
        v: &[f64; DOF],
    ) -> ContactKinematics {
        contact_kinematics(model, self.cs, j, q, v)
    }

    /// World position of the eccentric mass of rotor `k`, relative to the platform's
    /// centre of mass, m.
    pub fn eccentric_offset(&self, k: usize) -> [f64; 2] {
        [
            self.rho[k][0] + self.eps[k][0],
            self.rho[k][1] + self.eps[k][1],
        ]
    }
}

/// The kinematics of contact point `j` at state `(q, v)`, with `cs` the
/// `(sin theta, cos theta)` of `q` (no mass matrix needed: events use this).
pub fn contact_kinematics(
    model: &PlantModel,
    cs: (f64, f64),
    j: usize,
    q: &[f64; DOF],
    v: &[f64; DOF],
) -> ContactKinematics {
    let (n, t) = (model.normal, model.tangent);
    let r = rotate(cs, model.contacts[j].point);
    let p = [q[0] + r[0], q[1] + r[1]];
    let j_n = [n[0], n[1], cross(r, n), 0.0, 0.0];
    let j_t = [t[0], t[1], cross(r, t), 0.0, 0.0];
    let w2 = v[2] * v[2];
    let row = |jr: &[f64; DOF]| jr[0] * v[0] + jr[1] * v[1] + jr[2] * v[2];
    ContactKinematics {
        j_n,
        j_t,
        gap: dot(
            n,
            [p[0] - model.ground_point[0], p[1] - model.ground_point[1]],
        ),
        u_n: row(&j_n),
        u_t: row(&j_t),
        bias_n: -w2 * dot(n, r),
        bias_t: -w2 * dot(t, r),
    }
}

/// The inverse of the platform block's Schur complement `S = A - B D^-1 B^T`
/// (3x3, symmetric positive definite), by the adjugate.
fn schur_inverse(m: &[[f64; DOF]; DOF]) -> [[f64; 3]; 3] {
    let mut s = [[0.0; 3]; 3];
    for i in 0..3 {
        for j in 0..3 {
            s[i][j] = m[i][j] - m[i][3] * m[j][3] / m[3][3] - m[i][4] * m[j][4] / m[4][4];
        }
    }
    let c00 = s[1][1] * s[2][2] - s[1][2] * s[2][1];
    let c01 = s[1][2] * s[2][0] - s[1][0] * s[2][2];
    let c02 = s[1][0] * s[2][1] - s[1][1] * s[2][0];
    let det = s[0][0] * c00 + s[0][1] * c01 + s[0][2] * c02;
    let inv = 1.0 / det;
    [
        [
            c00 * inv,
            (s[0][2] * s[2][1] - s[0][1] * s[2][2]) * inv,
            (s[0][1] * s[1][2] - s[0][2] * s[1][1]) * inv,
        ],
        [
            c01 * inv,
            (s[0][0] * s[2][2] - s[0][2] * s[2][0]) * inv,
            (s[0][2] * s[1][0] - s[0][0] * s[1][2]) * inv,
        ],
        [
            c02 * inv,
            (s[0][1] * s[2][0] - s[0][0] * s[2][1]) * inv,
            (s[0][0] * s[1][1] - s[0][1] * s[1][0]) * inv,
        ],
    ]
}

/// Cholesky factor of a symmetric positive definite matrix (lower triangle).
fn cholesky(m: &[[f64; DOF]; DOF]) -> [[f64; DOF]; DOF] {
    let mut l = [[0.0; DOF]; DOF];
    for i in 0..DOF {
        for j in 0..=i {
            let mut s = m[i][j];
            for k in 0..j {
                s -= l[i][k] * l[j][k];
            }
            if i == j {
                l[i][i] = s.max(f64::MIN_POSITIVE).sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    l
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::Machine;

    /// The block solve and the Cholesky solve agree with M x = b (residual).
    #[test]
    fn block_solve_inverts_the_mass_matrix() {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../examples/vibro-driver.toml"
        ))
        .unwrap();
        let machine = Machine::from_text("m.toml", &text, std::path::Path::new("."), &[]).unwrap();
        let model = PlantModel::new(&machine);
        for (k, q) in [[0.0, 0.03, 0.1, 0.3, -2.0], [0.2, 0.05, -0.4, 5.0, 1.0]]
            .iter()
            .enumerate()
        {
            let b = [1.0, -2.0, 0.3, 0.01, -0.02];
            let fast = Frame::new(&model, q);
            let slow = Frame::locked(&model, q, &[false; DOF]);
            let mut held = Frame::new(&model, q);
            held.chol = cholesky(&held.mass);
            held.any_locked = true;
            for (name, x) in [
                ("block", fast.solve(&b)),
                ("cholesky", held.solve(&b)),
                ("unlocked", slow.solve(&b)),
            ] {
                for i in 0..DOF {
                    let r: f64 = (0..DOF).map(|j| fast.mass[i][j] * x[j]).sum::<f64>() - b[i];
                    assert!(
                        r.abs() < 1e-12 * (1.0 + b[i].abs()),
                        "case {k} {name}: residual {r}"
                    );
                }
            }
        }
    }
}
