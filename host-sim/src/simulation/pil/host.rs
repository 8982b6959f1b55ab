//! The host's end of the firmware's link in the processor in the loop: the run's
//! commands sent as protocol frames when due, as `host-sim device` sends them,
//! and a heartbeat whenever nothing was sent for
//! [`HEARTBEAT_PERIOD_MS`] (within the firmware's link timeout); the firmware's
//! frames decoded, a refused command noted.
//!
//! Other requests (the identification's, the capture's: [`super::script`]) are
//! asked with [`Host::ask`]: sent at the next exchange, before the commands due
//! there, and each one's answer (its Ack or Nack, or the data asked for) kept
//! as an [`Answer`] for [`Host::answers`]. With nothing asked, the bytes sent are
//! those of the commands and heartbeats alone.

use std::collections::VecDeque;

use shared::controller::Command;
use shared::pil::Bytes;
use shared::protocol::{
    encode, Decoder, Message, Request, Response, HEARTBEAT_PERIOD_MS, MAX_FRAME,
};

/// A request asked with [`Host::ask`] and the firmware's answer to it.
#[derive(Clone, Debug, PartialEq)]
pub struct Answer {
    /// The request.
    pub request: Request,
    /// The firmware's response: Ack, Nack, or the data asked for.
    pub response: Response,
}

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
    /// Requests asked, to send at the next exchange.
    asked: VecDeque<Request>,
    /// Requests asked and sent, not answered yet: (sequence number, request).
    awaiting: Vec<(u16, Request)>,
    /// Answers received since [`Host::answers`] was last called.
    answers: Vec<Answer>,
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
            asked: VecDeque::new(),
            awaiting: Vec::new(),
            answers: Vec::new(),
            notes: Vec::new(),
        }
    }

    /// Send `request` at the next exchange, before the commands due there; its
    /// answer goes to [`Host::answers`].
    pub fn ask(&mut self, request: Request) {
        self.asked.push_back(request);
    }

    /// The answers to the requests asked, received since the last call, in the
    /// order they came.
    pub fn answers(&mut self) -> Vec<Answer> {
        std::mem::take(&mut self.answers)
    }

    /// The bytes for the firmware at `t`, s: the requests asked, then the
    /// commands due, else a heartbeat when one is due (any request keeps the
    /// link alive); as many queued bytes as `rx` holds. While the link is
    /// `lost`, the requests asked, the commands due and the bytes queued are
    /// lost and no heartbeat is sent, as the controller in the loop loses them.
    pub fn send(&mut self, t: f64, lost: bool, rx: &mut Bytes) {
        let asked = self.asked.len();
        let mut requests: Vec<Request> = self.asked.drain(..).collect();
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
        for (k, r) in requests.into_iter().enumerate() {
            let mut frame = [0u8; MAX_FRAME];
            match encode(&r, self.seq, &mut frame) {
                Ok(n) => {
                    self.out.extend(&frame[..n]);
                    if k < asked {
                        self.awaiting.push((self.seq, r));
                    } else {
                        self.sent.push((self.seq, format!("{r:?}")));
                    }
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

    /// Bytes the firmware sent: the answers to requests asked kept, the
    /// answers to commands noted where they refuse.
    pub fn received(&mut self, mut bytes: &[u8]) {
        while let Some(event) = self.decoder.decode(&mut bytes) {
            let Ok(frame) = event else {
                self.notes
                    .push("a frame from the firmware failed its check".to_string());
                continue;
            };
            let response = Response::parse(&frame);
            // Telemetry carries the device's own counter, not a request's.
            let asked = match &response {
                Ok(Response::Telemetry(_)) | Err(_) => None,
                Ok(_) => self.awaiting.iter().position(|(s, _)| *s == frame.seq),
            };
            if let (Some(i), Ok(response)) = (asked, &response) {
                let (_, request) = self.awaiting.remove(i);
                self.answers.push(Answer {
                    request,
                    response: response.clone(),
                });
                continue;
            }
            if let Ok(Response::Nack { reason, .. }) = response {
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

#[cfg(test)]
mod tests {
    use super::*;
    use shared::protocol::{Message, NackReason};

    /// The frame of `response` to the request of sequence number `seq`.
    fn frame(response: &Response, seq: u16) -> Vec<u8> {
        let mut out = [0u8; MAX_FRAME];
        let n = encode(response, seq, &mut out).expect("a frame");
        out[..n].to_vec()
    }

    /// The requests in `rx`, decoded.
    fn sent(rx: &Bytes) -> Vec<(u16, Request)> {
        let mut decoder = Decoder::new();
        let mut bytes = rx.as_slice();
        let mut out = Vec::new();
        while let Some(Ok(f)) = decoder.decode(&mut bytes) {
            out.push((f.seq, Request::parse(&f).expect("a request")));
        }
        out
    }

    #[test]
    fn a_request_asked_goes_before_the_commands_due_and_its_answer_is_kept() {
        let stop = Command::Stop;
        let mut host = Host::new(vec![(0.0, stop)]);
        host.ask(Request::GetCapture);
        let mut rx = Bytes::default();
        host.send(0.001, false, &mut rx);
        assert_eq!(
            sent(&rx),
            vec![(0, Request::GetCapture), (1, Request::Command(stop))]
        );
        // The command's refusal is a warning; the answer asked for is kept.
        let nack = Response::Nack {
            request: Request::Command(stop).id() as u8,
            reason: NackReason::Busy,
        };
        let ack = Response::Ack {
            request: Request::GetCapture.id() as u8,
        };
        let mut bytes = frame(&nack, 1);
        bytes.extend(frame(&ack, 0));
        host.received(&bytes);
        assert_eq!(
            host.answers(),
            vec![Answer {
                request: Request::GetCapture,
                response: ack
            }]
        );
        assert!(host.answers().is_empty());
        assert_eq!(host.warnings().len(), 1, "{:?}", host.warnings());
    }

    #[test]
    fn a_request_asked_keeps_the_link_alive_as_a_heartbeat_does() {
        let mut host = Host::new(vec![]);
        let mut rx = Bytes::default();
        host.send(0.0, false, &mut rx);
        assert!(sent(&rx).is_empty());
        host.ask(Request::GetStatus);
        host.send(0.001, false, &mut rx);
        // 100 ms after that request: a heartbeat.
        let mut rx = Bytes::default();
        host.send(0.101, false, &mut rx);
        assert_eq!(sent(&rx), vec![(1, Request::Command(Command::Heartbeat))]);
    }
}
