//! `host-sim device telemetry --serve [ADDR]`: the telemetry stream on a live web
//! page. This thread keeps the device link as `telemetry` does (the stream on, a
//! heartbeat every 50 ms, the silence watch, the stream off at the end) and hands
//! each frame to the pages; a server on `std::net` serves the page, the frames as
//! Server-Sent Events, and the page's one command, Stop, which reaches the device
//! only through this thread.
//!
//! - [`server`]: the connections, their requests read as they come, the routes;
//! - [`guard`]: whose requests are answered, whose Stops taken;
//! - [`stream`]: an event stream, and when its page is dropped;
//! - [`lag`]: how far behind its stream a page is;
//! - [`stops`]: the Stops answered, all those waiting with one Stop on the link;
//! - [`http`]: just enough HTTP/1.1;
//! - [`hub`]: frames to the pages, Stop requests to the link thread;
//! - [`frame`]: a frame as JSON.
//!
//! The page listens on loopback unless told otherwise: an address other machines
//! can reach needs `--allow-remote`, and then the page says so.

pub mod frame;
pub mod guard;
pub mod http;
pub mod hub;
pub mod lag;
pub mod server;
pub mod stops;
pub mod stream;

use shared::controller::Command;
use std::net::{SocketAddr, TcpListener, ToSocketAddrs};
use std::time::Duration;

use shared::protocol::{Request, StatusReport};

use super::args::TelemetryArgs;
use super::telemetry_stream::{self, Sink};
use crate::failure::{Console, Failure};
use crate::link::client::Client;
use crate::link::requests::command;
use hub::{Event, LinkEnd};
use server::{Limits, Page, Server};

/// How long the open pages get to receive the stream's end before the process
/// ends.
const END_WAIT: Duration = Duration::from_millis(500);

/// The addresses `--serve ADDR` names, checked: `HOST:PORT` that resolves, and a
/// loopback one unless `allow_remote`.
pub fn listen_address(addr: &str, allow_remote: bool) -> Result<Vec<SocketAddr>, Failure> {
    let addrs: Vec<SocketAddr> = addr
        .to_socket_addrs()
        .map_err(|e| {
            Failure::usage(format!(
                "--serve: `{addr}` is no address to listen on ({e}): expected HOST:PORT, \
                 e.g. 127.0.0.1:8321 (port 0: any free port)"
            ))
        })?
        .collect();
    if addrs.is_empty() {
        return Err(Failure::usage(format!(
            "--serve: `{addr}` resolves to no address: expected HOST:PORT, e.g. 127.0.0.1:8321"
        )));
    }
    if !allow_remote && addrs.iter().any(|a| !a.ip().is_loopback()) {
        return Err(Failure::usage(format!(
            "--serve: {addr} is not a loopback address: the page and its Stop button \
             would be reachable from other machines; add --allow-remote to serve there, or \
             serve on 127.0.0.1:PORT"
        )));
    }
    Ok(addrs)
}

/// The frames to the pages; the pages' Stop requests to the device.
struct Served<'a, 'c> {
    link: LinkEnd,
    out: &'a mut Console<'c>,
}

impl Sink for Served<'_, '_> {
    fn frame(&mut self, report: &StatusReport) -> Result<bool, Failure> {
        self.link.publish(Event::Frame(frame::json(report).into()));
        Ok(true)
    }

    fn between(&mut self, client: &mut Client) -> Result<(), Failure> {
        // The Stops that came since the last look are one Stop to the device,
        // its answer to each: however many pages press it at once, the link
        // spends one request's time on them, not one each, between heartbeats.
        let replies = self.link.stop_requests();
        if replies.is_empty() {
            return Ok(());
        }
        // A refused or unanswered Stop is the page's to show; the stream goes
        // on (its own watch ends a link that is gone).
        let answer = match command(client, &Request::Command(Command::Stop)) {
            Ok(()) => Ok("stop: accepted".to_string()),
            Err(f) => Err(f.text()),
        };
        self.out.print(&match &answer {
            Ok(a) => format!("{a} (from the page)\n"),
            Err(e) => format!("stop (from the page): {e}\n"),
        });
        for reply in replies {
            let _ = reply.send(answer.clone());
        }
        Ok(())
    }
}

/// Runs `host-sim device telemetry --serve ADDR` on `client` (the device at
/// `--port` `device`) until `--duration`, Ctrl-C or a failure of the link.
pub fn run(
    client: &mut Client,
    a: &TelemetryArgs,
    addr: &str,
    device: &str,
    out: &mut Console<'_>,
) -> Result<(), Failure> {
    let addrs = listen_address(addr, a.allow_remote)?;
    // An address in use or not ours is the user's to change, as for device-sim.
    let listener = TcpListener::bind(&addrs[..])
        .map_err(|e| Failure::usage(format!("--serve: cannot listen on {addr}: {e}")))?;
    let local = listener
        .local_addr()
        .map_err(|e| Failure::usage(format!("--serve: {addr}: {e}")))?;
    let page = Page {
        device: device.to_string(),
        period_ms: a.period,
        remote: a.allow_remote && !local.ip().is_loopback(),
    };
    let (link, pages) = hub::hub();
    let server = Server::start(listener, &page, pages, Limits::default())
        .map_err(|e| Failure::usage(format!("--serve: {addr}: {e}")))?;
    out.note(&format!(
        "telemetry: live page on http://{local}/ (a frame every {} ms; Ctrl-C ends it)\n",
        a.period
    ));
    if page.remote {
        out.note(&format!(
            "warning: --allow-remote: the page and its Stop button are reachable from the network at {local}\n"
        ));
    }
    let mut served = Served { link, out };
    let result = telemetry_stream::stream(client, a.period, a.duration, &mut served);
    let why = match &result {
        Ok(n) => format!("the stream ended after {n} frames"),
        Err(f) => f.message().trim_end().to_string(),
    };
    served.link.publish(Event::End(why.into()));
    drop(served.link);
    server.finish(END_WAIT);
    let frames = result?;
    out.print(&format!("telemetry: {frames} frames served\n"));
    Ok(())
}
