//! The link's state between the control task and `idle`, under RTIC's lock: the
//! lock `shared::protocol::link::Link::poll` takes for each access ([`Locked`]),
//! the control tick's port on it ([`link_port`]) and a tick run with it
//! ([`run_tick`]), and idle's pass of the link over it ([`serve`]), on the board
//! and in QEMU.

use embedded_storage::nor_flash::NorFlash;
use heapless::spsc::Consumer;
use shared::controller::Controller;
use shared::protocol::link::{ForTick, Link, LinkState, StateLock};
use shared::protocol::StatusReport;
use shared::tick::{Board, LinkPort};

use crate::log::Logger;
use crate::{link, log};

/// RTIC's lock on the link's state (shared with the control task), as the lock
/// `shared::protocol::link::Link::poll` takes for each access.
pub struct Locked<'a, M>(pub &'a mut M);

impl<M: rtic::Mutex<T = LinkState>> StateLock for Locked<'_, M> {
    fn lock<R>(&mut self, f: impl FnOnce(&mut LinkState) -> R) -> R {
        self.0.lock(f)
    }
}

/// Control stages 2 and 5 over the link's state ([`shared::tick::Port`]): the
/// pending command taken (a newly stored tuning table handed to the controller,
/// a requested self-test started), the status and the self-test's published.
/// What the controller refused is flagged for idle's log after the tick
/// ([`log_refusals`]).
pub fn link_port<M: rtic::Mutex<T = LinkState>>(
    link: &mut M,
    uptime_ms: u32,
) -> LinkPort<Locked<'_, M>> {
    LinkPort::new(Locked(link), uptime_ms)
}

/// One control tick ([`shared::tick::run`], its stages 1 to 5): `controller` on
/// `board` with the nominal tick and the link's port over `link` at `uptime_ms`;
/// what the controller refused flagged for idle's log ([`log_refusals`]).
pub fn run_tick<M: rtic::Mutex<T = LinkState>>(
    controller: &mut Controller,
    board: &mut impl Board,
    link: &mut M,
    uptime_ms: u32,
) {
    let mut port = link_port(link, uptime_ms);
    let dt = controller.params().tick_s();
    shared::tick::run(controller, board, &mut port, dt);
    log_refusals(&port.taken);
}

/// Flags for idle's log what the controller refused in a tick's port.
pub fn log_refusals(taken: &ForTick) {
    if taken.tuning_refused {
        log::note(log::Event::TuningRefused);
    }
    if taken.self_test_refused {
        log::note(log::Event::SelfTestRefused);
    }
    if taken.identify_refused {
        log::note(log::Event::IdentifyRefused);
    }
}

/// Idle's look at the link's state, every pass: the bytes the receive ring has
/// lost so far noted in it, and the status the control task published.
fn idle_status<M: rtic::Mutex<T = LinkState>>(link: &mut M) -> StatusReport {
    let dropped = link::dropped();
    link.lock(|l| {
        l.rx_dropped = dropped;
        l.status
    })
}

/// One pass of idle's link task: idle's look at the link's state
/// (`idle_status`), the control task's events logged, then `link` polled at the
/// published uptime on the bytes received into `rx` and the parameter `flash`,
/// its answers handed to `send`. Whether a byte came (idle sleeps otherwise).
pub fn serve<M, F>(
    link: &mut Link,
    rx: &mut Consumer<'_, u8>,
    state: &mut M,
    flash: &mut F,
    logger: &mut Logger,
    send: impl FnMut(&[u8]),
) -> bool
where
    M: rtic::Mutex<T = LinkState>,
    F: NorFlash,
{
    let status = idle_status(state);
    logger.poll(&status);
    link.poll(
        || rx.dequeue(),
        status.uptime_ms,
        Locked(state),
        flash,
        send,
    )
}
