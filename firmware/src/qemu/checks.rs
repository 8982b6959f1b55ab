//! The run's verdict: every check is logged (level INFO when it holds, ERROR when
//! it fails) and counted; the
//! run exits through semihosting with status 0 only if at least one check ran and
//! none failed.

use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};

/// Checks passed so far.
static PASSED: AtomicU32 = AtomicU32::new(0);
/// Checks failed so far.
static FAILED: AtomicU32 = AtomicU32::new(0);

/// Count one check's result; returns it.
pub fn record(ok: bool) -> bool {
    let counter = if ok { &PASSED } else { &FAILED };
    counter.fetch_add(1, Ordering::Relaxed);
    ok
}

/// Check that `$ok` holds, logging the message after it at level INFO if it does,
/// ERROR if not; evaluates to the result.
macro_rules! check {
    ($ok:expr, $fmt:literal $(, $arg:expr)* $(,)?) => {{
        let ok: bool = $ok;
        if $crate::qemu::checks::record(ok) {
            defmt::info!($fmt $(, $arg)*);
        } else {
            defmt::error!($fmt $(, $arg)*);
        }
        ok
    }};
}
pub(crate) use check;

/// Log the totals and leave QEMU: status 0 if every check passed.
pub fn finish() -> ! {
    let passed = PASSED.load(Ordering::Relaxed);
    let failed = FAILED.load(Ordering::Relaxed);
    let success = failed == 0 && passed > 0;
    defmt::info!(
        "checks: {=u32} passed, {=u32} failed: {=str}",
        passed,
        failed,
        if success { "PASS" } else { "FAIL" }
    );
    exit(success)
}

/// Leave QEMU with status 0 (`success`) or 1.
pub fn exit(success: bool) -> ! {
    debug::exit(if success { EXIT_SUCCESS } else { EXIT_FAILURE });
    // Only reached without a semihosting host (on a board): wait.
    loop {
        cortex_m::asm::wfi();
    }
}
