//! The limits on a joint's spring-damper (docs/machine-file.md, "Several bodies"):
//! how fast it makes the relative rotation move, and how far it is wound at t = 0.
//!
//! The plant integrates with an explicit method, whose step must follow the fastest
//! motion of the machine: a joint of stiffness `k` (N m/rad) and damping `c`
//! (N m s/rad) on an effective inertia `J` (kg m^2) swings at `sqrt(k / J)` rad/s
//! and, overdamped, relaxes at `c / J` 1/s. Above [`MAX_JOINT_RATE`] a joint is
//! refused with its key: a spring that fast is a rigid joint at the time scale of the
//! impacts, and integrating it would take hundreds of thousands of steps a simulated
//! second.
//!
//! `J` is the least inertia the joint's relative rotation can have: the two bodies
//! alone, pinned at the hinge and otherwise free (every other body, rotor or contact
//! only adds kinetic energy at a given relative rate, so it only raises `J`). With
//! the hinge's velocity `v` and the two angular velocities `w_a, w_b` as coordinates,
//! body `i` (mass `m_i`, inertia `I_i` about its centre of mass, centre `d_i` from the
//! hinge) moves at `v + w_i x d_i`, and
//!
//! ```text
//! T = 1/2 x^T M x,  x = (v_x, v_y, w_a, w_b),
//! M = sum_i [ m_i I2          m_i (-d_iy, d_ix)^T e_i^T ]
//!           [ sym.            (I_i + m_i |d_i|^2) e_i e_i^T ]
//! J = 1 / (e^T M^-1 e),  e = (0, 0, -1, 1)
//! ```
//!
//! (the least `2 T` at a unit relative rate `w_b - w_a = 1`: minimising a quadratic
//! form under one linear constraint). Against the fundament the body turns about the
//! hinge: `J = I + m |d|^2`.
//!
//! The preload: a spring relaxed at `rest_angle` while the bodies' relative angle at
//! t = 0 is `theta_B - theta_A` is wound by their difference at t = 0. At most half a
//! turn ([`MAX_PRELOAD`]) is allowed: a hinge's flat spring wound further has broken,
//! and a rest angle of a million radians (a slip of the keyboard) once flung a machine
//! at hundreds of kilometres a second.

use crate::bodies::{Joint, FUNDAMENT};
use crate::input::{number, Named, Section};
use crate::Platform;

/// The fastest rate a joint may have, `sqrt(k / J)` or `c / J`, 1/s (rad/s for the
/// swing: 100 000 rad/s is 16 kHz, a period of 63 us). At this bound the Fig. 8
/// machine's first spring makes its run cost about 20 times the shipped file's
/// (docs/machine-file.md, "A joint's limits"); a joint of 1e12 N m/rad had run for
/// hours.
pub const MAX_JOINT_RATE: f64 = 1.0e5;

/// The most a joint's spring may be wound at t = 0, `|theta_B - theta_A - rest_angle|`,
/// rad: half a turn.
pub const MAX_PRELOAD: f64 = std::f64::consts::PI;

/// The least effective inertia of a joint's relative rotation, kg m^2 (the module
/// doc's `J`); `a`, `b` the two bodies (`None`: the fundament), `hinge` the joint's
/// point at t = 0.
pub fn effective_inertia(a: Option<&Platform>, b: Option<&Platform>, hinge: [f64; 2]) -> f64 {
    let about_hinge = |r: &Platform| {
        let d = [r.position[0] - hinge[0], r.position[1] - hinge[1]];
        r.inertia + r.mass * (d[0] * d[0] + d[1] * d[1])
    };
    let (a, b) = match (a, b) {
        (Some(a), Some(b)) => (a, b),
        (Some(r), None) | (None, Some(r)) => return about_hinge(r),
        (None, None) => return f64::INFINITY,
    };
    let mut m = [[0.0_f64; 4]; 4];
    for (k, r) in [(2, a), (3, b)] {
        let d = [r.position[0] - hinge[0], r.position[1] - hinge[1]];
        m[0][0] += r.mass;
        m[1][1] += r.mass;
        m[0][k] = -r.mass * d[1];
        m[1][k] = r.mass * d[0];
        m[k][0] = m[0][k];
        m[k][1] = m[1][k];
        m[k][k] = about_hinge(r);
    }
    match solve4(m, [0.0, 0.0, -1.0, 1.0]) {
        Some(x) => 1.0 / (x[3] - x[2]),
        None => 0.0,
    }
}

/// `M x = rhs` for a symmetric positive definite 4x4 `M` (Cholesky); `None` if `M`
/// is not positive definite.
fn solve4(m: [[f64; 4]; 4], rhs: [f64; 4]) -> Option<[f64; 4]> {
    let mut l = [[0.0_f64; 4]; 4];
    for i in 0..4 {
        for j in 0..=i {
            let s = m[i][j] - (0..j).map(|k| l[i][k] * l[j][k]).sum::<f64>();
            if i == j {
                if s <= 0.0 || !s.is_finite() {
                    return None;
                }
                l[i][i] = s.sqrt();
            } else {
                l[i][j] = s / l[j][j];
            }
        }
    }
    let mut y = [0.0_f64; 4];
    for i in 0..4 {
        y[i] = (rhs[i] - (0..i).map(|k| l[i][k] * y[k]).sum::<f64>()) / l[i][i];
    }
    let mut x = [0.0_f64; 4];
    for i in (0..4).rev() {
        x[i] = (y[i] - (i + 1..4).map(|k| l[k][i] * x[k]).sum::<f64>()) / l[i][i];
    }
    Some(x)
}

/// Checks every joint's swing `sqrt(k / J)` and relaxation `c / J` against
/// [`MAX_JOINT_RATE`], and its preload against [`MAX_PRELOAD`]; a problem at
/// `joints[i].stiffness`, `joints[i].damping` or `joints[i].rest_angle` for each one
/// beyond. `rigid` finds a moving body by name. `false` when a problem
/// was recorded.
pub fn check<'a>(
    root: &Section,
    joints: &[Named<Joint>],
    rigid: impl Fn(&str) -> Option<&'a Platform>,
) -> bool {
    let mut ok = true;
    for (i, joint) in joints.iter().enumerate() {
        let Some(j) = &joint.value else { continue };
        // The fundament is `None`; a body that does not exist was reported already.
        let body = |name: &str| match name {
            FUNDAMENT => Some(None),
            _ => rigid(name).map(Some),
        };
        let (Some(a), Some(b)) = (body(&j.bodies[0]), body(&j.bodies[1])) else {
            continue;
        };
        let inertia = effective_inertia(a, b, j.point);
        let about = format!(
            "J = {} kg m^2 being the least inertia of its relative rotation",
            rounded(inertia)
        );
        let swing = (j.stiffness / inertia).sqrt();
        if swing > MAX_JOINT_RATE {
            root.problem(
                &format!("joints[{i}].stiffness"),
                format!(
                    "{} N m/rad swings the joint at sqrt(k / J) = {} rad/s, {about}; at most {} rad/s ({} kHz) is allowed, a stiffness of at most {} N m/rad here: a spring that stiff is rigid at the impacts' time scale (make the two bodies one)",
                    number(j.stiffness),
                    rounded(swing),
                    number(MAX_JOINT_RATE),
                    rounded(MAX_JOINT_RATE / std::f64::consts::TAU / 1e3),
                    rounded_down(MAX_JOINT_RATE * MAX_JOINT_RATE * inertia)
                ),
            );
            ok = false;
        }
        let relax = j.damping / inertia;
        if relax > MAX_JOINT_RATE {
            root.problem(
                &format!("joints[{i}].damping"),
                format!(
                    "{} N m s/rad relaxes the joint at c / J = {} 1/s, {about}; at most {} 1/s is allowed, a damping of at most {} N m s/rad here",
                    number(j.damping),
                    rounded(relax),
                    number(MAX_JOINT_RATE),
                    rounded_down(MAX_JOINT_RATE * inertia)
                ),
            );
            ok = false;
        }
        if let Some(rest) = j.rest_angle {
            let angle = |r: Option<&Platform>| r.map_or(0.0, |r| r.angle);
            let wound = angle(b) - angle(a) - rest;
            if wound.abs() > MAX_PRELOAD {
                root.problem(
                    &format!("joints[{i}].rest_angle"),
                    format!(
                        "{} rad winds the spring by {} rad at t = 0 (the bodies' relative angle then is {} rad); at most {} rad (half a turn) is allowed",
                        number(rest),
                        rounded(wound),
                        number(angle(b) - angle(a)),
                        rounded_down(MAX_PRELOAD)
                    ),
                );
                ok = false;
            }
        }
    }
    ok
}

/// A computed figure for a message, to 4 significant digits.
fn rounded(x: f64) -> String {
    to_4_digits(x, f64::round)
}

/// A bound for a message, to 4 significant digits towards zero (so that the value
/// it names is allowed).
fn rounded_down(x: f64) -> String {
    to_4_digits(x, f64::trunc)
}

fn to_4_digits(x: f64, round: fn(f64) -> f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return number(x);
    }
    let scale = 10f64.powi(3 - x.abs().log10().floor() as i32);
    number(round(x * scale) / scale)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body(mass: f64, inertia: f64, position: [f64; 2]) -> Platform {
        Platform {
            mass,
            inertia,
            position,
            angle: 0.0,
            velocity: [0.0; 2],
            angular_velocity: 0.0,
        }
    }

    /// Against the fundament a body turns about the hinge (Steiner:
    /// `J = I + m |d|^2`), whichever side of the joint the fundament is.
    #[test]
    fn against_the_fundament_the_inertia_is_about_the_hinge() {
        let b = body(0.3, 1e-3, [0.3, 0.4]);
        let want = 1e-3 + 0.3 * 0.25;
        for j in [
            effective_inertia(Some(&b), None, [0.0, 0.0]),
            effective_inertia(None, Some(&b), [0.0, 0.0]),
        ] {
            assert!((j - want).abs() < 1e-15, "{j} against {want}");
        }
    }

    /// Two bodies hinged at both their centres of mass: the hinge's translation
    /// leaves their rotations alone, and the relative rotation's inertia is the
    /// reduced `I_a I_b / (I_a + I_b)` (two flywheels on one axle).
    #[test]
    fn two_bodies_hinged_at_their_centres_have_the_reduced_inertia() {
        let (a, b) = (body(2.0, 7e-3, [0.1, 0.2]), body(0.5, 3e-3, [0.1, 0.2]));
        let j = effective_inertia(Some(&a), Some(&b), [0.1, 0.2]);
        let want = 7e-3 * 3e-3 / (7e-3 + 3e-3);
        assert!((j / want - 1.0).abs() < 1e-13, "{j} against {want}");
    }

    /// Two bodies on a line through the hinge, either side of it (centres at
    /// `(-r_a, 0)` and `(r_b, 0)`), by hand in other coordinates: the hinge's
    /// velocity `u` across the line and `w_a` (`w_b = w_a + 1`); the bodies' centres
    /// move across it at `u - w_a r_a` and `u + w_b r_b`, and
    /// `2 T = m_a (u - w_a r_a)^2 + I_a w_a^2 + m_b (u + w_b r_b)^2 + I_b w_b^2`
    /// is least where its two partial derivatives vanish (a 2x2 system, by Cramer's
    /// rule). With point-like bodies (`I` nearly 0) the pair turns almost for free:
    /// each body turns about its own centre and the hinge swings between them. That
    /// `J` (6e-13 kg m^2) is the difference of terms of 0.2 kg m^2, so both ways
    /// lose `0.2 / 6e-13 x 2.2e-16`, some 7e-5 of it, to rounding: 1e-3 there,
    /// 1e-12 with real inertias.
    #[test]
    fn two_bodies_on_a_line_match_the_least_energy_by_hand() {
        for (ia, ib, tol) in [(1e-3, 4e-4, 1e-12), (1e-12, 1e-12, 1e-3)] {
            let (ma, mb, ra, rb) = (2.0, 0.5, 0.3, 0.1);
            let a = body(ma, ia, [-ra, 0.0]);
            let b = body(mb, ib, [rb, 0.0]);
            let j = effective_inertia(Some(&a), Some(&b), [0.0, 0.0]);
            let (m11, m12) = (ma + mb, mb * rb - ma * ra);
            let m22 = ma * ra * ra + ia + mb * rb * rb + ib;
            let (f1, f2) = (-mb * rb, -mb * rb * rb - ib);
            let det = m11 * m22 - m12 * m12;
            let u = (f1 * m22 - m12 * f2) / det;
            let wa = (m11 * f2 - m12 * f1) / det;
            let wb = wa + 1.0;
            let want = ma * (u - wa * ra).powi(2)
                + ia * wa * wa
                + mb * (u + wb * rb).powi(2)
                + ib * wb * wb;
            assert!((j / want - 1.0).abs() < tol, "{j} against {want}");
        }
    }
}
