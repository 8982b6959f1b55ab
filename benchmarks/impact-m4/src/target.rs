//! The target's side: the entry point, the SysTick counting, the trace markers
//! and the panic handler.
//!
//! **Counting.** Under `-icount shift=0` every guest instruction advances QEMU's
//! virtual clock by exactly 1 ns, and netduinoplus2's SysTick counts that clock
//! at 168 MHz: `n` instructions move it by `0.168 n` counts (one count every
//! 5.95 instructions). [`calibrate`] measures the ratio on the firmware's loop
//! of known length (`firmware/src/qemu/counter.rs`) rather than assuming it. A measurement reads the counter (counting
//! down from its 24-bit maximum, interrupts off) before and after `runs`
//! repetitions and fails if it wrapped in between (COUNTFLAG); the same
//! loop without the work is timed the same way and subtracted.

use core::fmt::Write;
use core::hint::black_box;

use cortex_m::peripheral::syst::SystClkSource;
use cortex_m::peripheral::SYST;
use cortex_m_rt::entry;
use cortex_m_semihosting::debug::{self, EXIT_FAILURE, EXIT_SUCCESS};
use cortex_m_semihosting::{hio, hprintln};
use shared::impact::solve;

use crate::counter::{count_loop, elapsed, now};
use crate::{describe, landing};

/// Impacts timed in `f32`: about 6 900 SysTick counts each (the counter holds
/// 16.7 million before it wraps).
const RUNS_F32: u32 = 200;
/// Impacts timed in `f64`: soft-float, about 51 000 counts each.
const RUNS_F64: u32 = 50;
/// Passes of the calibration loop, 2 instructions each.
const CAL_ITERATIONS: u32 = 1_000_000;
/// SysTick's reload: the 24-bit maximum.
const RELOAD: u32 = 0x00FF_FFFF;

#[entry]
fn main() -> ! {
    let mut cp = cortex_m::Peripherals::take().unwrap();
    let p32 = landing::problem::<f32>();
    let p64 = landing::problem::<f64>();

    // 1. The trace markers around nothing, then around one impact in f32, then
    //    in f64.
    trace_begin();
    trace_end();
    trace_begin();
    let traced32 = solve(black_box(&p32));
    black_box(&traced32);
    trace_end();
    trace_begin();
    let traced64 = solve(black_box(&p64));
    black_box(&traced64);
    trace_end();
    let traced = traced32.is_ok() && traced64.is_ok();
    if command_line_has(b"trace") {
        // Thumb function pointers carry bit 0; QEMU's log shows the address.
        hprintln!(
            "trace: trace_begin at {:#010x}, trace_end at {:#010x}",
            trace_begin as extern "C" fn() as usize & !1,
            trace_end as extern "C" fn() as usize & !1
        );
        exit(traced);
    }

    // 2. SysTick at the core clock, free-running from its maximum, no interrupt.
    let syst = &mut cp.SYST;
    syst.disable_interrupt();
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(RELOAD);
    syst.clear_current();
    syst.enable_counter();
    let (cal_instructions, cal_counts) = calibrate(syst);
    hprintln!(
        "calibration: {} instructions in {} SysTick counts",
        cal_instructions,
        cal_counts
    );

    // 3. The impacts, and the loops without them.
    // The outcome is kept in memory whole (`black_box(&o)`), as a caller would
    // have it; the empty loop passes the problem through `black_box` alone.
    let f32_counts = time(syst, RUNS_F32, || {
        let o = solve(black_box(&p32));
        black_box(&o);
    });
    let f32_empty = time(syst, RUNS_F32, || {
        black_box(&p32);
    });
    let f64_counts = time(syst, RUNS_F64, || {
        let o = solve(black_box(&p64));
        black_box(&o);
    });
    let f64_empty = time(syst, RUNS_F64, || {
        black_box(&p64);
    });
    let calibration = (cal_instructions, cal_counts);
    report("f32", RUNS_F32, f32_counts, f32_empty, calibration);
    report("f64", RUNS_F64, f64_counts, f64_empty, calibration);

    // 4. The outcomes, for comparison with the host's.
    let mut out = hio::hstdout().unwrap();
    let r32 = solve(&p32);
    let r64 = solve(&p64);
    let printed =
        describe(&mut out, "f32", &r32).is_ok() && describe(&mut out, "f64", &r64).is_ok();
    exit(traced && r32.is_ok() && r64.is_ok() && printed);
}

/// Marks the start of a traced stretch: `run.sh`'s trace counts the
/// instructions executed from this function's entry to [`trace_end`]'s, around
/// the impact less around nothing.
#[inline(never)]
#[no_mangle]
pub extern "C" fn trace_begin() {
    // Something the optimiser cannot merge with `trace_end`.
    black_box(1u32);
}

/// Marks the end of a traced stretch.
#[inline(never)]
#[no_mangle]
pub extern "C" fn trace_end() {
    black_box(2u32);
}

/// Restarts the counter at its maximum and clears COUNTFLAG.
fn restart(syst: &mut SYST) {
    syst.clear_current();
    // After the clear the counter reads 0 until it reloads.
    while now() == 0 {}
    let _ = syst.has_wrapped();
}

/// `(instructions, counts)` of the firmware's calibration loop
/// ([`count_loop`]); fails if the counter wrapped meanwhile.
fn calibrate(syst: &mut SYST) -> (u32, u32) {
    restart(syst);
    let calibration = count_loop(CAL_ITERATIONS);
    if syst.has_wrapped() {
        fail("the calibration loop wrapped SysTick");
    }
    calibration
}

/// SysTick counts of `runs` calls of `work` (loop included); fails if the
/// counter wrapped.
#[inline(never)]
fn time(syst: &mut SYST, runs: u32, mut work: impl FnMut()) -> u32 {
    restart(syst);
    let before = now();
    for _ in 0..black_box(runs) {
        work();
    }
    let after = now();
    if syst.has_wrapped() {
        fail("a measurement wrapped SysTick: fewer runs");
    }
    elapsed(before, after)
}

/// Prints the counts of one type and the instructions per impact, the empty
/// loop subtracted, converted by the calibration `(instructions, counts)`.
fn report(name: &str, runs: u32, counts: u32, empty: u32, calibration: (u32, u32)) {
    let (ins, cal) = calibration;
    let net = u64::from(counts.saturating_sub(empty));
    // Instructions per impact in tenths, rounded to nearest.
    let tenths = (net * u64::from(ins) * 10 + u64::from(cal) * u64::from(runs) / 2)
        / (u64::from(cal) * u64::from(runs));
    hprintln!(
        "{}: {} impacts in {} SysTick counts, empty loop {}: {}.{} instructions per impact",
        name,
        runs,
        counts,
        empty,
        tenths / 10,
        tenths % 10
    );
}

/// True when the semihosting command line (QEMU: `-semihosting-config`'s `arg`s,
/// else the kernel's name and `-append`'s text) contains `word`.
fn command_line_has(word: &[u8]) -> bool {
    let mut buf = [0u8; 128];
    let mut block = [buf.as_mut_ptr() as usize, buf.len() - 1];
    // SAFETY: SYS_GET_CMDLINE writes at most `block[1]` bytes into `buf` and the
    // length it wrote into `block[1]`; both pointers come from `&mut`.
    let status = unsafe {
        cortex_m_semihosting::syscall1(
            cortex_m_semihosting::nr::GET_CMDLINE,
            block.as_mut_ptr() as usize,
        )
    };
    if status != 0 {
        return false;
    }
    let line = &buf[..block[1].min(buf.len())];
    line.windows(word.len()).any(|w| w == word)
}

/// Prints `message` and exits with failure.
fn fail(message: &str) -> ! {
    hprintln!("error: {}", message);
    exit(false)
}

/// Exits QEMU through semihosting with status 0 (`success`) or 1.
fn exit(success: bool) -> ! {
    debug::exit(if success { EXIT_SUCCESS } else { EXIT_FAILURE });
    // Only reached without a semihosting host.
    loop {
        cortex_m::asm::wfi();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    if let Ok(mut out) = hio::hstderr() {
        let _ = writeln!(out, "panic: {info}");
    }
    exit(false)
}
