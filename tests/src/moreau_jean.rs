//! A second method for the platform with its rotors held at constant speed:
//! Moreau-Jean time stepping, written without the plant's code.
//!
//! The system: a rigid platform (mass `m_p`, inertia `J_p` about its centre of
//! mass `C`) in plane motion, `q = (x, y, theta)`; on it two eccentric point
//! masses `m_k` at `r_k = R(theta) a_k + e_k (cos psi_k, sin psi_k)` from `C`, with
//! `psi_k = theta + phi_k0 + w_k t` (each rotor held at the constant speed `w_k`
//! relative to the platform), and the rotors' own inertia `I_k` turning at
//! `theta' + w_k`. D'Alembert's principle gives `M(q, t) q'' = Q(q, q', t) + J^T
//! lambda` with
//!
//! ```text
//!   M = diag(m_p, m_p, J_p + sum I_k) + sum m_k [1 0 -r_y; 0 1 r_x; -r_y r_x |r|^2]
//!   Q = (0, -m_p g, 0) + sum J_k^T m_k ((0, -g) - b_k),   J_k^T f = (f_x, f_y, r_k x f)
//!   b_k = -theta'^2 R(theta) a_k - (theta' + w_k)^2 e_k (cos psi_k, sin psi_k)
//! ```
//!
//! (`b_k` the eccentric's acceleration not proportional to `q''`). A foot at `c`
//! (platform frame) is at `p = R(theta) c` from `C`; with the floor `y = 0`,
//! normal `n = (0, 1)` and tangent `t = (-1, 0)`: gap `y + p_y`, normal row
//! `(0, 1, p_x)`, tangential row `(-1, 0, p_y)`.
//!
//! The scheme (Jean, Comput. Methods Appl. Mech. Engrg. 177 (1999) 235-257;
//! Acary & Brogliato, *Numerical Methods for Nonsmooth Dynamical Systems*,
//! Springer 2008, ch. 10), with `theta = 1/2`:
//!
//! ```text
//!   q_m = q_k + h/2 v_k,  t_m = t_k + h/2
//!   M(q_m, t_m) (v_k+1 - v_k) = h Q(q_m, v_k, t_m) + J(q_m)^T P
//!   q_k+1 = q_m + h/2 v_k+1
//! ```
//!
//! with, for every foot whose gap at `q_m` is `<= 0`, Newton's impact law at
//! velocity level and Coulomb's law on the step's impulse `P`:
//! `0 <= P_n  _|_  U_n,k+1 + e U_n,k >= 0`, `|P_t| <= mu P_n`, and `U_t,k+1 = 0`
//! or `P_t = -mu P_n sign(U_t,k+1)`. Friction acts on the step's total impulse
//! only (the cone), not along the impulse's path as in the paper's
//! Darboux-Keller impacts, so the two agree where no slip reverses or stops
//! inside an impact. The impulses are solved by nonsmooth Gauss-Seidel: each
//! foot's local problem solved exactly (open, stick, or slip either way, with
//! the other feet's impulses fixed), sweeps repeated until a sweep changes the
//! velocities by rounding only, 1e-14 of the largest (Moreau 1988; Jean 1999;
//! Siconos' NSGS).

// Numeric kernels index several parallel arrays with one loop variable.
#![allow(clippy::needless_range_loop)]

/// One rotor, held at constant speed relative to the platform.
#[derive(Clone, Copy, Debug)]
pub struct Rotor {
    /// Axis in the platform frame, from the platform's centre of mass, m.
    pub axis: [f64; 2],
    /// Eccentric mass, kg.
    pub mass: f64,
    /// Eccentricity, m.
    pub eccentricity: f64,
    /// The rotor's own inertia about its axis, kg m^2.
    pub inertia: f64,
    /// Eccentric angle in the platform frame at t = 0, rad.
    pub angle: f64,
    /// Speed relative to the platform, rad/s (signed, ccw positive).
    pub speed: f64,
}

/// The platform, its rotors and its feet.
#[derive(Clone, Debug)]
pub struct Machine {
    /// Platform mass without the eccentric masses, kg.
    pub mass: f64,
    /// Platform inertia about its centre of mass, kg m^2.
    pub inertia: f64,
    /// The two rotors.
    pub rotors: [Rotor; 2],
    /// Feet in the platform frame, from the centre of mass, m.
    pub feet: Vec<[f64; 2]>,
    /// Restitution of every foot.
    pub restitution: f64,
    /// Friction coefficient of every foot.
    pub friction: f64,
    /// Gravity, m/s^2 (pointing down).
    pub gravity: f64,
}

/// The stepper's state.
#[derive(Clone, Debug)]
pub struct Stepper {
    /// The machine.
    pub machine: Machine,
    /// Step, s.
    pub h: f64,
    /// Time, s.
    pub t: f64,
    /// `(x, y, theta)`: m, m, rad.
    pub q: [f64; 3],
    /// Their rates.
    pub v: [f64; 3],
}

/// Solves the 3 x 3 system `m x = b` (Gaussian elimination with partial
/// pivoting; `m` is symmetric positive definite here).
fn solve3(m: [[f64; 3]; 3], b: [f64; 3]) -> [f64; 3] {
    let mut a = [[0.0; 4]; 3];
    for i in 0..3 {
        a[i][..3].copy_from_slice(&m[i]);
        a[i][3] = b[i];
    }
    for col in 0..3 {
        let p = (col..3)
            .max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))
            .unwrap_or(col);
        a.swap(col, p);
        for row in col + 1..3 {
            let f = a[row][col] / a[col][col];
            for k in col..4 {
                a[row][k] -= f * a[col][k];
            }
        }
    }
    let mut x = [0.0; 3];
    for i in (0..3).rev() {
        let s: f64 = (i + 1..3).map(|k| a[i][k] * x[k]).sum();
        x[i] = (a[i][3] - s) / a[i][i];
    }
    x
}

impl Stepper {
    /// The machine at rest on its feet (centre of mass at `q0`), at t = 0.
    pub fn new(machine: Machine, h: f64, q0: [f64; 3]) -> Self {
        Stepper {
            machine,
            h,
            t: 0.0,
            q: q0,
            v: [0.0; 3],
        }
    }

    /// Mass matrix and forces without contacts at `(q, v, t)`.
    fn dynamics(&self, q: &[f64; 3], v: &[f64; 3], t: f64) -> ([[f64; 3]; 3], [f64; 3]) {
        let m = &self.machine;
        let g = m.gravity;
        let total_inertia = m.inertia + m.rotors.iter().map(|r| r.inertia).sum::<f64>();
        let mut mass = [
            [m.mass, 0.0, 0.0],
            [0.0, m.mass, 0.0],
            [0.0, 0.0, total_inertia],
        ];
        let mut f = [0.0, -m.mass * g, 0.0];
        let w = v[2];
        for r in &m.rotors {
            let rho = crate::rig::rot(q[2], r.axis);
            let psi = q[2] + r.angle + r.speed * t;
            let eps = [r.eccentricity * psi.cos(), r.eccentricity * psi.sin()];
            let p = [rho[0] + eps[0], rho[1] + eps[1]];
            mass[0][0] += r.mass;
            mass[1][1] += r.mass;
            mass[0][2] -= r.mass * p[1];
            mass[2][0] -= r.mass * p[1];
            mass[1][2] += r.mass * p[0];
            mass[2][1] += r.mass * p[0];
            mass[2][2] += r.mass * (p[0] * p[0] + p[1] * p[1]);
            // m_k ((0, -g) - b_k), b_k = -w^2 rho - (w + w_k)^2 eps.
            let spin = (w + r.speed) * (w + r.speed);
            let fk = [
                r.mass * (w * w * rho[0] + spin * eps[0]),
                r.mass * (-g + w * w * rho[1] + spin * eps[1]),
            ];
            f[0] += fk[0];
            f[1] += fk[1];
            f[2] += p[0] * fk[1] - p[1] * fk[0];
        }
        (mass, f)
    }

    /// One step of the scheme.
    pub fn step(&mut self) {
        let h = self.h;
        let t_m = self.t + 0.5 * h;
        let q_m: [f64; 3] = core::array::from_fn(|i| self.q[i] + 0.5 * h * self.v[i]);
        let (mass, f) = self.dynamics(&q_m, &self.v, t_m);
        let acc = solve3(mass, f);
        let v_free: [f64; 3] = core::array::from_fn(|i| self.v[i] + h * acc[i]);

        // The feet in contact at the middle of the step: their rows.
        let mut rows: Vec<([f64; 3], [f64; 3])> = Vec::new();
        for c in &self.machine.feet {
            let p = crate::rig::rot(q_m[2], *c);
            if q_m[1] + p[1] <= 0.0 {
                rows.push(([0.0, 1.0, p[0]], [-1.0, 0.0, p[1]]));
            }
        }
        let mut v_next = v_free;
        if !rows.is_empty() {
            let impulse = self.contact_impulses(&mass, &rows, &v_free);
            for (j, (jn, jt)) in rows.iter().enumerate() {
                let gen: [f64; 3] =
                    core::array::from_fn(|i| jn[i] * impulse[j][0] + jt[i] * impulse[j][1]);
                let dv = solve3(mass, gen);
                for i in 0..3 {
                    v_next[i] += dv[i];
                }
            }
        }
        self.v = v_next;
        self.q = core::array::from_fn(|i| q_m[i] + 0.5 * h * self.v[i]);
        self.t += h;
    }

    /// The impulses `(P_n, P_t)` of the feet with rows `rows` over the step, by
    /// nonsmooth Gauss-Seidel with each foot's local problem solved exactly.
    fn contact_impulses(
        &self,
        mass: &[[f64; 3]; 3],
        rows: &[([f64; 3], [f64; 3])],
        v_free: &[f64; 3],
    ) -> Vec<[f64; 2]> {
        let dot = |a: &[f64; 3], b: &[f64; 3]| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
        let n = rows.len();
        // M^-1 J^T, the Delassus blocks, the free and the pre-step velocities.
        let minv: Vec<([f64; 3], [f64; 3])> = rows
            .iter()
            .map(|(jn, jt)| (solve3(*mass, *jn), solve3(*mass, *jt)))
            .collect();
        let w = |a: usize, ra: usize, b: usize, rb: usize| {
            let row = if ra == 0 { &rows[a].0 } else { &rows[a].1 };
            let col = if rb == 0 { &minv[b].0 } else { &minv[b].1 };
            dot(row, col)
        };
        let u_free: Vec<[f64; 2]> = rows
            .iter()
            .map(|(jn, jt)| [dot(jn, v_free), dot(jt, v_free)])
            .collect();
        let u_before: Vec<f64> = rows.iter().map(|(jn, _)| dot(jn, &self.v)).collect();
        let (e, mu) = (self.machine.restitution, self.machine.friction);
        let target: Vec<f64> = u_before.iter().map(|u| (-e * u).max(0.0)).collect();
        let mut p = vec![[0.0f64; 2]; n];
        // The velocity change the impulses give, `M^-1 J^T P`: unique, unlike the
        // impulses where two sticking feet share an internal force.
        let dv = |p: &[[f64; 2]]| -> [f64; 3] {
            core::array::from_fn(|i| {
                (0..n)
                    .map(|j| minv[j].0[i] * p[j][0] + minv[j].1[i] * p[j][1])
                    .sum::<f64>()
            })
        };
        let mut last = [f64::INFINITY; 3];
        for _sweep in 0..10_000 {
            for j in 0..n {
                // The velocities at foot j with the other feet's impulses.
                let mut un = u_free[j][0];
                let mut ut = u_free[j][1];
                for k in 0..n {
                    if k != j {
                        un += w(j, 0, k, 0) * p[k][0] + w(j, 0, k, 1) * p[k][1];
                        ut += w(j, 1, k, 0) * p[k][0] + w(j, 1, k, 1) * p[k][1];
                    }
                }
                p[j] = local_problem(
                    [
                        [w(j, 0, j, 0), w(j, 0, j, 1)],
                        [w(j, 1, j, 0), w(j, 1, j, 1)],
                    ],
                    [un, ut],
                    target[j],
                    mu,
                );
            }
            // Converged when a sweep changes the velocities by rounding only.
            let now = dv(&p);
            let scale = now
                .iter()
                .chain(v_free.iter())
                .fold(0.0f64, |m, x| m.max(x.abs()));
            let change = (0..3).fold(0.0f64, |m, i| m.max((now[i] - last[i]).abs()));
            if change <= 1e-14 * scale {
                break;
            }
            last = now;
        }
        p
    }

    /// Advances to `t_end`.
    pub fn run_to(&mut self, t_end: f64) {
        while self.t < t_end - 0.5 * self.h {
            self.step();
        }
    }
}

/// One foot's local problem, exactly: with the Delassus block `w`, the velocity
/// `u0` the other impulses leave, the normal target `target`, find `(P_n, P_t)`:
/// open (`P = 0`, `u_n >= target`), or closed at `u_n = target` sticking
/// (`u_t = 0`, `|P_t| <= mu P_n`) or slipping (`P_t = -mu s P_n`, `u_t` of sign
/// `s`), with `P_n >= 0`.
fn local_problem(w: [[f64; 2]; 2], u0: [f64; 2], target: f64, mu: f64) -> [f64; 2] {
    if u0[0] >= target {
        return [0.0, 0.0];
    }
    // Stick: w P = (target - u_n, -u_t).
    let det = w[0][0] * w[1][1] - w[0][1] * w[1][0];
    if det.abs() > 1e-14 * (w[0][0] * w[1][1]).abs() {
        let (bn, bt) = (target - u0[0], -u0[1]);
        let pn = (w[1][1] * bn - w[0][1] * bt) / det;
        let pt = (w[0][0] * bt - w[1][0] * bn) / det;
        if pn >= 0.0 && pt.abs() <= mu * pn {
            return [pn, pt];
        }
    }
    // Slip in direction s: P_t = -mu s P_n, u_n = target.
    for s in [1.0, -1.0] {
        let a = w[0][0] - mu * s * w[0][1];
        if a <= 0.0 {
            continue;
        }
        let pn = (target - u0[0]) / a;
        let ut = u0[1] + (w[1][0] - mu * s * w[1][1]) * pn;
        if pn >= 0.0 && s * ut >= 0.0 {
            return [pn, -mu * s * pn];
        }
    }
    // No exact local solution (friction beyond what the geometry allows): the
    // frictionless one.
    [((target - u0[0]) / w[0][0]).max(0.0), 0.0]
}
