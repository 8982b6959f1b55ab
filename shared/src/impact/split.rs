//! Sharing the impulses (or forces) that the equations leave undetermined, within
//! the friction cones.
//!
//! With two or more closed contacts on one rigid body, the equations of a candidate
//! set of contact states fix the impulse rates only up to **internal forces**:
//! combinations `z` of the unknowns with `G z = 0`, where the columns of `G` are the
//! generalized directions of the unknowns (a normal rate along `J_n - mu s J_t` for
//! a slipping contact, `J_n` and `J_t` for a sticking one). Two sticking feet can
//! squeeze or stretch the body between them without changing its motion. The
//! equations' weighted minimum-norm solution `z0` ([`super::linalg`]) shares them
//! by the contacts' weights, but may put one sticking contact outside its cone
//! while another has friction to spare. The rates taken are the ones closest to
//! `z0` with every normal rate `>= 0` and every sticking contact inside its cone:
//!
//! ```text
//!   min |z - z0|_D   subject to   z - z0 in null(G),
//!                                 x_j(z) >= 0,   |y_k(z)| <= mu_k x_k(z),
//!   |v|_D^2 = sum_r v_r^2 / w_r   (w_r: the weight of the unknown's contact)
//! ```
//!
//! a convex quadratic program (Boyd & Vandenberghe, *Convex Optimization*, 2004,
//! sec. 4.4); the indeterminacy of redundant contact forces and the choice among
//! them is discussed by Pfeiffer & Glocker, *Multibody Dynamics with Unilateral
//! Contacts* (1996).
//!
//! **The null space from the Delassus matrix alone.** With `E` the map from the
//! unknowns to the contact impulses (`P_n,j = x_j`; `P_t,j = -mu_j s_j x_j` for a
//! slipping contact, `y_k` for a sticking one) the generalized force is
//! `J^T E z`, and since `M` is positive definite
//!
//! ```text
//!   G z = J^T E z = 0   <=>   z^T E^T J M^-1 J^T E z = z^T Q z = 0   <=>   Q z = 0,
//!   Q = E^T W E   (symmetric, positive semi-definite)
//! ```
//!
//! so the internal forces are the null space of `Q`, found here by Gauss-Jordan
//! elimination with partial pivoting (relative tolerance
//! [`super::linalg::rank_tolerance`]). Internal forces change no contact velocity
//! (`W E z = 0`), so the velocities, the events and the slip checks of a candidate
//! do not depend on the split.
//!
//! **Reduction to a small problem.** `z0 = D A^T w` is `D`-orthogonal to the null
//! space of the candidate's system matrix `A`, which contains `null(G)`; so with a
//! basis `N` of `null(G)` made `D`-orthonormal (Gram-Schmidt),
//! `|z0 + N c|_D^2 = |z0|_D^2 + |c|^2`: the closest split is the `c` of least
//! Euclidean norm within the linear constraints `a_l . c + b_l >= 0`.
//!
//! - **One internal force** (two contacts sharing, the usual case): the
//!   constraints bound `c` to an interval `[lo, hi]`, and the answer is exact:
//!   `c = clamp(0, lo, hi)`.
//! - **More** (three or more contacts sharing): the projection's optimality
//!   conditions as a linear complementarity problem with the positive
//!   semi-definite matrix `A A^T` (one multiplier per constraint), solved by
//!   Lemke's method ([`super::lemke`]): a finite number of pivots, ending at the
//!   point of least norm, or at a ray that proves no split exists. (Hildreth's
//!   method, cyclic coordinate ascent on the same dual, converges only in the
//!   limit and could not tell an empty feasible set before its 500 sweeps were
//!   spent. Cyclic coordinate descent on `c` itself stops at
//!   corners where the constraints couple the coordinates: on three sticking feet it ended 0.5 % farther than the true
//!   closest split, the test `three_feet_against_a_scan`.)
//!
//! Where no split is found, the rates are left where the largest violation
//! `max_l -(a_l c + b_l)` is smallest: exactly for one internal force (a convex
//! piecewise-linear function of one coordinate, least where two of its lines
//! cross); for more, as the solution of one strictly convex problem that
//! weighs the violation against the distance from `z0` (`least_violation`),
//! solved by Lemke's method like the projection. Its solution moves
//! continuously with the state, so a split that stops holding every cone
//! misses by little at first, and the plant's event functions (`lambda_n`,
//! `mu lambda_n - |lambda_t|`) report the violation where it begins.

use super::lemke::{pivot_cap, Lcp, Lemke};
use super::linalg::{rank_tolerance, DIM};
use super::outcome::SlipState;
use super::problem::{slip_coeff, ImpactProblem};
use crate::real::Real;

/// Most constraints: a normal and two cone sides per contact.
const MAX_CONSTRAINTS: usize = 3 * super::MAX_CONTACTS;

/// What [`within_cones`] did.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Split {
    /// The given rates already satisfied every constraint; unchanged.
    Inside,
    /// Moved along the internal forces to a split satisfying every constraint.
    Moved,
    /// No split found that satisfies every constraint; the rates are left where
    /// the largest violation is smallest.
    Infeasible,
}

impl Split {
    /// True when the rates satisfy every constraint.
    pub fn feasible(self) -> bool {
        self != Split::Infeasible
    }
}

/// The unknowns of a candidate: contact index and kind (normal or tangential),
/// and the impulse each puts on its contact.
struct Unknowns<T, const D: usize> {
    contact: [usize; D],
    normal: [bool; D],
    /// The components (normal, tangential) of each unknown's impulse at its
    /// contact `i` per unit of it, a column of `E`: a normal unknown puts
    /// `(1, -mu_i s_i)` on `(P_n,i, P_t,i)` (Coulomb's `y = -mu s x` while
    /// slipping, 0 while sticking), a tangential one `(0, 1)`.
    impulse: [(T, T); D],
    len: usize,
}

impl<T: Real, const D: usize> Unknowns<T, D> {
    /// The unknowns of the active contacts, in the order of the candidate's
    /// equations: contact by contact, its normal rate (where `normals_free`),
    /// then its tangential rate where it sticks (a slipping contact's is
    /// `-mu s x`, no unknown of its own).
    fn of<const N: usize>(
        p: &ImpactProblem<T, N>,
        active: &[bool; N],
        mode: &[SlipState; N],
        normals_free: bool,
    ) -> Self {
        let mut u = Unknowns {
            contact: [0; D],
            normal: [false; D],
            impulse: [(T::ZERO, T::ZERO); D],
            len: 0,
        };
        for i in 0..p.len {
            if !active[i] {
                continue;
            }
            if normals_free {
                u.contact[u.len] = i;
                u.normal[u.len] = true;
                u.impulse[u.len] = (T::ONE, slip_coeff(p, mode, i));
                u.len += 1;
            }
            if mode[i] == SlipState::Stick {
                u.contact[u.len] = i;
                u.normal[u.len] = false;
                u.impulse[u.len] = (T::ZERO, T::ONE);
                u.len += 1;
            }
        }
        u
    }

    /// `Q = E^T W E` over these unknowns (m/s per N s): `Q z = 0` exactly for
    /// the internal forces `z`, the rates that change no generalized force (the
    /// module documentation: `G z = J^T E z = 0 <=> z^T Q z = 0`, `M` positive
    /// definite). With `(n_a, t_a)` unknown `a`'s impulse at its contact `i` and
    /// `(n_b, t_b)` unknown `b`'s at `j`:
    ///
    /// ```text
    ///   Q_ab = n_a n_b W_nn,ij + n_a t_b W_nt,ij + t_a n_b W_tn,ij + t_a t_b W_tt,ij
    /// ```
    fn internal_force_matrix<const N: usize>(&self, p: &ImpactProblem<T, N>) -> [[T; D]; D] {
        let mut q = [[T::ZERO; D]; D];
        for a in 0..self.len {
            let (na, ta) = self.impulse[a];
            let i = self.contact[a];
            for b in 0..self.len {
                let (nb, tb) = self.impulse[b];
                let j = self.contact[b];
                q[a][b] = na * nb * p.w_nn[i][j]
                    + na * tb * p.w_nt[i][j]
                    + ta * nb * p.w_nt[j][i]
                    + ta * tb * p.w_tt[i][j];
            }
        }
        q
    }

    /// The candidate's equations' own square matrix `A = S W E` over these
    /// unknowns (m/s per N s): one row per unknown, in the unknowns' order
    /// (contact `i`'s normal row for its normal unknown, its tangential row for
    /// a sticking one's tangential unknown). `A z = 0` for every change `z` of
    /// the rates that keeps the equations (the normal rates of the active
    /// contacts and the tangential ones of the sticking contacts). With
    /// `(n_b, t_b)` unknown `b`'s impulse at its contact `j`:
    ///
    /// ```text
    ///   row (i, normal):      A_ab = W_nn,ij n_b + W_nt,ij t_b
    ///   row (i, tangential):  A_ab = W_tn,ij n_b + W_tt,ij t_b
    /// ```
    fn mode_equations_matrix<const N: usize>(&self, p: &ImpactProblem<T, N>) -> [[T; D]; D] {
        let mut rows = [[T::ZERO; D]; D];
        for (a, row) in rows.iter_mut().enumerate().take(self.len) {
            let i = self.contact[a];
            for b in 0..self.len {
                let (nb, tb) = self.impulse[b];
                let j = self.contact[b];
                row[b] = if self.normal[a] {
                    nb * p.w_nn[i][j] + tb * p.w_nt[i][j]
                } else {
                    nb * p.w_nt[j][i] + tb * p.w_tt[i][j]
                };
            }
        }
        rows
    }

    /// The first `k` rows of `basis` (coefficients of these unknowns) as
    /// changes of the rates `(x, y)` per contact (the rates' units: N s per unit
    /// `lambda` in an impact, N for the forces of persistent contact): a normal
    /// unknown `z_r` of contact `i` changes `x_i` by `z_r` and `y_i` by
    /// `-mu_i s_i z_r`; a tangential one changes `y_i` by `z_r`.
    fn as_rates<const N: usize>(
        &self,
        basis: &[[T; D]; D],
        k: usize,
    ) -> ([[T; N]; D], [[T; N]; D]) {
        let mut dx = [[T::ZERO; N]; D];
        let mut dy = [[T::ZERO; N]; D];
        for c in 0..k {
            for r in 0..self.len {
                let i = self.contact[r];
                if self.normal[r] {
                    dx[c][i] += basis[c][r];
                    dy[c][i] += self.impulse[r].1 * basis[c][r];
                } else {
                    dy[c][i] += basis[c][r];
                }
            }
        }
        (dx, dy)
    }
}

/// Moves the rates `(x, y)` of the contacts `active` in states `mode` along the
/// internal forces to the closest split (weighted norm, the contacts' weights) with
/// every active normal rate `>= 0` and every sticking contact inside its cone.
///
/// `normals_free`: the normal rates are unknowns of the candidate (false when they
/// are fixed, as under Poisson's and Stronge's laws: then only the sticking
/// contacts' tangential rates can move). `tol`: the absolute slack of the final
/// check, in the units of the rates. Slipping contacts keep `y = -mu s x`.
/// The module documentation gives the problem and the method.
#[allow(clippy::too_many_arguments)]
pub fn within_cones<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    active: &[bool; N],
    mode: &[SlipState; N],
    normals_free: bool,
    x: &mut [T; N],
    y: &mut [T; N],
    tol: T,
) -> Split {
    split(p, active, mode, normals_free, Freedom::Internal, x, y, tol)
}

/// [`within_cones`] along every solution of the candidate's equations, not only
/// its internal forces: the closest split (to the weighted minimum-norm one the
/// rates are) among all rates that keep every active contact's normal rate at
/// its value (`(W E z)_n = 0`) and every sticking contact's tangential one
/// (`(W E z)_t = 0`), with every normal rate `>= 0` and every sticking contact
/// inside its cone.
///
/// With slipping contacts this is a larger set than the internal forces: a
/// change of the normal rates may change the slipping contacts' tangential rates
/// (the motion), which their equations leave free. Where several bodies' feet
/// slip on one line, the equations leave such a choice, and the internal forces
/// alone cannot reach a split with every normal rate `>= 0` although the mode
/// decision found one. The null space is then that of the equations' own square
/// matrix `A = S W E` (`S` selecting the rows they hold, one per unknown); `z0`,
/// the weighted minimum-norm solution of `A z = -b`, is `D`-orthogonal to it, so
/// the reduction to the least `|c|` holds as for the internal forces.
#[allow(clippy::too_many_arguments)]
pub fn within_mode_equations<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    active: &[bool; N],
    mode: &[SlipState; N],
    x: &mut [T; N],
    y: &mut [T; N],
    tol: T,
) -> Split {
    split(p, active, mode, true, Freedom::ModeEquations, x, y, tol)
}

/// Which changes of the rates a split may make.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Freedom {
    /// Internal forces only (`G z = 0`): the motion is unchanged.
    Internal,
    /// Any solution of the candidate's equations (`S W E z = 0`).
    ModeEquations,
}

/// [`within_cones`] with the changes `freedom` allows.
#[allow(clippy::too_many_arguments)]
fn split<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    active: &[bool; N],
    mode: &[SlipState; N],
    normals_free: bool,
    freedom: Freedom,
    x: &mut [T; N],
    y: &mut [T; N],
    tol: T,
) -> Split {
    if satisfied(p, active, mode, x, y, tol) {
        return Split::Inside;
    }
    // Storage sized to the active contacts (`D` >= 2 unknowns and `C` >= 3
    // constraints each; never more than `N` contacts): the same arithmetic as in
    // the capacity's, without zeroing it (16 contacts: 48 constraints in 32
    // coordinates) at every split.
    let a = (0..p.len).filter(|&i| active[i]).count();
    let args = (p, active, mode, normals_free, freedom);
    if a <= 2 || N <= 2 {
        split_in::<T, N, 4, 6>(args, x, y, tol)
    } else if a <= 4 || N <= 4 {
        split_in::<T, N, 8, 12>(args, x, y, tol)
    } else if a <= 8 || N <= 8 {
        split_in::<T, N, 16, 24>(args, x, y, tol)
    } else {
        split_in::<T, N, DIM, MAX_CONSTRAINTS>(args, x, y, tol)
    }
}

/// [`within_cones`] for rates outside the cones, in storage of `D` unknowns and
/// `C` constraints: the directions the split may take (a basis of the null space
/// that `freedom` names, orthonormal in the contacts' weights), the constraints
/// along them, the closest coefficients within those (or the least violation),
/// and the rates moved by them.
#[inline(never)]
#[allow(clippy::type_complexity)]
fn split_in<T: Real, const N: usize, const D: usize, const C: usize>(
    (p, active, mode, normals_free, freedom): (
        &ImpactProblem<T, N>,
        &[bool; N],
        &[SlipState; N],
        bool,
        Freedom,
    ),
    x: &mut [T; N],
    y: &mut [T; N],
    tol: T,
) -> Split {
    let u = Unknowns::<T, D>::of(p, active, mode, normals_free);
    if u.len == 0 {
        return Split::Infeasible;
    }
    let mut basis = [[T::ZERO; D]; D];
    let k = free_directions(p, &u, freedom, &mut basis);
    if k == 0 {
        // No internal force: the split is what the equations gave.
        return Split::Infeasible;
    }
    let (dx, dy) = u.as_rates(&basis, k);
    let rows = ConstraintRows::<T, D, C>::along(p, active, mode, (x, y), (&dx, &dy), k);
    let coef = rows.closest(k, tol);
    move_rates(x, y, &coef, (&dx, &dy), k, p.len);
    if satisfied(p, active, mode, x, y, tol) {
        Split::Moved
    } else {
        Split::Infeasible
    }
}

/// The directions a split may take, in the rows of `basis`; returns their
/// number. A basis of the null space of `Q = E^T W E` (the internal forces, by
/// Gauss-Jordan elimination) or of the equations' own matrix `A = S W E` (every
/// solution of them, by the singular value decomposition, whose null vectors
/// move continuously where `A` is close to losing two ranks), made orthonormal
/// in the weighted inner product `<u, v> = sum_r u_r v_r / w_r` (`w_r` the
/// weight of unknown `r`'s contact) so that the closest split is the least
/// `|c|`: the module documentation gives the reduction.
fn free_directions<T: Real, const N: usize, const D: usize>(
    p: &ImpactProblem<T, N>,
    u: &Unknowns<T, D>,
    freedom: Freedom,
    basis: &mut [[T; D]; D],
) -> usize {
    let m = u.len;
    let k = match freedom {
        Freedom::Internal => null_space(&mut u.internal_force_matrix(p), m, basis),
        Freedom::ModeEquations => null_space_by_svd(&mut u.mode_equations_matrix(p), m, basis),
    };
    let mut weights = [T::ONE; D];
    for (r, w) in weights.iter_mut().enumerate().take(m) {
        *w = p.contacts[u.contact[r]].weight;
    }
    orthonormalize(basis, k, m, &weights)
}

/// The constraints `a_l . c + b_l >= 0` of a split in the coordinates `c` of
/// the free directions, in the rates' units: every active normal rate `>= 0`
/// and both sides of every sticking contact's cone ([`constraints`]), in `C`
/// rows of `D` coordinates.
struct ConstraintRows<T, const D: usize, const C: usize> {
    a: [[T; D]; C],
    b: [T; C],
    count: usize,
}

impl<T: Real, const D: usize, const C: usize> ConstraintRows<T, D, C> {
    /// The constraints on a step from the rates `(x, y)` along the first `k`
    /// directions `(dx, dy)`: row `l`'s `a_l` has one coordinate per direction,
    /// `b_l` its value at the rates themselves.
    fn along<const N: usize>(
        p: &ImpactProblem<T, N>,
        active: &[bool; N],
        mode: &[SlipState; N],
        (x, y): (&[T; N], &[T; N]),
        (dx, dy): (&[[T; N]; D], &[[T; N]; D]),
        k: usize,
    ) -> Self {
        let mut rows = ConstraintRows {
            a: [[T::ZERO; D]; C],
            b: [T::ZERO; C],
            count: 0,
        };
        for c in 0..k {
            let mut cs = [(T::ZERO, T::ZERO); C];
            rows.count = constraints(p, active, mode, x, y, &dx[c], &dy[c], &mut cs);
            for (l, &(a, b)) in cs.iter().enumerate().take(rows.count) {
                rows.a[l][c] = a;
                rows.b[l] = b;
            }
        }
        rows
    }

    /// The coefficients `c` of the split along the first `k` directions: the
    /// least `|c|` within every constraint, or where none satisfies them all,
    /// the least largest violation. For one direction exactly ([`best_step`]:
    /// `c = clamp(0, lo, hi)`, or where two of the violations' lines cross);
    /// for more, the projection's complementarity problem ([`closest_split`]),
    /// else [`least_violation`]'s; zero (the rates as the equations gave them)
    /// where neither was solved within the pivot cap.
    fn closest(&self, k: usize, tol: T) -> [T; D] {
        let (a, b, count) = (&self.a, &self.b, self.count);
        let mut coef = [T::ZERO; D];
        let found = if k == 1 {
            let mut cs = [(T::ZERO, T::ZERO); C];
            for l in 0..count {
                cs[l] = (a[l][0], b[l]);
            }
            coef[0] = best_step(&cs[..count], T::ZERO);
            true
        } else {
            closest_split(a, b, count, k, tol, &mut coef)
        };
        if !found && !least_violation(a, b, count, k, &mut coef) {
            // Not even the least violation solved within the pivot cap: the
            // rates as the equations gave them.
            coef = [T::ZERO; D];
        }
        coef
    }
}

/// Moves the rates `(x, y)` of the first `n` contacts (N s per unit `lambda`,
/// or N) by `sum_c coef_c (dx_c, dy_c)` over the first `k` directions, added
/// direction by direction.
fn move_rates<T: Real, const N: usize, const D: usize>(
    x: &mut [T; N],
    y: &mut [T; N],
    coef: &[T; D],
    (dx, dy): (&[[T; N]; D], &[[T; N]; D]),
    k: usize,
    n: usize,
) {
    for c in 0..k {
        for i in 0..n {
            x[i] += coef[c] * dx[c][i];
            y[i] += coef[c] * dy[c][i];
        }
    }
}

/// The point of least Euclidean norm `c` with `a_l . c + b_l >= -tol / 4` for the
/// first `count` rows, as the linear complementarity problem of its optimality
/// conditions (Karush-Kuhn-Tucker; Cottle, Pang & Stone, *The Linear
/// Complementarity Problem*, sec. 1.2, the LCP of a convex quadratic program):
///
/// ```text
///   c = A^T mu,   mu >= 0,   v = A A^T mu + b + tol/4 >= 0,   mu . v = 0
/// ```
///
/// solved by Lemke's method ([`super::lemke`]). `A A^T` is positive
/// semi-definite, so Lemke's path ends at the solution, or at a secondary ray
/// exactly when no `c` satisfies the constraints (Cottle, Pang & Stone,
/// Thm. 4.4.13): an infeasible split is found out within the pivot cap
/// ([`super::lemke::pivot_cap`] of `count`), each pivot `O(count^2)`. Returns true
/// with `c` where solved; false otherwise (no split, or the cap).
fn closest_split<T: Real, const D: usize, const C: usize>(
    a: &[[T; D]; C],
    b: &[T; C],
    count: usize,
    k: usize,
    tol: T,
    c: &mut [T; D],
) -> bool {
    let problem = Projection {
        a,
        b,
        count,
        k,
        shift: tol * T::from_f64(0.25),
        spread: T::ZERO,
    };
    project::<T, D, C>(&problem, c)
}

/// Where no split satisfies the constraints: the `c` that makes the largest
/// violation `s = max_l -(a_l . c + b_l)` least, found as the strictly convex
/// problem
///
/// ```text
///   min |c|^2 + (s / e)^2   subject to   a_l . c + b_l + s >= 0,
/// ```
///
/// whose optimality conditions (as in [`closest_split`], with `sigma = s / e`
/// one more coordinate of every row, of coefficient `e`) are the complementarity
/// problem `M = A A^T + e^2 1 1^T`, `q = b`. Its solution is unique and moves
/// continuously with `b`, so a force that leaves its cone does so continuously
/// and the event functions built on it cross zero rather than jump; its
/// violation exceeds the least one by at most `e |c|`: with `e^2` the square
/// root of the machine epsilon times the largest `|a_l|^2` (1.5e-8 in f64), a
/// ten-thousandth of the forces' scale. The problem is always feasible (a large
/// `s`), so Lemke's path ends at its solution (Cottle, Pang & Stone,
/// Thm. 4.4.13). (Coordinate descent on the largest violation stops at
/// corners of that non-smooth function: on two hinged bodies with four
/// sticking feet it left every foot 3.6 N outside where a split within 1e-8 N
/// existed an instant before.) Returns true with `c` where solved; false only
/// at the pivot cap.
fn least_violation<T: Real, const D: usize, const C: usize>(
    a: &[[T; D]; C],
    b: &[T; C],
    count: usize,
    k: usize,
    c: &mut [T; D],
) -> bool {
    let largest = a[..count].iter().fold(T::ZERO, |s, row| {
        s.max((0..k).fold(T::ZERO, |s, j| s + row[j] * row[j]))
    });
    let problem = Projection {
        a,
        b,
        count,
        k,
        shift: T::ZERO,
        spread: T::EPSILON.sqrt() * largest,
    };
    project::<T, D, C>(&problem, c)
}

/// Solves `problem` by Lemke's method and writes `c = A^T mu` (the violation's
/// coordinate aside). Returns false where the path ends without a solution.
fn project<T: Real, const D: usize, const C: usize>(
    problem: &Projection<'_, T, D>,
    c: &mut [T; D],
) -> bool {
    let (a, count, k) = (problem.a, problem.count, problem.k);
    // The workspace sized to the constraints, on the stack of a call that is not
    // inlined (a few constraints never reserve the largest basis inverse).
    let mu = &mut [T::ZERO; C];
    // (`count <= C`: the sizes above `C` are never taken.)
    let solved = if count <= 8 || C <= 8 {
        project_in::<T, D, 8>(problem, mu)
    } else if count <= 16 || C <= 16 {
        project_in::<T, D, 16>(problem, mu)
    } else if count <= 32 || C <= 32 {
        project_in::<T, D, 32>(problem, mu)
    } else {
        project_in::<T, D, MAX_CONSTRAINTS>(problem, mu)
    };
    *c = [T::ZERO; D];
    if !solved {
        return false;
    }
    for l in 0..count {
        for j in 0..k {
            c[j] += mu[l] * a[l][j];
        }
    }
    true
}

/// [`closest_split`]'s problem in a workspace of `C` constraints: `mu` where
/// solved.
#[inline(never)]
fn project_in<T: Real, const D: usize, const L: usize>(
    p: &Projection<'_, T, D>,
    mu: &mut [T],
) -> bool {
    let mut work: Lemke<T, L> = Lemke::new();
    if !work.solve(p, pivot_cap(p.count)).solved() {
        return false;
    }
    mu[..p.count].copy_from_slice(work.z());
    true
}

/// The projection's complementarity problem: `M = A A^T + spread 1 1^T`,
/// `q = b + shift`.
struct Projection<'a, T, const D: usize> {
    a: &'a [[T; D]],
    b: &'a [T],
    count: usize,
    k: usize,
    shift: T,
    /// `e^2` of [`least_violation`]; zero for [`closest_split`].
    spread: T,
}

impl<T: Real, const D: usize> Lcp<T> for Projection<'_, T, D> {
    fn size(&self) -> usize {
        self.count
    }
    fn q(&self, i: usize) -> T {
        self.b[i] + self.shift
    }
    fn column(&self, j: usize, out: &mut [T]) {
        let aj = &self.a[j];
        for (o, ai) in out.iter_mut().zip(&self.a[..self.count]) {
            *o = (0..self.k).fold(self.spread, |s, m| s + ai[m] * aj[m]);
        }
    }
}

/// True when every active normal rate is `>= -tol` and every sticking contact's
/// `|y| <= mu max(x, 0) + tol`.
fn satisfied<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    active: &[bool; N],
    mode: &[SlipState; N],
    x: &[T; N],
    y: &[T; N],
    tol: T,
) -> bool {
    (0..p.len).all(|i| {
        !active[i]
            || (x[i] >= -tol
                && (mode[i] != SlipState::Stick
                    || y[i].abs() <= p.contacts[i].friction * x[i].max(T::ZERO) + tol))
    })
}

/// The constraints `a t + b >= 0` on a step `t` along `(dx, dy)` from `(x, y)`:
/// normal rates `>= 0` and both sides of every sticking contact's cone. Returns
/// their number.
#[allow(clippy::too_many_arguments)]
fn constraints<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    active: &[bool; N],
    mode: &[SlipState; N],
    x: &[T; N],
    y: &[T; N],
    dx: &[T; N],
    dy: &[T; N],
    out: &mut [(T, T)],
) -> usize {
    let mut count = 0;
    for i in 0..p.len {
        if !active[i] {
            continue;
        }
        out[count] = (dx[i], x[i]);
        count += 1;
        if mode[i] == SlipState::Stick {
            let mu = p.contacts[i].friction;
            // mu x - y >= 0 and mu x + y >= 0.
            out[count] = (mu * dx[i] - dy[i], mu * x[i] - y[i]);
            out[count + 1] = (mu * dx[i] + dy[i], mu * x[i] + y[i]);
            count += 2;
        }
    }
    count
}

/// The step closest to `target` within every constraint `a t + b >= 0`, or, where
/// they admit none, the one with the smallest largest violation.
///
/// A constraint the step cannot move (`|a|` within the rank tolerance of the
/// largest) is left as it is: violated, by rounding or not, it cannot make the
/// others' interval empty nor choose where in it the step goes. (Counted as
/// emptying the interval, a contact at exactly zero force whose `b` went from 0
/// to -1e-17 sent the split to the least violation of the rest, 0.045 N outside,
/// although the same point was still within every movable constraint: the
/// forces jumped at that instant, and the lift-off's event function with them.)
fn best_step<T: Real>(cs: &[(T, T)], target: T) -> T {
    let a_scale = cs.iter().fold(T::ZERO, |s, &(a, _)| s.max(a.abs()));
    let eps = rank_tolerance::<T>() * a_scale;
    let movable = |&&(a, _): &&(T, T)| a.abs() > eps;
    let mut lo: Option<T> = None;
    let mut hi: Option<T> = None;
    for &(a, b) in cs.iter().filter(movable) {
        let v = -b / a;
        if a > T::ZERO {
            lo = Some(lo.map_or(v, |l| l.max(v)));
        } else {
            hi = Some(hi.map_or(v, |h| h.min(v)));
        }
    }
    if !matches!((lo, hi), (Some(l), Some(h)) if l > h) {
        let mut t = target;
        if let Some(l) = lo {
            t = t.max(l);
        }
        if let Some(h) = hi {
            t = t.min(h);
        }
        return t;
    }
    // Empty: minimize the largest violation max_l -(a_l t + b_l) of the movable
    // constraints, convex and piecewise linear: its minimum is where two of the
    // lines cross (or t = 0, where the search starts).
    let violation = |t: T| {
        cs.iter()
            .filter(movable)
            .fold(None, |m: Option<T>, &(a, b)| {
                let v = -(a * t + b);
                Some(m.map_or(v, |m| m.max(v)))
            })
            .unwrap_or(T::ZERO)
    };
    let mut best = (violation(T::ZERO), T::ZERO);
    for (i, &(a1, b1)) in cs.iter().enumerate().filter(|(_, c)| movable(c)) {
        for &(a2, b2) in cs[i + 1..].iter().filter(movable) {
            if (a1 - a2).abs() > eps {
                let t = (b2 - b1) / (a1 - a2);
                let v = violation(t);
                if v < best.0 {
                    best = (v, t);
                }
            }
        }
    }
    best.1
}

/// Most sweeps of [`null_space_by_svd`]'s rotations (they converge
/// quadratically: a few sweeps for the sizes here).
const SVD_SWEEPS: usize = 30;

/// A basis of the null space of the leading `m x m` block of `a` (destroyed), its
/// vectors in the rows of `basis`, orthonormal; returns their number. By the
/// one-sided Jacobi method (Hestenes 1958; Demmel & Veselic, *Jacobi's method is
/// more accurate than QR*, SIAM J. Matrix Anal. Appl. 13, 1992): plane rotations
/// `V` applied to the columns of `a` until every two are orthogonal, so that
/// `a V = U S`; the columns of `V` whose column of `a V` has a norm (a singular
/// value) within the rank tolerance of the largest span the null space.
///
/// The modes' equations' matrix can be close to losing two ranks (feet of two
/// hinged bodies slipping on one line). There the null vector that Gauss-Jordan
/// elimination returns depends on which pivots it takes, and changed direction
/// between two states 1e-13 s apart, the split's forces and the lift-off's
/// event function with it; the singular vector of the least singular value moves
/// continuously while that value is simple.
fn null_space_by_svd<T: Real, const D: usize>(
    a: &mut [[T; D]; D],
    m: usize,
    basis: &mut [[T; D]; D],
) -> usize {
    let mut v = [[T::ZERO; D]; D];
    for (i, row) in v.iter_mut().enumerate().take(m) {
        row[i] = T::ONE;
    }
    for _ in 0..SVD_SWEEPS {
        let mut rotated = false;
        for p in 0..m {
            for q in p + 1..m {
                let (mut alpha, mut beta, mut gamma) = (T::ZERO, T::ZERO, T::ZERO);
                for row in a.iter().take(m) {
                    alpha += row[p] * row[p];
                    beta += row[q] * row[q];
                    gamma += row[p] * row[q];
                }
                if gamma.abs() <= T::EPSILON * (alpha * beta).sqrt() {
                    continue;
                }
                rotated = true;
                // The rotation that makes columns p and q orthogonal:
                // zeta = (beta - alpha) / (2 gamma), t = sign(zeta) / (|zeta| +
                // sqrt(1 + zeta^2)), c = 1 / sqrt(1 + t^2), s = c t.
                let zeta = (beta - alpha) / (T::from_f64(2.0) * gamma);
                let sign = if zeta < T::ZERO { -T::ONE } else { T::ONE };
                let t = sign / (zeta.abs() + (T::ONE + zeta * zeta).sqrt());
                let c = T::ONE / (T::ONE + t * t).sqrt();
                let s = c * t;
                for row in a.iter_mut().take(m).chain(v.iter_mut().take(m)) {
                    let (x, y) = (row[p], row[q]);
                    row[p] = c * x - s * y;
                    row[q] = s * x + c * y;
                }
            }
        }
        if !rotated {
            break;
        }
    }
    let norm = |j: usize| {
        a.iter()
            .take(m)
            .fold(T::ZERO, |s, row| s + row[j] * row[j])
            .sqrt()
    };
    let largest = (0..m).fold(T::ZERO, |s, j| s.max(norm(j)));
    let tol = rank_tolerance::<T>() * largest;
    let mut k = 0;
    for j in 0..m {
        if norm(j) <= tol {
            for (r, row) in v.iter().enumerate().take(m) {
                basis[k][r] = row[j];
            }
            k += 1;
        }
    }
    k
}

/// A basis of the null space of the leading `m x m` block of `q` (destroyed), by
/// Gauss-Jordan elimination with partial pivoting; its vectors in the rows of
/// `basis`. Returns their number.
fn null_space<T: Real, const D: usize>(
    q: &mut [[T; D]; D],
    m: usize,
    basis: &mut [[T; D]; D],
) -> usize {
    let scale = (0..m).fold(T::ZERO, |s, i| (0..m).fold(s, |s, j| s.max(q[i][j].abs())));
    let tol = rank_tolerance::<T>() * scale;
    let mut pivot_col = [0usize; D];
    let mut is_pivot = [false; D];
    let mut rank = 0;
    for col in 0..m {
        if rank == m {
            break;
        }
        let mut pr = rank;
        for r in rank..m {
            if q[r][col].abs() > q[pr][col].abs() {
                pr = r;
            }
        }
        if q[pr][col].abs() <= tol {
            continue;
        }
        q.swap(rank, pr);
        let pv = q[rank][col];
        for v in q[rank].iter_mut().take(m) {
            *v = *v / pv;
        }
        for r in 0..m {
            if r != rank {
                let f = q[r][col];
                if f != T::ZERO {
                    for c in 0..m {
                        let d = f * q[rank][c];
                        q[r][c] -= d;
                    }
                }
            }
        }
        pivot_col[rank] = col;
        is_pivot[col] = true;
        rank += 1;
    }
    let mut k = 0;
    for free in 0..m {
        if is_pivot[free] {
            continue;
        }
        let v = &mut basis[k];
        *v = [T::ZERO; D];
        v[free] = T::ONE;
        for (r, &pc) in pivot_col.iter().enumerate().take(rank) {
            v[pc] = -q[r][free];
        }
        k += 1;
    }
    k
}

/// Makes the first `k` rows of `basis` orthonormal in the inner product
/// `<u, v> = sum u_r v_r / w_r` (modified Gram-Schmidt), dropping dependent ones.
/// Returns how many remain.
fn orthonormalize<T: Real, const D: usize>(
    basis: &mut [[T; D]; D],
    k: usize,
    m: usize,
    w: &[T; D],
) -> usize {
    let dot = |a: &[T; D], b: &[T; D]| (0..m).fold(T::ZERO, |s, r| s + a[r] * b[r] / w[r]);
    let mut kept = 0;
    for c in 0..k {
        let mut v = basis[c];
        let before = dot(&v, &v).sqrt();
        for b in basis.iter().take(kept) {
            let f = dot(&v, b);
            for r in 0..m {
                v[r] -= f * b[r];
            }
        }
        let norm = dot(&v, &v).sqrt();
        // Dependent (or not finite): dropped.
        let keep = norm > rank_tolerance::<T>().sqrt() * before;
        if !keep {
            continue;
        }
        for e in v.iter_mut().take(m) {
            *e = *e / norm;
        }
        basis[kept] = v;
        kept += 1;
    }
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::impact::body::{body_problem, BodyContact, PlanarBody};
    use crate::impact::problem::{ContactLaw, ImpactLaw};

    /// Two nearly parallel constraints, `c1 >= 1` and `-c1 + d c2 + 1 - d >= 0`
    /// with `d = 1e-3`: the closest point is `(1, 1)`, both active, with the
    /// multipliers `1 + 1/d` and `1/d`. Hildreth's coordinate ascent gains a
    /// factor of about `1 - d^2` per sweep here and was not feasible after its 500
    /// sweeps (no split); the complementarity problem is exact in a few pivots.
    /// And the same pair made contradictory (`c1 >= 1`, `c1 <= 0`) is no split.
    #[test]
    fn nearly_parallel_constraints_are_exact() {
        let d = 1e-3;
        let mut a = [[0.0; DIM]; MAX_CONSTRAINTS];
        let mut b = [0.0; MAX_CONSTRAINTS];
        a[0][0] = 1.0;
        b[0] = -1.0;
        a[1][0] = -1.0;
        a[1][1] = d;
        b[1] = 1.0 - d;
        let mut c = [0.0; DIM];
        assert!(closest_split(&a, &b, 2, 2, 1e-12, &mut c));
        assert!(
            (c[0] - 1.0).abs() < 1e-9 && (c[1] - 1.0).abs() < 1e-9,
            "{:?}",
            &c[..2]
        );
        a[1][1] = 0.0;
        b[1] = 0.0;
        assert!(!closest_split(&a, &b, 2, 2, 1e-12, &mut c));
    }

    /// Three feet on one line, slipping, each with its own friction (not linear
    /// in the feet's positions): the columns `J_n - mu s J_t` of the three are
    /// independent, so there is no internal force, but the normal rows see only two of the body's three coordinates, so
    /// the equations that hold the feet's normal rates leave one direction free
    /// (it changes the slip's rate). A split with a foot pulling is out of reach of
    /// the internal forces and within reach of the equations' solutions: moved
    /// there, every normal rate is `>= 0` and every foot's normal velocity rate is
    /// the one it had.
    #[test]
    fn slipping_feet_of_unequal_friction_share_along_the_equations() {
        let p = three_feet([0.2, 0.7, 0.3]);
        let active = [true; 3];
        let mode = [SlipState::SlipPositive; 3];
        let slip = |x: &[f64; 3]| core::array::from_fn(|i| -p.contacts[i].friction * x[i]);
        let x0 = [5.0, -1.0, 5.0];
        let (du_n0, _) = p.velocity_change(&x0, &slip(&x0));
        let (mut x, mut y) = (x0, slip(&x0));
        let internal = within_cones(&p, &active, &mode, true, &mut x, &mut y, 1e-9);
        assert_eq!(internal, Split::Infeasible, "no internal force: {x:?}");
        let (mut x, mut y) = (x0, slip(&x0));
        let s = within_mode_equations(&p, &active, &mode, &mut x, &mut y, 1e-9);
        assert_eq!(s, Split::Moved, "{x:?}");
        assert!(x.iter().all(|&v| v >= -1e-9), "{x:?}");
        let kept = slip(&x);
        for i in 0..3 {
            assert!(
                (y[i] - kept[i]).abs() <= 1e-12,
                "y = -mu s x: {y:?} against {kept:?}"
            );
        }
        let (du_n, _) = p.velocity_change(&x, &y);
        for i in 0..3 {
            assert!(
                (du_n[i] - du_n0[i]).abs() <= 1e-9 * du_n0[i].abs().max(1.0),
                "{du_n:?} against {du_n0:?}"
            );
        }
    }

    /// A level platform at rest: mass 2 kg, inertia 7.3e-3 kg m^2, its centre
    /// 0.03 m above the floor.
    fn platform<T: Real>() -> PlanarBody<T> {
        let f = T::from_f64;
        PlanarBody {
            mass: f(2.0),
            inertia: f(7.3e-3),
            position: [f(0.0), f(0.03)],
            velocity: [f(0.0), f(0.0)],
            angular_velocity: f(0.0),
        }
    }

    /// A foot of [`platform`] on the floor at `x` m, of friction `mu`, without
    /// rebound, of weight 1.
    fn foot<T: Real>(x: f64, mu: f64) -> BodyContact<T> {
        let f = T::from_f64;
        BodyContact {
            point: [f(x), f(0.0)],
            normal: [f(0.0), f(1.0)],
            law: ContactLaw {
                restitution: f(0.0),
                friction: f(mu),
                weight: f(1.0),
            },
        }
    }

    /// [`platform`] standing on two feet at x = -0.1 and +0.1 m with friction
    /// `mu`.
    fn two_feet<T: Real>(mu: f64) -> ImpactProblem<T, 2> {
        let contacts = [-0.1, 0.1].map(|x| foot(x, mu));
        body_problem(&platform(), None, &contacts, ImpactLaw::Newton)
    }

    /// [`platform`] standing on three feet at x = -0.1, 0 and 0.1 m with the
    /// frictions `mu`.
    fn three_feet(mu: [f64; 3]) -> ImpactProblem<f64, 3> {
        let contacts = [(-0.1, mu[0]), (0.0, mu[1]), (0.1, mu[2])].map(|(x, mu)| foot(x, mu));
        body_problem(&platform(), None, &contacts, ImpactLaw::Newton)
    }

    /// [`within_cones`] with every contact of `p` active and sticking, their
    /// normal rates free.
    fn all_sticking<T: Real, const N: usize>(
        p: &ImpactProblem<T, N>,
        x: &mut [T; N],
        y: &mut [T; N],
        tol: T,
    ) -> Split {
        within_cones(p, &[true; N], &[SlipState::Stick; N], true, x, y, tol)
    }

    /// Both feet sticking: the equal (minimum-norm) split of the friction puts the
    /// lightly loaded foot 0 outside its cone; the internal force (equal and
    /// opposite tangential rates: the feet squeeze the platform) moves friction to
    /// foot 1. Hand solution: the total friction `y0 + y1 = 2 Y` and the normals are
    /// fixed by the motion, so the closest split puts foot 0 at its cone's edge,
    /// `y0 = mu x0`, `y1 = 2 Y - mu x0`.
    fn friction_moves_to_the_loaded_foot<T: Real>(tol: f64) {
        let p = two_feet::<T>(0.4);
        let f = T::from_f64;
        let (x0, x1, yy) = (2.0, 10.0, 2.0);
        let mut x = [f(x0), f(x1)];
        let mut y = [f(yy), f(yy)];
        let s = all_sticking(&p, &mut x, &mut y, f(1e-9 * 10.0));
        assert_eq!(s, Split::Moved);
        let close = |a: T, b: f64| (a.to_f64() - b).abs() <= tol * 10.0;
        assert!(close(y[0], 0.4 * x0), "{x:?} {y:?}");
        assert!(close(y[1], 2.0 * yy - 0.4 * x0), "{x:?} {y:?}");
        assert!(close(x[0], x0) && close(x[1], x1), "{x:?} {y:?}");
        // The split changes no contact velocity: it is an internal force.
        let (dn, dt) = p.velocity_change(
            &[f(x[0].to_f64() - x0), f(x[1].to_f64() - x1)],
            &[f(y[0].to_f64() - yy), f(y[1].to_f64() - yy)],
        );
        for v in dn.iter().chain(dt.iter()) {
            assert!(v.to_f64().abs() <= tol * 100.0, "{dn:?} {dt:?}");
        }
    }

    #[test]
    fn friction_moves_to_the_loaded_foot_f64() {
        friction_moves_to_the_loaded_foot::<f64>(1e-12);
    }

    #[test]
    fn friction_moves_to_the_loaded_foot_f32() {
        friction_moves_to_the_loaded_foot::<f32>(1e-5);
    }

    /// When the total friction exceeds `mu (x0 + x1)` no split holds both feet:
    /// infeasible, left where both feet miss their cones by the same amount
    /// (the least largest violation), with the total friction kept.
    fn too_much_friction_cannot_stick<T: Real>(tol: f64) {
        let p = two_feet::<T>(0.4);
        let f = T::from_f64;
        let mut x = [f(2.0), f(3.0)];
        let mut y = [f(2.6), f(2.6)];
        let s = all_sticking(&p, &mut x, &mut y, f(1e-9));
        assert_eq!(s, Split::Infeasible);
        let (y0, y1) = (y[0].to_f64(), y[1].to_f64());
        assert!((y0 + y1 - 5.2).abs() <= tol * 10.0, "{y:?}");
        // Equal violations: y0 - 0.8 = y1 - 1.2.
        assert!(((y0 - 0.8) - (y1 - 1.2)).abs() <= tol * 10.0, "{y:?}");
    }

    #[test]
    fn too_much_friction_cannot_stick_f64() {
        too_much_friction_cannot_stick::<f64>(1e-12);
    }

    #[test]
    fn too_much_friction_cannot_stick_f32() {
        too_much_friction_cannot_stick::<f32>(1e-5);
    }

    /// Already inside: unchanged.
    #[test]
    fn inside_is_left_alone() {
        let p = two_feet::<f64>(0.4);
        let mut x = [5.0, 5.0];
        let mut y = [1.0, 1.0];
        let s = all_sticking(&p, &mut x, &mut y, 1e-9);
        assert_eq!(s, Split::Inside);
        assert_eq!((x, y), ([5.0, 5.0], [1.0, 1.0]));
    }

    /// Three sticking feet of friction `mu` at x = -0.1, 0 and 0.1 m under
    /// [`platform`], their rates `(x0, y0)` split within their cones: what
    /// [`within_cones`] says and the rates it leaves, after checking that they
    /// differ from the given ones by internal forces only (no contact velocity
    /// changes).
    fn split_three_feet(mu: [f64; 3], x0: [f64; 3], y0: [f64; 3]) -> (Split, [f64; 3], [f64; 3]) {
        let p = three_feet(mu);
        let (mut x, mut y) = (x0, y0);
        let s = all_sticking(&p, &mut x, &mut y, 1e-9);
        let dx: [f64; 3] = core::array::from_fn(|i| x[i] - x0[i]);
        let dy: [f64; 3] = core::array::from_fn(|i| y[i] - y0[i]);
        let (dn, dt) = p.velocity_change(&dx, &dy);
        for v in dn.iter().chain(dt.iter()) {
            assert!(v.abs() < 1e-9, "{dn:?} {dt:?}");
        }
        (s, x, y)
    }

    /// Three sticking feet under more friction than their cones hold (18 N
    /// along the floor on 15 N of load, friction 0.2, 0.4 and 0.8 at x = -0.1,
    /// 0 and 0.1 m): no split exists, and the least largest miss
    /// `max(|y_i| - mu_i x_i, -x_i)` has a closed form. The internal forces
    /// move friction freely among the feet and load along `(1, -2, 1)` (no net
    /// force, no moment): `x = (1 + s, 4 - 2 s, 10 + s)`. At the least `v` every
    /// foot misses by `v` with `y_i = mu_i x_i + v`, so
    /// `3 v = 18 - sum mu_i x_i = 8.2 - 0.2 s`, largest where the middle foot is
    /// at the lower end its miss allows, `x_2 = -v`, `s = (4 + v) / 2`:
    /// `3.1 v = 7.8`, `v = 78/31 = 2.51613 N`. Coordinate descent along a basis
    /// of the internal forces stopped at a corner above it.
    #[test]
    fn the_least_violation_is_shared_by_the_feet() {
        let mu = [0.2, 0.4, 0.8];
        let (s, x, y) = split_three_feet(mu, [1.0, 4.0, 10.0], [6.0, 6.0, 6.0]);
        assert_eq!(s, Split::Infeasible);
        let miss: [f64; 3] = core::array::from_fn(|i| (y[i].abs() - mu[i] * x[i]).max(-x[i]));
        let largest = miss.iter().fold(f64::MIN, |m, v| m.max(*v));
        let least = 78.0 / 31.0;
        // Above the least by at most e |c| (`least_violation`): e^2 = 1.5e-8
        // of the largest |a|^2 and |c| < 20 here: 3e-3 N at most.
        assert!(
            (least - 1e-9..least + 3e-3).contains(&largest),
            "{miss:?}: {x:?} {y:?}"
        );
    }

    /// The singular vectors' null space: of a rank-2 matrix the line through
    /// (1, 1, -1), of a rank-1 one a plane, each orthonormal and annihilated.
    #[test]
    fn the_null_space_by_svd_is_orthonormal_and_annihilated() {
        let cases: [([[f64; 3]; 3], usize); 2] = [
            ([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [1.0, 0.0, 1.0]], 1),
            ([[1.0, 1.0, 1.0], [2.0, 2.0, 2.0], [3.0, 3.0, 3.0]], 2),
        ];
        for (a, expected) in cases {
            let mut work = a;
            let mut basis = [[0.0; 3]; 3];
            let k = null_space_by_svd(&mut work, 3, &mut basis);
            assert_eq!(k, expected, "{a:?}");
            for (i, u) in basis.iter().take(k).enumerate() {
                for row in &a {
                    let r: f64 = (0..3).map(|j| row[j] * u[j]).sum();
                    assert!(r.abs() < 1e-12, "{a:?} {u:?}");
                }
                for (j, w) in basis.iter().take(k).enumerate() {
                    let d: f64 = (0..3).map(|c| u[c] * w[c]).sum();
                    let want = if i == j { 1.0 } else { 0.0 };
                    assert!((d - want).abs() < 1e-12, "{basis:?}");
                }
            }
        }
        let mut a = [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [1.0, 0.0, 1.0]];
        let mut basis = [[0.0; 3]; 3];
        null_space_by_svd(&mut a, 3, &mut basis);
        let u = basis[0];
        let along = (u[0] + u[1] - u[2]).abs() / 3f64.sqrt();
        assert!((along - 1.0).abs() < 1e-12, "{u:?}");
    }

    /// A constraint the step cannot move, at `-1e-17` (a foot at zero force,
    /// by rounding), neither empties the others' interval nor moves the step
    /// within it: the step closest to the target, 0.3, in [0, 1].
    #[test]
    fn an_immovable_constraint_leaves_the_interval_alone() {
        let t = best_step(&[(0.0, -1e-17), (1.0, 0.0), (-1.0, 1.0)], 0.3);
        assert_eq!(t, 0.3);
    }

    /// Three sticking feet (x = -0.1, 0, 0.1): three internal forces, so the
    /// projection's complementarity problem is solved. The internal forces of a
    /// level platform on feet on a line are `dx = s (1, -2, 1)` (no net force, no
    /// moment) and any `dy` with `sum dy = 0`; a brute-force scan over
    /// `(s, dy0, dy1)` finds the feasible split closest to the start, which the
    /// solver must match.
    #[test]
    fn three_feet_against_a_scan() {
        let (x0, y0) = ([1.0, 4.0, 10.0], [2.0, 2.0, 2.0]);
        let (s, x, y) = split_three_feet([0.4; 3], x0, y0);
        assert_eq!(s, Split::Moved);
        let dx: [f64; 3] = core::array::from_fn(|i| x[i] - x0[i]);
        let dy: [f64; 3] = core::array::from_fn(|i| y[i] - y0[i]);
        let dist =
            |dx: &[f64; 3], dy: &[f64; 3]| dx.iter().chain(dy.iter()).map(|v| v * v).sum::<f64>();
        let solver = dist(&dx, &dy);
        // Scan, then refine around the best point.
        let feasible = |dx: &[f64; 3], dy: &[f64; 3]| {
            (0..3).all(|i| {
                let (xi, yi) = (x0[i] + dx[i], y0[i] + dy[i]);
                xi >= 0.0 && yi.abs() <= 0.4 * xi + 1e-12
            })
        };
        let (mut centre, mut half) = ([0.0f64; 3], [2.0f64, 4.0, 4.0]);
        let mut best = f64::INFINITY;
        for _ in 0..6 {
            let n = 40;
            let mut next = centre;
            for a in 0..=n {
                for b in 0..=n {
                    for c in 0..=n {
                        let g = |k: usize, i: usize| {
                            centre[k] + half[k] * (2.0 * i as f64 / n as f64 - 1.0)
                        };
                        let (s, a0, a1) = (g(0, a), g(1, b), g(2, c));
                        let ddx = [s, -2.0 * s, s];
                        let ddy = [a0, a1, -a0 - a1];
                        if feasible(&ddx, &ddy) {
                            let d = dist(&ddx, &ddy);
                            if d < best {
                                best = d;
                                next = [s, a0, a1];
                            }
                        }
                    }
                }
            }
            centre = next;
            for h in half.iter_mut() {
                *h *= 0.25;
            }
        }
        assert!(best.is_finite());
        // The scan's optimum is approached from the feasible side, so it is at
        // least the true minimum up to its grid; the solver must be as close.
        assert!(
            solver <= best * (1.0 + 1e-3) + 1e-9,
            "solver {solver} scan {best}: {x:?} {y:?}"
        );
    }
}
