//! Sharing the contact forces that the motion leaves undetermined, within the
//! friction cones.
//!
//! With two or more closed contacts on a rigid platform, the contact forces are
//! fixed only up to **internal forces**: combinations `z` with `G z = 0`, where the
//! columns of `G` are the generalized directions of the unknown forces (a normal
//! force along `J_n - mu s J_t` for a slipping contact, `J_n` and `J_t` for a
//! sticking one). Two sticking feet can squeeze or stretch the platform between
//! them without changing its motion. The equations' weighted minimum-norm solution
//! `z0` shares the forces by the contacts' weights, but may put a sticking foot
//! outside its cone while the other has friction to spare. The physical forces are
//! the ones closest to `z0` (weighted norm) with every normal force `>= 0` and every
//! sticking force inside its cone:
//!
//! ```text
//!   min |N c|_W   subject to   x_j(c) >= 0,   |y_k(c)| <= mu_k x_k(c),   z = z0 + N c
//! ```
//!
//! with `N` a basis of the null space of `G` (`z0` is already W-orthogonal to it).
//! With one internal force (two feet, the usual case) this is an interval for `c`
//! and the answer is exact; with more, coordinate descent on the same intervals.
//! Where no `c` satisfies every cone, the forces are taken where the largest
//! violation is smallest: the sticking state cannot hold, and the stick event
//! function (`mu lambda_n - |lambda_t|`) says so.

use super::dynamics::DOF;

/// One unknown force: its generalized direction, and what it is.
#[derive(Clone, Copy, Debug)]
pub struct Unknown {
    /// Generalized direction (a column of `G`).
    pub direction: [f64; DOF],
    /// Index of its contact.
    pub contact: usize,
    /// A normal force (else a sticking contact's tangential force).
    pub normal: bool,
}

/// Friction coefficients of the contacts, and which of them stick.
pub struct Cones<'a> {
    /// Coulomb coefficient per contact.
    pub friction: &'a [f64],
    /// True for a sticking contact.
    pub sticking: &'a [bool],
}

/// Moves `z` (forces of `unknowns`, in order) along the internal forces to the
/// closest point satisfying the cones; returns false when none does.
pub fn within_cones(unknowns: &[Unknown], z: &mut [f64], cones: &Cones<'_>) -> bool {
    let m = unknowns.len();
    let scale = z
        .iter()
        .fold(0.0f64, |a, b| a.max(b.abs()))
        .max(f64::MIN_POSITIVE);
    let tol = 1e-12 * scale;
    if satisfied(unknowns, z, cones, tol) {
        return true;
    }
    let basis = null_space(unknowns);
    if basis.is_empty() {
        return false;
    }
    let mut c = vec![0.0; basis.len()];
    // Coordinate descent: each coordinate to the point of its interval closest to
    // zero (the minimum norm), or of least violation where the interval is empty.
    let sweeps = if basis.len() == 1 { 1 } else { 50 };
    for _ in 0..sweeps {
        for i in 0..basis.len() {
            let current: Vec<f64> = (0..m)
                .map(|r| {
                    z[r] + (0..basis.len())
                        .filter(|&k| k != i)
                        .map(|k| basis[k][r] * c[k])
                        .sum::<f64>()
                })
                .collect();
            c[i] = best_coordinate(unknowns, &current, &basis[i], cones, scale);
        }
    }
    for r in 0..m {
        z[r] += (0..basis.len()).map(|k| basis[k][r] * c[k]).sum::<f64>();
    }
    satisfied(unknowns, z, cones, 1e-9 * scale)
}

/// Constraints `a c + b >= 0` on one coordinate along `dir` from forces `z`.
fn constraints(unknowns: &[Unknown], z: &[f64], dir: &[f64], cones: &Cones<'_>) -> Vec<(f64, f64)> {
    let mut out = Vec::new();
    for (r, u) in unknowns.iter().enumerate() {
        if !u.normal {
            continue;
        }
        out.push((dir[r], z[r]));
        if cones.sticking[u.contact] {
            if let Some(t) = unknowns
                .iter()
                .position(|v| !v.normal && v.contact == u.contact)
            {
                let mu = cones.friction[u.contact];
                // mu x - y >= 0 and mu x + y >= 0.
                out.push((mu * dir[r] - dir[t], mu * z[r] - z[t]));
                out.push((mu * dir[r] + dir[t], mu * z[r] + z[t]));
            }
        }
    }
    out
}

/// The coordinate along `dir` closest to zero within every constraint, or, where
/// they admit none, the one with the smallest largest violation.
fn best_coordinate(
    unknowns: &[Unknown],
    z: &[f64],
    dir: &[f64],
    cones: &Cones<'_>,
    scale: f64,
) -> f64 {
    let cs = constraints(unknowns, z, dir, cones);
    let (mut lo, mut hi) = (f64::NEG_INFINITY, f64::INFINITY);
    let eps = 1e-14 * scale;
    for &(a, b) in &cs {
        if a > eps {
            lo = lo.max(-b / a);
        } else if a < -eps {
            hi = hi.min(-b / a);
        }
    }
    if lo <= hi {
        return 0.0f64.max(lo).min(hi);
    }
    // Empty: minimize the largest violation max_i -(a_i c + b_i), convex and
    // piecewise linear: its minimum is where two of the lines cross.
    let violation = |c: f64| {
        cs.iter()
            .map(|&(a, b)| -(a * c + b))
            .fold(f64::NEG_INFINITY, f64::max)
    };
    let mut best = (violation(0.0), 0.0);
    for (i, &(a1, b1)) in cs.iter().enumerate() {
        for &(a2, b2) in &cs[i + 1..] {
            if (a1 - a2).abs() > eps {
                let c = (b2 - b1) / (a1 - a2);
                let v = violation(c);
                if v < best.0 {
                    best = (v, c);
                }
            }
        }
    }
    best.1
}

/// True when every normal force is >= 0 and every sticking force in its cone.
fn satisfied(unknowns: &[Unknown], z: &[f64], cones: &Cones<'_>, tol: f64) -> bool {
    let zero = vec![0.0; z.len()];
    constraints(unknowns, z, &zero, cones)
        .iter()
        .all(|&(_, b)| b >= -tol)
}

/// A basis of the null space of `G` (columns: the unknowns' directions), by
/// Gauss-Jordan elimination with partial pivoting on `G` (DOF x m).
pub fn null_space(unknowns: &[Unknown]) -> Vec<Vec<f64>> {
    let m = unknowns.len();
    let mut g: Vec<Vec<f64>> = (0..DOF)
        .map(|i| unknowns.iter().map(|u| u.direction[i]).collect())
        .collect();
    let scale = g.iter().flatten().fold(0.0f64, |a, b| a.max(b.abs()));
    let tol = 1e-10 * scale.max(f64::MIN_POSITIVE);
    let mut pivots = Vec::new();
    let mut row = 0;
    for col in 0..m {
        if row == DOF {
            break;
        }
        let p = (row..DOF)
            .max_by(|&a, &b| g[a][col].abs().total_cmp(&g[b][col].abs()))
            .unwrap_or(row);
        if g[p][col].abs() <= tol {
            continue;
        }
        g.swap(row, p);
        let pv = g[row][col];
        for v in g[row].iter_mut() {
            *v /= pv;
        }
        for r in 0..DOF {
            if r != row {
                let f = g[r][col];
                if f != 0.0 {
                    for k in 0..m {
                        g[r][k] -= f * g[row][k];
                    }
                }
            }
        }
        pivots.push(col);
        row += 1;
    }
    (0..m)
        .filter(|c| !pivots.contains(c))
        .map(|free| {
            let mut v = vec![0.0; m];
            v[free] = 1.0;
            for (r, &pc) in pivots.iter().enumerate() {
                v[pc] = -g[r][free];
            }
            v
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unknown(direction: [f64; DOF], contact: usize, normal: bool) -> Unknown {
        Unknown {
            direction,
            contact,
            normal,
        }
    }

    /// Two feet at x = -0.1 and +0.1 under a level platform (C at height h), both
    /// sticking: the equal split puts foot 0 (lightly loaded) outside its cone, the
    /// internal force moves friction to foot 1. Hand solution: total Y is fixed, so
    /// y0 = mu x0 at the limit, y1 = Y - y0.
    #[test]
    fn friction_moves_to_the_loaded_foot() {
        let h = 0.03;
        // J_n = (0, 1, r x n) with n = (0, 1): r x n = r_x; J_t with t = (-1, 0): r_y = -h.
        let u = [
            unknown([0.0, 1.0, -0.1, 0.0, 0.0], 0, true),
            unknown([-1.0, 0.0, -h, 0.0, 0.0], 0, false),
            unknown([0.0, 1.0, 0.1, 0.0, 0.0], 1, true),
            unknown([-1.0, 0.0, -h, 0.0, 0.0], 1, false),
        ];
        let (x0, x1, y) = (2.0, 10.0, 2.0);
        let mut z = vec![x0, y, x1, y];
        let mu = [0.4, 0.4];
        let ok = within_cones(
            &u,
            &mut z,
            &Cones {
                friction: &mu,
                sticking: &[true, true],
            },
        );
        assert!(ok);
        assert!((z[1] - 0.4 * x0).abs() < 1e-12, "{z:?}");
        assert!((z[1] + z[3] - 2.0 * y).abs() < 1e-12);
        assert!((z[0] - x0).abs() < 1e-12 && (z[2] - x1).abs() < 1e-12);
    }

    /// When the total friction exceeds mu (x0 + x1) no split holds both feet.
    #[test]
    fn too_much_friction_cannot_stick() {
        let u = [
            unknown([0.0, 1.0, -0.1, 0.0, 0.0], 0, true),
            unknown([-1.0, 0.0, -0.03, 0.0, 0.0], 0, false),
            unknown([0.0, 1.0, 0.1, 0.0, 0.0], 1, true),
            unknown([-1.0, 0.0, -0.03, 0.0, 0.0], 1, false),
        ];
        let mut z = vec![2.0, 2.6, 3.0, 2.6];
        let ok = within_cones(
            &u,
            &mut z,
            &Cones {
                friction: &[0.4, 0.4],
                sticking: &[true, true],
            },
        );
        assert!(!ok);
        // Least violation: both feet equally over their cones' sum.
        assert!((z[1] + z[3] - 5.2).abs() < 1e-12);
    }
}
