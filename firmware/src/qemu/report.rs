//! The `qemu` run's measurements, logged at its end as lines starting with
//! `measure:` (left out of the comparison with the expected output): the SysTick
//! calibration, the control step's and the control tick's cost (the motor
//! identification's apart), the stack used.

use super::cycles;
use super::stack;
use super::world::World;

/// Log the measurements: `init_stack` and `run_stack` the stack `init` and the
/// run used, bytes; `calibration` SysTick's `(instructions, counts)` of a known
/// loop; the costs and the control task's stack from the `world`.
pub fn report(
    init_stack: usize,
    run_stack: usize,
    calibration: (u32, u32),
    world: &mut impl rtic::Mutex<T = World>,
) {
    let (ins, counts) = calibration;
    defmt::info!(
        "measure: calibration: {=u32} instructions in {=u32} SysTick counts",
        ins,
        counts
    );
    let (off, driving, tick_off, tick_driving, tick_identify, control_stack) = world.lock(|w| {
        (
            w.cost_off,
            w.cost_driving,
            w.tick_off,
            w.tick_driving,
            w.tick_identify,
            w.control_stack,
        )
    });
    for (what, cost) in [
        ("control step, motors off", off),
        ("control step, driving", driving),
        ("control tick without the rotor model, motors off", tick_off),
        (
            "control tick without the rotor model, driving",
            tick_driving,
        ),
        (
            "control tick without the rotor model, identify",
            tick_identify,
        ),
    ] {
        defmt::info!(
            "measure: {=str}: {=u32} ticks, mean {=u32} / max {=u32} SysTick counts = mean {=u32} / max {=u32} instructions",
            what,
            cost.steps,
            cost.mean(),
            cost.max,
            cycles::instructions(cost.mean(), calibration),
            cycles::instructions(cost.max, calibration)
        );
    }
    defmt::info!(
        "measure: stack used: init {=usize} bytes, run {=usize} bytes (scripted host included), of {=usize}; control task {=usize} bytes on top of idle",
        init_stack,
        run_stack,
        stack::size(),
        control_stack
    );
}
