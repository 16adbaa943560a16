//! HTTP requests as the console's tests mean them, on reqwest: to the console's API (the
//! attacks among them: a forged `Host`, any `Origin` or `Sec-Fetch-Site`, cookies) and to
//! chromedriver's status.
//!
//! The server must see the request the test wrote and nothing the client thought of: so
//! redirects are not followed (a login's `303` is the answer a test checks), there is no
//! cookie store (a cookie goes only where a test puts it), no proxy from the environment,
//! and a `Host` given is sent as given (hyper only fills it in when it is missing).
//! reqwest adds `Accept: */*` and nothing else; the console does not read it.

use reqwest::blocking::Client;
use reqwest::header::{HeaderName, HeaderValue, CONTENT_TYPE};
use reqwest::{redirect, Method};
use std::net::SocketAddr;
use std::sync::OnceLock;
use std::time::Duration;

/// An answer.
pub struct Answer {
    pub status: u16,
    pub headers: Vec<(String, String)>,
    pub body: String,
}

impl Answer {
    /// A header's value (names compared without case).
    pub fn header(&self, name: &str) -> Option<&str> {
        self.headers
            .iter()
            .find(|(n, _)| n.eq_ignore_ascii_case(name))
            .map(|(_, v)| v.as_str())
    }

    /// The body as JSON.
    pub fn json(&self) -> serde_json::Value {
        serde_json::from_str(&self.body).unwrap_or_else(|e| panic!("not JSON ({e}): {}", self.body))
    }
}

/// The one client of the test process (reqwest's blocking client runs its own runtime on a
/// thread of its own, so the tests stay synchronous).
fn client() -> &'static Client {
    static CLIENT: OnceLock<Client> = OnceLock::new();
    CLIENT.get_or_init(|| {
        Client::builder()
            .redirect(redirect::Policy::none())
            .no_proxy()
            // One request a connection: a request after a refusal (the console's rate limit,
            // a killed server) starts afresh, as each test's requests always have.
            .pool_max_idle_per_host(0)
            .connect_timeout(Duration::from_secs(10))
            // Generous: the whole answer of a busy console on a busy host, not a measurement.
            .timeout(Duration::from_secs(120))
            .build()
            .expect("an HTTP client")
    })
}

/// Sends `method path` to `addr` with `headers` and a `body` (JSON unless a content type
/// is among the headers).
pub fn request(
    addr: SocketAddr,
    method: &str,
    path: &str,
    headers: &[(&str, &str)],
    body: Option<&str>,
) -> Answer {
    let method = Method::from_bytes(method.as_bytes())
        .unwrap_or_else(|e| panic!("not an HTTP method ({e}): {method}"));
    let mut builder = client().request(method.clone(), format!("http://{addr}{path}"));
    for (name, value) in headers {
        let name = HeaderName::from_bytes(name.as_bytes())
            .unwrap_or_else(|e| panic!("not a header name ({e}): {name}"));
        let value = HeaderValue::from_str(value)
            .unwrap_or_else(|e| panic!("not a header value ({e}): {value}"));
        builder = builder.header(name, value);
    }
    if let Some(body) = body {
        if !headers
            .iter()
            .any(|(n, _)| n.eq_ignore_ascii_case(CONTENT_TYPE.as_str()))
        {
            builder = builder.header(CONTENT_TYPE, "application/json");
        }
        builder = builder.body(body.to_owned());
    }
    let answer = builder
        .send()
        .unwrap_or_else(|e| panic!("{method} http://{addr}{path}: {e}"));
    let status = answer.status().as_u16();
    let headers = answer
        .headers()
        .iter()
        .map(|(n, v)| {
            let value = String::from_utf8_lossy(v.as_bytes()).into_owned();
            (n.as_str().to_owned(), value)
        })
        .collect();
    let body = answer
        .bytes()
        .unwrap_or_else(|e| panic!("{method} http://{addr}{path}: the body: {e}"));
    Answer {
        status,
        headers,
        body: String::from_utf8_lossy(&body).into_owned(),
    }
}

/// A server of one connection on loopback: the request it read (its head, lower-cased),
/// once it has answered `answer`.
fn one_request(answer: &'static str) -> (SocketAddr, std::thread::JoinHandle<String>) {
    use std::io::{Read, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let addr = listener.local_addr().unwrap();
    let server = std::thread::spawn(move || {
        let (mut stream, _) = listener.accept().unwrap();
        let mut raw = Vec::new();
        let mut buf = [0u8; 4096];
        while !raw.windows(4).any(|w| w == b"\r\n\r\n") {
            let n = stream.read(&mut buf).unwrap();
            assert!(n > 0, "the request ended before its head did");
            raw.extend_from_slice(&buf[..n]);
        }
        stream.write_all(answer.as_bytes()).unwrap();
        String::from_utf8_lossy(&raw).to_ascii_lowercase()
    });
    (addr, server)
}

/// The values of header `name` in a request's lower-cased head.
fn values<'a>(head: &'a str, name: &str) -> Vec<&'a str> {
    head.lines()
        .filter_map(|l| l.split_once(':'))
        .filter(|(n, _)| *n == name)
        .map(|(_, v)| v.trim())
        .collect()
}

#[test]
fn a_forged_host_and_origin_are_sent_as_given_and_a_redirect_is_the_answer() {
    let (addr, server) = one_request(
        "HTTP/1.1 303 See Other\r\nLocation: /elsewhere\r\nSet-Cookie: s=1\r\n\
         Content-Length: 0\r\nConnection: close\r\n\r\n",
    );
    let answer = request(
        addr,
        "POST",
        "/api/runs/lathe%207/hold",
        &[
            ("Host", "evil.example:80"),
            ("Origin", "http://evil.example"),
        ],
        Some("{}"),
    );
    let head = server.join().unwrap();
    assert!(
        head.starts_with("post /api/runs/lathe%207/hold http/1.1\r\n"),
        "{head}"
    );
    assert_eq!(values(&head, "host"), ["evil.example:80"], "{head}");
    assert_eq!(values(&head, "origin"), ["http://evil.example"], "{head}");
    assert_eq!(
        values(&head, "content-type"),
        ["application/json"],
        "{head}"
    );
    // A 303 followed would have been a second request, to a server that takes none.
    assert_eq!(answer.status, 303);
    assert_eq!(answer.header("location"), Some("/elsewhere"));
}

#[test]
fn a_plain_request_names_its_address_and_carries_no_origin_or_cookie() {
    // A cookie set before is not kept: the client has no cookie store. (A store would send
    // it to the second server too: cookies are not kept apart by port, RFC 6265 § 8.5.)
    let (addr, server) = one_request(
        "HTTP/1.1 200 OK\r\nSet-Cookie: s=1\r\nContent-Length: 2\r\nConnection: close\r\n\r\nok",
    );
    assert_eq!(request(addr, "GET", "/", &[], None).body, "ok");
    server.join().unwrap();
    let (addr, server) = one_request(
        "HTTP/1.1 200 OK\r\nTransfer-Encoding: chunked\r\nConnection: close\r\n\r\n\
         2\r\n{}\r\n0\r\n\r\n",
    );
    let answer = request(addr, "GET", "/api/runs", &[], None);
    let head = server.join().unwrap();
    assert_eq!(values(&head, "host"), [addr.to_string()], "{head}");
    for absent in [
        "origin",
        "cookie",
        "sec-fetch-site",
        "referer",
        "content-type",
    ] {
        assert!(values(&head, absent).is_empty(), "{absent}: {head}");
    }
    assert_eq!(answer.json(), serde_json::json!({}));
}

/// The address a `whirl serve` says on its first line of standard output that it listens
/// on (`… at http://ADDRESS/ …`).
pub fn listening(child: &mut std::process::Child) -> SocketAddr {
    use std::io::BufRead;
    let mut line = String::new();
    std::io::BufReader::new(child.stdout.take().expect("whirl serve's stdout piped"))
        .read_line(&mut line)
        .unwrap();
    line.split("http://")
        .nth(1)
        .and_then(|rest| rest.split('/').next())
        .and_then(|a| a.parse().ok())
        .unwrap_or_else(|| panic!("whirl serve said no address: {line:?}"))
}
