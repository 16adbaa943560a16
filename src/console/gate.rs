//! Who may talk to the console, and how a request that acts proves it comes from the
//! console's own page.
//!
//! A console on loopback is reachable from every page the operator's browser opens, so
//! "only this machine can reach it" protects nothing by itself:
//!
//! - **Another site's page** can send a *simple* request (a form, `fetch` with a
//!   `text/plain` body, an image, `navigator.sendBeacon`) to `http://127.0.0.1:PORT/…`
//!   without asking anyone. Every action must therefore carry the [`PAGE_HEADER`] with
//!   this console's page key ([`Gate::key`]): a custom header makes the browser ask first
//!   (a CORS preflight, which the console never grants), and the key is readable only by
//!   a page of the console's own origin. An `Origin` or `Sec-Fetch-Site` that names
//!   another origin is refused as well, before anything else is read.
//! - **DNS rebinding**: a page of `evil.example` whose name is rebound to 127.0.0.1 is
//!   same-origin to whatever listens there, so it could read the key. The browser still
//!   says `Host: evil.example:PORT`: every request, reads included, must name the console
//!   by an allowed host ([`Gate::allows_host`]).
//! - **Another port of the same host** (a second web server on 127.0.0.1) is the same
//!   *site*, so a `SameSite=Strict` cookie goes with its requests; it is another *origin*,
//!   so it has no key and its `Origin` is refused.
//!
//! The rules are plain functions of the request's header values, tested without a server;
//! [`crate::console::http`] applies them to every request.

use std::net::{IpAddr, SocketAddr};

/// The header every action carries the page key in.
pub const PAGE_HEADER: &str = "x-whirl-page";

/// The console's gate: the hosts it answers to, and its page key.
#[derive(Clone)]
pub struct Gate {
    /// The address the console listens on.
    listen: SocketAddr,
    /// Every `Host` header value the console answers to, lower case.
    hosts: Vec<String>,
    /// The page key, random for each start of the console.
    key: String,
}

impl std::fmt::Debug for Gate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Gate")
            .field("listen", &self.listen)
            .field("hosts", &self.hosts)
            .field("key", &"…")
            .finish()
    }
}

/// Why a request was refused, in words for the answer and the console's log.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Refusal {
    /// A `Host` the console does not answer to (DNS rebinding, or a name not allowed).
    #[error(
        "this console answers to {allowed}, not to Host {given}; name another host with \
         --allow-host"
    )]
    Host {
        /// The `Host` header, or "(none)".
        given: String,
        /// The hosts allowed, in words.
        allowed: String,
    },
    /// An action from a page of another origin.
    #[error("an action from another origin ({0}) is refused: press it on the console's own page")]
    CrossOrigin(String),
    /// An action without the page key, or with a wrong one.
    #[error(
        "an action needs the console's page key in the {PAGE_HEADER} header, which only the \
         console's own page has: press it there (a script reads the key from /api/session)"
    )]
    NoPageKey,
}

impl Gate {
    /// The gate of a console listening on `listen`, answering also to `names` (host names
    /// the operator gives, such as the machine's name on the shop's network), with `key`.
    pub fn new(listen: SocketAddr, names: &[String], key: String) -> Gate {
        let port = listen.port();
        let mut bare: Vec<String> = vec!["localhost".into()];
        let mut push_ip = |ip: IpAddr| match ip {
            IpAddr::V4(v4) => bare.push(v4.to_string()),
            IpAddr::V6(v6) => bare.push(format!("[{v6}]")),
        };
        push_ip(IpAddr::from([127, 0, 0, 1]));
        push_ip(IpAddr::from(std::net::Ipv6Addr::LOCALHOST));
        if !listen.ip().is_unspecified() {
            push_ip(listen.ip());
        }
        bare.extend(names.iter().map(|n| n.to_ascii_lowercase()));
        let mut hosts: Vec<String> = bare.iter().map(|h| format!("{h}:{port}")).collect();
        // A browser leaves the port out of Host when it is the scheme's own.
        if port == 80 {
            hosts.extend(bare);
        }
        hosts.dedup();
        Gate { listen, hosts, key }
    }

    /// The address the console listens on.
    pub fn listen(&self) -> SocketAddr {
        self.listen
    }

    /// Every `Host` the console answers to (a host and its port).
    pub fn hosts(&self) -> &[String] {
        &self.hosts
    }

    /// A gate with a fresh random page key.
    pub fn with_random_key(listen: SocketAddr, names: &[String]) -> Result<Gate, getrandom::Error> {
        Ok(Gate::new(listen, names, random_key()?))
    }

    /// The page key: handed to the console's own page (`/api/session`), required of every
    /// action.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Whether the console answers a request with this `Host` header.
    pub fn allows_host(&self, host: Option<&str>) -> Result<(), Refusal> {
        match host {
            Some(h) if self.hosts.iter().any(|a| a.eq_ignore_ascii_case(h)) => Ok(()),
            _ => Err(Refusal::Host {
                given: host.unwrap_or("(none)").to_owned(),
                allowed: self.hosts.join(", "),
            }),
        }
    }

    /// Whether a request that acts may: its `Origin` (if sent) is the console's own, its
    /// `Sec-Fetch-Site` (if sent) says the same origin, and it carries the page key.
    pub fn allows_action(
        &self,
        origin: Option<&str>,
        fetch_site: Option<&str>,
        page_key: Option<&str>,
    ) -> Result<(), Refusal> {
        self.allows_origin(origin, fetch_site)?;
        match page_key {
            Some(given) if same(given, &self.key) => Ok(()),
            _ => Err(Refusal::NoPageKey),
        }
    }

    /// Whether a form the console's own page posts (the login form, which cannot set a
    /// header) comes from it: as [`Gate::allows_action`], the key in the form.
    pub fn allows_origin(
        &self,
        origin: Option<&str>,
        fetch_site: Option<&str>,
    ) -> Result<(), Refusal> {
        if let Some(origin) = origin {
            let own = origin
                .strip_prefix("http://")
                .is_some_and(|host| self.allows_host(Some(host)).is_ok());
            if !own {
                return Err(Refusal::CrossOrigin(origin.to_owned()));
            }
        }
        match fetch_site {
            None | Some("same-origin") => Ok(()),
            Some(other) => Err(Refusal::CrossOrigin(format!("Sec-Fetch-Site: {other}"))),
        }
    }
}

/// 128 random bits as 32 hexadecimal digits.
pub fn random_key() -> Result<String, getrandom::Error> {
    let mut bytes = [0u8; 16];
    getrandom::fill(&mut bytes)?;
    Ok(bytes.iter().map(|b| format!("{b:02x}")).collect())
}

/// `a == b` in time that depends on their lengths only.
pub fn same(a: &str, b: &str) -> bool {
    let (a, b) = (a.as_bytes(), b.as_bytes());
    let mut difference = u8::from(a.len() != b.len());
    for (i, &byte) in b.iter().enumerate() {
        difference |= byte ^ a.get(i).copied().unwrap_or(0);
    }
    std::hint::black_box(difference) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: &str = "0123456789abcdef0123456789abcdef";

    fn gate(listen: &str, names: &[&str]) -> Gate {
        let names: Vec<String> = names.iter().map(|n| n.to_string()).collect();
        Gate::new(listen.parse().unwrap(), &names, KEY.into())
    }

    #[test]
    fn the_console_answers_to_its_own_names_only() {
        let g = gate("127.0.0.1:8480", &["Lathe-3"]);
        for host in [
            "127.0.0.1:8480",
            "localhost:8480",
            "LOCALHOST:8480",
            "[::1]:8480",
            "lathe-3:8480",
        ] {
            assert_eq!(g.allows_host(Some(host)), Ok(()), "{host}");
        }
        // A rebound name, another port, no port (80 is not the console's), no Host.
        for host in [
            Some("evil.example:8480"),
            Some("127.0.0.1:8481"),
            Some("127.0.0.1"),
            Some("localhost.evil.example:8480"),
            None,
        ] {
            assert!(
                matches!(g.allows_host(host), Err(Refusal::Host { .. })),
                "{host:?}"
            );
        }
        // On port 80 a browser leaves the port out.
        let g = gate("127.0.0.1:80", &[]);
        assert_eq!(g.allows_host(Some("localhost")), Ok(()));
        // Listening on a shop address adds it; listening on every address adds none.
        let g = gate("192.168.1.20:8480", &[]);
        assert_eq!(g.allows_host(Some("192.168.1.20:8480")), Ok(()));
        let g = gate("0.0.0.0:8480", &[]);
        assert!(g.allows_host(Some("0.0.0.0:8480")).is_err());
    }

    #[test]
    fn an_action_needs_its_own_origin_and_the_page_key() {
        let g = gate("127.0.0.1:8480", &[]);
        let own = Some("http://127.0.0.1:8480");
        assert_eq!(g.allows_action(own, Some("same-origin"), Some(KEY)), Ok(()));
        // A script or curl sends neither Origin nor Sec-Fetch-Site.
        assert_eq!(g.allows_action(None, None, Some(KEY)), Ok(()));
        assert_eq!(g.allows_action(own, None, None), Err(Refusal::NoPageKey));
        assert_eq!(
            g.allows_action(own, None, Some("0123456789abcdef0123456789abcdeF")),
            Err(Refusal::NoPageKey)
        );
        for (origin, site) in [
            (Some("http://evil.example"), Some("cross-site")),
            // Another port of the same host: the same site, another origin.
            (Some("http://127.0.0.1:18490"), Some("same-site")),
            (Some("null"), None),
            (Some("https://127.0.0.1:8480"), None),
            (None, Some("cross-site")),
            (None, Some("same-site")),
        ] {
            assert!(
                matches!(
                    g.allows_action(origin, site, Some(KEY)),
                    Err(Refusal::CrossOrigin(_))
                ),
                "{origin:?} {site:?}"
            );
        }
    }

    #[test]
    fn random_keys_are_32_hex_digits_and_differ() {
        let (a, b) = (random_key().unwrap(), random_key().unwrap());
        assert_eq!(a.len(), 32);
        assert!(a.chars().all(|c| c.is_ascii_hexdigit()));
        assert_ne!(a, b);
    }
}
