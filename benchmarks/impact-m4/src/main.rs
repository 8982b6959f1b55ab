//! Instructions of one 4-contact frictional impact of `shared::impact` on the
//! Cortex-M4F (thumbv7em-none-eabihf, the firmware's target and profile), counted
//! in QEMU's netduinoplus2 (STM32F405) under `-icount shift=0`.
//!
//! The impact is the host benchmark's (`shared/benches/landing/mod.rs`, included
//! below): a free 2 kg platform landing on four collinear frictional feet,
//! Poisson's law. `run.sh` builds and runs this program and says how to read it;
//! `benchmarks/impact.md` has the results.
//!
//! On the target the program:
//!
//! 1. solves the impact once in `f32` and once in `f64`, each between the
//!    markers `trace_begin` and `trace_end` (and the markers once around nothing),
//!    for an instruction trace (`run.sh`'s second run); with `trace` on the
//!    semihosting command line it prints the markers' addresses and exits there;
//! 2. calibrates SysTick against a loop of known length (instructions per count);
//! 3. times `RUNS_F32` impacts in `f32` (hardware FPU), `RUNS_F64` in `f64`
//!    (soft-float calls on this single-precision FPU) and an empty loop of each
//!    length, and prints instructions per impact, the empty loop subtracted;
//! 4. prints each outcome (energy change, impulses, cases) for comparison with the
//!    host's, and exits through semihosting (status 1 on any failure or panic).
//!
//! Built for the host (`cargo run --release --target <host triple>`) it prints
//! the same outcome lines, computed on the host: the reference `run.sh` compares
//! the target's lines with.
#![cfg_attr(target_os = "none", no_std)]
#![cfg_attr(target_os = "none", no_main)]

use core::fmt::{self, Write};

use shared::impact::{ImpactError, ImpactOutcome};
use shared::Real;

#[path = "../../../shared/benches/landing/mod.rs"]
mod landing;

/// SysTick as an instruction counter: the firmware's own module, so the
/// benchmark and the firmware's QEMU measurements count alike.
#[cfg(target_os = "none")]
#[path = "../../../firmware/src/qemu/counter.rs"]
mod counter;
#[cfg(target_os = "none")]
mod target;

/// Writes one line describing an impact's outcome: what run.sh compares between
/// the target and the host. Every number is printed in the type's shortest
/// round-trip form, so equal lines mean equal bits.
fn describe<T: Real>(
    w: &mut dyn Write,
    name: &str,
    outcome: &Result<ImpactOutcome<T, 8>, ImpactError>,
) -> fmt::Result {
    let o = match outcome {
        Ok(o) => o,
        Err(e) => return writeln!(w, "outcome {name}: error {e:?}"),
    };
    write!(w, "outcome {name}: energy change {:?} J;", o.energy_change)?;
    write!(w, " normal impulses")?;
    for c in &o.contacts[..o.len] {
        write!(w, " {:?}", c.normal_impulse)?;
    }
    write!(w, " N s; tangential")?;
    for c in &o.contacts[..o.len] {
        write!(w, " {:?}", c.tangential_impulse)?;
    }
    write!(w, " N s; cases")?;
    for c in &o.contacts[..o.len] {
        write!(w, " {}", c.case as u8)?;
    }
    writeln!(w)
}

/// The host's outcome lines, for comparison with the target's.
#[cfg(not(target_os = "none"))]
fn main() {
    /// `std`'s stdout through `core::fmt::Write`.
    struct Out(String);
    impl Write for Out {
        fn write_str(&mut self, s: &str) -> fmt::Result {
            self.0.push_str(s);
            Ok(())
        }
    }
    let mut out = Out(String::new());
    let r32 = shared::impact::solve(&landing::problem::<f32>());
    let r64 = shared::impact::solve(&landing::problem::<f64>());
    describe(&mut out, "f32", &r32).unwrap();
    describe(&mut out, "f64", &r64).unwrap();
    print!("{}", out.0);
}
