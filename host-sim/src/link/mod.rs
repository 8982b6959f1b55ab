//! The host's end of the UART link to a board, below `host-sim device` and
//! `host-sim device-sim`: the byte pipe and what carries it, and the client that
//! speaks the `shared` protocol over it (`docs/protocol.md`).
//!
//! - [`pipe`]: the byte pipe, a [`pipe::Port`];
//! - [`port`]: a `--port`: a serial port or a TCP socket;
//! - [`serial`]: a serial port raw at 115200 baud 8N1;
//! - [`pty`]: the pseudo-terminal `device-sim` serves (Unix);
//! - [`client`]: requests numbered, sent, retried, answers matched, telemetry kept;
//! - [`requests`]: a request and its expected answer, as a [`crate::failure::Failure`];
//! - [`rest`]: the machine at rest after a stop, as its status says, awaited.

pub mod client;
pub mod pipe;
pub mod port;
#[cfg(unix)]
pub mod pty;
pub mod requests;
pub mod rest;
pub mod serial;
