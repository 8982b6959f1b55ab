//! Between the thread that owns the device link and the threads that serve the
//! pages: frames fanned out to every open event stream, Stop requests carried to
//! the link and their answers back. The link stays with one thread (one
//! [`crate::link::client::Client`], one sequence of requests); the pages only
//! ever reach it through here.

use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::Duration;

/// Frames a page's stream may fall behind by before it misses some (a page that
/// does not read for 64 frames, 6.4 s at the default period, is not watching).
const QUEUE: usize = 64;

/// What goes to a page's event stream.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Event {
    /// A telemetry frame, as JSON ([`super::frame::json`]).
    Frame(Arc<str>),
    /// The stream ended, and why (for people).
    End(Arc<str>),
}

/// The answer to a page's Stop: `Ok` with the device's acknowledgement, or `Err`
/// with why not, for people.
pub type StopAnswer = Result<String, String>;

/// The link thread's end.
pub struct LinkEnd {
    subscribe: Receiver<SyncSender<Event>>,
    stops: Receiver<Sender<StopAnswer>>,
    pages: Vec<SyncSender<Event>>,
}

/// The pages' end, one clone per connection.
#[derive(Clone)]
pub struct PageEnd {
    subscribe: Sender<SyncSender<Event>>,
    stops: Sender<Sender<StopAnswer>>,
}

/// A new hub: its two ends.
pub fn hub() -> (LinkEnd, PageEnd) {
    let (subscribe_tx, subscribe) = mpsc::channel();
    let (stops_tx, stops) = mpsc::channel();
    (
        LinkEnd {
            subscribe,
            stops,
            pages: Vec::new(),
        },
        PageEnd {
            subscribe: subscribe_tx,
            stops: stops_tx,
        },
    )
}

impl LinkEnd {
    /// `event` to every page's stream: new streams joined first, closed ones
    /// dropped, a frame skipped for a stream that is 64 frames behind.
    pub fn publish(&mut self, event: Event) {
        self.pages.extend(self.subscribe.try_iter());
        self.pages
            .retain(|page| match page.try_send(event.clone()) {
                Ok(()) | Err(TrySendError::Full(_)) => true,
                Err(TrySendError::Disconnected(_)) => false,
            });
    }

    /// The Stop requests waiting, each with where its answer goes.
    pub fn stop_requests(&self) -> Vec<Sender<StopAnswer>> {
        self.stops.try_iter().collect()
    }

    /// The streams open now.
    pub fn pages(&self) -> usize {
        self.pages.len()
    }
}

impl PageEnd {
    /// A new event stream; `None` once the link thread has ended.
    pub fn subscribe(&self) -> Option<Receiver<Event>> {
        let (tx, rx) = mpsc::sync_channel(QUEUE);
        self.subscribe.send(tx).ok().map(|()| rx)
    }

    /// Ask the link thread to send Stop; its answer, or why there is none within
    /// `wait`.
    pub fn stop(&self, wait: Duration) -> StopAnswer {
        let (tx, rx) = mpsc::channel();
        if self.stops.send(tx).is_err() {
            return Err(ended());
        }
        match rx.recv_timeout(wait) {
            Ok(answer) => answer,
            Err(RecvTimeoutError::Timeout) => Err(format!(
                "no answer from the link within {:.1} s",
                wait.as_secs_f64()
            )),
            Err(RecvTimeoutError::Disconnected) => Err(ended()),
        }
    }
}

/// Why a page can no longer reach the device.
fn ended() -> String {
    "the telemetry stream has ended: the device link is closed".into()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_reach_every_open_stream_and_a_closed_one_is_dropped() {
        let (mut link, pages) = hub();
        let a = pages.subscribe().unwrap();
        let b = pages.subscribe().unwrap();
        link.publish(Event::Frame("1".into()));
        assert_eq!(link.pages(), 2);
        drop(b);
        link.publish(Event::Frame("2".into()));
        assert_eq!(link.pages(), 1);
        assert_eq!(
            a.try_iter().collect::<Vec<_>>(),
            [Event::Frame("1".into()), Event::Frame("2".into())]
        );
    }

    #[test]
    fn a_stream_that_falls_behind_misses_frames_and_the_others_do_not() {
        let (mut link, pages) = hub();
        let slow = pages.subscribe().unwrap();
        let fast = pages.subscribe().unwrap();
        let n = QUEUE + 10;
        let mut got = 0;
        for k in 0..n {
            link.publish(Event::Frame(k.to_string().into()));
            got += fast.try_iter().count();
        }
        assert_eq!(got, n);
        assert_eq!(slow.try_iter().count(), QUEUE);
        assert_eq!(link.pages(), 2);
    }

    #[test]
    fn a_stop_is_answered_by_the_link_thread_or_refused_once_it_ended() {
        let (link, pages) = hub();
        let asker = std::thread::spawn(move || pages.stop(Duration::from_secs(5)));
        // The link thread's loop: requests taken between reads of the link.
        let reply = loop {
            if let Some(reply) = link.stop_requests().pop() {
                break reply;
            }
            std::thread::sleep(Duration::from_millis(1));
        };
        reply.send(Ok("accepted".into())).unwrap();
        assert_eq!(asker.join().unwrap(), Ok("accepted".into()));
        let (link, pages) = hub();
        drop(link);
        assert_eq!(pages.stop(Duration::from_secs(5)), Err(ended()));
        assert!(pages.subscribe().is_none());
    }
}
