//! The host's end of the firmware's link in the processor in the loop: the run's
//! commands sent as protocol frames when due, as `host-sim device` sends them,
//! and a heartbeat whenever nothing was sent for
//! [`HEARTBEAT_PERIOD_MS`] (within the firmware's link timeout); the firmware's
//! frames decoded, a refused request noted.

use std::collections::VecDeque;

use shared::controller::Command;
use shared::pil::Bytes;
use shared::protocol::{
    encode, Decoder, Message, Request, Response, HEARTBEAT_PERIOD_MS, MAX_FRAME,
};

/// The host's link.
pub struct Host {
    /// Commands still to send: (time, command), in time order.
    schedule: VecDeque<(f64, Command)>,
    /// Bytes queued for the firmware.
    out: VecDeque<u8>,
    /// Sequence number of the next request.
    seq: u16,
    /// When the last request was sent, s.
    last_sent: Option<f64>,
    /// Heartbeat period, s.
    heartbeat_s: f64,
    decoder: Decoder,
    /// Requests sent: (sequence number, what).
    sent: Vec<(u16, String)>,
    notes: Vec<String>,
}

impl Host {
    /// The link sending `schedule` (times in s).
    pub fn new(schedule: Vec<(f64, Command)>) -> Self {
        Host {
            schedule: schedule.into(),
            out: VecDeque::new(),
            seq: 0,
            last_sent: None,
            heartbeat_s: f64::from(HEARTBEAT_PERIOD_MS) * 1e-3,
            decoder: Decoder::new(),
            sent: Vec::new(),
            notes: Vec::new(),
        }
    }

    /// The bytes for the firmware at `t`, s: the commands due, else a heartbeat
    /// when one is due; as many queued bytes as `rx` holds. While the link is
    /// `lost`, the commands due and the bytes queued are lost and no heartbeat
    /// is sent, as the controller in the loop loses them.
    pub fn send(&mut self, t: f64, lost: bool, rx: &mut Bytes) {
        let mut requests = Vec::new();
        while self
            .schedule
            .front()
            .is_some_and(|(tc, _)| *tc <= t + 1e-12)
        {
            if let Some((_, c)) = self.schedule.pop_front() {
                requests.push(Request::from(c));
            }
        }
        if lost {
            self.out.clear();
            return;
        }
        if requests.is_empty()
            && self
                .last_sent
                .is_some_and(|s| t - s >= self.heartbeat_s - 1e-12)
        {
            requests.push(Request::Command(Command::Heartbeat));
        }
        for r in requests {
            let mut frame = [0u8; MAX_FRAME];
            match encode(&r, self.seq, &mut frame) {
                Ok(n) => {
                    self.out.extend(&frame[..n]);
                    self.sent.push((self.seq, format!("{r:?}")));
                }
                Err(e) => self.notes.push(format!("request {r:?} not encoded: {e:?}")),
            }
            self.seq = self.seq.wrapping_add(1);
            self.last_sent = Some(t);
        }
        while !rx.is_full() {
            match self.out.pop_front() {
                Some(b) => {
                    rx.push(b);
                }
                None => break,
            }
        }
    }

    /// Bytes the firmware sent: its answers noted where they refuse.
    pub fn received(&mut self, mut bytes: &[u8]) {
        while let Some(event) = self.decoder.decode(&mut bytes) {
            let Ok(frame) = event else {
                self.notes
                    .push("a frame from the firmware failed its check".to_string());
                continue;
            };
            if let Ok(Response::Nack { reason, .. }) = Response::parse(&frame) {
                let what = self
                    .sent
                    .iter()
                    .find(|(s, _)| *s == frame.seq)
                    .map_or("a request", |(_, w)| w.as_str());
                self.notes
                    .push(format!("the firmware refused {what}: {reason:?}"));
            }
        }
    }

    /// What the link noticed, for the summary's warnings.
    pub fn warnings(&self) -> Vec<String> {
        self.notes
            .iter()
            .map(|n| format!("firmware link: {n}"))
            .collect()
    }
}
