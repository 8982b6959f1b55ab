//! Devices of the tests' own making on a TCP port, for the misbehaviours the
//! firmware's link code never shows: one that never answers, and one whose
//! answers a test function chooses.

use std::io::{Read, Write};
use std::net::TcpListener;
use std::time::Duration;

use shared::protocol::{encode, Decoder, Message, Request, Response, MAX_FRAME};

/// A device that answers every request by `answer`: each request decoded and
/// handed to it, its responses sent back with the request's sequence number. It
/// serves one host after another until the test process ends; its `--port`.
pub fn answering(answer: fn(&Request) -> Vec<Response>) -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = format!("tcp:{}", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(mut stream) = stream else { return };
            let mut decoder = Decoder::new();
            let mut buf = [0u8; 512];
            while let Ok(n @ 1..) = stream.read(&mut buf) {
                let mut input = &buf[..n];
                let mut out = Vec::new();
                while let Some(event) = decoder.decode(&mut input) {
                    let Ok(frame) = event else { continue };
                    let Ok(request) = Request::parse(&frame) else {
                        continue;
                    };
                    for response in answer(&request) {
                        let mut bytes = [0u8; MAX_FRAME];
                        let len = encode(&response, frame.seq, &mut bytes).unwrap();
                        out.extend_from_slice(&bytes[..len]);
                    }
                }
                if stream.write_all(&out).is_err() {
                    break;
                }
            }
        }
    });
    port
}

/// The Ack a well-behaved device gives `request`.
pub fn ack(request: &Request) -> Response {
    Response::Ack {
        request: request.id() as u8,
    }
}

/// A device that accepts one host, reads what it sends for at most 10 s and
/// says nothing; its `--port`.
pub fn silent() -> String {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let port = format!("tcp:{}", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        if let Ok((mut s, _)) = listener.accept() {
            let _ = s.set_read_timeout(Some(Duration::from_secs(10)));
            let mut buf = [0u8; 256];
            while matches!(s.read(&mut buf), Ok(n) if n > 0) {}
        }
    });
    port
}
