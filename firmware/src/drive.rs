//! The two H-bridges, driven by the shared driver (`shared::drive::HBridge`) over
//! any PWM outputs: the board's TIM8 channels (`motor_out`), or the `qemu`
//! binaries' emulated compare registers (`qemu::pwm`). The same code decides what
//! each bridge input does on the board and in QEMU; what is specific to the board
//! (the timer's main output enable, its break input) stays in `motor_out`.
//!
//! The decay mode is the machine file's (`[drive] decay`, compiled in as
//! `MACHINE.bridge`): slow decay by default, the mean winding voltage `duty x V_s`
//! that the controller assumes (`shared::drive`). Which bridges are driven, and at
//! what duty, is the controller's word (`Outputs::bridges`): on a machine with one
//! rotor, motor 2's never is.

use embedded_hal::pwm::SetDutyCycle;
use shared::controller::Bridge;
use shared::drive::{CentreAligned, Decay, HBridge};

/// TIM8's clock, Hz: twice PCLK2 (84 MHz, `board::PCLK2_HZ`).
pub const TIMER_HZ: u32 = shared::drive::BOARD_TIMER_HZ;

/// TIM8's setup for the machine's `[drive]`: centre-aligned at `pwm_hz`
/// (`ARR = 4200` at 20 kHz), an update every `periods_per_update` periods. The
/// board's timer (`motor_out`) and the `qemu` binaries' emulated compare registers
/// (`qemu::pwm`) both take their full scale, `ARR`, from here.
pub const PWM_TIMER: CentreAligned = CentreAligned::new(TIMER_HZ, crate::machine::MACHINE.bridge);

/// Motor 1's and motor 2's bridges, inputs IN1/IN2 each.
pub struct Drive<P: SetDutyCycle> {
    bridges: [HBridge<P, P>; 2],
}

impl<P: SetDutyCycle> Drive<P> {
    /// The bridges on the channels in the order motor 1 IN1, IN2, motor 2 IN1,
    /// IN2, in `decay` mode; both written to coast.
    pub fn new(channels: [P; 4], decay: Decay) -> Self {
        let [a, b, c, d] = channels;
        Drive {
            bridges: [HBridge::new(a, b, decay), HBridge::new(c, d, decay)],
        }
    }

    /// One tick's inputs: each bridge driven (`Outputs::bridges`: both while the
    /// controller drives on two rotors, motor 1's alone on one) at its signed
    /// duty, the others coasting (both inputs low). An input that fails leaves its
    /// bridge coasting (the driver writes both inputs low on an error); the other
    /// bridge is still driven. Returns whether every input took its value.
    pub fn apply(&mut self, bridges: [Bridge; 2]) -> bool {
        let mut ok = true;
        for (bridge, command) in self.bridges.iter_mut().zip(bridges) {
            let result = match command {
                Bridge::Driven(duty) => bridge.drive(duty),
                Bridge::Off => bridge.coast(),
            };
            ok &= result.is_ok();
        }
        ok
    }

    /// Both bridges coasting (both inputs low), through the driver, so that what
    /// it last wrote is what the outputs hold (after a register-level cut).
    pub fn coast(&mut self) {
        for bridge in self.bridges.iter_mut() {
            let _ = bridge.coast();
        }
    }
}
