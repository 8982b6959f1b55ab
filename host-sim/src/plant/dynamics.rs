//! Equations of motion of the bodies with their unbalance rotors, in the
//! generalized coordinates of [`super::model`] (`q = (x, y, theta, phi_1, phi_2)`
//! for a single platform).
//!
//! Every mass is a point with a Jacobian: a body's centre of mass (mass `m_b`,
//! inertia `I_b` turning at `theta_b'`) and each rotor's eccentric mass `m_k` at
//! `eps_k = e_k (cos(theta_b + phi_k), sin(theta_b + phi_k))` from its axis, the
//! rotor (armature and hub, inertia `I_k`) turning at `theta_b' + phi_k'`. A point
//! `p = base + sum_s w_s` (the segments of its chain, [`Chain`]) moves at
//! `v = J q'` with one column per coordinate,
//!
//! ```text
//!   d/dx = (1, 0),  d/dy = (0, 1)  (a free root),   d/dtheta_a = sum of z x w_s over the segments turning with theta_a
//! ```
//!
//! and accelerates at `J q'' + b` with the velocity-product term
//! `b = -sum_s omega_s^2 w_s` (`omega_s` the segment's angular velocity).
//! Lagrange's equations (Goldstein, *Classical Mechanics*, ch. 1; d'Alembert for
//! point masses) give
//!
//! ```text
//!   M(q) q'' = Q_g + Q_motor + Q_spring + J_c^T lambda - sum_e m_e J_e^T b_e
//!   M = sum_e (m_e J_e^T J_e + I_e s_e s_e^T)
//! ```
//!
//! with `s_e` the coordinates the element turns with (`e_theta_b`, plus `e_phi_k`
//! for a rotor), so the coupling is complete: the exciting force of an eccentric
//! `m e (phi'^2 cos phi + phi'' sin phi, ...)` is in the `m_k J_k^T b_k` and `M`
//! terms, and the bodies' accelerations and gravity act back on the rotors through
//! the same terms (Sommerfeld effect, self-synchronisation; Blekhman, *Vibrational
//! Mechanics*, 2000). A motor's torque acts between its body and its rotor, so its
//! generalized force is on `phi_k` only; a joint's spring-damper acts on the two
//! bodies' angles, equal and opposite.
//!
//! The single platform's terms come out in the same floating-point operations, in
//! the same order, as the one-body closed forms (a machine file without further
//! bodies gives the same numbers to the bit).

use super::model::{Face, Mount, OneFreeBody, PlantModel, NY};
use crate::machine::bodies::{MAX_BODIES, MAX_DOF, MAX_ROTORS};
use shared::vec2::{cross, dot, perp, rotate};

/// A vector of generalized coordinates (a machine uses the first
/// [`PlantModel::dof`]).
pub type Vector = [f64; MAX_DOF];

/// One segment of a point's chain: a world vector turning at `v[angle]` (plus
/// `v[spin]`, a rotor's eccentric angle, for an eccentric).
#[derive(Clone, Copy, Debug)]
struct Segment {
    w: [f64; 2],
    angle: usize,
    spin: Option<usize>,
}

impl Segment {
    /// Its angular velocity, rad/s.
    #[inline]
    fn omega(&self, v: &Vector) -> f64 {
        match self.spin {
            None => v[self.angle],
            Some(k) => v[self.angle] + v[k],
        }
    }
}

/// A point of the machine at a configuration: where it is, and the chain of
/// segments its velocity is made of: the hinges from its tree's root to its body
/// ([`Pose`] keeps them), the segment from its body's reference point, and for an
/// eccentric the eccentric's own. It borrows the pose: building one copies
/// nothing of the chain (chains are built in the innermost loops).
#[derive(Clone, Copy, Debug)]
pub struct Chain<'a> {
    /// World position, m.
    pub p: [f64; 2],
    /// The free root's `x` coordinate, if the tree has one.
    trans: Option<usize>,
    model: &'a PlantModel,
    pose: &'a Pose,
    /// The bodies from the tree's root to the point's body.
    path: &'a [usize],
    own: Segment,
    eccentric: Option<Segment>,
}

impl Chain<'_> {
    /// Calls `f` with each segment from the root out: the hinges, the body's, the
    /// eccentric's.
    #[inline(always)]
    fn each_segment(&self, mut f: impl FnMut(&Segment)) {
        for pair in self.path.windows(2) {
            f(&Segment {
                w: self.pose.hinge[pair[1]],
                angle: self.model.bodies[pair[0]].angle,
                spin: None,
            });
        }
        f(&self.own);
        if let Some(e) = &self.eccentric {
            f(e);
        }
    }

    /// Its velocity `J q'`, m/s.
    pub fn velocity(&self, v: &Vector) -> [f64; 2] {
        let mut u = match self.trans {
            Some(x) => [v[x], v[x + 1]],
            None => [0.0; 2],
        };
        self.each_segment(|s| {
            let w = s.omega(v);
            u[0] -= w * s.w[1];
            u[1] += w * s.w[0];
        });
        u
    }

    /// The velocity-product part of its acceleration along `d`,
    /// `d . b = -sum_s omega_s^2 d . w_s`, m/s^2.
    pub fn bias_along(&self, d: [f64; 2], v: &Vector) -> f64 {
        let mut b = 0.0;
        self.each_segment(|s| {
            let w = s.omega(v);
            b -= (w * w) * dot(d, s.w);
        });
        b
    }

    /// Adds `sign d . J` to `row` (the Jacobian row of its velocity along `d`).
    pub fn add_row(&self, d: [f64; 2], sign: f64, row: &mut Vector) {
        if let Some(x) = self.trans {
            row[x] += sign * d[0];
            row[x + 1] += sign * d[1];
        }
        self.each_segment(|s| {
            let c = sign * cross(s.w, d);
            row[s.angle] += c;
            if let Some(k) = s.spin {
                row[k] += c;
            }
        });
    }

    /// The columns of its angular coordinates, each once, in increasing order
    /// (parents' angles before children's, rotors' last): `(coordinate, z x w)`
    /// summed over the segments turning with it.
    #[inline(always)]
    fn columns(&self, cols: &mut Columns) -> usize {
        let mut n = 0;
        let mut add = |i: usize, c: [f64; 2]| {
            if n > 0 && cols[n - 1].0 == i {
                cols[n - 1].1 = [cols[n - 1].1[0] + c[0], cols[n - 1].1[1] + c[1]];
            } else {
                cols[n] = (i, c);
                n += 1;
            }
        };
        self.each_segment(|s| add(s.angle, perp(s.w)));
        // The eccentric's own angle after every body angle.
        if let Some(Segment {
            w, spin: Some(k), ..
        }) = self.eccentric
        {
            add(k, perp(w));
        }
        n
    }
}

/// A point's Jacobian columns, `(coordinate, column)` ([`Chain::columns`]).
type Columns = [(usize, [f64; 2]); MAX_BODIES + 2];

/// Where the bodies are at a configuration: each one's angle (sine, cosine),
/// reference point (world, m) and hinge (from its parent's reference point to
/// its own, world, m). No mass matrix: the event functions use this alone.
#[derive(Clone, Copy, Debug)]
pub struct Pose {
    cs: [(f64, f64); MAX_BODIES],
    reference: [[f64; 2]; MAX_BODIES],
    hinge: [[f64; 2]; MAX_BODIES],
}

impl Pose {
    /// The pose at `q`.
    pub fn new(model: &PlantModel, q: &Vector) -> Self {
        let mut pose = Pose {
            cs: [(0.0, 1.0); MAX_BODIES],
            reference: [[0.0; 2]; MAX_BODIES],
            hinge: [[0.0; 2]; MAX_BODIES],
        };
        for &b in &model.order {
            let body = &model.bodies[b];
            pose.cs[b] = q[body.angle].sin_cos();
            pose.reference[b] = match body.mount {
                Mount::Free { x } => [q[x], q[x + 1]],
                Mount::Pinned { pivot } => pivot,
                Mount::Child { parent, joint } => {
                    let r = rotate(pose.cs[parent], joint);
                    pose.hinge[b] = r;
                    let o = pose.reference[parent];
                    [o[0] + r[0], o[1] + r[1]]
                }
            };
        }
        pose
    }

    /// The point of body `b` at `w` (world, m) from its reference point.
    fn chain<'a>(&'a self, model: &'a PlantModel, b: usize, w: [f64; 2]) -> Chain<'a> {
        let path = &model.bodies[b].chain[..];
        let trans = match model.bodies[path[0]].mount {
            Mount::Free { x } => Some(x),
            _ => None,
        };
        let o = self.reference[b];
        Chain {
            p: [o[0] + w[0], o[1] + w[1]],
            trans,
            model,
            pose: self,
            path,
            own: Segment {
                w,
                angle: model.bodies[b].angle,
                spin: None,
            },
            eccentric: None,
        }
    }

    /// The point of body `b` at `r` from its reference point (body frame, m).
    pub fn point<'a>(&'a self, model: &'a PlantModel, b: usize, r: [f64; 2]) -> Chain<'a> {
        self.chain(model, b, rotate(self.cs[b], r))
    }

    /// The material point of body `b` that is at world position `p` now.
    pub fn point_at<'a>(&'a self, model: &'a PlantModel, b: usize, p: [f64; 2]) -> Chain<'a> {
        let o = self.reference[b];
        self.chain(model, b, [p[0] - o[0], p[1] - o[1]])
    }

    /// Body `b`'s centre of mass.
    pub fn centre_of_mass<'a>(&'a self, model: &'a PlantModel, b: usize) -> Chain<'a> {
        self.point(model, b, model.bodies[b].com)
    }

    /// Rotor `k`'s eccentric mass at `eps` from its axis (world, m;
    /// [`eccentric_offset`]), turning at `theta_b' + phi_k'`.
    fn eccentric<'a>(&'a self, model: &'a PlantModel, k: usize, eps: [f64; 2]) -> Chain<'a> {
        let rotor = &model.rotors[k];
        let b = rotor.body;
        let mut chain = self.point(model, b, rotor.axis);
        chain.p = [chain.p[0] + eps[0], chain.p[1] + eps[1]];
        chain.eccentric = Some(Segment {
            w: eps,
            angle: model.bodies[b].angle,
            spin: Some(rotor.phi),
        });
        chain
    }

    /// The gap of contact `j` along its face's normal, m (negative: penetration):
    /// [`ContactKinematics::gap`] without the Jacobian rows and velocities
    /// (`gap_along`, the same formula).
    pub fn gap(&self, model: &PlantModel, j: usize) -> f64 {
        let c = &model.contacts[j];
        let point = self.point(model, c.body, c.point);
        match c.face {
            Face::Fundament => {
                let (n, g) = (model.normal, model.ground_point);
                gap_along(n, point.p, g)
            }
            Face::Body {
                body: a,
                point: f,
                normal,
            } => {
                let n = rotate(self.cs[a], normal);
                let face = self.point(model, a, f);
                gap_along(n, point.p, face.p)
            }
        }
    }

    /// The kinematics of contact `j` at velocities `v` (this pose's `q`).
    pub fn contact(&self, model: &PlantModel, j: usize, v: &Vector) -> ContactKinematics {
        let c = &model.contacts[j];
        let point = self.point(model, c.body, c.point);
        let mut k = ContactKinematics::default();
        match c.face {
            Face::Fundament => {
                let (n, t) = (model.normal, model.tangent);
                point.add_row(n, 1.0, &mut k.j_n);
                point.add_row(t, 1.0, &mut k.j_t);
                let g = model.ground_point;
                k.gap = gap_along(n, point.p, g);
                k.bias_n = point.bias_along(n, v);
                k.bias_t = point.bias_along(t, v);
            }
            Face::Body {
                body: a,
                point: f,
                normal,
            } => {
                // The face turns with body a: n = R(theta_a) n_a, t = z x n. With
                // d = P - F (F the face's point), g = n . d and the relative velocity
                // at the contact u = v_P - v_C (C: a's material point at P),
                //   g' = n . u,  u_t = t . u,
                //   g'' = n . (J_P - J_C) q'' + n . (b_P - b_F) + 2 w_a t . (v_P - v_F) - w_a^2 g,
                //   u_t' = t . (J_P - J_C) q'' + t . (b_P - b_F) - w_a n . (v_P - v_F) - w_a g'.
                let n = rotate(self.cs[a], normal);
                let t = perp(n);
                let face = self.point(model, a, f);
                let coincident = self.point_at(model, a, point.p);
                point.add_row(n, 1.0, &mut k.j_n);
                coincident.add_row(n, -1.0, &mut k.j_n);
                point.add_row(t, 1.0, &mut k.j_t);
                coincident.add_row(t, -1.0, &mut k.j_t);
                k.gap = gap_along(n, point.p, face.p);
                let (vp, vf) = (point.velocity(v), face.velocity(v));
                let rel = [vp[0] - vf[0], vp[1] - vf[1]];
                let wa = v[model.bodies[a].angle];
                let u_n = row_dot(&k.j_n, v, model.dof);
                k.bias_n = point.bias_along(n, v) - face.bias_along(n, v) + 2.0 * wa * dot(t, rel)
                    - wa * wa * k.gap;
                k.bias_t =
                    point.bias_along(t, v) - face.bias_along(t, v) - wa * dot(n, rel) - wa * u_n;
            }
        }
        k.u_n = row_dot(&k.j_n, v, model.dof);
        k.u_t = row_dot(&k.j_t, v, model.dof);
        k
    }
}

// A body's motion is the model's reading of a state, but away from the free
// root's own coordinates it needs a pose: it lives here, beside `Pose`, so that
// the model stays below the dynamics (`model.rs` uses no sibling).
impl PlantModel {
    /// Body `b`'s motion in state `y`: centre of mass (m, m), angle (rad), its
    /// velocity (m/s, m/s) and angular velocity (rad/s).
    pub fn body_motion(&self, b: usize, y: &[f64; NY]) -> [f64; 6] {
        let n = self.dof;
        let body = &self.bodies[b];
        let (angle, omega) = (y[body.angle], y[n + body.angle]);
        if let Mount::Free { x } = body.mount {
            return [y[x], y[x + 1], angle, y[n + x], y[n + x + 1], omega];
        }
        let (q, v) = (self.q(y), self.v(y));
        let pose = Pose::new(self, &q);
        let com = pose.centre_of_mass(self, b);
        let u = com.velocity(&v);
        [com.p[0], com.p[1], angle, u[0], u[1], omega]
    }
}

/// The gap of point `p` to the face through `f` with unit normal `n`,
/// `n . (p - f)`, m: one formula for [`Pose::gap`] and [`Pose::contact`].
#[inline]
fn gap_along(n: [f64; 2], p: [f64; 2], f: [f64; 2]) -> f64 {
    dot(n, [p[0] - f[0], p[1] - f[1]])
}

/// Rotor `k`'s eccentric at `q`, from its axis (world, m):
/// `eps = e (cos(theta_b + phi_k), sin(theta_b + phi_k))`.
fn eccentric_offset(model: &PlantModel, k: usize, q: &Vector) -> [f64; 2] {
    let rotor = &model.rotors[k];
    let angle = model.bodies[rotor.body].angle;
    let (s, c) = (q[angle] + q[rotor.phi]).sin_cos();
    let e = rotor.eccentricity;
    [e * c, e * s]
}

/// `j . v` over the first `n` coordinates, the machine's (the rest of both are
/// zero and would add only zeros).
#[inline]
pub fn row_dot(j: &Vector, v: &Vector, n: usize) -> f64 {
    let mut s = 0.0;
    for (ji, vi) in j[..n].iter().zip(&v[..n]) {
        s += ji * vi;
    }
    s
}

/// A contact point's kinematics at a state.
#[derive(Clone, Copy, Debug, Default)]
pub struct ContactKinematics {
    /// Normal Jacobian row: `u_n = j_n . q'`.
    pub j_n: Vector,
    /// Tangential Jacobian row: `u_t = j_t . q'`.
    pub j_t: Vector,
    /// Gap to the face along its normal, m (negative: penetration).
    pub gap: f64,
    /// Normal velocity, m/s.
    pub u_n: f64,
    /// Tangential velocity, m/s.
    pub u_t: f64,
    /// Velocity-product part of the normal acceleration, m/s^2.
    pub bias_n: f64,
    /// Velocity-product part of the tangential acceleration, m/s^2.
    pub bias_t: f64,
}

/// A point mass of the machine at a configuration: a body's centre of mass or a
/// rotor's eccentric mass, with the inertia that turns with it.
#[derive(Clone, Copy, Debug)]
struct Element<'a> {
    chain: Chain<'a>,
    mass: f64,
    /// Inertia about the point, kg m^2, turning with `spin` (a body's angle; a
    /// rotor's body angle plus its eccentric angle).
    inertia: f64,
    spin: (usize, Option<usize>),
    /// The rotor it is, if it is one.
    rotor: Option<usize>,
}

impl Element<'_> {
    fn spins_with(&self, i: usize) -> bool {
        self.spin.0 == i || self.spin.1 == Some(i)
    }
}

/// Everything that depends on the configuration: the mass matrix (factored) and
/// the point masses' chains.
#[derive(Clone, Debug)]
pub struct Frame {
    /// The mass matrix, kg / kg m / kg m^2 (the first [`PlantModel::dof`] rows
    /// and columns).
    pub mass: [[f64; MAX_DOF]; MAX_DOF],
    /// Where the bodies are.
    pub pose: Pose,
    /// Coordinates: all, the bodies' (the rotors' follow).
    n: usize,
    nb: usize,
    /// The Cholesky factor (lower) of the mass matrix with the held coordinates'
    /// rows and columns replaced by the identity when some are held; else of the
    /// bodies' Schur complement `S = A - B D^-1 B^T` (see [`Frame::solve`]) unless
    /// that is 3x3.
    factor: [[f64; MAX_DOF]; MAX_DOF],
    /// `S^-1` by the adjugate where the bodies have three coordinates (one free
    /// body, the common case).
    schur_inv: [[f64; 3]; 3],
    /// Each rotor's eccentric from its axis (world, m).
    eps: [[f64; 2]; MAX_ROTORS],
    /// Coordinates held still.
    locked: [bool; MAX_DOF],
    /// Some coordinate is held: solve with the full Cholesky factor.
    any_locked: bool,
}

impl Frame {
    /// The configuration-dependent terms at `q`, with the coordinates marked in
    /// `locked` held (their rows and columns of the factored mass matrix replaced
    /// by the identity, so that no force or impulse moves them; [`Frame::mass`]
    /// stays the true mass matrix).
    pub fn locked(model: &PlantModel, q: &Vector, locked: &[bool; MAX_DOF]) -> Self {
        Self::assemble(model, q, locked, None).0
    }

    /// Holds the coordinates marked in `locked` ([`Frame::locked`]).
    fn hold(&mut self, locked: &[bool; MAX_DOF]) {
        if locked.iter().any(|l| *l) {
            let f = self;
            let mut m = f.mass;
            for i in 0..f.n {
                if locked[i] {
                    for j in 0..f.n {
                        m[i][j] = 0.0;
                        m[j][i] = 0.0;
                    }
                    m[i][i] = 1.0;
                }
            }
            cholesky_in_place(&mut m, f.n);
            f.factor = m;
            f.locked = *locked;
            f.any_locked = true;
        }
    }

    /// The configuration-dependent terms at `q`.
    pub fn new(model: &PlantModel, q: &Vector) -> Self {
        Self::assemble(model, q, &[false; MAX_DOF], None).0
    }

    /// [`Frame::new`] with the generalized forces without contacts at velocities
    /// `v` and motor torques `tau`: gravity, the motor torques (on each `phi_k`,
    /// N m), the joints' spring-dampers, minus the velocity-product terms,
    ///
    /// ```text
    ///   Q = sum_e J_e^T m_e (g - b_e) + Q_spring + tau on phi
    /// ```
    ///
    /// (on a free root's `x, y`: its tree's weight plus `sum_e m_e (a_e - g)`,
    /// `a_e = g - b_e`), assembled in the same pass over the point masses as the
    /// mass matrix (each one's chain and columns built once).
    pub fn with_forces(model: &PlantModel, q: &Vector, v: &Vector, tau: &[f64]) -> (Self, Vector) {
        Self::assemble(model, q, &[false; MAX_DOF], Some((v, tau)))
    }

    /// The frame at `q` with the coordinates `locked` held ([`Frame::locked`])
    /// and, given `(v, tau)`, the generalized forces ([`Frame::with_forces`];
    /// zero without).
    fn assemble(
        model: &PlantModel,
        q: &Vector,
        locked: &[bool; MAX_DOF],
        motion: Option<(&Vector, &[f64])>,
    ) -> (Self, Vector) {
        let mut frame = Frame::empty(model);
        let forces = frame.assemble_into(model, q, locked, motion);
        (frame, forces)
    }

    /// A frame of `model` with every term zero, to be filled by
    /// [`Frame::assemble_into`].
    pub fn empty(model: &PlantModel) -> Self {
        Frame {
            mass: [[0.0; MAX_DOF]; MAX_DOF],
            pose: Pose::new(model, &[0.0; MAX_DOF]),
            n: model.dof,
            nb: model.body_dof,
            factor: [[0.0; MAX_DOF]; MAX_DOF],
            schur_inv: [[0.0; 3]; 3],
            eps: [[0.0; 2]; MAX_ROTORS],
            locked: [false; MAX_DOF],
            any_locked: false,
        }
    }

    /// Fills this frame of `model` (made by [`Frame::empty`] for the same
    /// model) at `q` with the coordinates `locked` held, as [`Frame::locked`] and
    /// [`Frame::with_forces`] make theirs, in place: only the machine's `n x n`
    /// block is written, nothing of the capacity is zeroed or copied (this runs at
    /// every evaluation of the equations of motion). Returns the generalized forces
    /// at `motion = (v, tau)` (zero without). One free body carrying its rotors
    /// (the reference machine) takes the closed forms (`Frame::one_free_body_into`);
    /// every other machine the generic pass over its point masses
    /// (`Frame::generic_into`), which the tests hold the closed forms to.
    pub fn assemble_into(
        &mut self,
        model: &PlantModel,
        q: &Vector,
        locked: &[bool; MAX_DOF],
        motion: Option<(&Vector, &[f64])>,
    ) -> Vector {
        let frame = self;
        let (n, nb) = (model.dof, model.body_dof);
        debug_assert!(frame.n == n && frame.nb == nb, "a frame of another model");
        frame.pose = Pose::new(model, q);
        for k in 0..model.rotors.len() {
            frame.eps[k] = eccentric_offset(model, k, q);
        }
        frame.locked = [false; MAX_DOF];
        frame.any_locked = false;

        let mut forces = match &model.one_free_body() {
            Some(c) => frame.one_free_body_into(c, model.gravity, motion),
            None => frame.generic_into(model, motion),
        };
        let m = &mut frame.mass;
        for i in 0..n {
            for j in 0..i {
                m[i][j] = m[j][i];
            }
        }
        // The Schur complement in the factor's place, then factored there (or
        // inverted by the adjugate when 3x3).
        frame.schur_into_factor();
        if nb == 3 {
            frame.schur_inv = inverse3(&frame.factor);
        } else {
            cholesky_in_place(&mut frame.factor, nb);
        }
        if let Some((v, _)) = motion {
            add_spring_forces(model, q, v, &mut forces);
        }
        frame.hold(locked);
        forces
    }

    /// The mass matrix's upper triangle (the first `n` rows and columns) and the
    /// generalized forces at `motion` (zero without) of any machine:
    /// `M = sum_e (m_e J_e^T J_e + I_e s_e s_e^T)` over the point masses, the forces
    /// element by element alongside ([`Frame::with_forces`]).
    fn generic_into(&mut self, model: &PlantModel, motion: Option<(&Vector, &[f64])>) -> Vector {
        let frame = self;
        let n = model.dof;
        let mut forces = [0.0; MAX_DOF];
        if motion.is_some() {
            forces = root_weights(model);
        }
        let m = &mut frame.mass;
        for row in m.iter_mut().take(n) {
            row[..n].fill(0.0);
        }
        for i in 0..model.bodies.len() + model.rotors.len() {
            let e = &element(model, &frame.pose, &frame.eps, i);
            let mut cols: Columns = [(0, [0.0; 2]); MAX_BODIES + 2];
            let nc = e.chain.columns(&mut cols);
            let cols = &cols[..nc];
            if let Some((v, tau)) = motion {
                add_element_forces(model, e, cols, v, tau, &mut forces);
            }
            if let Some(x) = e.chain.trans {
                m[x][x] += e.mass;
                m[x + 1][x + 1] += e.mass;
                for &(i, c) in cols {
                    m[x][i] += e.mass * c[0];
                    m[x + 1][i] += e.mass * c[1];
                }
            }
            for (a, &(i, ci)) in cols.iter().enumerate() {
                for &(j, cj) in &cols[a..] {
                    let spin = if e.spins_with(i) && e.spins_with(j) {
                        e.inertia
                    } else {
                        0.0
                    };
                    m[i][j] += e.mass * dot(ci, cj) + spin;
                }
            }
        }
        forces
    }

    /// [`Frame::generic_into`] in closed form for one free body carrying its
    /// rotors (`c`, the constants; the pose and eccentrics already set). With the
    /// body's centre of mass at `w_b = R(theta) com` and rotor `k`'s eccentric at
    /// `w_k = R(theta) axis_k + eps_k` from the reference point (`eps_k` from its
    /// axis, turning at `theta' + phi_k'`), `z x w = (-w_y, w_x)`, `M_tot` the
    /// whole mass and `I_tot` every inertia:
    ///
    /// ```text
    ///   M_xx = M_yy = M_tot,   M_x,theta = -sum_e m_e w_e,y,   M_y,theta = sum_e m_e w_e,x
    ///   M_theta,theta = I_tot + sum_e m_e |w_e|^2
    ///   M_x,phi_k = -m_k eps_k,y,   M_y,phi_k = m_k eps_k,x
    ///   M_theta,phi_k = m_k w_k . eps_k + I_k,   M_phi_k,phi_k = m_k |eps_k|^2 + I_k
    /// ```
    ///
    /// and the forces `Q = sum_e J_e^T m_e a_e` with `a_b = g + theta'^2 w_b`,
    /// `a_k = g + theta'^2 R(theta) axis_k + (theta' + phi_k')^2 eps_k` (the
    /// velocity-product terms moved to the right-hand side), plus `tau_k` on
    /// `phi_k`. The same sums as the generic pass, without its chains.
    fn one_free_body_into(
        &mut self,
        c: &OneFreeBody,
        g: [f64; 2],
        motion: Option<(&Vector, &[f64])>,
    ) -> Vector {
        let (x, y, th) = (c.x, c.x + 1, c.theta);
        let cs = self.pose.cs[0];
        let n = self.n;
        let m = &mut self.mass;
        for row in m.iter_mut().take(n) {
            row[..n].fill(0.0);
        }
        let mut set = |i: usize, j: usize, value: f64| {
            m[i][j] = value;
            m[j][i] = value;
        };
        set(x, x, c.total_mass);
        set(y, y, c.total_mass);
        let mut forces = [0.0; MAX_DOF];
        let w_th2 = motion.map(|(v, _)| v[th] * v[th]);
        // The body's centre of mass.
        let wb = rotate(cs, c.com);
        let mut m_w = [c.mass * wb[0], c.mass * wb[1]];
        let mut m_th = c.total_inertia + c.mass * dot(wb, wb);
        if let Some(w2) = w_th2 {
            let fe = [c.mass * (g[0] + w2 * wb[0]), c.mass * (g[1] + w2 * wb[1])];
            forces[x] = c.total_mass * g[0] + (fe[0] - c.mass * g[0]);
            forces[y] = c.total_mass * g[1] + (fe[1] - c.mass * g[1]);
            forces[th] = cross(wb, fe);
        }
        // Each rotor's eccentric.
        for (k, &(phi, axis, mass, inertia)) in c.rotors[..n - 3].iter().enumerate() {
            let (ra, eps) = (rotate(cs, axis), self.eps[k]);
            let w = [ra[0] + eps[0], ra[1] + eps[1]];
            m_w = [m_w[0] + mass * w[0], m_w[1] + mass * w[1]];
            m_th += mass * dot(w, w);
            set(x, phi, -mass * eps[1]);
            set(y, phi, mass * eps[0]);
            set(th, phi, mass * dot(w, eps) + inertia);
            set(phi, phi, mass * dot(eps, eps) + inertia);
            if let (Some(w2), Some((v, tau))) = (w_th2, motion) {
                let s = v[th] + v[phi];
                let s2 = s * s;
                let a = [
                    g[0] + w2 * ra[0] + s2 * eps[0],
                    g[1] + w2 * ra[1] + s2 * eps[1],
                ];
                let fe = [mass * a[0], mass * a[1]];
                forces[x] += fe[0] - mass * g[0];
                forces[y] += fe[1] - mass * g[1];
                forces[th] += cross(w, fe);
                forces[phi] = cross(eps, fe) + tau[k];
            }
        }
        set(x, th, -m_w[1]);
        set(y, th, m_w[0]);
        set(th, th, m_th);
        forces
    }

    /// The bodies' Schur complement `S = A - B D^-1 B^T` of
    /// `M = [A B; B^T D]`, `D` the rotors' block: diagonal (two eccentrics never
    /// share a coordinate).
    fn schur_into_factor(&mut self) {
        // Symmetric to the bit (M is mirrored, and m_ir m_jr = m_jr m_ir exactly):
        // the upper triangle computed, the lower copied.
        let (m, nb) = (&self.mass, self.nb);
        for i in 0..nb {
            for j in i..nb {
                let mut x = m[i][j];
                for r in nb..self.n {
                    x -= m[i][r] * m[j][r] / m[r][r];
                }
                self.factor[i][j] = x;
                self.factor[j][i] = x;
            }
        }
    }

    /// `M^-1 b` (held coordinates: zero).
    ///
    /// Nothing held: block elimination of the rotors, whose block `D` is diagonal
    /// (`M = [A B; B^T D]`, `A` the bodies' block):
    /// `x_b = S^-1 (b_b - B D^-1 b_r)`, `x_r = D^-1 (b_r - B^T x_b)`.
    pub fn solve(&self, b: &Vector) -> Vector {
        let (n, nb) = (self.n, self.nb);
        let mut x = [0.0; MAX_DOF];
        if !self.any_locked {
            let m = &self.mass;
            let mut br = [0.0; MAX_ROTORS];
            for r in nb..n {
                br[r - nb] = b[r] / m[r][r];
            }
            let mut rhs = [0.0; MAX_DOF];
            for i in 0..nb {
                let mut y = b[i];
                for r in nb..n {
                    y -= m[i][r] * br[r - nb];
                }
                rhs[i] = y;
            }
            if nb == 3 {
                let si = &self.schur_inv;
                for i in 0..3 {
                    x[i] = si[i][0] * rhs[0] + si[i][1] * rhs[1] + si[i][2] * rhs[2];
                }
            } else {
                x = cholesky_solve(&self.factor, &rhs, nb, &[false; MAX_DOF]);
            }
            for r in nb..n {
                let mut y = b[r];
                for i in 0..nb {
                    y -= m[i][r] * x[i];
                }
                x[r] = y / m[r][r];
            }
            return x;
        }
        cholesky_solve(&self.factor, b, n, &self.locked)
    }

    /// Kinetic energy `q'^T M q' / 2`, J.
    pub fn kinetic_energy(&self, v: &Vector) -> f64 {
        let mut e = 0.0;
        for i in 0..self.n {
            for j in 0..self.n {
                e += v[i] * self.mass[i][j] * v[j];
            }
        }
        0.5 * e
    }

    /// Potential energy of gravity, `-sum m g . r` (zero at the origin), and of the
    /// joints' springs, `k (alpha - alpha_0)^2 / 2`, J.
    pub fn potential_energy(&self, model: &PlantModel, q: &Vector) -> f64 {
        let g = model.gravity;
        let mut e = 0.0;
        for i in 0..model.bodies.len() + model.rotors.len() {
            let el = element(model, &self.pose, &self.eps, i);
            e -= el.mass * dot(g, el.chain.p);
        }
        for s in &model.springs {
            let angle = |x: Option<usize>| x.map_or(0.0, |b| q[model.bodies[b].angle]);
            let stretch = angle(s.b) - angle(s.a) - s.rest_angle;
            e += 0.5 * s.stiffness * stretch * stretch;
        }
        e
    }

    /// The kinematics of contact point `j` at `(q, v)` (`q` this frame's).
    pub fn contact(&self, model: &PlantModel, j: usize, v: &Vector) -> ContactKinematics {
        self.pose.contact(model, j, v)
    }
}

/// Point mass `i`: the bodies' centres of mass in order, then the rotors'
/// eccentrics.
fn element<'a>(
    model: &'a PlantModel,
    pose: &'a Pose,
    eps: &[[f64; 2]; MAX_ROTORS],
    i: usize,
) -> Element<'a> {
    let nb = model.bodies.len();
    if i < nb {
        let body = &model.bodies[i];
        Element {
            chain: pose.centre_of_mass(model, i),
            mass: body.mass,
            inertia: body.inertia,
            spin: (body.angle, None),
            rotor: None,
        }
    } else {
        let k = i - nb;
        let rotor = &model.rotors[k];
        Element {
            chain: pose.eccentric(model, k, eps[k]),
            mass: rotor.mass,
            inertia: rotor.inertia,
            spin: (model.bodies[rotor.body].angle, Some(rotor.phi)),
            rotor: Some(k),
        }
    }
}

/// Gravity on each free root's `x, y`: its tree's weight, N.
fn root_weights(model: &PlantModel) -> Vector {
    let g = model.gravity;
    let mut f = [0.0; MAX_DOF];
    for &(x, mass) in &model.free_roots {
        f[x] = mass * g[0];
        f[x + 1] = mass * g[1];
    }
    f
}

/// Adds point mass `e`'s generalized force to `f`: `J_e^T m_e (g - b_e)` (its
/// columns `cols`), less the gravity already in its tree's weight on a free
/// root's `x, y`, and its motor's torque `tau` on a rotor's `phi`.
fn add_element_forces(
    model: &PlantModel,
    e: &Element,
    cols: &[(usize, [f64; 2])],
    v: &Vector,
    tau: &[f64],
    f: &mut Vector,
) {
    let g = model.gravity;
    // Force on the point mass: m (g - b), b = -sum_s omega_s^2 w_s.
    let mut a = g;
    e.chain.each_segment(|s| {
        let w = s.omega(v);
        a[0] += w * w * s.w[0];
        a[1] += w * w * s.w[1];
    });
    let fe = [e.mass * a[0], e.mass * a[1]];
    if let Some(x) = e.chain.trans {
        // Gravity's share on x, y is already in the tree's weight.
        f[x] += fe[0] - e.mass * g[0];
        f[x + 1] += fe[1] - e.mass * g[1];
    }
    for &(i, c) in cols {
        match e.rotor {
            Some(k) if i == model.rotors[k].phi => f[i] += dot(c, fe) + tau[k],
            _ => f[i] += dot(c, fe),
        }
    }
}

/// Adds the joints' spring-dampers to `f`: `-k (alpha - alpha_0) - c alpha'` on
/// the second body's angle, the reaction on the first's (`alpha` the relative
/// angle at `q`, `v`).
fn add_spring_forces(model: &PlantModel, q: &Vector, v: &Vector, f: &mut Vector) {
    for s in &model.springs {
        let angle = |x: Option<usize>| {
            x.map_or((0.0, 0.0), |b| {
                let i = model.bodies[b].angle;
                (q[i], v[i])
            })
        };
        let ((ta, wa), (tb, wb)) = (angle(s.a), angle(s.b));
        let torque = -s.stiffness * ((tb - ta) - s.rest_angle) - s.damping * (wb - wa);
        if let Some(b) = s.b {
            f[model.bodies[b].angle] += torque;
        }
        if let Some(a) = s.a {
            f[model.bodies[a].angle] -= torque;
        }
    }
}

/// The inverse of a 3x3 symmetric positive definite matrix (the first three rows
/// and columns of `s`), by the adjugate.
fn inverse3(s: &[[f64; MAX_DOF]; MAX_DOF]) -> [[f64; 3]; 3] {
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

/// The Cholesky factor (lower triangle) of the leading `n x n` block of a
/// symmetric positive definite matrix, in its place (the upper triangle is left
/// as it was and never read).
fn cholesky_in_place(l: &mut [[f64; MAX_DOF]; MAX_DOF], n: usize) {
    for i in 0..n {
        for j in 0..=i {
            let mut s = l[i][j];
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
}

/// `x = (L L^T)^-1 b` over the leading `n` coordinates, the `held` ones' right-hand
/// side taken as zero.
fn cholesky_solve(
    l: &[[f64; MAX_DOF]; MAX_DOF],
    b: &Vector,
    n: usize,
    held: &[bool; MAX_DOF],
) -> Vector {
    let mut y = [0.0; MAX_DOF];
    for i in 0..n {
        let mut s = if held[i] { 0.0 } else { b[i] };
        for k in 0..i {
            s -= l[i][k] * y[k];
        }
        y[i] = s / l[i][i];
    }
    let mut x = [0.0; MAX_DOF];
    for i in (0..n).rev() {
        let mut s = y[i];
        for k in (i + 1)..n {
            s -= l[k][i] * x[k];
        }
        x[i] = s / l[i][i];
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machine::Machine;

    /// The reference machine, with `extra` appended to its file.
    fn machine(extra: &str) -> Machine {
        let text = std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../examples/vibro-driver.toml"
        ))
        .unwrap();
        Machine::from_text("m.toml", &(text + extra), std::path::Path::new("."), &[]).unwrap()
    }

    /// The block solve, the Cholesky solve of the whole matrix, and (three bodies,
    /// bodies' coordinates 3 + 1 + 3) the Cholesky solve of the Schur complement
    /// each give `M x = b`.
    #[test]
    fn block_solve_inverts_the_mass_matrix() {
        for (name, m) in [
            ("one body", machine("")),
            (
                "three bodies",
                machine(include_str!("../../../tests/fixtures/three-bodies.toml")),
            ),
        ] {
            let model = PlantModel::new(&m);
            let n = model.dof;
            for (k, q0) in [
                [0.0, 0.03, 0.1, 0.3, -2.0, 0.7, 0.2, -1.0],
                [0.2, 0.05, -0.4, 5.0, 1.0, -0.3, 0.0, 2.0],
            ]
            .iter()
            .enumerate()
            {
                let mut q = [0.0; MAX_DOF];
                q[..n.min(8)].copy_from_slice(&q0[..n.min(8)]);
                let mut b = [0.0; MAX_DOF];
                for (i, x) in b.iter_mut().take(n).enumerate() {
                    *x = 1.0 - 0.37 * i as f64;
                }
                let fast = Frame::new(&model, &q);
                let unlocked = Frame::locked(&model, &q, &[false; MAX_DOF]);
                let mut held = Frame::new(&model, &q);
                held.factor = held.mass;
                cholesky_in_place(&mut held.factor, n);
                held.any_locked = true;
                for (how, x) in [
                    ("block", fast.solve(&b)),
                    ("cholesky", held.solve(&b)),
                    ("unlocked", unlocked.solve(&b)),
                ] {
                    for i in 0..n {
                        let r: f64 = (0..n).map(|j| fast.mass[i][j] * x[j]).sum::<f64>() - b[i];
                        assert!(
                            r.abs() < 1e-12 * (1.0 + b[i].abs()),
                            "{name} case {k} {how}: residual {r}"
                        );
                    }
                }
            }
        }
    }

    /// The closed forms of one free body give the generic pass's mass matrix,
    /// Schur inverse and forces to rounding, at random configurations, velocities
    /// and torques of the reference machine, and of it with the centre of mass off
    /// the reference point under slanted gravity.
    #[test]
    fn one_free_body_closed_forms_match_the_generic_pass() {
        let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
        let mut uniform = |lo: f64, hi: f64| {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            lo + (hi - lo) * (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        let reference = PlantModel::new(&machine(""));
        let mut off_centre = reference.clone();
        off_centre.bodies[0].com = [0.013, -0.021];
        off_centre.gravity = [1.5, -9.7];
        for (name, closed) in [("reference", reference), ("off-centre", off_centre)] {
            assert!(closed.one_free_body().is_some(), "{name}: no closed forms");
            let generic = closed.clone().without_closed_forms();
            let n = closed.dof;
            for case in 0..500 {
                let mut q = [0.0; MAX_DOF];
                let mut v = [0.0; MAX_DOF];
                for i in 0..n {
                    q[i] = uniform(-7.0, 7.0);
                    v[i] = uniform(-700.0, 700.0);
                }
                let tau = [uniform(-0.5, 0.5), uniform(-0.5, 0.5)];
                let mut a = Frame::empty(&closed);
                let mut b = Frame::empty(&generic);
                let fa = a.assemble_into(&closed, &q, &[false; MAX_DOF], Some((&v, &tau)));
                let fb = b.assemble_into(&generic, &q, &[false; MAX_DOF], Some((&v, &tau)));
                let scale_m = (0..n).map(|i| b.mass[i][i]).fold(0.0, f64::max);
                let scale_f = (0..n).map(|i| fb[i].abs()).fold(1.0, f64::max);
                for i in 0..n {
                    assert!(
                        (fa[i] - fb[i]).abs() <= 1e-13 * scale_f,
                        "{name} case {case}: force {i}: {} against {}",
                        fa[i],
                        fb[i]
                    );
                    for j in 0..n {
                        assert!(
                            (a.mass[i][j] - b.mass[i][j]).abs() <= 1e-14 * scale_m,
                            "{name} case {case}: M[{i}][{j}]: {} against {}",
                            a.mass[i][j],
                            b.mass[i][j]
                        );
                    }
                }
                let x = b.solve(&fb);
                let y = a.solve(&fa);
                let scale_x = (0..n).map(|i| x[i].abs()).fold(1.0, f64::max);
                for i in 0..n {
                    assert!(
                        (x[i] - y[i]).abs() <= 1e-10 * scale_x,
                        "{name} case {case}: acceleration {i}: {} against {}",
                        y[i],
                        x[i]
                    );
                }
            }
        }
    }
}
