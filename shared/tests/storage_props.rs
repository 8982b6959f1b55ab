//! The parameter store under random histories (proptest): any sequence of stores,
//! each completed or cut by a power loss at a random byte, always loads the last
//! record whose store completed (none before the first), and sequence numbers grow
//! by one per completed store.

use proptest::prelude::*;

use shared::controller::self_test::{RotorSelfTest, SelfTest};
use shared::storage::{Record, SimFlash};

mod support;

use support::power_cut::{store_and_check, STORE_WORK};
use support::tables::table_from_steps;

fn record() -> impl Strategy<Value = Record> {
    (
        prop::collection::vec((1.0f32..500.0, 0.0f32..360.0, 0.0f32..360.0), 1..=32),
        prop::option::of((any::<[bool; 6]>(), any::<[u32; 4]>())),
    )
        .prop_map(|(rows, test)| {
            let rotor = |b: &[bool], cpr: u32, offset: u32| RotorSelfTest {
                motor_polarity_ok: b[0],
                encoder_polarity_ok: b[1],
                index_seen: b[2],
                counts_per_rev: cpr,
                index_offset_counts: offset,
            };
            Record {
                tuning: table_from_steps(rows),
                self_test: test.map(|(b, n)| SelfTest {
                    rotors: [rotor(&b[..3], n[0], n[1]), rotor(&b[3..], n[2], n[3])],
                }),
                identity: None,
            }
        })
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 300, ..ProptestConfig::default() })]

    #[test]
    fn the_last_completed_store_is_what_loads(
        history in prop::collection::vec(
            (record(), prop::option::of(0usize..STORE_WORK + 50)),
            1..12,
        ),
        zeroed in any::<bool>(),
    ) {
        let mut flash = if zeroed { SimFlash::filled(0) } else { SimFlash::new() };
        let mut last: Option<(Record, u32)> = None;
        for (record, cut) in history {
            store_and_check(&mut flash, record, cut, &mut last);
        }
    }
}
