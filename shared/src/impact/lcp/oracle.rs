//! The enumeration of contact modes that [`super::find_direction`] replaced, kept as
//! the tests' oracle: active sets from the largest, and for each the `3^z` friction
//! states of its contacts at zero slip, until one is consistent (at most
//! [`CANDIDATE_BUDGET`] candidates). Exponential in the contacts; tests only.

use super::*;

/// Most candidate (active set, friction states) pairs tried for one direction.
const CANDIDATE_BUDGET: u32 = 20_000;

/// The direction by enumeration: what `find_direction_into` did before Lemke.
pub fn enumerated_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    u_n: &[T; N],
    u_t: &[T; N],
    slip: &[T; N],
    rule: NormalRule<'_, T, N>,
    tol: &Tolerances<T>,
    out: &mut Direction<T, N>,
) {
    // A budget of candidates for each solve.
    direction_by(
        p,
        (u_n, u_t, slip),
        rule,
        tol,
        out,
        |p, base, g, tol, out| {
            let mut budget = CANDIDATE_BUDGET;
            complementary_direction(p, base, g, tol, &mut budget, out)
        },
        |p, base, x, tol, out| {
            let mut budget = CANDIDATE_BUDGET;
            fixed_direction(p, base, x, tol, &mut budget, out)
        },
    );
}

/// The complementarity problem of a `Target` rule, by enumeration of active sets
/// from the largest, into `out`. Returns false when no consistent solution exists
/// (`out` then unspecified).
fn complementary_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    g: &[T; N],
    tol: &Tolerances<T>,
    budget: &mut u32,
    out: &mut Direction<T, N>,
) -> bool {
    let n = p.len;
    // Only contacts at or below their target can take impulse; a contact above it
    // (separating) joins when its normal velocity comes down to the target, which
    // is an event of the path (see `released_event`), not a choice made here.
    let mut candidate_mask = 0u32;
    for i in 0..n {
        if base.all || base.u_n[i] <= g[i] + tol.velocity {
            candidate_mask |= 1 << i;
        }
    }
    // The candidates after the first of a size are solved here, and copied to
    // `out` only when better.
    let mut scratch: Option<Direction<T, N>> = None;
    for size in (0..=candidate_mask.count_ones() as usize).rev() {
        // The weighted norm of the best candidate of this size, held in `out`.
        let mut best: Option<T> = None;
        for mask in 0u32..(1u32 << n) {
            if mask & !candidate_mask != 0 || mask.count_ones() as usize != size {
                continue;
            }
            let mut active = [false; N];
            for (i, a) in active.iter_mut().enumerate().take(n) {
                *a = mask & (1 << i) != 0;
            }
            let first = best.is_none();
            let d = if first {
                &mut *out
            } else {
                scratch.get_or_insert_with(Direction::default)
            };
            let Some((score, how)) =
                first_consistent_states(p, base, &active, Some(g), None, tol, budget, d)
            else {
                if *budget == 0 {
                    return false;
                }
                continue;
            };
            // A unique solution of a full-rank system is the answer; where the
            // system was singular, keep the weighted minimum norm of this size.
            if how == Solved::Unique && first {
                return true;
            }
            if best.is_none_or(|s| score < s) {
                if !first {
                    if let Some(d) = &scratch {
                        *out = *d;
                    }
                }
                best = Some(score);
            }
        }
        if best.is_some() {
            return true;
        }
    }
    false
}

/// The direction of a `Fixed` rule: friction states only, into `out`.
fn fixed_direction<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    x: &[T; N],
    tol: &Tolerances<T>,
    budget: &mut u32,
    out: &mut Direction<T, N>,
) {
    let active = pushed(p, x);
    if first_consistent_states(p, base, &active, None, Some(x), tol, budget, out).is_some() {
        return;
    }
    clipped_direction(p, base, x, tol, out);
}

/// For one active set, tries the friction states of the contacts at zero slip
/// (stick first) and returns the weighted norm of the first consistent solution
/// and how its system was solved, the solution in `d`; `None` (with `d`
/// unspecified) where no state is consistent.
#[allow(clippy::too_many_arguments)]
fn first_consistent_states<T: Real, const N: usize>(
    p: &ImpactProblem<T, N>,
    base: &Base<'_, T, N>,
    active: &[bool; N],
    target: Option<&[T; N]>,
    fixed: Option<&[T; N]>,
    tol: &Tolerances<T>,
    budget: &mut u32,
    d: &mut Direction<T, N>,
) -> Option<(T, Solved)> {
    let n = p.len;
    let mut cand = Candidate {
        active: *active,
        mode: [SlipState::Stick; N],
    };
    let mut undecided = [0usize; N];
    let mut count = 0;
    for i in 0..n {
        match kinematic_state(base.slip[i], tol.velocity) {
            Some(s) => cand.mode[i] = s,
            None if active[i] => {
                undecided[count] = i;
                count += 1;
            }
            None => {}
        }
    }
    let combos = 3u32.pow(count as u32);
    for code in 0..combos {
        if *budget == 0 {
            return None;
        }
        *budget -= 1;
        let mut c = code;
        for &i in undecided.iter().take(count) {
            cand.mode[i] = match c % 3 {
                0 => SlipState::Stick,
                1 => SlipState::SlipPositive,
                _ => SlipState::SlipNegative,
            };
            c /= 3;
        }
        let Some((score, how)) = solve_states_into(
            p,
            base.u_n,
            base.u_t,
            &cand.active,
            &cand.mode,
            target,
            fixed,
            d,
        ) else {
            continue;
        };
        match admissible(p, base, &cand, target, fixed.is_none(), how, d, tol) {
            // The split moved along the internal forces: its norm.
            Some(Split::Moved) => return Some((weighted_norm(p, &cand.active, &d.x, &d.y), how)),
            Some(_) => return Some((score, how)),
            None => {}
        }
    }
    None
}
