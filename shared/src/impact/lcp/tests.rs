//! Lemke's direction against the enumeration it replaced ([`super::oracle`]), on
//! random contact problems of at most four contacts.

extern crate std;

use super::oracle::enumerated_direction;
use super::*;
use crate::impact::problem::{ContactLaw, ImpactLaw};
use crate::Enumerated;
use std::format;
use std::string::String;
use std::vec::Vec;

std::thread_local! {
    /// [`find_direction_into`] runs the enumeration instead (on this thread).
    pub(super) static USE_ORACLE: core::cell::Cell<bool> = const { core::cell::Cell::new(false) };
}

/// The integration tests' deterministic generator (SplitMix64), so that the
/// cases are the same on every run.
#[path = "../../../tests/support/rng.rs"]
#[allow(dead_code)]
mod rng;
use rng::Rng;

/// A random problem of `k` contacts on a mechanism of `dof` coordinates with the
/// identity mass matrix: `W = J J^T` (rank `min(2k, dof)`: redundant contacts
/// where `dof < 2k`), normal velocities in `[-1, 1]`, tangential ones zero for
/// about half of the contacts, friction in `[0, 1.5]`.
fn random_problem(rng: &mut Rng, k: usize, dof: usize) -> ImpactProblem<f64, 4> {
    let mut jn = [[0.0; 6]; 4];
    let mut jt = [[0.0; 6]; 4];
    for i in 0..k {
        for c in 0..dof {
            jn[i][c] = rng.uniform_f64(-1.0, 1.0);
            jt[i][c] = rng.uniform_f64(-1.0, 1.0);
        }
    }
    let dot = |a: &[f64; 6], b: &[f64; 6]| (0..dof).map(|c| a[c] * b[c]).sum::<f64>();
    let mut p = ImpactProblem::new(ImpactLaw::Newton);
    p.len = k;
    for i in 0..k {
        for j in 0..k {
            p.w_nn[i][j] = dot(&jn[i], &jn[j]);
            p.w_nt[i][j] = dot(&jn[i], &jt[j]);
            p.w_tt[i][j] = dot(&jt[i], &jt[j]);
        }
        p.u_n[i] = rng.uniform_f64(-1.0, 1.0);
        p.u_t[i] = if rng.unit_f64() < 0.5 {
            0.0
        } else {
            rng.uniform_f64(-1.0, 1.0)
        };
        p.contacts[i] = ContactLaw {
            restitution: 0.0,
            friction: rng.uniform_f64(0.0, 1.5),
            weight: rng.uniform_f64(0.5, 2.0),
        };
    }
    p
}

const TOL: Tolerances<f64> = Tolerances {
    velocity: 1e-10,
    impulse: 1e-10,
    zero_slip: 0.0,
};

/// The direction satisfies the complementarity conditions of its rule (to `1e-7`):
/// active contacts with a normal rate `>= 0` reaching their target, the others at
/// or above it (`all`, or at or below it before); sticking contacts inside their
/// cone holding their tangential row at zero; slipping ones on the cone's edge
/// against the way they (then) move.
fn check(
    p: &ImpactProblem<f64, 4>,
    g: Option<&[f64; 4]>,
    all: bool,
    d: &Direction<f64, 4>,
) -> Result<(), String> {
    let tol = 1e-7;
    for i in 0..p.len {
        let mu = p.contacts[i].friction;
        let un = p.u_n[i] + d.du_n[i];
        let ut = p.u_t[i] + d.du_t[i];
        if d.active[i] {
            if d.x[i] < -tol {
                return Err(format!("contact {i}: x = {}", d.x[i]));
            }
            if let Some(g) = g {
                if (un - g[i]).abs() > tol {
                    return Err(format!("contact {i}: active, u_n = {un}"));
                }
            }
            match d.mode[i] {
                SlipState::Stick => {
                    if d.y[i].abs() > mu * d.x[i] + tol {
                        return Err(format!("contact {i}: |y| > mu x"));
                    }
                    if p.u_t[i] == 0.0 && ut.abs() > tol {
                        return Err(format!("contact {i}: sticks but u_t = {ut}"));
                    }
                }
                s => {
                    let sign = s.sign::<f64>();
                    if (d.y[i] + mu * sign * d.x[i]).abs() > tol {
                        return Err(format!("contact {i}: slip off the cone's edge"));
                    }
                    if p.u_t[i] == 0.0 && sign * ut < -tol {
                        return Err(format!("contact {i}: slips against its motion"));
                    }
                    if p.u_t[i] != 0.0 && sign * p.u_t[i] < 0.0 {
                        return Err(format!("contact {i}: slip state against its slip"));
                    }
                }
            }
        } else if let Some(g) = g {
            if (all || p.u_n[i] <= g[i]) && un < g[i] - tol {
                return Err(format!("contact {i}: released below its target, {un}"));
            }
        }
    }
    Ok(())
}

/// On 3000 random problems of one to four contacts (with redundant contacts
/// where the mechanism has fewer coordinates than twice the contacts), for the
/// `TargetAll`, `Target` and `Fixed` rules: Lemke's answers are complementary,
/// and Lemke finds one wherever the enumeration does on the problem without
/// friction, whose matrix is copositive-plus (Cottle, Pang & Stone 1992,
/// sec. 4.4: Lemke's method then ends at a solution whenever one exists).
/// With friction the matrix is copositive but not copositive-plus (Stewart &
/// Trinkle's cone edges; a slipping contact's `-mu s` folded into its normal
/// column can even make it lose copositivity, Painleve's `W_nn - mu s W_nt < 0`),
/// and a ray is then no proof that nothing is consistent: those misses, with or
/// without a slipping contact, are counted and listed (printed with
/// `--nocapture`), at most one in a hundred, and the plant and the impact solver
/// take their Painleve rule there. Pivots stay under the cap; the most taken is
/// printed.
#[test]
fn lemke_agrees_with_the_enumeration() {
    let mut rng = Rng::new(24);
    let mut missed: Vec<String> = Vec::new();
    let (mut both, mut neither, mut lemke_only, mut most_pivots) = (0, 0, 0, 0);
    let zeros = [0.0; 4];
    for case in 0..3000 {
        let k = 1 + case % 4;
        let dof = 2 + (case / 4) % 5;
        let with_friction = random_problem(&mut rng, k, dof);
        let mut fixed = [0.0; 4];
        for f in fixed.iter_mut().take(k) {
            *f = if rng.unit_f64() < 0.3 {
                0.0
            } else {
                rng.uniform_f64(0.0, 1.0)
            };
        }
        let mut frictionless = with_friction.clone();
        for c in frictionless.contacts.iter_mut() {
            c.friction = 0.0;
        }
        for (p, copositive_plus) in [(&with_friction, false), (&frictionless, true)] {
            let rules = [
                (NormalRule::TargetAll(&zeros), Some(&zeros), true),
                (NormalRule::Target(&zeros), Some(&zeros), false),
                (NormalRule::Fixed(&fixed), None, false),
            ];
            for (rule, g, all) in rules {
                let old = {
                    let mut d = Direction::default();
                    enumerated_direction(p, &p.u_n, &p.u_t, &p.u_t, rule, &TOL, &mut d);
                    d
                };
                let new = find_direction(p, &p.u_n, &p.u_t, &p.u_t, rule, &TOL);
                most_pivots = most_pivots.max(new.outcome.pivots());
                assert!(
                    new.outcome.pivots() <= pivot_cap(4 * k),
                    "case {case}: {:?}",
                    new.outcome
                );
                let old_found = old.consistent && (g.is_none() || old.ends_at_one);
                let new_found = new.consistent && (g.is_none() || new.ends_at_one);
                if new_found {
                    if let Err(e) = check(p, g, all, &new) {
                        panic!(
                            "case {case} ({k} contacts, {dof} dof, {rule:?}): {e}\n{p:?}\n{new:?}"
                        );
                    }
                }
                match (old_found, new_found) {
                    (true, true) => both += 1,
                    (false, false) => neither += 1,
                    (false, true) => lemke_only += 1,
                    (true, false) => {
                        assert!(
                            !copositive_plus,
                            "case {case} ({k} contacts, {dof} dof, {rule:?}): Lemke missed without friction: {:?}\n{p:?}",
                            new.outcome
                        );
                        assert_eq!(
                            check(p, g, all, &old),
                            Ok(()),
                            "case {case}: the oracle's answer"
                        );
                        let slipping = (0..k).any(|i| p.u_t[i] != 0.0);
                        missed.push(format!(
                            "case {case} ({k} contacts, {dof} dof, {rule:?}): {:?}; {}",
                            new.outcome,
                            if slipping {
                                "a contact slips"
                            } else {
                                "every contact at zero slip"
                            }
                        ));
                    }
                }
            }
        }
    }
    std::println!(
        "both {both}, neither {neither}, Lemke only {lemke_only}, enumeration only {}; \
         most pivots {most_pivots}",
        missed.len()
    );
    std::println!(
        "Lemke found none where the enumeration did:\n{}",
        missed.join("\n")
    );
    assert!(
        missed.len() * 100 < both,
        "more than one case in a hundred missed"
    );
}

/// The impact solver on 2000 random problems (one to four contacts, the three
/// impact laws, restitution in `[0, 1]`) with Lemke's directions and with the
/// enumeration's: the impulses agree to `1e-6` of their scale, and the interaction
/// cases agree, except where the enumeration's direction has no Lemke
/// counterpart (counted as in `lemke_agrees_with_the_enumeration`).
#[test]
fn impact_solver_agrees_with_the_enumeration() {
    let mut rng = Rng::new(13);
    let (mut same, mut differ) = (0, Vec::new());
    for case in 0..2000 {
        let k = 1 + case % 4;
        let dof = 2 + (case / 4) % 5;
        let mut p = random_problem(&mut rng, k, dof);
        p.law = ImpactLaw::ALL[case % 3];
        for c in p.contacts.iter_mut().take(k) {
            c.restitution = rng.unit_f64();
        }
        let new = crate::impact::solve(&p);
        USE_ORACLE.with(|o| o.set(true));
        let old = crate::impact::solve(&p);
        USE_ORACLE.with(|o| o.set(false));
        let (new, old) = match (new, old) {
            (Ok(new), Ok(old)) => (new, old),
            (Err(a), Err(b)) if a == b => {
                same += 1;
                continue;
            }
            (new, old) => {
                differ.push(format!(
                    "case {case}: Lemke's {:?}, the enumeration's {:?}",
                    new.err(),
                    old.err()
                ));
                continue;
            }
        };
        let scale = (0..k).fold(1e-12f64, |s, i| {
            s.max(old.contacts[i].normal_impulse.abs())
                .max(old.contacts[i].tangential_impulse.abs())
        });
        let agree = (0..k).all(|i| {
            let (a, b) = (&new.contacts[i], &old.contacts[i]);
            (a.normal_impulse - b.normal_impulse).abs() <= 1e-6 * scale
                && (a.tangential_impulse - b.tangential_impulse).abs() <= 1e-6 * scale
                && a.case == b.case
        });
        if agree {
            same += 1;
        } else {
            differ.push(format!(
                "case {case} ({k} contacts, {dof} dof, {:?})",
                p.law
            ));
        }
    }
    std::println!(
        "impacts: {same} agree, {} differ:\n{}",
        differ.len(),
        differ.join("\n")
    );
    assert!(
        differ.len() * 100 < same,
        "more than one impact in a hundred differs"
    );
}

/// `solve_into` on one outcome kept from impact to impact (one to four
/// contacts, the three laws, in turn) gives what `solve` gives to the bit: every
/// contact reset, the entries past the problem's default, no history left over
/// from a longer impact before.
#[test]
fn solve_into_a_kept_outcome_is_solve() {
    let mut rng = Rng::new(29);
    let mut kept = crate::impact::ImpactOutcome::default();
    let mut solved = 0;
    for case in 0..400 {
        let k = 4 - case % 4;
        let mut p = random_problem(&mut rng, k, 2 + (case / 4) % 5);
        p.law = ImpactLaw::ALL[case % 3];
        for c in p.contacts.iter_mut().take(k) {
            c.restitution = rng.unit_f64();
        }
        match (
            crate::impact::solve(&p),
            crate::impact::solve_into(&p, &mut kept),
        ) {
            (Ok(fresh), Ok(())) => {
                assert_eq!(fresh.len, kept.len, "case {case}");
                assert_eq!(fresh.contacts, kept.contacts, "case {case}");
                assert_eq!(
                    fresh.energy_change.to_bits(),
                    kept.energy_change.to_bits(),
                    "case {case}"
                );
                assert_eq!(fresh.warnings, kept.warnings, "case {case}");
                solved += 1;
            }
            (Err(a), Err(b)) => assert_eq!(a, b, "case {case}"),
            (a, b) => panic!("case {case}: solve {:?}, solve_into {b:?}", a.err()),
        }
    }
    assert!(solved > 200, "only {solved} of 400 impacts solved");
}

/// A plant's decision where the path of the covering vector `(1, ..., 1)` ends at
/// a secondary ray although a solution exists (the enumeration finds one): four
/// feet of two hinged bodies, all at zero slip, at t = 0.6017 s of
/// `benchmarks/contacts_random.py --seed 6 --bodies 2` (its Delassus blocks and
/// accelerations as the plant built them). Before the other covering vectors were
/// tried, the plant took it for a Painleve configuration and gave the four feet a
/// tangential impact, 35 times at that instant. Now a consistent direction is
/// found: every normal rate `>= 0`, every normal acceleration `>= 0` and zero where
/// the contact takes force, each slipping contact on its cone's edge and moving
/// the way it slips.
#[test]
fn another_covering_vector_finds_what_the_first_path_missed() {
    let mut p = ImpactProblem::<f64, 4>::new(ImpactLaw::Newton);
    p.len = 4;
    p.w_nn = [
        [
            0.9778672866393399,
            -0.11911653557079555,
            -0.19741033149299997,
            0.07018903438855507,
        ],
        [
            -0.11911653557079549,
            1.1424162159703455,
            0.9480455678103157,
            -0.3370771117169793,
        ],
        [
            -0.19741033149299997,
            0.9480455678103159,
            1.0090958298050967,
            0.6585250726668469,
        ],
        [
            0.070189034388555,
            -0.33707711171697907,
            0.658525072666847,
            4.279197287141201,
        ],
    ];
    p.w_nt = [
        [
            0.20847719646719592,
            0.20847735516486873,
            0.03379560991112361,
            0.03379590702586675,
        ],
        [
            -0.23845046136569936,
            -0.23845064386821926,
            0.17898785962551297,
            0.1789864327578013,
        ],
        [
            -0.2166254264635885,
            -0.21662559217358512,
            -0.018461511917876233,
            -0.018461901155496924,
        ],
        [
            0.07702044005916764,
            0.07702049897725594,
            -0.7680352668110316,
            -0.7680312467899397,
        ],
    ];
    p.w_tt = [
        [
            0.4820391765230291,
            0.48203924117884056,
            0.3699654584165445,
            0.36996578445063627,
        ],
        [
            0.4820392411788406,
            0.4820393058347014,
            0.3699654374119757,
            0.3699657634463169,
        ],
        [
            0.3699654584165446,
            0.36996543741197574,
            0.5513177263509828,
            0.5513168941015755,
        ],
        [
            0.3699657844506363,
            0.3699657634463169,
            0.5513168941015755,
            0.5513160618570637,
        ],
    ];
    let mu = [0.66, 0.38, 0.22, 0.37];
    for i in 0..4 {
        p.contacts[i] = ContactLaw {
            restitution: 0.0,
            friction: mu[i],
            weight: 1.0,
        };
    }
    let base_n = [
        -18.5143974359369,
        -18.954620299603743,
        -16.41495749179006,
        -7.471928092418011,
    ];
    let base_t = [
        9.492611157494633,
        9.492611221180479,
        7.464838519045246,
        7.464848448462957,
    ];
    let (velocity, impulse) = (9.810000000000001e-9, 2.4721199999999998e-8);
    let tol = Tolerances {
        velocity,
        impulse,
        zero_slip: 0.0,
    };
    let zeros = [0.0; 4];
    let rule = NormalRule::TargetAll(&zeros);
    let (b_n, b_t) = (&base_n, &base_t);
    let mut oracle = Direction::default();
    enumerated_direction(&p, b_n, b_t, &zeros, rule, &tol, &mut oracle);
    assert!(
        oracle.consistent && oracle.ends_at_one,
        "the enumeration finds one: {oracle:?}"
    );
    let d = find_direction(&p, b_n, b_t, &zeros, rule, &tol);
    assert!(d.consistent && d.ends_at_one, "{d:?}");
    let scale = 1e-9 * 30.0;
    for i in 0..4 {
        let (un, ut) = (base_n[i] + d.du_n[i], base_t[i] + d.du_t[i]);
        assert!(
            d.x[i] >= 0.0 && un >= -scale,
            "contact {i}: x {}, u_n {un}",
            d.x[i]
        );
        assert!(
            !d.active[i] || un.abs() <= scale,
            "contact {i}: active, u_n {un}"
        );
        assert!(
            d.active[i] || d.x[i] == 0.0,
            "contact {i}: released with x {}",
            d.x[i]
        );
        match d.mode[i] {
            SlipState::Stick => {
                assert!(d.y[i].abs() <= mu[i] * d.x[i] + scale && ut.abs() <= scale)
            }
            s => {
                let sign = s.sign::<f64>();
                assert!(
                    (d.y[i] + mu[i] * sign * d.x[i]).abs() <= scale,
                    "contact {i}: off the cone's edge"
                );
                assert!(
                    sign * ut >= -scale,
                    "contact {i}: slips against its motion, {ut}"
                );
            }
        }
    }
}
