//! Requests and their answers as the commands need them: a Nack is the device's
//! refusal, an answer of another kind a device failure, an Ack for the request
//! sent its acceptance; and how often a streaming command sends its heartbeat.

use std::time::Duration;

use shared::protocol::{Request, Response, HEARTBEAT_PERIOD_MS};

use super::client::{answer_text, nack_text, request_name, Client, LinkError};
use crate::failure::Failure;

/// How often the streaming commands send a heartbeat: twice per
/// [`HEARTBEAT_PERIOD_MS`].
pub const HEARTBEAT_EVERY: Duration = Duration::from_millis(HEARTBEAT_PERIOD_MS as u64 / 2);

/// Send `request` and take its answer; a Nack is the device's refusal, with its
/// reason. The client has checked that the answer is one to `request`.
pub fn ask(client: &mut Client, request: &Request) -> Result<Response, Failure> {
    match client.request(request)? {
        Response::Nack { reason, .. } => Err(Failure::device(format!(
            "the device refused {}: {}",
            request_name(request),
            nack_text(reason)
        ))),
        response => Ok(response),
    }
}

/// A request answered by Ack: an Ack for `request` is its acceptance; anything
/// else is a failure.
pub fn command(client: &mut Client, request: &Request) -> Result<(), Failure> {
    match ask(client, request)? {
        Response::Ack { .. } => Ok(()),
        other => Err(unexpected(request, &other)),
    }
}

/// An answer of another kind than `request` asks for: the device's failure.
pub fn unexpected(request: &Request, response: &Response) -> Failure {
    Failure::from(LinkError::WrongAnswer {
        request: request_name(request),
        answer: answer_text(response),
    })
}
