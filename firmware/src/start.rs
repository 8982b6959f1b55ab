//! The controller and the link's state at start, on the board and in QEMU: the
//! compiled-in machine ([`crate::machine`]) with the tuning table stored in flash,
//! or the compiled-in one ([`crate::tuning`]) when none is stored.

use embedded_storage::nor_flash::ReadNorFlash;
use shared::capture::{Capture, MachineFingerprint, Slot, BOARD_CAPACITY};
use shared::controller::{Controller, Params, ResetCause, TuningTable};
use shared::protocol::link::{use_stored, LinkState};
use shared::storage;

#[cfg(feature = "qemu")]
use shared::storage::SimFlash;

use crate::machine::{MACHINE, MACHINE_FILE_CRC32, MACHINE_FILE_LEN};
use crate::tuning::TUNING_ROWS;

/// The capture's buffer: [`BOARD_CAPACITY`] ticks of [`shared::capture::RECORD_LEN`]
/// bytes, 72 KiB of the SRAM (benchmarks/firmware.md). Each app's `init` owns
/// one as a local (a zeroed static, never on a stack).
pub type CaptureBuffer = [Slot; BOARD_CAPACITY];

/// A zeroed [`CaptureBuffer`], for an `init` local's initialiser: RTIC makes
/// that local a static, so the constant is evaluated at compile time into
/// `.bss` and never copied through a stack.
#[allow(clippy::large_const_arrays)]
pub const CAPTURE_BUFFER: CaptureBuffer = [[0; shared::capture::RECORD_LEN]; BOARD_CAPACITY];

/// The controller and the link's state at start: the compiled-in machine with the
/// tuning table stored in `flash` (`&mut` the driver, or `&` a simulated flash), or
/// the compiled-in one when none is stored (first start); the stored self-test
/// result, if any; the capture recording into `capture`, stamped with the
/// compiled-in machine file's fingerprint.
pub fn start<F: ReadNorFlash>(
    flash: F,
    reset_cause: ResetCause,
    capture: &'static mut CaptureBuffer,
) -> (Controller, LinkState) {
    let mut params = Params::from_machine(&MACHINE);
    let stored = storage::load(flash);
    match &stored {
        Some(s) => defmt::info!("tuning table from flash, record {=u32}", s.sequence),
        None => match TuningTable::from_rows(&TUNING_ROWS) {
            Ok(table) => params.tuning = table,
            Err(e) => defmt::error!("compiled-in tuning table rejected: {}", e),
        },
    }
    use_stored(&mut params, stored.as_ref());
    let controller = Controller::new(&params, reset_cause);
    if let Some(e) = controller.params_error() {
        defmt::error!(
            "parameters invalid: {=str} must be {=str}",
            e.field,
            e.requirement
        );
    }
    defmt::info!(
        "vibro driver {=str}: reset cause {}, state {=str}, {=usize} tuning rows",
        env!("CARGO_PKG_VERSION"),
        reset_cause,
        controller.state().name(),
        TUNING_ROWS.len()
    );
    if !MACHINE.rotor_count.has_rotor2() {
        defmt::info!("one rotor: its speed held, no phase loop; motor 2's bridge off");
    }
    let fingerprint = MachineFingerprint {
        crc32: MACHINE_FILE_CRC32,
        len: MACHINE_FILE_LEN,
    };
    let link = LinkState::at_start(&controller, stored.as_ref()).with_capture(Capture::new(
        capture,
        fingerprint,
        params.tick_s(),
    ));
    (controller, link)
}

/// The start on QEMU (the features `qemu` and `pil`): the parameter flash in RAM,
/// erased as QEMU's unwritten flash reads (0x00), so that nothing is stored at
/// start, and [`start`] on it after a power-on.
///
/// `#[inline]`: compiled into the binary that calls it, with `start`, as a call
/// from the binary's own init is; the scripted QEMU log's tick timings follow
/// the binary's code to the instruction.
#[cfg(feature = "qemu")]
#[inline]
pub fn start_in_qemu(capture: &'static mut CaptureBuffer) -> (SimFlash, Controller, LinkState) {
    let flash = SimFlash::filled(0x00);
    let (controller, link) = start(&flash, ResetCause::PowerOn, capture);
    (flash, controller, link)
}
