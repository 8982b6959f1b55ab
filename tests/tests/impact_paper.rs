//! The impact model against the reference paper's closed forms (*Mechanism motion
//! studies with collisions at several points*), for many random parameter sets.
//!
//! Geometry (docs/impact-model.md, "The paper's examples: their geometry"): the body is
//! pinned at O = (0, 0), the contact point is K = (-d, h) with d, h > 0, the obstacle
//! normal is n = (1, 0), so the tangent is t = (-n_y, n_x) = (0, 1), and omega_0 > 0.
//! The paper's `JO` is about O: `JO = Jc + m (xc^2 + yc^2)` (parallel axis).
//!
//! Every expected value is derived here from the paper's equations, never from the
//! solver. Kinematics used throughout (pinned body, omega counter-clockwise):
//!
//! ```text
//!   v_P = omega x (P - O) = omega (-P_y, P_x)
//!   v_K = omega (-h, -d):   u_n = n . v_K = -omega h,   u_t = t . v_K = -omega d
//!   v_C = omega (-yc, xc)
//! ```
//!
//! so with omega_0 > 0 the contact approaches (u_n < 0) and slides along -t; the
//! friction impulse of compression then acts along +t, which is the paper's `+SFI`
//! (its eq. (2), second line: `0 - m omega_0 xc = SYI + SFI`, a y impulse).

use shared::impact::{
    solve_body, BodyContact, BodyImpact, ContactLaw, ImpactLaw, InteractionCase, Phase, PlanarBody,
    SlipState, Warnings,
};
use shared::Real;

use tests::Rng;

/// The paper's Fig. 5 body and contact (see the module doc for the geometry).
#[derive(Clone, Copy, Debug)]
struct PaperBody {
    /// Mass m, kg.
    m: f64,
    /// Inertia about C, kg m^2 (the paper's JO minus m |OC|^2).
    jc: f64,
    /// Centre of mass C = (xc, yc), m.
    xc: f64,
    yc: f64,
    /// Contact K = (-d, h), m.
    d: f64,
    h: f64,
    /// Initial angular velocity, rad/s, > 0.
    omega0: f64,
    /// Restitution R and friction f.
    r: f64,
    f: f64,
}

impl PaperBody {
    /// A random body; `q = f d / h` is drawn in `[q_lo, q_hi)` so the regime
    /// (springing back `q < 1`, jammed `q > 1`) is chosen by the caller.
    fn random(rng: &mut Rng, q_lo: f64, q_hi: f64) -> Self {
        let m = rng.uniform(0.1, 10.0);
        let xc = rng.uniform(-1.0, 1.0);
        let yc = rng.uniform(-1.0, 1.0);
        // Radius of gyration about C between 0.05 m and 1 m.
        let k = rng.uniform(0.05, 1.0);
        let d = rng.uniform(0.05, 2.0);
        let h = rng.uniform(0.05, 2.0);
        let omega0 = rng.uniform(0.1, 50.0);
        // Restitution: mostly (0, 1], sometimes exactly 0 or 1 (the ends of the range).
        let r = match rng.next_u64() % 10 {
            0 => 0.0,
            1 => 1.0,
            _ => rng.uniform(0.0, 1.0),
        };
        let q = rng.uniform(q_lo, q_hi);
        PaperBody {
            m,
            jc: m * k * k,
            xc,
            yc,
            d,
            h,
            omega0,
            r,
            f: q * h / d,
        }
    }

    /// The same body with every input rounded to f32 (so an f32 run can be compared
    /// with the closed form of exactly the numbers it was given).
    fn rounded_to_f32(self) -> Self {
        let r = |x: f64| x as f32 as f64;
        PaperBody {
            m: r(self.m),
            jc: r(self.jc),
            xc: r(self.xc),
            yc: r(self.yc),
            d: r(self.d),
            h: r(self.h),
            omega0: r(self.omega0),
            r: r(self.r),
            f: r(self.f),
        }
    }

    /// The paper's `JO = Jc + m (xc^2 + yc^2)`.
    fn jo(&self) -> f64 {
        self.jc + self.m * (self.xc * self.xc + self.yc * self.yc)
    }

    /// Solves the impact with the model under test.
    fn solve<T: Real>(&self, law: ImpactLaw) -> BodyImpact<T, 8> {
        let t = T::from_f64;
        let body = PlanarBody {
            mass: t(self.m),
            inertia: t(self.jc),
            position: [t(self.xc), t(self.yc)],
            // Ignored when pinned (then omega x (C - O)).
            velocity: [T::ZERO, T::ZERO],
            angular_velocity: t(self.omega0),
        };
        let contact = BodyContact {
            point: [t(-self.d), t(self.h)],
            normal: [T::ONE, T::ZERO],
            law: ContactLaw {
                restitution: t(self.r),
                friction: t(self.f),
                weight: T::ONE,
            },
        };
        solve_body::<T, 8>(&body, Some([T::ZERO, T::ZERO]), &[contact], law)
            .unwrap_or_else(|e| panic!("solve_body failed with {e:?} for {self:?}"))
    }

    /// Scale of the impulses, N s: the compression impulse and the momentum of C.
    fn impulse_scale(&self) -> f64 {
        let oc = (self.xc * self.xc + self.yc * self.yc).sqrt();
        (self.jo() * self.omega0 / (self.h + self.f * self.d)).max(self.m * self.omega0 * oc)
    }
}

/// The eight impulses and omega_2 of the paper's eqs. (5)-(6), in the paper's names.
#[derive(Debug)]
struct PaperImpulses {
    omega2: f64,
    sni: f64,
    snii: f64,
    sfi: f64,
    sfii: f64,
    sxi: f64,
    sxii: f64,
    syi: f64,
    syii: f64,
}

/// The paper's eqs. (5)-(6), transcribed as printed (valid for h > f d).
///
/// Checked against eqs. (2)-(4) by hand: eq. (2) third line
/// `-JO omega_0 = -SNI h - SFI d` with `SFI = f SNI` gives `SNI = JO omega_0/(h + f d)`;
/// eq. (3) third line `JO omega_2 = -SNII h + SFII d` with `SNII = R SNI`,
/// `SFII = f SNII` gives `omega_2 = R omega_0 (f d - h)/(h + f d)`; the first two lines
/// of (2) and (3) give the pivot impulses.
fn paper_eqs_5_6(b: &PaperBody) -> PaperImpulses {
    let (jo, w0, h, d, f, r, m) = (b.jo(), b.omega0, b.h, b.d, b.f, b.r, b.m);
    let hf = h + f * d;
    PaperImpulses {
        // (5)
        omega2: r * w0 * (d * f - h) / hf,
        sni: jo * w0 / hf,
        snii: r * jo * w0 / hf,
        // (6)
        sfi: f * jo * w0 / hf,
        sfii: r * f * jo * w0 / hf,
        sxi: (hf * m * w0 * b.yc - jo * w0) / hf,
        sxii: r * ((h - f * d) * m * w0 * b.yc - jo * w0) / hf,
        syi: -(hf * m * w0 * b.xc + f * jo * w0) / hf,
        syii: r * ((-h + f * d) * m * w0 * b.xc + f * jo * w0) / hf,
    }
}

/// Asserts `|got - expected| <= tol`, naming the quantity and the case.
fn check(what: &str, got: f64, expected: f64, tol: f64, context: &dyn core::fmt::Debug) {
    assert!(
        (got - expected).abs() <= tol,
        "{what}: got {got:.15e}, expected {expected:.15e}, |diff| {:.3e} > tol {tol:.3e}\n  case: {context:?}",
        (got - expected).abs()
    );
}

/// Compares a solved paper body with eqs. (5)-(6) under the API mapping
/// (checked against eqs. (2)-(3) in the module doc):
/// compression `[SNI, SFI]`, restitution `[SNII, -SFII]` (the slip, and so the
/// friction, reverses), pivot compression `(SXI, SYI)`, pivot restitution
/// `(SXII, SYII)`.
fn compare_with_paper<T: Real>(b: &PaperBody, out: &BodyImpact<T, 8>, rel: f64) {
    let e = paper_eqs_5_6(b);
    let tol_p = rel * b.impulse_scale();
    let tol_w = rel * b.omega0;
    let k = &out.outcome.contacts[0];
    let pivot = out.pivot.expect("a pinned body reports its pivot impulse");
    let g = |x: T| x.to_f64();
    check("omega_2", g(out.angular_velocity_after), e.omega2, tol_w, b);
    check("SNI", g(k.compression[0]), e.sni, tol_p, b);
    check("SFI", g(k.compression[1]), e.sfi, tol_p, b);
    check("SNII", g(k.restitution[0]), e.snii, tol_p, b);
    check("-SFII", g(k.restitution[1]), -e.sfii, tol_p, b);
    check("SXI", g(pivot.compression[0]), e.sxi, tol_p, b);
    check("SYI", g(pivot.compression[1]), e.syi, tol_p, b);
    check("SXII", g(pivot.restitution[0]), e.sxii, tol_p, b);
    check("SYII", g(pivot.restitution[1]), e.syii, tol_p, b);
    // Totals are the sums of the phases.
    check("SNI + SNII", g(k.normal_impulse), e.sni + e.snii, tol_p, b);
    check(
        "SFI - SFII",
        g(k.tangential_impulse),
        e.sfi - e.sfii,
        tol_p,
        b,
    );
    // Contact velocities after, from the kinematics of the module doc.
    check(
        "u_n after = -omega_2 h",
        g(k.normal_velocity_after),
        -e.omega2 * b.h,
        rel * b.omega0 * b.h,
        b,
    );
    check(
        "u_t after = -omega_2 d",
        g(k.tangential_velocity_after),
        -e.omega2 * b.d,
        rel * b.omega0 * b.d,
        b,
    );
}

/// Springing back (h > f d), Poisson's law (the paper's eq. (4)), f64: all eight
/// impulses and omega_2 match eqs. (5)-(6) to 1e-9 of the impulse scale (the f64
/// accuracy of docs/impact-model.md, "Accuracy and limits"). The slip (along -t in
/// compression) stops exactly as compression ends (u_n and u_t of a pinned body vanish
/// together, both being proportional to omega) and reverses in restitution: case 6.
#[test]
fn paper_eqs_5_6_springing_back_poisson_f64() {
    let mut rng = Rng::new(0x5eed_0005);
    for _ in 0..2000 {
        // f d / h in [0, 0.95): at least 5 % away from jamming.
        let b = PaperBody::random(&mut rng, 0.0, 0.95);
        let out = b.solve::<f64>(ImpactLaw::Poisson);
        compare_with_paper(&b, &out, 1e-9);

        let k = &out.outcome.contacts[0];
        assert!(
            !out.outcome.warnings.contains(Warnings::JAMMING),
            "springing back is not jamming: {b:?}"
        );
        assert!(
            !out.outcome.warnings.contains(Warnings::ENERGY_GAINED),
            "{b:?}"
        );
        // The case is defined only when there is friction to slip against and a
        // restitution phase for the reversal to fall in.
        if b.f > 0.0 && b.r > 0.0 {
            assert_eq!(
                k.case,
                InteractionCase::ReversalInRestitution,
                "springing back is case 6: {b:?}"
            );
            // History: slip along -t in compression, along +t in restitution.
            let first = k.segments.first().expect("a history");
            let last = k.segments.last().expect("a history");
            assert_eq!(
                (first.phase, first.state),
                (Phase::Compression, SlipState::SlipNegative),
                "{b:?}"
            );
            assert_eq!(
                (last.phase, last.state),
                (Phase::Restitution, SlipState::SlipPositive),
                "{b:?}"
            );
        }
        // Kinetic energy after: the body spins at omega_2 about O, 1/2 JO omega_2^2.
        let e = paper_eqs_5_6(&b);
        check(
            "kinetic energy after",
            out.kinetic_energy_after,
            0.5 * b.jo() * e.omega2 * e.omega2,
            1e-9 * 0.5 * b.jo() * b.omega0 * b.omega0,
            &b,
        );
    }
}

/// The same in f32: within 1e-4 of the closed form evaluated (in f64) on the f32
/// inputs (docs/impact-model.md, "Accuracy and limits": f32 within 1e-4 relative of
/// f64, and f64 within 1e-9 of exact).
#[test]
fn paper_eqs_5_6_springing_back_poisson_f32() {
    let mut rng = Rng::new(0x5eed_0032);
    for _ in 0..1000 {
        let b = PaperBody::random(&mut rng, 0.0, 0.95).rounded_to_f32();
        let out = b.solve::<f32>(ImpactLaw::Poisson);
        compare_with_paper(&b, &out, 1e-4);
    }
}

/// Jammed regime (h < f d), Poisson's law. The paper's eq. (5) would give
/// omega_2 > 0 (the body turning on into the obstacle), which is not physical.
///
/// Derivation: compression is as in eq. (5) (slip along -t, friction +f dP_n), so
/// `SNI = JO omega_0 / (h + f d)`, `SFI = f SNI`, and it ends with omega = 0, where
/// u_n and u_t vanish together. In restitution, moment about O (eq. (3), third line)
/// `JO d omega = -h dP_n - d dP_t`:
/// - slip along +t (friction -f dP_n): `JO d omega = -(h - f d) dP_n > 0`, so omega
///   turns positive and u_t = -omega d < 0: contradicts slip along +t;
/// - slip along -t (friction +f dP_n): `JO d omega = -(h + f d) dP_n < 0`, so
///   u_t > 0: contradicts slip along -t;
/// - stick (omega stays 0): `dP_t = -(h/d) dP_n`, inside the cone since h/d < f.
///
/// So the contact sticks: Poisson gives `SNII = R SNI` with tangential impulse
/// `-(h/d) SNII`, omega_2 = 0. Pivot impulses from the momentum of C
/// (`m (v_C+ - v_C-) = P_K + P_O`, `v_C = omega (-yc, xc)`, `P_K = (P_n, P_t)`):
/// compression as eq. (6) `SXI = m omega_0 yc - SNI`, `SYI = -m omega_0 xc - SFI`;
/// restitution (v_C stays 0) `SXII = -SNII`, `SYII = (h/d) SNII`. The slip stops at
/// the end of compression and the contact then sticks in restitution: case 4, with a
/// jamming warning.
#[test]
fn paper_jammed_regime_sticks_in_restitution() {
    let mut rng = Rng::new(0x5eed_0a11);
    for _ in 0..1000 {
        // f d / h in [1.05, 5): at least 5 % into jamming.
        let b = PaperBody::random(&mut rng, 1.05, 5.0);
        let out = b.solve::<f64>(ImpactLaw::Poisson);
        let (jo, w0, m) = (b.jo(), b.omega0, b.m);
        let sni = jo * w0 / (b.h + b.f * b.d);
        let sfi = b.f * sni;
        let snii = b.r * sni;
        let ptii = -(b.h / b.d) * snii;
        let tol_p = 1e-9 * b.impulse_scale();
        let k = &out.outcome.contacts[0];
        let pivot = out.pivot.expect("pinned");
        check("omega_2", out.angular_velocity_after, 0.0, 1e-9 * w0, &b);
        check("SNI", k.compression[0], sni, tol_p, &b);
        check("SFI", k.compression[1], sfi, tol_p, &b);
        check("SNII", k.restitution[0], snii, tol_p, &b);
        check("P_t restitution", k.restitution[1], ptii, tol_p, &b);
        check("SXI", pivot.compression[0], m * w0 * b.yc - sni, tol_p, &b);
        check("SYI", pivot.compression[1], -m * w0 * b.xc - sfi, tol_p, &b);
        check("SXII", pivot.restitution[0], -snii, tol_p, &b);
        check("SYII", pivot.restitution[1], (b.h / b.d) * snii, tol_p, &b);
        check(
            "u_n after",
            k.normal_velocity_after,
            0.0,
            1e-9 * w0 * b.h,
            &b,
        );
        check(
            "u_t after",
            k.tangential_velocity_after,
            0.0,
            1e-9 * w0 * b.d,
            &b,
        );
        if b.r > 0.0 {
            assert_eq!(
                k.case,
                InteractionCase::StickInRestitution,
                "jammed body is case 4: {b:?}"
            );
            assert!(
                out.outcome.warnings.contains(Warnings::JAMMING),
                "jammed body (h < f d) raises the jamming warning: {b:?}"
            );
            let last = k.segments.last().expect("a history");
            assert_eq!(
                (last.phase, last.state),
                (Phase::Restitution, SlipState::Stick),
                "{b:?}"
            );
        }
    }
}

/// The paper's Fig. 7 body, eqs. (7)-(9) (with the two sign corrections of
/// docs/impact-model.md, "The paper's examples: their geometry"),
/// generalised to contact weights w_i. Pinned at O = (0, 0), contacts
/// K_i = (L_i, 0), L_i > 0, normal n = (0, -1) (obstacle above), so
/// t = (-n_y, n_x) = (1, 0); omega_0 > 0.
///
/// Derivation. `v_Ki = omega (0, L_i)`: `u_n,i = -omega L_i < 0` (approaching),
/// `u_t,i = 0`. Jacobian rows about O: `J_n,i = (K_i x n) = -L_i`,
/// `J_t,i = (K_i x t) = 0` (tangential rows vanish: friction cannot act).
/// - Compression (eq. (7), first line): `JO (0 - omega_0) = -sum_i S_iI L_i`. Only
///   the sum is fixed; the weighted minimum-norm share (metric diag(1/w)) minimises
///   `sum S_i^2 / w_i` under that constraint: `S_iI = lambda w_i L_i`,
///   `lambda = JO omega_0 / sum_j w_j L_j^2` (equal weights: eq. (9)).
/// - Restitution (Poisson, eq. (7) second line): `S_iII = R_i S_iI`,
///   `JO omega_2 = -sum_i R_i S_iI L_i`, so
///   `omega_2 = -omega_0 sum_i R_i w_i L_i^2 / sum_i w_i L_i^2` <= 0: every contact
///   then separates (`u_n,i = -omega_2 L_i >= 0`), no extra impulse is needed.
/// - Pivot (momentum of C, `v_C = omega (-yc, xc)`, contact impulses `(0, -S_i)`):
///   x: `m yc (omega_0 - omega)` = SXO (eq. (8), first line, sign corrected);
///   y: `m xc (omega - omega_0) = -sum_i S_i + SYO`. Per phase: compression
///   `SXO_I = m yc omega_0`, `SYO_I = -m xc omega_0 + sum S_iI`; restitution
///   `SXO_II = -m yc omega_2`, `SYO_II = m xc omega_2 + sum R_i S_iI`.
fn four_point_body(rng: &mut Rng, weighted: bool) {
    let m = rng.uniform(0.1, 10.0);
    let k = rng.uniform(0.05, 1.0);
    let jc = m * k * k;
    let (xc, yc) = (rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
    let jo = jc + m * (xc * xc + yc * yc);
    let omega0 = rng.uniform(0.1, 50.0);
    let mut l = [0.0; 3];
    let mut r = [0.0; 3];
    let mut w = [1.0; 3];
    let mut contacts = Vec::new();
    for i in 0..3 {
        l[i] = rng.uniform(0.1, 2.0);
        r[i] = rng.uniform(0.0, 1.0);
        if weighted {
            w[i] = rng.uniform(0.2, 5.0);
        }
        contacts.push(BodyContact {
            point: [l[i], 0.0],
            normal: [0.0, -1.0],
            law: ContactLaw {
                restitution: r[i],
                // Friction present but irrelevant (tangential rows are zero).
                friction: rng.uniform(0.1, 1.5),
                weight: w[i],
            },
        });
    }
    let body = PlanarBody {
        mass: m,
        inertia: jc,
        position: [xc, yc],
        velocity: [0.0, 0.0],
        angular_velocity: omega0,
    };
    let context = (m, jc, xc, yc, omega0, l, r, w);
    let out = solve_body::<f64, 8>(&body, Some([0.0, 0.0]), &contacts, ImpactLaw::Poisson)
        .unwrap_or_else(|e| panic!("solve_body failed with {e:?} for {context:?}"));

    let sum_wl2: f64 = (0..3).map(|i| w[i] * l[i] * l[i]).sum();
    let lambda = jo * omega0 / sum_wl2;
    let s1: Vec<f64> = (0..3).map(|i| lambda * w[i] * l[i]).collect();
    let omega2 = -omega0 * (0..3).map(|i| r[i] * w[i] * l[i] * l[i]).sum::<f64>() / sum_wl2;
    let scale_p = s1
        .iter()
        .cloned()
        .fold(0.0, f64::max)
        .max(m * omega0 * (xc.hypot(yc)));
    let tol_p = 1e-9 * scale_p;

    check(
        "omega_2",
        out.angular_velocity_after,
        omega2,
        1e-9 * omega0,
        &context,
    );
    for i in 0..3 {
        let c = &out.outcome.contacts[i];
        check("S_iI (eq. 9)", c.compression[0], s1[i], tol_p, &context);
        check(
            "S_iII = R_i S_iI",
            c.restitution[0],
            r[i] * s1[i],
            tol_p,
            &context,
        );
        check(
            "tangential, compression",
            c.compression[1],
            0.0,
            tol_p,
            &context,
        );
        check(
            "tangential, restitution",
            c.restitution[1],
            0.0,
            tol_p,
            &context,
        );
        check(
            "tangential, total",
            c.tangential_impulse,
            0.0,
            tol_p,
            &context,
        );
        check(
            "u_n after = -omega_2 L_i",
            c.normal_velocity_after,
            -omega2 * l[i],
            1e-9 * omega0 * l[i],
            &context,
        );
        assert_eq!(c.case, InteractionCase::NoSlip, "contact {i}: {context:?}");
    }
    let pivot = out.pivot.expect("pinned");
    let sum_s1: f64 = s1.iter().sum();
    let sum_rs1: f64 = (0..3).map(|i| r[i] * s1[i]).sum();
    check(
        "SXO_I",
        pivot.compression[0],
        m * yc * omega0,
        tol_p,
        &context,
    );
    check(
        "SYO_I",
        pivot.compression[1],
        -m * xc * omega0 + sum_s1,
        tol_p,
        &context,
    );
    check(
        "SXO_II",
        pivot.restitution[0],
        -m * yc * omega2,
        tol_p,
        &context,
    );
    check(
        "SYO_II",
        pivot.restitution[1],
        m * xc * omega2 + sum_rs1,
        tol_p,
        &context,
    );
    check(
        "SXO (eq. 8, sign corrected)",
        pivot.impulse[0],
        m * yc * (omega0 - omega2),
        tol_p,
        &context,
    );
    check(
        "SYO (eq. 8)",
        pivot.impulse[1],
        m * xc * (omega2 - omega0) + sum_s1 + sum_rs1,
        tol_p,
        &context,
    );
    assert!(
        !out.outcome.warnings.contains(Warnings::PENETRATION_LEFT),
        "{context:?}"
    );
}

/// Fig. 7 with equal weights: eq. (9) proportionality and the corrected omega_2.
#[test]
fn paper_four_point_body_eqs_7_9() {
    let mut rng = Rng::new(0x5eed_0007);
    for _ in 0..1000 {
        four_point_body(&mut rng, false);
    }
}

/// Fig. 7 with unequal contact weights: the weighted minimum-norm share.
#[test]
fn paper_four_point_body_weighted_minimum_norm() {
    let mut rng = Rng::new(0x5eed_0077);
    for _ in 0..1000 {
        four_point_body(&mut rng, true);
    }
}

/// Jammed regime (h < f d) under Newton's and Stronge's laws. Compression is the
/// same as under Poisson's (eq. (5): `SNI = JO omega_0/(h + f d)`, `SFI = f SNI`),
/// ending with omega = 0; in restitution the contact can only stick (derivation in
/// `paper_jammed_regime_sticks_in_restitution`), and while it sticks omega stays 0,
/// so u_n stays 0: Newton's end (`u_n = -R u_n0 > 0`) is never reached, and the
/// normal impulse does no work, so Stronge's end (`W_R = R^2 |W_C| > 0`) is never
/// reached either. The body stops: omega_2 = 0, u_n = u_t = 0 after, with the
/// jamming warning. Any restitution impulse must be a stick impulse
/// (`P_t = -(h/d) P_n`, moment about O zero); its size is not fixed by either law,
/// but it cannot exceed the compression impulse SNI (Poisson's law, the only one
/// that fixes it here, gives R SNI <= SNI); a phase integrated until rounding
/// makes u_n positive would produce an unbounded impulse.
#[test]
fn paper_jammed_regime_newton_and_stronge_stop_the_body() {
    let mut rng = Rng::new(0x5eed_0a12);
    for _ in 0..300 {
        let mut b = PaperBody::random(&mut rng, 1.05, 5.0);
        b.r = b.r.max(0.05);
        for law in [ImpactLaw::Newton, ImpactLaw::Stronge] {
            let out = b.solve::<f64>(law);
            let sni = b.jo() * b.omega0 / (b.h + b.f * b.d);
            let tol_p = 1e-9 * b.impulse_scale();
            let k = &out.outcome.contacts[0];
            let ctx = (law, b);
            check(
                "omega_2",
                out.angular_velocity_after,
                0.0,
                1e-9 * b.omega0,
                &ctx,
            );
            check("SNI", k.compression[0], sni, tol_p, &ctx);
            check("SFI", k.compression[1], b.f * sni, tol_p, &ctx);
            check(
                "u_n after",
                k.normal_velocity_after,
                0.0,
                1e-9 * b.omega0 * b.h,
                &ctx,
            );
            check(
                "u_t after",
                k.tangential_velocity_after,
                0.0,
                1e-9 * b.omega0 * b.d,
                &ctx,
            );
            let (pn, pt) = (k.restitution[0], k.restitution[1]);
            assert!(
                (-tol_p..=sni + tol_p).contains(&pn),
                "restitution normal impulse {pn:e} outside [0, SNI = {sni:e}]: {ctx:?}"
            );
            check(
                "stick ratio P_t = -(h/d) P_n",
                pt,
                -(b.h / b.d) * pn,
                tol_p,
                &ctx,
            );
            assert!(
                out.outcome.warnings.contains(Warnings::JAMMING),
                "jammed body (h < f d) raises the jamming warning: {ctx:?}"
            );
        }
    }
}

/// Fig. 7 with equal restitution R at the three contacts under Newton's law: every
/// contact's normal velocity is `-omega L_i`, so all reach Newton's target
/// `-R u_n0,i = R omega_0 L_i` together, at omega_2 = -R omega_0 (eq. (7) with
/// R1 = R2 = R3, for any impulse path).
#[test]
fn paper_four_point_body_newton_equal_restitution() {
    let mut rng = Rng::new(0x5eed_0707);
    for _ in 0..300 {
        let m = rng.uniform(0.1, 10.0);
        let k = rng.uniform(0.05, 1.0);
        let (xc, yc) = (rng.uniform(-1.0, 1.0), rng.uniform(-1.0, 1.0));
        let omega0 = rng.uniform(0.1, 50.0);
        let r = rng.uniform(0.0, 1.0);
        let contacts: Vec<BodyContact<f64>> = (0..3)
            .map(|_| BodyContact {
                point: [rng.uniform(0.1, 2.0), 0.0],
                normal: [0.0, -1.0],
                law: ContactLaw {
                    restitution: r,
                    friction: rng.uniform(0.1, 1.5),
                    weight: rng.uniform(0.2, 5.0),
                },
            })
            .collect();
        let body = PlanarBody {
            mass: m,
            inertia: m * k * k,
            position: [xc, yc],
            velocity: [0.0, 0.0],
            angular_velocity: omega0,
        };
        let ctx = (m, k, xc, yc, omega0, r, &contacts);
        let out = solve_body::<f64, 8>(&body, Some([0.0, 0.0]), &contacts, ImpactLaw::Newton)
            .unwrap_or_else(|e| panic!("solve_body failed with {e:?} for {ctx:?}"));
        check(
            "omega_2 = -R omega_0",
            out.angular_velocity_after,
            -r * omega0,
            1e-9 * omega0,
            &ctx,
        );
    }
}
