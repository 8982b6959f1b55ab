//! The safe state of the `qemu` binaries ([`crate::exceptions::SafeState`]): the
//! emulated bridge inputs zeroed ([`pwm::cut`]), then QEMU left with a failure
//! status ([`checks::exit`]), so a panic or a fault fails the run instead of
//! hanging it.

use super::{checks, pwm, script};
use crate::exceptions::SafeState;

/// A `qemu` binary's safe state; `SCRIPTED`: the scripted run, whose last step
/// pends an interrupt nothing is bound to.
pub struct Qemu<const SCRIPTED: bool>;

/// The scripted run (binary `qemu`): an unexpected interrupt is the one its
/// script pends as its last step, and ends the run with the verdict
/// ([`script::unexpected_interrupt`]).
pub type Scripted = Qemu<true>;

/// The run with the link on USART2 (binary `qemu-uart`): every unexpected
/// interrupt fails it.
pub type Uart = Qemu<false>;

impl<const SCRIPTED: bool> SafeState for Qemu<SCRIPTED> {
    #[inline(always)]
    fn cut() {
        pwm::cut();
    }

    fn driven() -> bool {
        pwm::driven()
    }

    fn halt() -> ! {
        checks::exit(false)
    }

    fn unexpected(irqn: i16, driven: bool) -> ! {
        if SCRIPTED {
            script::unexpected_interrupt(irqn, driven)
        } else {
            Self::halt()
        }
    }
}
