//! The link's state between the control task and `idle`, under RTIC's lock: the
//! lock `shared::protocol::link::Link::poll` takes for each access ([`Locked`]),
//! and the control tick's port on it ([`link_port`]), on the board and in QEMU.

use shared::protocol::link::{ForTick, LinkState, StateLock};
use shared::protocol::StatusReport;
use shared::tick::LinkPort;

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

/// Flags for idle's log what the controller refused in a tick's port.
pub fn log_refusals(taken: &ForTick) {
    if taken.tuning_refused {
        log::note(log::Event::TuningRefused);
    }
    if taken.self_test_refused {
        log::note(log::Event::SelfTestRefused);
    }
}

/// Idle's look at the link's state, every pass: the bytes the receive ring has
/// lost so far noted in it, and the status the control task published.
pub fn idle_status<M: rtic::Mutex<T = LinkState>>(link: &mut M) -> StatusReport {
    let dropped = link::dropped();
    link.lock(|l| {
        l.rx_dropped = dropped;
        l.status
    })
}
