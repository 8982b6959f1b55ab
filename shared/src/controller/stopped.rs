//! The motors stopped: when the device may write the tuning table to flash (and
//! start the self-test, which needs the same rest).
//!
//! Erasing a 128 KiB flash sector takes about 1 s (2 s at most, STM32F405
//! datasheet, `t_ERASE128KB` at 32-bit parallelism), and while the flash is busy the
//! CPU stalls on every fetch from it: the control loop does not run. So a write is
//! allowed only with the driver off and both rotors at rest, which the controller's
//! state and its last measured speeds tell; the link asks [`may_write_table`] with
//! the last tick's status before every store.

use super::State;

/// Highest rotor speed, rpm, at which [`may_write_table`] allows a flash write: a
/// rotor at rest rocks by a few rpm; at 10 rpm it turns a third of a turn during a
/// 2 s erase, and the controller sees that as one jump when its loop resumes.
pub const WRITE_MAX_SPEED_RPM: f32 = 10.0;

/// Whether the tuning table may be written now: the driver is off (`state` idle or
/// fault) and both rotors are at rest (`|speed_rpm| <= WRITE_MAX_SPEED_RPM`, rpm; NaN
/// is not at rest). A write stalls the CPU for the whole erase (module
/// documentation).
pub fn may_write_table(state: State, speed_rpm: [f32; 2]) -> bool {
    let off = matches!(state, State::Idle | State::Fault);
    let at_rest = speed_rpm
        .iter()
        .all(|s| libm::fabsf(*s) <= WRITE_MAX_SPEED_RPM);
    off && at_rest
}
