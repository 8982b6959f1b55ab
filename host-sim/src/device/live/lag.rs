//! How far behind its event stream a page is: the age of the oldest byte
//! written to it that it has not read yet.
//!
//! A write to a socket succeeds as long as the kernel buffers take it, and for a
//! client that never reads Linux keeps growing the client's receive buffer (up
//! to `net.ipv4.tcp_rmem`'s largest, megabytes: an hour of frames), so the
//! server's writes alone say nothing of the page for a long time. What the page
//! has read is the bytes written less those still queued between the two
//! programs: in the server's send queue and the page's receive queue. On Linux,
//! for a page on this machine (the loopback address the server listens on by
//! default), both queues are in `/proc/net/tcp` (`tcp6`): the `tx_queue` of the
//! server's socket and the `rx_queue` of the page's ([`queued`]). Elsewhere
//! [`queued`] is `None`, and a page is known to have stopped reading only once
//! the buffers are full and a write waits.

use std::collections::VecDeque;
use std::net::{IpAddr, SocketAddr};
use std::time::{Duration, Instant};

/// The bytes written to a page, and when.
#[derive(Debug, Default)]
pub struct Lag {
    /// Bytes written in all.
    written: u64,
    /// `(when, written by then)` of the writes whose bytes may be unread,
    /// oldest first.
    writes: VecDeque<(Instant, u64)>,
}

impl Lag {
    /// `n` bytes written at `at`.
    pub fn wrote(&mut self, n: usize, at: Instant) {
        self.written += n as u64;
        self.writes.push_back((at, self.written));
    }

    /// How long before `now` the oldest byte the page has not read was written,
    /// when `queued` bytes are still on their way (zero when it has read all).
    pub fn behind(&mut self, queued: u64, now: Instant) -> Duration {
        let read = self.written.saturating_sub(queued);
        // Writes whose last byte is read are of no more use.
        while self.writes.front().is_some_and(|&(_, upto)| upto <= read) {
            self.writes.pop_front();
        }
        self.writes
            .front()
            .map_or(Duration::ZERO, |&(at, _)| now.saturating_duration_since(at))
    }
}

/// The bytes queued between the server's socket at `local` and the page's at
/// `peer`: the server's unacknowledged and unsent bytes, and the page's
/// received and unread ones (bytes received and not acknowledged yet are in
/// both for a moment: at most that much more than written and unread); `None`
/// when the system does not say (not Linux, or the page is on another
/// machine).
pub fn queued(local: SocketAddr, peer: SocketAddr) -> Option<u64> {
    #[cfg(target_os = "linux")]
    {
        let (local, peer) = (canonical(local), canonical(peer));
        let table = if local.is_ipv4() {
            "/proc/net/tcp"
        } else {
            "/proc/net/tcp6"
        };
        let text = std::fs::read_to_string(table).ok()?;
        queued_in(&text, local, peer)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = (local, peer);
        None
    }
}

/// `addr` with an IPv4 address mapped into IPv6 (`::ffff:127.0.0.1`) as the
/// IPv4 one the other end's socket has.
fn canonical(addr: SocketAddr) -> SocketAddr {
    SocketAddr::new(addr.ip().to_canonical(), addr.port())
}

/// [`queued`] from the text of `/proc/net/tcp` or `tcp6`: the `tx_queue` of
/// the line `local -> peer` and the `rx_queue` of the line `peer -> local`,
/// both needed.
fn queued_in(text: &str, local: SocketAddr, peer: SocketAddr) -> Option<u64> {
    let (ours, theirs) = (proc_address(local), proc_address(peer));
    let (mut sending, mut unread) = (None, None);
    for line in text.lines().skip(1) {
        let fields: Vec<&str> = line.split_whitespace().take(5).collect();
        let [_, from, to, _, queues] = fields[..] else {
            continue;
        };
        let Some((tx, rx)) = queues.split_once(':') else {
            continue;
        };
        let hex = |q: &str| u64::from_str_radix(q, 16).ok();
        if from == ours && to == theirs {
            sending = hex(tx);
        } else if from == theirs && to == ours {
            unread = hex(rx);
        }
        if let (Some(s), Some(u)) = (sending, unread) {
            return Some(s + u);
        }
    }
    None
}

/// `addr` as `/proc/net/tcp` writes it: the address's bytes as the kernel
/// holds them, read as 32-bit words in this machine's byte order, in hex, then
/// `:` and the port in hex (`127.0.0.1:8321` is `0100007F:2081` on a
/// little-endian machine).
fn proc_address(addr: SocketAddr) -> String {
    let words: String = match addr.ip() {
        IpAddr::V4(ip) => format!("{:08X}", u32::from_ne_bytes(ip.octets())),
        IpAddr::V6(ip) => ip
            .octets()
            .chunks(4)
            .map(|w| format!("{:08X}", u32::from_ne_bytes([w[0], w[1], w[2], w[3]])))
            .collect(),
    };
    format!("{words}:{:04X}", addr.port())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn behind_is_the_age_of_the_oldest_unread_byte() {
        let t0 = Instant::now();
        let s = Duration::from_secs(1);
        let mut lag = Lag::default();
        lag.wrote(100, t0);
        lag.wrote(100, t0 + s);
        lag.wrote(100, t0 + 2 * s);
        // All read.
        assert_eq!(lag.behind(0, t0 + 3 * s), Duration::ZERO);
        let mut lag = Lag::default();
        lag.wrote(100, t0);
        lag.wrote(100, t0 + s);
        lag.wrote(100, t0 + 2 * s);
        // 150 of 300 unread: the oldest unread byte is the second write's.
        assert_eq!(lag.behind(150, t0 + 3 * s), 2 * s);
        // Then all but the last write's: its age.
        assert_eq!(lag.behind(100, t0 + 3 * s), s);
    }

    #[test]
    fn proc_addresses_are_the_kernels_words_in_hex() {
        let v4: SocketAddr = "127.0.0.1:8321".parse().unwrap();
        let v6: SocketAddr = "[::1]:8321".parse().unwrap();
        if cfg!(target_endian = "little") {
            assert_eq!(proc_address(v4), "0100007F:2081");
            assert_eq!(proc_address(v6), "00000000000000000000000001000000:2081");
        } else {
            assert_eq!(proc_address(v4), "7F000001:2081");
        }
        let mapped: SocketAddr = "[::ffff:127.0.0.1]:1".parse().unwrap();
        assert_eq!(canonical(mapped), "127.0.0.1:1".parse().unwrap());
    }

    #[test]
    fn the_queues_of_both_ends_are_added() {
        let server: SocketAddr = "127.0.0.1:8321".parse().unwrap();
        let page: SocketAddr = "127.0.0.1:40000".parse().unwrap();
        let (s, p) = (proc_address(server), proc_address(page));
        let text = format!(
            "  sl  local_address rem_address   st tx_queue rx_queue tr\n\
             0: {s} 00000000:0000 0A 00000000:00000000 00:00000000\n\
             1: {s} {p} 01 00000010:00000000 00:00000000\n\
             2: {p} {s} 01 00000000:00000200 00:00000000\n"
        );
        assert_eq!(queued_in(&text, server, page), Some(0x10 + 0x200));
        // The page's socket elsewhere: not known.
        let other: SocketAddr = "127.0.0.1:40001".parse().unwrap();
        assert_eq!(queued_in(&text, server, other), None);
    }

    /// On this machine's own table: bytes written and not read are counted.
    #[cfg(target_os = "linux")]
    #[test]
    fn unread_bytes_on_this_machine_are_found() {
        use std::io::{Read, Write};
        use std::net::{TcpListener, TcpStream};
        let listener = TcpListener::bind("127.0.0.1:0").unwrap();
        let mut page = TcpStream::connect(listener.local_addr().unwrap()).unwrap();
        let (mut server, _) = listener.accept().unwrap();
        let (local, peer) = (server.local_addr().unwrap(), server.peer_addr().unwrap());
        // Bytes delivered and not acknowledged yet count on both sides for a
        // moment (microseconds on loopback): looked at until they settle.
        let settles_at = |n: u64| {
            let until = Instant::now() + Duration::from_secs(20);
            while queued(local, peer) != Some(n) {
                assert!(Instant::now() < until, "{:?}, not {n}", queued(local, peer));
                std::thread::sleep(Duration::from_millis(1));
            }
        };
        settles_at(0);
        server.write_all(&[7; 1000]).unwrap();
        settles_at(1000);
        let mut buf = [0u8; 600];
        page.read_exact(&mut buf).unwrap();
        settles_at(400);
    }
}
