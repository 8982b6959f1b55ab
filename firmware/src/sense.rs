//! The analog inputs: both winding currents and the supply voltage, converted by
//! ADC1 at TIM8's update event and moved by DMA into a buffer that the control
//! tick reads without waiting (RM0090 section 13, ADC; section 10, DMA).
//!
//! # Where in the PWM period
//!
//! TIM8 counts up and down (centre-aligned, `motor_out`), and its update event,
//! once every [`shared::drive::BridgeConfig::periods_per_update`] periods, falls
//! on an extreme of the counter: the valley, the middle of every bridge's brake
//! part in slow decay, or the peak, the middle of its drive part (which of the
//! two depends on when the repetition counter was loaded: RM0090, "repetition
//! down-counter"; with an odd RCR loaded before the counter starts, as
//! `motor_out` does, the reference manual's note puts it on the overflow, the
//! peak; `docs/bring-up.md` confirms it on the scope). For a ripple that is linear
//! over a period (the reference winding's `L/R` is 0.25 ms, five PWM periods)
//! the current in the middle of either part is the period's mean: the controller
//! gets the mean current, not a sample at a random point of the ripple.
//!
//! # The chain
//!
//! - TIM8: `TRGO` = update (`CR2.MMS = 010`), set by `motor_out`;
//! - ADC1: the regular group on `EXTSEL = 1110` (TIM8_TRGO), rising edge; scan of
//!   three channels, IN10 (current 1), IN11 (current 2), IN12 (supply), 56 cycles
//!   of sampling each at 21 MHz: `3 x (56 + 12) / 21 MHz = 9.7 us` a scan, within
//!   the 20 us between two updates at most ([`shared::drive::MAX_UPDATE_HZ`]);
//!   `DMA = 1`, `DDS = 1` (a request after every conversion, for good);
//! - DMA2 stream 0 channel 0: ADC1's data register to `BUFFER`, half-words,
//!   circular, `SCANS` scans deep: one control tick of updates, so the tick
//!   averages the currents over its own millisecond.
//!
//! # Failures, and what the controller sees
//!
//! The tick checks the chain before it trusts the buffer: the ADC's `STRT` flag
//! (set by every conversion start, cleared by the tick) shows that conversions
//! ran since the last tick, and `OVR` (a conversion lost: the DMA fell behind)
//! stops the ADC's DMA for good until it is restarted. A stopped chain gives NaN
//! for all three readings, and the chain is restarted; the controller counts a
//! NaN current as over-current and a NaN supply as out of range, so a chain that
//! stays dead latches `OVER_CURRENT` within `over_current_time_s` (2 ms): the
//! motors stop rather than run on stale currents. While a debugger halts the
//! core TIM8 stops too (`DBG_TIM8_STOP`), and so do the conversions.

use core::cell::UnsafeCell;

use shared::controller::CONTROL_RATE_HZ;
use stm32f4xx_hal::gpio::{Analog, PC0, PC1, PC2};
use stm32f4xx_hal::pac::{ADC1, ADC_COMMON, DMA2};
use stm32f4xx_hal::rcc::{Enable, Rcc, Reset};

use crate::machine::MACHINE;

/// Timer updates (scans) a control tick.
const SCANS: usize = {
    let updates = MACHINE.bridge.pwm_hz / MACHINE.bridge.periods_per_update();
    let n = updates as usize / CONTROL_RATE_HZ as usize;
    if n == 0 {
        1
    } else {
        n
    }
};
/// Conversions a scan: current 1, current 2, supply.
const CHANNELS: usize = 3;
/// Half-words in the DMA buffer.
const LEN: usize = SCANS * CHANNELS;
// A buffer the DMA's 16-bit transfer counter can cover.
const _: () = assert!(LEN <= 65_535);

/// ADC channels of the scan, in order: PC0 = IN10, PC1 = IN11, PC2 = IN12.
const SEQUENCE: [u8; CHANNELS] = [10, 11, 12];
/// Sample time code 011: 56 ADC cycles (2.7 us at 21 MHz). The datasheet's bound
/// on the source impedance, `R_AIN < (k - 0.5) / (f_ADC C_ADC ln(2^(N+2))) -
/// R_ADC` with `k = 56`, `C_ADC = 4 pF`, `R_ADC = 6 kOhm`, `N = 12`, is about
/// 62 kOhm; the supply divider is 9.1 kOhm, the current amplifiers' outputs less.
const SMP_56: u8 = 0b011;
/// ADC prescaler code 01: PCLK2 / 4 = 21 MHz (the F405's ADC allows 36 MHz).
const ADCPRE_DIV4: u8 = 0b01;
/// EXTSEL 1110: TIM8_TRGO (RM0090, ADC1 external trigger for regular channels).
const EXTSEL_TIM8_TRGO: u8 = 0b1110;

/// ADC reference (VDDA = VREF+), V.
const VREF_V: f32 = 3.3;
/// ADC full scale, counts (12 bit).
const ADC_FULL_SCALE: f32 = 4095.0;
/// Current sense: output at zero current, V (a bidirectional amplifier biased at
/// mid-supply, e.g. an INA240A1 with REF at VDDA/2, in line with the winding).
const CURRENT_ZERO_V: f32 = 1.65;
/// Current sense gain, V/A (e.g. 5 mOhm shunt x gain 20 = 0.1 V/A: +-16 A span).
const CURRENT_V_PER_A: f32 = 0.1;
/// Sign of each current reading: +1 when a positive sense voltage means the
/// motor is driven forward (its driven sense), -1 otherwise. Check on the bench.
const CURRENT_SIGN: [f32; 2] = [1.0, 1.0];
/// Supply divider ratio `V_bus / V_pin` (e.g. 100 kOhm over 10 kOhm: 11, so
/// 3.3 V at the pin is 36.3 V on the bus).
const SUPPLY_DIVIDER: f32 = 11.0;

/// The DMA's target: written by the DMA only, read by the control tick.
struct DmaBuffer(UnsafeCell<[u16; LEN]>);

// SAFETY: the CPU only reads it, element by element with volatile reads; the
// DMA writes whole half-words, so a read sees an old or a new sample, never a
// torn one.
unsafe impl Sync for DmaBuffer {}

/// The conversions, [`SCANS`] scans of [`SEQUENCE`].
static BUFFER: DmaBuffer = DmaBuffer(UnsafeCell::new([0; LEN]));

/// One tick's analog readings in the controller's units.
pub struct Analog3 {
    /// Winding currents, A, positive driving forward (NaN: no conversion).
    pub current: [f32; 2],
    /// Supply voltage, V (NaN: no conversion).
    pub supply_voltage: f32,
}

/// ADC1 and DMA2 stream 0, converting at TIM8's update.
pub struct Sense {
    adc: ADC1,
    dma: DMA2,
    _pins: (PC0<Analog>, PC1<Analog>, PC2<Analog>),
    /// Times the chain was found stopped and restarted.
    restarts: u32,
}

impl Sense {
    /// Set up the ADC and the DMA (module documentation); conversions start with
    /// TIM8's first update once `motor_out` has set its trigger output.
    pub fn new(
        adc: ADC1,
        common: &ADC_COMMON,
        dma: DMA2,
        pins: (PC0<Analog>, PC1<Analog>, PC2<Analog>),
        rcc: &mut Rcc,
    ) -> Self {
        ADC1::enable(rcc);
        ADC1::reset(rcc);
        DMA2::enable(rcc);
        common
            .ccr()
            .modify(|_, w| unsafe { w.adcpre().bits(ADCPRE_DIV4) });
        adc.cr2().write(|w| w.adon().clear_bit());
        adc.cr1().write(|w| w.scan().set_bit());
        adc.smpr1().write(|w| unsafe {
            w.smp10().bits(SMP_56);
            w.smp11().bits(SMP_56);
            w.smp12().bits(SMP_56)
        });
        adc.sqr1()
            .write(|w| unsafe { w.l().bits(CHANNELS as u8 - 1) });
        adc.sqr3().write(|w| unsafe {
            w.sq1().bits(SEQUENCE[0]);
            w.sq2().bits(SEQUENCE[1]);
            w.sq3().bits(SEQUENCE[2])
        });
        let mut sense = Sense {
            adc,
            dma,
            _pins: pins,
            restarts: 0,
        };
        sense.start();
        sense
    }

    /// (Re)start the chain (RM0090 13.8.1: after an overrun both the DMA and the
    /// ADC are re-initialised): the ADC off, which aborts a conversion and resets
    /// the scan to its first channel; the DMA stream from the buffer's start; the
    /// ADC on with DMA requests, its stabilisation time, and only then the
    /// external trigger, so the first conversion is a scan's first and lands in
    /// the buffer's first slot.
    fn start(&mut self) {
        let adc = &self.adc;
        adc.cr2().write(|w| w.adon().clear_bit());
        let st = self.dma.st(0);
        st.cr().modify(|_, w| w.en().clear_bit());
        let mut polls = 0;
        while st.cr().read().en().bit_is_set() && polls < 10_000 {
            polls += 1;
        }
        // Clear stream 0's flags: FEIF0, DMEIF0, TEIF0, HTIF0, TCIF0.
        self.dma.lifcr().write(|w| unsafe { w.bits(0b11_1101) });
        st.par()
            .write(|w| unsafe { w.pa().bits(adc.dr().as_ptr() as u32) });
        st.m0ar()
            .write(|w| unsafe { w.m0a().bits(BUFFER.0.get() as u32) });
        st.ndtr().write(|w| unsafe { w.ndt().bits(LEN as u16) });
        st.fcr().write(|w| w.dmdis().clear_bit());
        st.cr().write(|w| unsafe {
            w.chsel().bits(0);
            w.pl().bits(0b10);
            w.msize().bits(0b01);
            w.psize().bits(0b01);
            w.minc().set_bit();
            w.pinc().clear_bit();
            w.circ().set_bit();
            w.dir().bits(0b00)
        });
        st.cr().modify(|_, w| w.en().set_bit());
        // Clear a stale overrun and start flag (the PAC writes the others 1,
        // which leaves them: the flags clear on 0).
        adc.sr()
            .write(|w| w.ovr().clear_bit().strt().clear_bit().eoc().clear_bit());
        adc.cr2().write(|w| {
            w.adon().set_bit();
            w.dma().set_bit();
            w.dds().set_bit()
        });
        // t_STAB, the ADC's power-up time: 3 us at most (datasheet); 1000
        // iterations are over 6 us at 168 MHz.
        for _ in 0..1000 {
            cortex_m::asm::nop();
        }
        adc.cr2().modify(|_, w| unsafe {
            w.extsel().bits(EXTSEL_TIM8_TRGO);
            w.exten().bits(0b01)
        });
    }

    /// Times the chain was found stopped and restarted since start.
    pub fn restarts(&self) -> u32 {
        self.restarts
    }

    /// The tick's readings: each channel averaged over the buffer (the last
    /// tick's worth of updates), or NaN if no conversion ran since the last call
    /// or the ADC overran (the chain is then restarted). Never waits.
    pub fn read(&mut self) -> Analog3 {
        let sr = self.adc.sr().read();
        let alive = sr.strt().bit_is_set() && sr.ovr().bit_is_clear();
        if !alive {
            self.restarts = self.restarts.wrapping_add(1);
            self.start();
            return Analog3 {
                current: [f32::NAN; 2],
                supply_voltage: f32::NAN,
            };
        }
        // STRT is cleared by writing 0 (the PAC writes the other flags 1: kept).
        self.adc.sr().write(|w| w.strt().clear_bit());
        let mut sum = [0u32; CHANNELS];
        let base = BUFFER.0.get() as *const u16;
        for scan in 0..SCANS {
            for (c, total) in sum.iter_mut().enumerate() {
                // SAFETY: inside the buffer; the DMA writes half-words (module docs).
                let raw = unsafe { core::ptr::read_volatile(base.add(scan * CHANNELS + c)) };
                *total += u32::from(raw);
            }
        }
        let volts = |s: u32| s as f32 / SCANS as f32 * (VREF_V / ADC_FULL_SCALE);
        // i = s (v - v0) / gain
        Analog3 {
            current: [
                CURRENT_SIGN[0] * (volts(sum[0]) - CURRENT_ZERO_V) / CURRENT_V_PER_A,
                CURRENT_SIGN[1] * (volts(sum[1]) - CURRENT_ZERO_V) / CURRENT_V_PER_A,
            ],
            supply_voltage: volts(sum[2]) * SUPPLY_DIVIDER,
        }
    }
}
