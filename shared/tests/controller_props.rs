//! Properties of `shared::controller` on generated inputs: it never panics, whatever
//! the counters, index latches, currents, supply, E-stop, commands, tick timing and
//! `dt` (NaN and infinities included), and its outputs keep their invariants: duties
//! finite in [-1, 1], zero whenever the driver is disabled; a latched fault means the safe
//! state and stays until a reset command; telemetry angles in their ranges.

use proptest::prelude::*;
use shared::controller::{
    Command, Controller, Direction, Faults, Inputs, Outputs, Params, ResetCause, State, TickTiming,
};

/// Any `f32`, with the special values well represented.
fn any_f32() -> impl Strategy<Value = f32> {
    prop_oneof![
        3 => -1.0e4f32..1.0e4,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::NEG_INFINITY),
        1 => Just(0.0f32),
        1 => Just(-0.0f32),
        1 => proptest::num::f32::ANY,
    ]
}

fn direction() -> impl Strategy<Value = Direction> {
    prop_oneof![Just(Direction::Right), Just(Direction::Left)]
}

/// Commands with any values, and plausible ones that get the motors going.
fn command() -> impl Strategy<Value = Option<Command>> {
    prop_oneof![
        6 => Just(None),
        1 => Just(Some(Command::Stop)),
        1 => Just(Some(Command::ResetFaults)),
        1 => Just(Some(Command::Heartbeat)),
        1 => (direction(), any_f32())
            .prop_map(|(direction, speed_rpm)| Some(Command::Travel { direction, speed_rpm })),
        1 => (direction(), 300.0f32..4500.0)
            .prop_map(|(direction, speed_rpm)| Some(Command::Travel { direction, speed_rpm })),
        1 => (any_f32(), any_f32())
            .prop_map(|(speed_rpm, offset_deg)| Some(Command::HoldOffset { speed_rpm, offset_deg })),
        1 => (300.0f32..4500.0, 0.0f32..360.0)
            .prop_map(|(speed_rpm, offset_deg)| Some(Command::HoldOffset { speed_rpm, offset_deg })),
    ]
}

/// The generated parts of one tick's inputs but the counters: index latches,
/// currents, supply, E-stop, command and (late, busy) timing.
type Parts = (
    [Option<u32>; 2],
    [f32; 2],
    f32,
    bool,
    Option<Command>,
    (f32, f32),
);

/// One tick's inputs from the counters `encoder` and the generated parts.
fn inputs(
    encoder: [u32; 2],
    (index, current, supply_voltage, estop, command, timing): Parts,
) -> Inputs {
    let (late_s, busy_s) = timing;
    Inputs {
        encoder,
        index,
        current,
        supply_voltage,
        estop,
        command,
        timing: TickTiming { late_s, busy_s },
    }
}

/// One tick of arbitrary inputs.
fn wild_tick() -> impl Strategy<Value = (Inputs, f32)> {
    (
        any::<[u32; 2]>(),
        any::<[Option<u32>; 2]>(),
        [any_f32(), any_f32()],
        any_f32(),
        any::<bool>(),
        command(),
        any_f32(),
        (any_f32(), any_f32()),
    )
        .prop_map(
            |(encoder, index, current, supply_voltage, estop, command, dt, timing)| {
                (
                    inputs(
                        encoder,
                        (index, current, supply_voltage, estop, command, timing),
                    ),
                    dt,
                )
            },
        )
}

/// One tick of mostly sane inputs: small count steps, currents and supply near
/// their ranges, rare E-stop, the nominal `dt` or close to it. The encoder deltas
/// are added to running counters, which emit their index pulses; the generated
/// index values (rare) replace them with wrong ones.
fn sane_tick() -> impl Strategy<Value = ([i32; 2], [Option<u32>; 2], Inputs, f32)> {
    (
        [-5i32..300, -5i32..300],
        prop_oneof![100 => Just([None, None]), 1 => any::<[Option<u32>; 2]>()],
        [-2.5f32..2.5, -2.5f32..2.5],
        prop_oneof![20 => 11.0f32..13.0, 1 => any_f32()],
        prop_oneof![50 => Just(false), 1 => Just(true)],
        command(),
        prop_oneof![10 => Just(1.0e-3f32), 1 => 0.0f32..0.02, 1 => any_f32()],
        prop_oneof![
            1000 => (0.0f32..5.0e-5, 1.0e-4f32..3.0e-4),
            1 => (0.0f32..2.0e-3, 0.0f32..2.0e-3),
        ],
    )
        .prop_map(
            |(delta, index, current, supply_voltage, estop, command, dt, timing)| {
                (
                    delta,
                    index,
                    inputs(
                        [0; 2],
                        (index, current, supply_voltage, estop, command, timing),
                    ),
                    dt,
                )
            },
        )
}

/// The output invariants; `before` is the previous tick's faults.
fn check(out: &Outputs, before: Faults, command: Option<Command>, p: &Params) {
    for d in out.duties() {
        assert!(d.is_finite() && (-1.0..=1.0).contains(&d), "duty {d}");
        assert!(d >= p.min_duty, "duty {d} below min_duty");
    }
    // The bridges driven: both while the state drives the motors (two rotors),
    // none otherwise.
    assert_eq!(out.bridges.map(|b| b.is_driven()), [out.state.drives(); 2]);
    if !out.faults.is_empty() {
        assert_eq!(out.state, State::Fault);
        assert!(!out.drives());
    }
    if matches!(out.state, State::Idle | State::Fault) {
        assert!(!out.drives());
    }
    // Latched: a flag only goes away on a reset command.
    if command != Some(Command::ResetFaults) {
        assert!(
            out.faults.contains(before),
            "{before:?} -> {:?}",
            out.faults
        );
    }
    let t = &out.telemetry;
    assert!((0.0..360.0).contains(&t.phase_offset_deg));
    assert!((0.0..360.0).contains(&t.commanded_offset_deg));
    assert!((0.0..360.0).contains(&t.target_offset_deg));
    assert!(t.phase_error_deg > -180.0 && t.phase_error_deg <= 180.0);
    assert!(t.speed_rpm.iter().all(|s| s.is_finite()));
    assert!(t.speed_ref_rpm.iter().all(|s| s.is_finite()));
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn arbitrary_inputs_never_panic_and_keep_the_invariants(
        watchdog in any::<bool>(),
        ticks in proptest::collection::vec(wild_tick(), 1..200),
    ) {
        let p = Params::reference();
        let cause = if watchdog { ResetCause::Watchdog } else { ResetCause::PowerOn };
        let mut ctl = Controller::new(&p, cause);
        let mut before = ctl.faults();
        for (inputs, dt) in &ticks {
            let out = ctl.step(inputs, *dt);
            check(&out, before, inputs.command, &p);
            before = out.faults;
        }
    }

    #[test]
    fn plausible_inputs_keep_the_invariants_while_driving(
        start in any::<[u32; 2]>(),
        speed in 300.0f32..4500.0,
        ticks in proptest::collection::vec(sane_tick(), 1..400),
    ) {
        let p = Params::reference();
        let mut ctl = Controller::new(&p, ResetCause::PowerOn);
        let mut count = start;
        let mut before = ctl.faults();
        // Start a run so that the loops are exercised.
        let first = Inputs {
            encoder: count,
            supply_voltage: 12.0,
            command: Some(Command::Travel { direction: Direction::Right, speed_rpm: speed }),
            ..Inputs::default()
        };
        let out = ctl.step(&first, 1.0e-3);
        check(&out, before, first.command, &p);
        before = out.faults;
        let n = p.encoder_counts;
        for (delta, index, mut inputs, dt) in ticks {
            for k in 0..2 {
                let before = count[k];
                count[k] = count[k].wrapping_add(delta[k] as u32);
                // The index at every whole turn from `start` crossed this tick...
                let (a, b) = (before.wrapping_sub(start[k]) / n, count[k].wrapping_sub(start[k]) / n);
                let turn = if delta[k] >= 0 { b } else { a };
                inputs.index[k] = (a != b).then(|| start[k].wrapping_add(turn * n));
                // ... or a wrong one.
                if index[k].is_some() {
                    inputs.index[k] = index[k];
                }
            }
            inputs.encoder = count;
            let out = ctl.step(&inputs, dt);
            check(&out, before, inputs.command, &p);
            before = out.faults;
        }
    }
}
