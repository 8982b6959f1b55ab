//! Stack high-water mark by painting: fill the free stack with a pattern early,
//! find later how far down the pattern was overwritten.
//!
//! The stack is the region `[bottom, _stack_start)`, growing down from
//! `_stack_start` (cortex-m-rt's symbol, the initial stack pointer). Linked with
//! flip-link (`firmware/.cargo/config.toml`) the stack sits at the start of RAM,
//! below `.data`/`.bss`, so `bottom` is the start of RAM and an overflow faults on
//! the RAM boundary instead of overwriting statics; linked without it the stack
//! sits above `.bss` and `bottom` is cortex-m-rt's `_stack_end`.

use core::ptr::{addr_of, read_volatile, write_volatile};
use core::sync::atomic::{AtomicUsize, Ordering};

/// Start of RAM (memory.x: `RAM : ORIGIN = 0x20000000`).
const RAM_START: usize = 0x2000_0000;
/// The paint pattern.
const PAINT: u32 = 0xACE0_BACE;
/// Bytes left unpainted below the painting function's own stack pointer.
const MARGIN: usize = 64;

extern "C" {
    /// Initial stack pointer: the top of the stack (cortex-m-rt, moved by flip-link).
    static _stack_start: u32;
    /// End of `.bss`/`.uninit` (cortex-m-rt).
    static _stack_end: u32;
}

/// `[bottom, top)` of the stack region.
pub fn region() -> (usize, usize) {
    // Only the symbols' addresses are taken, never their contents.
    let (top, end) = (
        addr_of!(_stack_start) as usize,
        addr_of!(_stack_end) as usize,
    );
    // flip-link puts the statics above the stack: then the stack starts at RAM.
    let bottom = if end < top { end } else { RAM_START };
    // Its lowest bytes are the MPU's guard (never painted nor read).
    let bottom = if bottom == RAM_START {
        bottom + crate::exceptions::STACK_GUARD_BYTES
    } else {
        bottom
    };
    (bottom, top)
}

/// Paint the stack from its bottom up to just below the current stack pointer.
/// Call it early (in `init`, interrupts off); what the stack held deeper before
/// is not counted.
#[inline(never)]
pub fn paint() {
    let (bottom, _) = region();
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = bottom;
    while p + 4 <= sp - MARGIN {
        // SAFETY: `[bottom, sp - MARGIN)` is free stack: below the live frames, and
        // nothing else uses it (interrupts are off in init).
        unsafe { write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// Bytes of stack used so far: from the top down to the lowest word that no
/// longer holds the paint.
pub fn used() -> usize {
    let (bottom, top) = region();
    let mut p = bottom;
    // SAFETY: reads of the stack region, word aligned.
    while p < top && unsafe { read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    top - p.min(LOWEST.load(Ordering::Relaxed))
}

/// Forget what the windows recorded (before [`paint`] starts a new measurement).
pub fn reset() {
    LOWEST.store(usize::MAX, Ordering::Relaxed);
}

/// Bytes of the stack region.
pub fn size() -> usize {
    let (bottom, top) = region();
    top - bottom
}

/// Bytes of the window [`paint_window`] paints below a task's stack pointer.
pub const WINDOW: usize = 8 * 1024;

/// The lowest address found written in a window before it was painted again
/// (`usize::MAX`: none yet), so that window painting loses nothing of the
/// whole-stack record [`used`] reports.
static LOWEST: AtomicUsize = AtomicUsize::new(usize::MAX);

/// Paint the `WINDOW` bytes below `top` (a task's stack pointer, read at its
/// start), except the frame of this function and `MARGIN`: before the task's
/// work, so that [`window_lowest`] can tell how deep that work went. What the
/// window shows written so far is kept for [`used`] first.
#[inline(never)]
pub fn paint_window(top: usize) {
    LOWEST.fetch_min(window_lowest(top), Ordering::Relaxed);
    let (bottom, _) = region();
    let sp = cortex_m::register::msp::read() as usize;
    let mut p = top.saturating_sub(WINDOW).max(bottom);
    while p + 4 <= sp - MARGIN {
        // SAFETY: below this function's own frame: free stack (nothing preempts
        // the control task in the binary `qemu`).
        unsafe { write_volatile(p as *mut u32, PAINT) };
        p += 4;
    }
}

/// The lowest address written in the window below `top` since
/// [`paint_window`]`(top)` (`top` if none).
pub fn window_lowest(top: usize) -> usize {
    let (bottom, _) = region();
    let mut p = top.saturating_sub(WINDOW).max(bottom);
    // SAFETY: reads of the stack region, word aligned.
    while p < top && unsafe { read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    p
}

/// The stack pointer of the task the control task interrupts (idle, recorded
/// before it sleeps); 0 until then.
static IDLE_SP: AtomicUsize = AtomicUsize::new(0);

/// Record the current stack pointer as idle's.
#[inline(always)]
pub fn record_idle_sp() {
    IDLE_SP.store(cortex_m::register::msp::read() as usize, Ordering::Relaxed);
}

/// Bytes an interrupt used on top of idle's stack, its lowest address written
/// being `lowest` (exception frame and the handler's frames included); 0 before
/// idle recorded its stack pointer.
pub fn above_idle(lowest: usize) -> usize {
    IDLE_SP.load(Ordering::Relaxed).saturating_sub(lowest)
}
