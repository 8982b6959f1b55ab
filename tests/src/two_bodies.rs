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
//!
//! The closed forms ([`central_after`], [`poisson_closed_form`]) are written from the
//! textbook impulse-momentum relations of each body, not from these Jacobians: the
//! solver (`multibody_impact.rs`) and the plant (`two_bodies_plant.rs`) are checked
//! against them, with the cases below.

use shared::impact::{ContactLaw, ImpactLaw, ImpactProblem};

use shared::vec2::{cross, spin, sub};

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

/// A body at `centre` (m) with mass (kg), inertia (kg m^2), velocity (m/s) and
/// angular velocity (rad/s).
pub fn body(mass: f64, inertia: f64, centre: [f64; 2], velocity: [f64; 2], omega: f64) -> Body {
    Body {
        mass,
        inertia,
        centre,
        velocity,
        omega,
    }
}

/// Poisson's law with restitution `e` and friction `mu` (weight 1).
pub fn law(restitution: f64, friction: f64) -> ContactLaw<f64> {
    ContactLaw {
        restitution,
        friction,
        weight: 1.0,
    }
}

/// Central impacts `(m_A kg, m_B kg, e, v_A m/s, v_B m/s)`: equal masses
/// exchanging their velocities (`e = 1`), a heavy body striking a light one moving
/// towards it, a plastic impact of a light body on a heavy one.
pub const CENTRAL_CASES: [(f64, f64, f64, f64, f64); 3] = [
    (1.0, 1.0, 1.0, 2.0, 0.0),
    (2.0, 0.5, 0.3, 1.5, -0.7),
    (0.2, 5.0, 0.0, 0.4, 0.1),
];

/// A central impact: discs on the x axis at the instant they meet, A (inertia
/// 0.01 kg m^2) at the origin moving at `v_A`, B (0.02 kg m^2) 0.2 m to its right
/// at `v_B`; B's point at x = 0.1 m on A's face, normal `+x`, frictionless.
pub fn central_pair(ma: f64, mb: f64, e: f64, va: f64, vb: f64) -> (Pair, Contact) {
    let pair = Pair {
        a: body(ma, 0.01, [0.0, 0.0], [va, 0.0], 0.0),
        b: body(mb, 0.02, [0.2, 0.0], [vb, 0.0], 0.0),
    };
    let contact = Contact {
        point: [0.1, 0.0],
        normal: [1.0, 0.0],
        law: law(e, 0.0),
    };
    (pair, contact)
}

/// The velocities after a central impact along the line of centres, `[v_A', v_B']`,
/// m/s: `v_A' = v_A - (1 + e) m_B / (m_A + m_B) (v_A - v_B)`, `v_B' = v_B + (1 + e)
/// m_A / (m_A + m_B) (v_A - v_B)` (Poisson and Newton agree here; Stronge, *Impact
/// Mechanics*, 2000, sec. 3.1; Goldsmith, *Impact*, 1960, ch. 2).
pub fn central_after(ma: f64, mb: f64, e: f64, va: f64, vb: f64) -> [f64; 2] {
    let closing = va - vb;
    [
        va - (1.0 + e) * mb / (ma + mb) * closing,
        vb + (1.0 + e) * ma / (ma + mb) * closing,
    ]
}

/// The kinetic energy a central impact takes, J: `(1 - e^2) m_A m_B (v_A -
/// v_B)^2 / (2 (m_A + m_B))` (Stronge 2000, sec. 3.1; Goldsmith 1960, ch. 2).
pub fn central_loss(ma: f64, mb: f64, e: f64, va: f64, vb: f64) -> f64 {
    (1.0 - e * e) * ma * mb * (va - vb).powi(2) / (2.0 * (ma + mb))
}

/// An off-centre impact: a slab A falling onto a bar B below it at a corner, both
/// turning; the face on A's underside, the point on B, so the normal from A
/// towards B points down. Frictionless, `e = 0.4`.
pub fn off_centre_pair() -> (Pair, Contact) {
    let pair = Pair {
        a: body(1.2, 0.015, [0.05, 0.3], [0.1, -0.8], 1.5),
        b: body(3.0, 0.04, [-0.1, 0.0], [0.0, 0.2], -0.5),
    };
    let contact = Contact {
        point: [0.12, 0.1],
        normal: [0.0, -1.0],
        law: law(0.4, 0.0),
    };
    (pair, contact)
}

/// An impact with friction where the slip never stops: B slides fast along A's
/// top face while they close; `e = 0.5`, `mu = 0.2`.
pub fn slipping_pair() -> (Pair, Contact) {
    let pair = Pair {
        a: body(2.0, 0.03, [0.0, 0.0], [0.0, 0.0], 0.0),
        b: body(0.5, 0.004, [0.05, 0.15], [-3.0, -0.6], 2.0),
    };
    let contact = Contact {
        point: [0.02, 0.1],
        normal: [0.0, 1.0],
        law: law(0.5, 0.2),
    };
    (pair, contact)
}

/// Poisson's closed form of one contact between the two bodies, and what it gives.
#[derive(Clone, Copy, Debug)]
pub struct ClosedForm {
    /// The normal relative velocity before, m/s.
    pub u_n: f64,
    /// The tangential relative velocity before, m/s.
    pub u_t: f64,
    /// `W_nn`, 1/kg: `1 / W_nn` is the effective mass along the normal, kg.
    pub w_nn: f64,
    /// `W_nt`, 1/kg.
    pub w_nt: f64,
    /// `W_tt`, 1/kg.
    pub w_tt: f64,
    /// The impulse on B along `n`, N s (its opposite on A).
    pub normal_impulse: f64,
    /// The impulse on B along `t`, N s (its opposite on A).
    pub tangential_impulse: f64,
    /// The tangential relative velocity after, m/s (its normal one is `-e u_n`).
    pub u_t_after: f64,
    /// Both bodies after.
    pub after: Pair,
}

/// The relative velocity `v_B(P) - v_A(P)` at the world point `p`, m/s, with
/// `v_X(P) = v_X + omega_X x (P - C_X)`.
pub fn relative_velocity(pair: &Pair, p: [f64; 2]) -> [f64; 2] {
    let (a, b) = (&pair.a, &pair.b);
    let sa = spin(a.omega, sub(p, a.centre));
    let sb = spin(b.omega, sub(p, b.centre));
    [
        b.velocity[0] + sb[0] - a.velocity[0] - sa[0],
        b.velocity[1] + sb[1] - a.velocity[1] - sa[1],
    ]
}

/// Both bodies after the impulse `impulse` (N s, world) on B at the world point
/// `p` and its opposite on A, each body's impulse-momentum relations: `m_B dv_B =
/// Pi`, `J_B d omega_B = r_B x Pi`, `m_A dv_A = -Pi`, `J_A d omega_A = -r_A x Pi`
/// (`r_X = P - C_X`; Stronge 2000, ch. 4).
pub fn struck(pair: &Pair, p: [f64; 2], impulse: [f64; 2]) -> Pair {
    let mut out = *pair;
    for (x, sign) in [(&mut out.a, -1.0), (&mut out.b, 1.0)] {
        let r = sub(p, x.centre);
        x.velocity[0] += sign * impulse[0] / x.mass;
        x.velocity[1] += sign * impulse[1] / x.mass;
        x.omega += sign * cross(r, impulse) / x.inertia;
    }
    out
}

/// Poisson's law at one contact, the slip keeping its sign `s` throughout (the
/// paper's case 1; frictionless impacts among them, `mu = 0`), in closed form:
///
/// - the effective inverse masses along the normal and tangent, 1/kg (Stronge
///   2000, ch. 4, for a planar pair): `W_nn = 1/m_A + 1/m_B + (r_A x n)^2 / J_A +
///   (r_B x n)^2 / J_B`, `W_tt` likewise with `t`, `W_nt = (r_A x n)(r_A x t) / J_A
///   + (r_B x n)(r_B x t) / J_B`;
/// - the normal impulse, N s: `P_n = (1 + e) (-u_n) / (W_nn - s mu W_nt)` (the
///   compression impulse `-u_n / (W_nn - s mu W_nt)` times `1 + e`), the friction
///   `P_t = -s mu P_n`; frictionless, `P_n = (1 + e) m_eff (-u_n)`, `m_eff = 1 /
///   W_nn`;
/// - the slip after, m/s: `u_t' = u_t + (W_nt - s mu W_tt) P_n`; the form holds
///   while `s u_t' > 0` (the caller checks it);
/// - the bodies after: [`struck`] with `P_n n + P_t t`.
pub fn poisson_closed_form(pair: &Pair, contact: &Contact) -> ClosedForm {
    let (a, b) = (&pair.a, &pair.b);
    let (p, n) = (contact.point, contact.normal);
    let t = tangent(n);
    let (ra, rb) = (sub(p, a.centre), sub(p, b.centre));
    let rel = relative_velocity(pair, p);
    let (u_n, u_t) = (rel[0] * n[0] + rel[1] * n[1], rel[0] * t[0] + rel[1] * t[1]);
    let inv = 1.0 / a.mass + 1.0 / b.mass;
    let w_nn = inv + cross(ra, n).powi(2) / a.inertia + cross(rb, n).powi(2) / b.inertia;
    let w_nt = cross(ra, n) * cross(ra, t) / a.inertia + cross(rb, n) * cross(rb, t) / b.inertia;
    let w_tt = inv + cross(ra, t).powi(2) / a.inertia + cross(rb, t).powi(2) / b.inertia;
    let (e, mu) = (contact.law.restitution, contact.law.friction);
    let s = if mu > 0.0 { u_t.signum() } else { 0.0 };
    let normal_impulse = (1.0 + e) * (-u_n) / (w_nn - s * mu * w_nt);
    let tangential_impulse = -s * mu * normal_impulse;
    let impulse = [
        normal_impulse * n[0] + tangential_impulse * t[0],
        normal_impulse * n[1] + tangential_impulse * t[1],
    ];
    ClosedForm {
        u_n,
        u_t,
        w_nn,
        w_nt,
        w_tt,
        normal_impulse,
        tangential_impulse,
        u_t_after: u_t + (w_nt - s * mu * w_tt) * normal_impulse,
        after: struck(pair, p, impulse),
    }
}
