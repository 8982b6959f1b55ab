//! The board of the binary `pil` at a control tick ([`shared::tick::Board`]):
//! the host over the record channel. `sample` sends the last tick's outputs (and
//! the UART bytes the link sent since) and reads this tick's sample (and the
//! bytes received, into the link's RX ring, as the board's UART interrupt fills
//! it); `apply` drives the emulated compare registers through the board's bridge
//! driver, exactly the values TIM8 would get. A channel that fails or a record
//! that is not the one due is a fault of the board: the bridges are cut and the
//! run ends with status 1 ([`fail`]).

use heapless::spsc::{Consumer, Producer};
use shared::controller::{Bridge, Inputs, Outputs, TickTiming};
use shared::pil::{Bytes, Drive as DriveRecord, Hello, Sample};
use shared::protocol::StatusReport;

use super::channel::Channel;
use crate::drive::Drive;
use crate::link;
use crate::qemu::{checks, pwm, pwm::SimPwm};

/// What the board keeps between ticks.
pub struct PilLink {
    channel: Channel,
    /// The last tick's outputs, sent with the next sample's request.
    pending: Option<DriveRecord>,
}

impl PilLink {
    /// The channel opened and the [`Hello`] sent: the build's machine file and
    /// tick period.
    pub fn start(hello: &Hello) -> PilLink {
        let mut channel = Channel::open().unwrap_or_else(|_| fail("cannot open pil.in/pil.out"));
        if channel.send(&hello.to_bytes()).is_err() {
            fail("cannot send the hello record");
        }
        PilLink {
            channel,
            pending: None,
        }
    }
}

/// The board at tick `tick`.
pub struct PilBoard<'a> {
    /// The channel and the last tick's outputs.
    pub link: &'a mut PilLink,
    /// The bridges, through the board's driver over the emulated compare registers.
    pub drive: &'a mut Drive<SimPwm>,
    /// The link's sent bytes.
    pub tx: &'a mut Consumer<'static, u8>,
    /// The link's received bytes.
    pub rx: &'a mut Producer<'static, u8>,
    /// This tick's number (1 for the first).
    pub tick: u32,
    /// The tick's timing, from SysTick.
    pub timing: TickTiming,
    /// How long the previous tick's task ran, ns (its record carries it).
    pub last_busy_ns: u32,
    /// The firmware's uptime at this tick, ms.
    pub uptime_ms: u32,
    /// The E-stop as this tick's sample read it.
    pub estop: bool,
    /// How late the next tick starts, us, as this tick's sample asks.
    pub next_late_us: u16,
}

impl shared::tick::Board for PilBoard<'_> {
    fn sample(&mut self) -> Inputs {
        if let Some(mut record) = self.link.pending.take() {
            record.tx = drain(self.tx);
            record.busy_ns = self.last_busy_ns;
            if self.link.channel.send(&record.to_bytes()).is_err() {
                fail("cannot send the drive record");
            }
        }
        let mut bytes = [0u8; Sample::LEN];
        if self.link.channel.receive(&mut bytes).is_err() {
            fail("cannot read the sample record");
        }
        let sample = match Sample::parse(&bytes, self.tick) {
            Ok(s) => s,
            Err(e) => {
                defmt::error!("pil: sample record refused: {}", e);
                fail("bad sample record")
            }
        };
        for &b in sample.rx.as_slice() {
            link::receive(self.rx, b);
        }
        self.estop = sample.estop;
        self.next_late_us = sample.next_late_us;
        Inputs {
            encoder: sample.encoder,
            index: sample.index,
            current: sample.current,
            supply_voltage: sample.supply_voltage,
            estop: sample.estop,
            command: None,
            timing: self.timing,
        }
    }

    fn apply(&mut self, out: &Outputs) {
        // As the board's `motor_out`: the bridges the controller drives, while
        // the E-stop circuit is closed; MOE set only then.
        let bridges = if self.estop {
            [Bridge::Off; 2]
        } else {
            out.bridges
        };
        self.drive.apply(bridges);
        self.link.pending = Some(DriveRecord {
            tick: self.tick,
            compare: pwm::compare_values(),
            enabled: bridges.iter().any(|b| b.is_driven()),
            busy_ns: 0,
            status: StatusReport::from_outputs(self.uptime_ms, out),
            tx: Bytes::default(),
        });
    }
}

/// The sent bytes queued, as many as a record carries.
fn drain(tx: &mut Consumer<'static, u8>) -> Bytes {
    let mut bytes = Bytes::default();
    while !bytes.is_full() {
        match tx.dequeue() {
            Some(b) => {
                bytes.push(b);
            }
            None => break,
        }
    }
    bytes
}

/// The board is lost: cut the bridges, say why, end the run with status 1.
pub fn fail(why: &str) -> ! {
    pwm::cut();
    defmt::error!("pil: {=str}: bridges cut, stopping", why);
    checks::exit(false)
}
