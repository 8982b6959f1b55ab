//! The parameter store fuzzed, bounded and seeded so that it runs in CI like any
//! test (`VIBRO_FUZZ_ITERS` cases, 10 000 by default, from seed `VIBRO_FUZZ_SEED`;
//! docs/development.md, "Fuzzing"). Each case is a history of up to 10 stores of
//! random records (a random tuning table, with or without a random self-test
//! result) on a simulated flash that starts erased or zeroed (QEMU's); each store
//! runs to the end or loses power after a random number of bytes: anywhere in the
//! erase and the programming, and often in the commit word's last bytes. After
//! every store the power comes back and `load` must give exactly the last committed
//! record: the new one when the store completed, else the one before (none before
//! the first), never another; sequence numbers grow by one per completed store.

mod support;

use shared::controller::identify::{Estimate, Identity, RotorIdentity};
use shared::controller::self_test::{RotorSelfTest, SelfTest};
use shared::storage::{Record, SimFlash};
use support::fuzz::{self, Rng};
use support::power_cut::{store_and_check, STORE_WORK};

/// Cases of a run by default: about a second at the test profile.
const CASES: u64 = 10_000;

/// A random rotor result.
fn rotor(rng: &mut Rng) -> RotorSelfTest {
    RotorSelfTest {
        motor_polarity_ok: rng.one_in(2),
        encoder_polarity_ok: rng.one_in(2),
        index_seen: rng.one_in(2),
        counts_per_rev: rng.next_u64() as u32,
        index_offset_counts: rng.next_u64() as u32,
    }
}

/// A random record: a random table, and half the time each a self-test result
/// and a motor identification.
fn record(rng: &mut Rng) -> Record {
    Record {
        tuning: fuzz::table(rng),
        self_test: rng.one_in(2).then(|| SelfTest {
            rotors: [rotor(rng), rotor(rng)],
        }),
        identity: rng.one_in(2).then(|| identity(rng)),
    }
}

/// A random motor identification: every value finite, every spread positive.
fn identity(rng: &mut Rng) -> Identity {
    let mut rotor = || {
        let mut e = || Estimate {
            value: rng.uniform(-10.0, 10.0),
            std_error: rng.uniform(0.0, 1.0),
        };
        RotorIdentity {
            shortfall: None,
            resistance_ohm: e(),
            torque_constant: e(),
            coulomb_friction_nm: e(),
            viscous_friction: e(),
            inertia_kg_m2: e(),
            offset_v: e(),
            drop_v: e(),
            voltage_residual_v: rng.uniform(0.0, 1.0),
            friction_residual_nm: rng.uniform(0.0, 1.0),
            standstill_levels: rng.byte(),
            speed_levels: rng.byte(),
        }
    };
    Identity {
        rotors: [rotor(), rotor()],
        rotors_run: 1 + rng.below(2) as u8,
    }
}

/// Where the power goes: never (half the stores), in the commit word's last bytes,
/// or anywhere (a few bytes past the end complete the store too).
fn cut(rng: &mut Rng) -> Option<usize> {
    match rng.below(4) {
        0 | 1 => None,
        2 => Some(rng.range(STORE_WORK - 8, STORE_WORK)),
        _ => Some(rng.range(0, STORE_WORK + 8)),
    }
}

#[test]
fn a_power_cut_anywhere_loads_the_last_committed_record() {
    fuzz::run(CASES, |rng| {
        let mut flash = if rng.one_in(2) {
            SimFlash::new()
        } else {
            SimFlash::filled(0x00)
        };
        let mut committed: Option<(Record, u32)> = None;
        for _ in 0..rng.range(1, 10) {
            let new = record(rng);
            let cut = cut(rng);
            store_and_check(&mut flash, new, cut, &mut committed);
        }
    });
}
