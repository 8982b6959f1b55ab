//! One rigid body in plane motion, free or pinned to the ground at a pivot, striking
//! obstacles at one or several points: the paper's Fig. 5 (pinned, one point) and
//! Fig. 7 (pinned, three points on a line through the pivot) bodies, a rocking
//! block's corner, a platform landing on its feet.
//!
//! Generalized velocities: free `q' = (v_Cx, v_Cy, omega)`, mass matrix
//! `M = diag(m, m, J_C)`; pinned at O `q' = omega`, `M = J_O = J_C + m |OC|^2`
//! (parallel axis). A contact at K with unit normal `n` and tangent `t = (-n_y, n_x)`
//! has Jacobian rows (with `r = K - C` free, `r = K - O` pinned, `a x b = a_x b_y - a_y b_x`)
//!
//! ```text
//!   free:   J_n = [n_x, n_y, r x n],  J_t = [t_x, t_y, r x t]
//!   pinned: J_n = [r x n],            J_t = [r x t]
//! ```
//!
//! The pivot's reaction impulse follows from the momentum balance of the centre of
//! mass (the paper's eqs. (2), (3) and (8)): `P_O = m (v_C+ - v_C-) - sum_i (P_n,i n_i + P_t,i t_i)`.

use super::outcome::ImpactOutcome;
use super::problem::{ContactLaw, ImpactLaw, ImpactProblem};
use super::solver::{solve, ImpactError};
use crate::real::Real;
use crate::vec2::{cross, spin};

/// A rigid body in plane motion at the instant of impact.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PlanarBody<T> {
    /// Mass, kg.
    pub mass: T,
    /// Moment of inertia about the centre of mass C, kg m^2.
    pub inertia: T,
    /// Position of C, m.
    pub position: [T; 2],
    /// Velocity of C, m/s (ignored when pinned: then `omega x (C - O)`).
    pub velocity: [T; 2],
    /// Angular velocity, rad/s, counter-clockwise positive.
    pub angular_velocity: T,
}

/// A contact point of the body touching an obstacle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BodyContact<T> {
    /// World position of the contact point K, m.
    pub point: [T; 2],
    /// Obstacle normal, from the obstacle to the body (normalised here).
    pub normal: [T; 2],
    /// The contact's restitution, friction and weight.
    pub law: ContactLaw<T>,
}

/// The pivot's reaction impulse, what the ground exerts on the body at O, N s.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PivotImpulse<T> {
    /// Over the whole impact.
    pub impulse: [T; 2],
    /// Over compression.
    pub compression: [T; 2],
    /// Over restitution.
    pub restitution: [T; 2],
}

/// The result of a body's impact.
#[derive(Clone, Debug)]
pub struct BodyImpact<T, const N: usize> {
    /// The contacts' results.
    pub outcome: ImpactOutcome<T, N>,
    /// Velocity of C before (as used: `omega x (C - O)` when pinned), m/s.
    pub velocity_before: [T; 2],
    /// Velocity of C after, m/s.
    pub velocity_after: [T; 2],
    /// Angular velocity before, rad/s.
    pub angular_velocity_before: T,
    /// Angular velocity after, rad/s.
    pub angular_velocity_after: T,
    /// The pivot's reaction, when pinned.
    pub pivot: Option<PivotImpulse<T>>,
    /// Kinetic energy before, J.
    pub kinetic_energy_before: T,
    /// Kinetic energy after, J.
    pub kinetic_energy_after: T,
}

/// The body's generalized description: Jacobian rows over `(v_x, v_y, omega)`
/// (first two entries zero when pinned) and the diagonal inverse mass matrix.
struct Kinematics<T, const N: usize> {
    j_n: [[T; 3]; N],
    j_t: [[T; 3]; N],
    normal: [[T; 2]; N],
    inv_mass: [T; 3],
}

impl<T: Real, const N: usize> Kinematics<T, N> {
    fn new(body: &PlanarBody<T>, pivot: Option<[T; 2]>, contacts: &[BodyContact<T>]) -> Self {
        let mut j_n = [[T::ZERO; 3]; N];
        let mut j_t = [[T::ZERO; 3]; N];
        let mut normal = [[T::ZERO; 2]; N];
        let inv_mass = match pivot {
            None => [
                T::ONE / body.mass,
                T::ONE / body.mass,
                T::ONE / body.inertia,
            ],
            Some(o) => {
                let oc = [body.position[0] - o[0], body.position[1] - o[1]];
                let j_o = body.inertia + body.mass * (oc[0] * oc[0] + oc[1] * oc[1]);
                [T::ZERO, T::ZERO, T::ONE / j_o]
            }
        };
        let origin = pivot.unwrap_or(body.position);
        for (i, c) in contacts.iter().enumerate().take(N) {
            let len = (c.normal[0] * c.normal[0] + c.normal[1] * c.normal[1]).sqrt();
            let n = [c.normal[0] / len, c.normal[1] / len];
            let t = [-n[1], n[0]];
            let r = [c.point[0] - origin[0], c.point[1] - origin[1]];
            let (lin_n, lin_t) = if pivot.is_some() {
                ([T::ZERO; 2], [T::ZERO; 2])
            } else {
                (n, t)
            };
            j_n[i] = [lin_n[0], lin_n[1], cross(r, n)];
            j_t[i] = [lin_t[0], lin_t[1], cross(r, t)];
            normal[i] = n;
        }
        Kinematics {
            j_n,
            j_t,
            normal,
            inv_mass,
        }
    }

    /// The impact problem: `W = J M^-1 J^T`, `u = J q'`.
    fn problem(
        &self,
        v0: [T; 2],
        omega0: T,
        contacts: &[BodyContact<T>],
        law: ImpactLaw,
    ) -> ImpactProblem<T, N> {
        let q0 = [v0[0], v0[1], omega0];
        let len = contacts.len().min(N);
        let mut problem = ImpactProblem::<T, N>::new(law);
        problem.len = len;
        for i in 0..len {
            for j in 0..len {
                problem.w_nn[i][j] = self.coupling(&self.j_n[i], &self.j_n[j]);
                problem.w_nt[i][j] = self.coupling(&self.j_n[i], &self.j_t[j]);
                problem.w_tt[i][j] = self.coupling(&self.j_t[i], &self.j_t[j]);
            }
            let dot = |row: &[T; 3]| row[0] * q0[0] + row[1] * q0[1] + row[2] * q0[2];
            problem.u_n[i] = dot(&self.j_n[i]);
            problem.u_t[i] = dot(&self.j_t[i]);
            problem.contacts[i] = contacts[i].law;
        }
        problem
    }

    /// `a M^-1 b^T` for two Jacobian rows.
    fn coupling(&self, a: &[T; 3], b: &[T; 3]) -> T {
        a[0] * b[0] * self.inv_mass[0]
            + a[1] * b[1] * self.inv_mass[1]
            + a[2] * b[2] * self.inv_mass[2]
    }

    /// `M^-1 J^T P`: the change of `(v_x, v_y, omega)` for contact impulses.
    fn response(&self, len: usize, p_n: &[T; N], p_t: &[T; N]) -> [T; 3] {
        let mut dq = [T::ZERO; 3];
        for i in 0..len {
            for (k, d) in dq.iter_mut().enumerate() {
                *d += self.inv_mass[k] * (self.j_n[i][k] * p_n[i] + self.j_t[i][k] * p_t[i]);
            }
        }
        dq
    }

    /// Sum of the contact impulse vectors `sum_i (P_n,i n_i + P_t,i t_i)`.
    fn contact_resultant(&self, len: usize, p_n: &[T; N], p_t: &[T; N]) -> [T; 2] {
        let mut f = [T::ZERO; 2];
        for i in 0..len {
            let n = self.normal[i];
            f[0] += p_n[i] * n[0] - p_t[i] * n[1];
            f[1] += p_n[i] * n[1] + p_t[i] * n[0];
        }
        f
    }
}

/// The velocity of C and the angular velocity before the impact (pinned: the
/// velocity of C is `omega x (C - O)`).
fn velocities_before<T: Real>(body: &PlanarBody<T>, pivot: Option<[T; 2]>) -> ([T; 2], T) {
    let omega0 = body.angular_velocity;
    let v0 = match pivot {
        None => body.velocity,
        Some(o) => spin(omega0, [body.position[0] - o[0], body.position[1] - o[1]]),
    };
    (v0, omega0)
}

/// The impact problem of a body (pinned at `pivot` if given) at `contacts`:
/// `W = J M^-1 J^T` and `u = J q'`. At most `N` contacts are used.
pub fn body_problem<T: Real, const N: usize>(
    body: &PlanarBody<T>,
    pivot: Option<[T; 2]>,
    contacts: &[BodyContact<T>],
    law: ImpactLaw,
) -> ImpactProblem<T, N> {
    let kin = Kinematics::<T, N>::new(body, pivot, contacts);
    let (v0, omega0) = velocities_before(body, pivot);
    kin.problem(v0, omega0, contacts, law)
}

/// Solves the impact of `body` (pinned at `pivot` if given) at `contacts` under
/// `law`. At most `N` contacts are used; contact normals need not be unit length.
pub fn solve_body<T: Real, const N: usize>(
    body: &PlanarBody<T>,
    pivot: Option<[T; 2]>,
    contacts: &[BodyContact<T>],
    law: ImpactLaw,
) -> Result<BodyImpact<T, N>, ImpactError> {
    if contacts.is_empty() || contacts.len() > N {
        return Err(ImpactError::InvalidProblem);
    }
    let kin = Kinematics::<T, N>::new(body, pivot, contacts);
    let len = contacts.len();
    let (v0, omega0) = velocities_before(body, pivot);
    let problem = kin.problem(v0, omega0, contacts, law);
    let outcome = solve(&problem)?;

    // Velocities after the whole impact and after compression: q'+ = q'- + M^-1 J^T P.
    let mut p_n = [T::ZERO; N];
    let mut p_t = [T::ZERO; N];
    let mut pc_n = [T::ZERO; N];
    let mut pc_t = [T::ZERO; N];
    for i in 0..len {
        let c = &outcome.contacts[i];
        p_n[i] = c.normal_impulse;
        p_t[i] = c.tangential_impulse;
        pc_n[i] = c.compression[0];
        pc_t[i] = c.compression[1];
    }
    let velocity_of = |dq: [T; 3]| -> ([T; 2], T) {
        let omega = omega0 + dq[2];
        match pivot {
            None => ([v0[0] + dq[0], v0[1] + dq[1]], omega),
            Some(o) => (
                spin(omega, [body.position[0] - o[0], body.position[1] - o[1]]),
                omega,
            ),
        }
    };
    let (v1, omega1) = velocity_of(kin.response(len, &p_n, &p_t));
    let (vc, _) = velocity_of(kin.response(len, &pc_n, &pc_t));

    // Pivot reaction from the momentum balance of C (paper eqs. (2), (3), (8)).
    let pivot_impulse = pivot.map(|_| {
        let m = body.mass;
        let total_f = kin.contact_resultant(len, &p_n, &p_t);
        let comp_f = kin.contact_resultant(len, &pc_n, &pc_t);
        let impulse = [
            m * (v1[0] - v0[0]) - total_f[0],
            m * (v1[1] - v0[1]) - total_f[1],
        ];
        let compression = [
            m * (vc[0] - v0[0]) - comp_f[0],
            m * (vc[1] - v0[1]) - comp_f[1],
        ];
        PivotImpulse {
            impulse,
            compression,
            restitution: [impulse[0] - compression[0], impulse[1] - compression[1]],
        }
    });

    let half = T::from_f64(0.5);
    let energy = |v: [T; 2], w: T| {
        half * body.mass * (v[0] * v[0] + v[1] * v[1]) + half * body.inertia * w * w
    };
    Ok(BodyImpact {
        velocity_before: v0,
        velocity_after: v1,
        angular_velocity_before: omega0,
        angular_velocity_after: omega1,
        pivot: pivot_impulse,
        kinetic_energy_before: energy(v0, omega0),
        kinetic_energy_after: energy(v1, omega1),
        outcome,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::impact::InteractionCase;

    /// The paper's Fig. 5 body: pinned at O = 0, contact K = (-d, h), n = +x.
    fn fig5(h: f64, d: f64, f: f64, r: f64) -> (BodyImpact<f64, 8>, f64, f64) {
        let (m, jc, c, omega0) = (2.0, 0.05, [0.3, 0.1], 5.0);
        let body = PlanarBody {
            mass: m,
            inertia: jc,
            position: c,
            velocity: [0.0, 0.0],
            angular_velocity: omega0,
        };
        let contact = BodyContact {
            point: [-d, h],
            normal: [1.0, 0.0],
            law: ContactLaw {
                restitution: r,
                friction: f,
                weight: 1.0,
            },
        };
        let jo = jc + m * (c[0] * c[0] + c[1] * c[1]);
        let out =
            solve_body::<f64, 8>(&body, Some([0.0, 0.0]), &[contact], ImpactLaw::Poisson).unwrap();
        (out, jo, omega0)
    }

    #[test]
    fn fig5_springing_back_matches_eq5() {
        let (h, d, f, r) = (0.25, 0.4, 0.3, 0.6);
        let (out, jo, w0) = fig5(h, d, f, r);
        // Eq. (5): omega_2 = R omega_0 (d f - h) / (h + f d), SNI = JO omega_0 / (h + f d).
        let omega2 = r * w0 * (d * f - h) / (h + f * d);
        let sni = jo * w0 / (h + f * d);
        let k = &out.outcome.contacts[0];
        assert!((out.angular_velocity_after - omega2).abs() < 1e-12 * w0);
        assert!((k.compression[0] - sni).abs() < 1e-12 * sni);
        assert!((k.compression[1] - f * sni).abs() < 1e-12 * sni);
        assert!((k.restitution[1] + f * r * sni).abs() < 1e-12 * sni);
        assert_eq!(k.case, InteractionCase::ReversalInRestitution);
        assert!(
            out.outcome.warnings.is_empty(),
            "{:?}",
            out.outcome.warnings
        );
    }

    #[test]
    fn fig5_jammed_sticks_in_restitution() {
        let (h, d, f, r) = (0.1, 0.4, 0.5, 0.6);
        let (out, jo, w0) = fig5(h, d, f, r);
        let sni = jo * w0 / (h + f * d);
        let k = &out.outcome.contacts[0];
        assert!(out.angular_velocity_after.abs() < 1e-12 * w0);
        // Stuck in restitution: moment about O vanishes, P_t = -h/d P_n.
        assert!((k.restitution[0] - r * sni).abs() < 1e-12 * sni);
        assert!((k.restitution[1] + h / d * r * sni).abs() < 1e-12 * sni);
        assert_eq!(k.case, InteractionCase::StickInRestitution);
        assert!(out
            .outcome
            .warnings
            .contains(crate::impact::Warnings::JAMMING));
    }

    #[test]
    fn fig7_shares_by_eq9() {
        let l = [0.2, 0.5, 0.9];
        let rs = [0.2, 0.5, 0.8];
        let body = PlanarBody {
            mass: 1.5,
            inertia: 0.04,
            position: [0.3, 0.05],
            velocity: [0.0, 0.0],
            angular_velocity: 3.0,
        };
        let contacts: [BodyContact<f64>; 3] = core::array::from_fn(|i| BodyContact {
            point: [l[i], 0.0],
            normal: [0.0, -1.0],
            law: ContactLaw {
                restitution: rs[i],
                friction: 0.4,
                weight: 1.0,
            },
        });
        let out =
            solve_body::<f64, 8>(&body, Some([0.0, 0.0]), &contacts, ImpactLaw::Poisson).unwrap();
        let s2: f64 = l.iter().map(|x| x * x).sum();
        let rl2: f64 = (0..3).map(|i| rs[i] * l[i] * l[i]).sum();
        assert!((out.angular_velocity_after + 3.0 * rl2 / s2).abs() < 1e-12);
        let c = &out.outcome.contacts;
        assert!((c[0].compression[0] / c[2].compression[0] - l[0] / l[2]).abs() < 1e-12);
        assert_eq!(c[1].case, InteractionCase::NoSlip);
    }
}
