//! A WebSocket client (RFC 6455) on `std::net`, as much as the DevTools protocol
//! needs: `ws://` only, text messages out (masked, as a client must), text and
//! binary messages in (unmasked, possibly fragmented), pings answered, a close
//! ending the stream. A reader thread turns frames into messages on a channel, so
//! that waiting for one can time out without losing a frame half read.

use std::io::{self, BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::sync::mpsc::{self, Receiver, RecvTimeoutError};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// Opcodes (RFC 6455, 5.2).
const CONTINUATION: u8 = 0x0;
const TEXT: u8 = 0x1;
const BINARY: u8 = 0x2;
const CLOSE: u8 = 0x8;
const PING: u8 = 0x9;
const PONG: u8 = 0xA;

/// A connected WebSocket.
pub struct WebSocket {
    writer: Arc<Mutex<TcpStream>>,
    messages: Receiver<String>,
    /// The next masking key (any value will do; it only has to vary).
    mask: u32,
}

impl WebSocket {
    /// Connect to `ws://HOST:PORT/PATH` and make the opening handshake.
    pub fn connect(url: &str) -> io::Result<WebSocket> {
        let rest = url
            .strip_prefix("ws://")
            .ok_or_else(|| io::Error::other(format!("{url}: not a ws:// address")))?;
        let (host, path) = rest.split_once('/').unwrap_or((rest, ""));
        let stream = TcpStream::connect(host)?;
        stream.set_nodelay(true)?;
        let mut writer = stream.try_clone()?;
        // The key is any 16 bytes in base64; the server's answer to it is not
        // checked (the server is the browser this test started).
        write!(
            writer,
            "GET /{path} HTTP/1.1\r\nHost: {host}\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n\
             Sec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\nSec-WebSocket-Version: 13\r\n\r\n"
        )?;
        let mut reader = BufReader::new(stream);
        let mut status = String::new();
        reader.read_line(&mut status)?;
        if !status.starts_with("HTTP/1.1 101") {
            return Err(io::Error::other(format!(
                "{url}: the handshake was answered {status:?}"
            )));
        }
        loop {
            let mut line = String::new();
            if reader.read_line(&mut line)? == 0 || line == "\r\n" {
                break;
            }
        }
        let writer = Arc::new(Mutex::new(writer));
        let (tx, messages) = mpsc::channel();
        let pong = writer.clone();
        std::thread::spawn(move || {
            while let Ok(Some(message)) = read_message(&mut reader, &pong) {
                if tx.send(message).is_err() {
                    break;
                }
            }
        });
        Ok(WebSocket {
            writer,
            messages,
            mask: 0x9e37_79b9,
        })
    }

    /// Send `text` as one text message.
    pub fn send(&mut self, text: &str) -> io::Result<()> {
        self.mask = self
            .mask
            .wrapping_mul(0x0019_660d)
            .wrapping_add(0x3c6e_f35f);
        let frame = frame(TEXT, text.as_bytes(), self.mask.to_be_bytes());
        let mut w = self.writer.lock().expect("the writer");
        w.write_all(&frame)
    }

    /// The next message, waiting at most `timeout`: `Ok(None)` when none came,
    /// an error once the connection is closed.
    pub fn recv(&mut self, timeout: Duration) -> io::Result<Option<String>> {
        match self.messages.recv_timeout(timeout) {
            Ok(m) => Ok(Some(m)),
            Err(RecvTimeoutError::Timeout) => Ok(None),
            Err(RecvTimeoutError::Disconnected) => Err(io::Error::new(
                io::ErrorKind::ConnectionAborted,
                "the WebSocket is closed",
            )),
        }
    }
}

/// A client frame: FIN, `opcode`, the payload masked with `mask` (RFC 6455, 5.2,
/// 5.3: a payload length of 7 bits, or 126 and 16 bits, or 127 and 64 bits).
fn frame(opcode: u8, payload: &[u8], mask: [u8; 4]) -> Vec<u8> {
    let mut out = vec![0x80 | opcode];
    let len = payload.len();
    if len < 126 {
        out.push(0x80 | len as u8);
    } else if len <= usize::from(u16::MAX) {
        out.push(0x80 | 126);
        out.extend_from_slice(&(len as u16).to_be_bytes());
    } else {
        out.push(0x80 | 127);
        out.extend_from_slice(&(len as u64).to_be_bytes());
    }
    out.extend_from_slice(&mask);
    out.extend(payload.iter().enumerate().map(|(i, b)| b ^ mask[i % 4]));
    out
}

/// The next whole message (fragments joined); `None` at a close.
fn read_message(r: &mut impl Read, writer: &Mutex<impl Write>) -> io::Result<Option<String>> {
    let mut message = Vec::new();
    loop {
        let mut head = [0u8; 2];
        r.read_exact(&mut head)?;
        let (fin, opcode) = (head[0] & 0x80 != 0, head[0] & 0x0f);
        let masked = head[1] & 0x80 != 0;
        let len = match head[1] & 0x7f {
            126 => {
                let mut b = [0u8; 2];
                r.read_exact(&mut b)?;
                u64::from(u16::from_be_bytes(b))
            }
            127 => {
                let mut b = [0u8; 8];
                r.read_exact(&mut b)?;
                u64::from_be_bytes(b)
            }
            n => u64::from(n),
        };
        let mut mask = [0u8; 4];
        if masked {
            r.read_exact(&mut mask)?;
        }
        let mut payload = Vec::new();
        r.take(len).read_to_end(&mut payload)?;
        if payload.len() as u64 != len {
            return Err(io::ErrorKind::UnexpectedEof.into());
        }
        if masked {
            for (i, b) in payload.iter_mut().enumerate() {
                *b ^= mask[i % 4];
            }
        }
        match opcode {
            CLOSE => return Ok(None),
            PING => {
                let pong = frame(PONG, &payload, [0; 4]);
                writer.lock().expect("the writer").write_all(&pong)?;
            }
            TEXT | BINARY | CONTINUATION => {
                message.extend_from_slice(&payload);
                if fin {
                    return String::from_utf8(message)
                        .map(Some)
                        .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, e));
                }
            }
            _ => {}
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_client_frame_is_masked_with_its_length_in_the_right_form() {
        // RFC 6455, 5.7: "Hello" masked with 37 fa 21 3d.
        assert_eq!(
            frame(TEXT, b"Hello", [0x37, 0xfa, 0x21, 0x3d]),
            [0x81, 0x85, 0x37, 0xfa, 0x21, 0x3d, 0x7f, 0x9f, 0x4d, 0x51, 0x58]
        );
        assert_eq!(
            &frame(TEXT, &[0; 200], [0; 4])[..4],
            [0x81, 0xfe, 0x00, 0xc8]
        );
        assert_eq!(
            &frame(TEXT, &vec![0; 70_000], [0; 4])[..10],
            [0x81, 0xff, 0, 0, 0, 0, 0, 0x01, 0x11, 0x70]
        );
    }

    #[test]
    fn fragments_are_joined_and_a_ping_between_them_answered() {
        // RFC 6455, 5.7: "Hel" and "lo" in two fragments, a ping "Hello" between.
        let input: &[u8] = &[
            0x01, 0x03, 0x48, 0x65, 0x6c, 0x89, 0x05, 0x48, 0x65, 0x6c, 0x6c, 0x6f, 0x80, 0x02,
            0x6c, 0x6f, 0x88, 0x00,
        ];
        let mut r = input;
        let pongs = Mutex::new(Vec::new());
        assert_eq!(
            read_message(&mut r, &pongs).unwrap().as_deref(),
            Some("Hello")
        );
        assert_eq!(read_message(&mut r, &pongs).unwrap(), None);
        let pongs = pongs.into_inner().unwrap();
        assert_eq!(&pongs[..2], [0x8a, 0x85]);
        assert_eq!(pongs.len(), 2 + 4 + 5);
    }
}
