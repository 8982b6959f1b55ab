//! USART2 on QEMU's netduinoplus2: the link's UART in the binary `qemu-uart`
//! (`docs/firmware-qemu.md`, "The link on the emulated USART").
//!
//! QEMU 7.2's STM32F2xx/F4 USART model implements SR, DR, BRR and CR1: a byte
//! received on the chardev sets RXNE (and raises the USART2 interrupt with
//! RXNEIE), reading DR clears RXNE and lets the next byte in; a write to DR goes
//! out at once (TXE stays set). RCC is not emulated, so the registers are written
//! directly: no HAL constructor, no clock enable, nothing that waits on a ready
//! flag. The n-th `-serial` option of QEMU is the n-th USART (USART1, USART2, ...),
//! so `-serial null -serial tcp::PORT,server=on,wait=off` puts USART2 on a TCP port.
//!
//! Split in two halves like the HAL's `Rx`/`Tx`: the receiver for the interrupt
//! task (SR and DR read), the transmitter for the link task (SR read, DR written).

use stm32f4xx_hal::pac::{usart1::RegisterBlock, USART2};

/// BRR for 115200 baud from APB1 at the 16 MHz of HSI (QEMU ignores it; set as
/// the board would without the PLL).
const BRR_115200_AT_16_MHZ: u16 = 139;

/// The receiving half of USART2.
pub struct UartRx {
    _private: (),
}

/// The transmitting half of USART2.
pub struct UartTx {
    _private: (),
}

fn regs() -> &'static RegisterBlock {
    // SAFETY: the USART2 peripheral was consumed by `split`; the two halves touch
    // disjoint state (the receiver reads SR and DR, the transmitter reads SR and
    // writes DR), as the HAL's `Rx` and `Tx` do.
    unsafe { &*USART2::ptr() }
}

/// Enable USART2 at 115200 8N1, transmitter and receiver on, the RX-not-empty
/// interrupt on; the two halves.
pub fn split(usart: USART2) -> (UartRx, UartTx) {
    let r: &RegisterBlock = &usart;
    r.cr1().reset();
    r.brr().write(|w| unsafe { w.bits(BRR_115200_AT_16_MHZ) });
    r.cr1().write(|w| {
        w.ue()
            .set_bit()
            .te()
            .set_bit()
            .re()
            .set_bit()
            .rxneie()
            .set_bit()
    });
    (UartRx { _private: () }, UartTx { _private: () })
}

impl UartRx {
    /// The received byte, if one is waiting (reading it clears RXNE).
    pub fn read(&mut self) -> Option<u8> {
        let r = regs();
        if r.sr().read().rxne().bit_is_set() {
            Some(r.dr().read().dr().bits() as u8)
        } else {
            None
        }
    }
}

impl UartTx {
    /// Send `bytes`, waiting for TXE before each (QEMU keeps it set).
    pub fn write_all(&mut self, bytes: &[u8]) {
        let r = regs();
        for &b in bytes {
            while r.sr().read().txe().bit_is_clear() {}
            r.dr().write(|w| w.dr().set(u16::from(b)));
        }
    }
}
