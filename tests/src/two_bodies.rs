//! Two free planar rigid bodies meeting at contact points: a point fixed on body B
//! strikes a face fixed on body A. The impact problem built by hand from the
//! bodies' Jacobians, as a multibody plant will build it, so the `shared` solver
//! can be checked on impacts between moving bodies (issue 12) against closed forms.
//!
//! Generalised velocities `q' = (v_A, omega_A, v_B, omega_B)` (6 numbers), mass
//! matrix `M = diag(m_A, m_A, J_A, m_B, m_B, J_B)` (`J` about each centre of mass).
//! A contact at the world point `P`, normal `n` from A towards B, tangent
//! `t = (-n_y, n_x)`: its relative velocity is `u = v_B(P) - v_A(P)` with
//! `v_X(P) = v_X + omega_X x (P - C_X)`, so (Glocker 2001, ch. 7)
//!
//! `u_n = J_n q'`, `J_n = (-n, -(r_A x n), n, r_B x n)`, `r_X = P - C_X`,
//!
//! and likewise `J_t` with `t`; `omega x r . n = omega (r x n)`. An impulse `P_n n +
//! P_t t` on B (its opposite on A) changes `q'` by `M^-1 (J_n^T P_n + J_t^T P_t)`,
//! and the contact velocities by the Delassus matrix `W = J M^-1 J^T`.

use shared::impact::{ContactLaw, ImpactLaw, ImpactProblem};

use crate::rig::cross;

/// A planar rigid body: mass, kg; inertia about its centre of mass, kg m^2;
/// centre of mass, m; velocity, m/s; angular velocity, rad/s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Body {
    pub mass: f64,
    pub inertia: f64,
    pub centre: [f64; 2],
    pub velocity: [f64; 2],
    pub omega: f64,
}

/// A contact between the two bodies: the world point, the unit normal from A
/// towards B, its law.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Contact {
    pub point: [f64; 2],
    pub normal: [f64; 2],
    pub law: ContactLaw<f64>,
}

/// Both bodies.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pair {
    pub a: Body,
    pub b: Body,
}

/// The tangent `t = (-n_y, n_x)`.
pub fn tangent(n: [f64; 2]) -> [f64; 2] {
    [-n[1], n[0]]
}

impl Pair {
    /// `q'`.
    pub fn q_dot(&self) -> [f64; 6] {
        let (a, b) = (&self.a, &self.b);
        [
            a.velocity[0],
            a.velocity[1],
            a.omega,
            b.velocity[0],
            b.velocity[1],
            b.omega,
        ]
    }

    /// `M^-1` (its diagonal).
    pub fn inverse_mass(&self) -> [f64; 6] {
        let (a, b) = (&self.a, &self.b);
        [
            1.0 / a.mass,
            1.0 / a.mass,
            1.0 / a.inertia,
            1.0 / b.mass,
            1.0 / b.mass,
            1.0 / b.inertia,
        ]
    }

    /// The Jacobian row of the relative velocity along `d` at the world point `p`.
    pub fn row(&self, p: [f64; 2], d: [f64; 2]) -> [f64; 6] {
        let ra = [p[0] - self.a.centre[0], p[1] - self.a.centre[1]];
        let rb = [p[0] - self.b.centre[0], p[1] - self.b.centre[1]];
        [-d[0], -d[1], -cross(ra, d), d[0], d[1], cross(rb, d)]
    }

    /// The impact problem of `contacts` (at most 4) under `law`.
    pub fn problem(&self, contacts: &[Contact], law: ImpactLaw) -> ImpactProblem<f64, 4> {
        let mut p = ImpactProblem::new(law);
        p.len = contacts.len();
        let inv = self.inverse_mass();
        let q = self.q_dot();
        let w = |x: &[f64; 6], y: &[f64; 6]| (0..6).map(|k| x[k] * inv[k] * y[k]).sum::<f64>();
        let dot = |x: &[f64; 6]| (0..6).map(|k| x[k] * q[k]).sum::<f64>();
        let rows: Vec<([f64; 6], [f64; 6])> = contacts
            .iter()
            .map(|c| {
                (
                    self.row(c.point, c.normal),
                    self.row(c.point, tangent(c.normal)),
                )
            })
            .collect();
        for (i, (ni, ti)) in rows.iter().enumerate() {
            p.u_n[i] = dot(ni);
            p.u_t[i] = dot(ti);
            p.contacts[i] = contacts[i].law;
            for (j, (nj, tj)) in rows.iter().enumerate() {
                p.w_nn[i][j] = w(ni, nj);
                p.w_nt[i][j] = w(ni, tj);
                p.w_tt[i][j] = w(ti, tj);
            }
        }
        p
    }

    /// The bodies after the impulses `(P_n, P_t)` at `contacts`:
    /// `q'+ = q' + M^-1 J^T P`.
    pub fn after(&self, contacts: &[Contact], impulses: &[(f64, f64)]) -> Pair {
        let inv = self.inverse_mass();
        let mut q = self.q_dot();
        for (c, (pn, pt)) in contacts.iter().zip(impulses) {
            let n = self.row(c.point, c.normal);
            let t = self.row(c.point, tangent(c.normal));
            for k in 0..6 {
                q[k] += inv[k] * (n[k] * pn + t[k] * pt);
            }
        }
        let mut out = *self;
        out.a.velocity = [q[0], q[1]];
        out.a.omega = q[2];
        out.b.velocity = [q[3], q[4]];
        out.b.omega = q[5];
        out
    }

    /// Linear momentum, kg m/s.
    pub fn momentum(&self) -> [f64; 2] {
        let (a, b) = (&self.a, &self.b);
        [
            a.mass * a.velocity[0] + b.mass * b.velocity[0],
            a.mass * a.velocity[1] + b.mass * b.velocity[1],
        ]
    }

    /// Angular momentum about the world origin, kg m^2/s:
    /// `sum J omega + C x m v`.
    pub fn angular_momentum(&self) -> f64 {
        [&self.a, &self.b]
            .iter()
            .map(|x| x.inertia * x.omega + x.mass * cross(x.centre, x.velocity))
            .sum()
    }

    /// Kinetic energy, J.
    pub fn energy(&self) -> f64 {
        [&self.a, &self.b]
            .iter()
            .map(|x| {
                0.5 * x.mass * (x.velocity[0].powi(2) + x.velocity[1].powi(2))
                    + 0.5 * x.inertia * x.omega.powi(2)
            })
            .sum()
    }
}
