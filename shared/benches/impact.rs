//! One 4-contact frictional impact: a free platform landing with spin and sideways
//! speed on four feet (the Delassus matrix is 8x8 of rank 3, so the weighted
//! minimum-norm path runs too), solved by the exact piecewise method in f64 and f32.
//!
//! Baseline, what a user would otherwise reach for: a projected Gauss-Seidel
//! (sequential impulses, as in box2d and rapier) on the same Delassus matrix with
//! Newton's law and the friction cone, 50 sweeps. It is not the same physics (one
//! velocity-level LCP, no phases, no events), but it is the usual cost reference.
use criterion::{black_box, criterion_group, criterion_main, Criterion};
use shared::impact::{solve, ImpactProblem};

mod landing;
use landing::problem;

/// Projected Gauss-Seidel on `W P + u0 = v`, Newton targets, friction cone.
fn pgs(p: &ImpactProblem<f64, 8>, sweeps: usize) -> [f64; 16] {
    let n = p.len;
    let mut pn = [0.0; 8];
    let mut pt = [0.0; 8];
    for _ in 0..sweeps {
        for i in 0..n {
            let (mut un, mut ut) = (p.u_n[i], p.u_t[i]);
            for j in 0..n {
                un += p.w_nn[i][j] * pn[j] + p.w_nt[i][j] * pt[j];
                ut += p.w_nt[j][i] * pn[j] + p.w_tt[i][j] * pt[j];
            }
            let target = -p.contacts[i].restitution * p.u_n[i].min(0.0);
            let new_n = (pn[i] + (target - un) / p.w_nn[i][i]).max(0.0);
            let lim = p.contacts[i].friction * new_n;
            let new_t = (pt[i] - ut / p.w_tt[i][i]).clamp(-lim, lim);
            pn[i] = new_n;
            pt[i] = new_t;
        }
    }
    let mut out = [0.0; 16];
    out[..8].copy_from_slice(&pn);
    out[8..].copy_from_slice(&pt);
    out
}

fn bench(c: &mut Criterion) {
    let p64 = problem::<f64>();
    let p32 = problem::<f32>();
    c.bench_function("impact 4 contacts friction f64 (piecewise exact)", |b| {
        b.iter(|| solve(black_box(&p64)).unwrap())
    });
    c.bench_function("impact 4 contacts friction f32 (piecewise exact)", |b| {
        b.iter(|| solve(black_box(&p32)).unwrap())
    });
    c.bench_function("baseline PGS 50 sweeps f64", |b| {
        b.iter(|| pgs(black_box(&p64), 50))
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
