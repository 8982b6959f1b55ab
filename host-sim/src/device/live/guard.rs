//! Who the live page answers: requests naming a loopback host when it listens
//! on loopback ([`loopback_host`]), and a Stop only from the page itself or from
//! no page at all ([`foreign_stop`]).
//!
//! A page of another site may post to `/stop` (a form or `fetch` needs no
//! permission to send, only to read the answer), so a Stop that says where it
//! comes from must come from this page: the browser says it in `Origin`, in
//! `Sec-Fetch-Site` and in `Referer`, and sends at least one of them with a
//! cross-site POST unless the site asked it to send none; a program such as
//! curl sends none, and is taken.

use std::net::IpAddr;

use super::http::Request;

/// Whether a `Host` header names a loopback host (`127.0.0.1:8321`,
/// `localhost:8321`, `[::1]:8321`).
pub fn loopback_host(host: Option<&str>) -> bool {
    let Some(host) = host else { return false };
    // Without the port: after the last colon, unless that is inside [::1].
    let name = match host.rsplit_once(':') {
        Some((name, port)) if !port.contains(']') => name,
        _ => host,
    };
    let name = name.trim_start_matches('[').trim_end_matches(']');
    name.eq_ignore_ascii_case("localhost")
        || name.parse::<IpAddr>().is_ok_and(|ip| ip.is_loopback())
}

/// Why a Stop is not this page's, if it says it comes from elsewhere: an
/// `Origin` other than `http://HOST` (`HOST` as its `Host` header names it),
/// a `Sec-Fetch-Site` other than `same-origin` or `none` (`same-site` is another
/// port of the same host: another program's page), or a `Referer` of another
/// origin.
pub fn foreign_stop(request: &Request) -> Option<String> {
    let own = format!("http://{}", request.header("host").unwrap_or_default());
    if let Some(origin) = request.header("origin") {
        if origin != own {
            return Some(format!("Origin {origin}"));
        }
    }
    if let Some(site) = request.header("sec-fetch-site") {
        if !matches!(site, "same-origin" | "none") {
            return Some(format!("Sec-Fetch-Site {site}"));
        }
    }
    if let Some(referer) = request.header("referer") {
        if origin_of(referer) != own {
            return Some(format!("Referer {referer}"));
        }
    }
    None
}

/// The origin of a URL, `scheme://host[:port]` (`http://a:1/b?c` gives
/// `http://a:1`); the URL itself when it has no `://`.
fn origin_of(url: &str) -> &str {
    let Some(at) = url.find("://") else {
        return url;
    };
    let rest = &url[at + 3..];
    let end = rest.find(['/', '?', '#']).map_or(url.len(), |i| at + 3 + i);
    &url[..end]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loopback_hosts() {
        for ok in [
            "127.0.0.1:8321",
            "localhost:1",
            "LOCALHOST",
            "[::1]:8321",
            "[::1]",
            "127.1.2.3:80",
        ] {
            assert!(loopback_host(Some(ok)), "{ok}");
        }
        for bad in [
            "evil.example:8321",
            "10.0.0.1:8321",
            "[::2]:1",
            "0.0.0.0:8321",
            "",
            "localhost.evil:1",
        ] {
            assert!(!loopback_host(Some(bad)), "{bad}");
        }
        assert!(!loopback_host(None));
    }

    /// A POST /stop to 127.0.0.1:8321 with `headers` besides its Host.
    fn stop(headers: &[(&str, &str)]) -> Request {
        let mut all = vec![("host".to_string(), "127.0.0.1:8321".to_string())];
        all.extend(headers.iter().map(|(n, v)| (n.to_string(), v.to_string())));
        Request {
            method: "POST".into(),
            path: "/stop".into(),
            headers: all,
        }
    }

    #[test]
    fn a_stop_from_this_page_or_from_no_page_is_taken() {
        let own = "http://127.0.0.1:8321";
        for ok in [
            vec![],
            vec![("origin", own)],
            vec![
                ("origin", own),
                ("sec-fetch-site", "same-origin"),
                ("referer", "http://127.0.0.1:8321/"),
            ],
            vec![("sec-fetch-site", "none")],
            vec![("referer", "http://127.0.0.1:8321")],
        ] {
            assert_eq!(foreign_stop(&stop(&ok)), None, "{ok:?}");
        }
    }

    #[test]
    fn a_stop_that_says_it_comes_from_elsewhere_is_not() {
        for (bad, why) in [
            (
                vec![("origin", "http://evil.example")],
                "Origin http://evil.example",
            ),
            (vec![("origin", "null")], "Origin null"),
            // No Origin, but the browser's other word for where it comes from.
            (
                vec![("sec-fetch-site", "cross-site")],
                "Sec-Fetch-Site cross-site",
            ),
            // Another port of this host: another program's page.
            (
                vec![("sec-fetch-site", "same-site")],
                "Sec-Fetch-Site same-site",
            ),
            (
                vec![("referer", "http://evil.example/x")],
                "Referer http://evil.example/x",
            ),
            (
                vec![("referer", "http://127.0.0.1:8321.evil.example/")],
                "Referer http://127.0.0.1:8321.evil.example/",
            ),
            (
                vec![("referer", "http://127.0.0.1:9999/")],
                "Referer http://127.0.0.1:9999/",
            ),
            (
                vec![
                    ("origin", "http://127.0.0.1:8321"),
                    ("referer", "https://evil.example/"),
                ],
                "Referer https://evil.example/",
            ),
        ] {
            assert_eq!(foreign_stop(&stop(&bad)).as_deref(), Some(why), "{bad:?}");
        }
    }
}
