//! The console's access token, and when one is required.
//!
//! On loopback the console serves whoever is at the machine's own keyboard; on any other
//! address it is on the shop's network, and [`check_listen`] refuses to start it without a
//! token. With a token, every request that moves the machine, plans or writes carries it
//! (a header, or the cookie the login form sets), and [`Token::matches`] compares it in
//! time that does not depend on where the first wrong character is.

use std::net::SocketAddr;

/// The header a request may carry the token in.
pub const HEADER: &str = "x-whirl-token";

/// The cookie the login form sets.
pub const COOKIE: &str = "whirl_token";

/// The fewest characters a token has: guessing it online is hopeless.
pub const MIN_LEN: usize = 16;

/// An access token.
#[derive(Clone)]
pub struct Token(String);

impl std::fmt::Debug for Token {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Token(…)")
    }
}

/// Why a token or a listening address was refused.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum TokenError {
    /// Too short.
    #[error("the access token (--token) has {0} characters: give at least {MIN_LEN}")]
    Short(usize),
    /// A character a cookie or a header cannot carry as it is.
    #[error(
        "the access token (--token) has a {0:?}: use letters, digits and punctuation other \
         than ; , \" \\ (no spaces)"
    )]
    Character(char),
    /// A non-loopback address without a token.
    #[error(
        "--listen {0} is reachable from other hosts: give an access token (--token) or \
         listen on loopback (127.0.0.1)"
    )]
    Unprotected(SocketAddr),
}

impl Token {
    /// `text` as a token: at least [`MIN_LEN`] visible ASCII characters, none that a
    /// cookie would need quoted.
    pub fn new(text: &str) -> Result<Token, TokenError> {
        if let Some(c) = text
            .chars()
            .find(|c| !c.is_ascii_graphic() || matches!(c, ';' | ',' | '"' | '\\'))
        {
            return Err(TokenError::Character(c));
        }
        if text.len() < MIN_LEN {
            return Err(TokenError::Short(text.len()));
        }
        Ok(Token(text.to_owned()))
    }

    /// The token itself (for the login cookie).
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// Whether `given` is the token, compared over the token's whole length whatever
    /// `given` is.
    pub fn matches(&self, given: &str) -> bool {
        let (expected, given) = (self.0.as_bytes(), given.as_bytes());
        let mut difference = u8::from(expected.len() != given.len());
        for (i, &byte) in expected.iter().enumerate() {
            difference |= byte ^ given.get(i).copied().unwrap_or(0);
        }
        std::hint::black_box(difference) == 0
    }
}

/// Refuses to listen on `addr`, reachable from other hosts, without a token.
pub fn check_listen(addr: SocketAddr, token: Option<&Token>) -> Result<(), TokenError> {
    if addr.ip().is_loopback() || token.is_some() {
        Ok(())
    } else {
        Err(TokenError::Unprotected(addr))
    }
}

/// The token a request carries: the [`HEADER`], else `Authorization: Bearer`, else the
/// [`COOKIE`] among `cookies` (a `Cookie` header's value).
pub fn presented<'a>(
    header: Option<&'a str>,
    authorization: Option<&'a str>,
    cookies: Option<&'a str>,
) -> Option<&'a str> {
    header
        .or_else(|| authorization.and_then(|a| a.strip_prefix("Bearer ")))
        .or_else(|| {
            cookies?.split(';').find_map(|c| {
                let (name, value) = c.trim().split_once('=')?;
                (name == COOKIE).then_some(value)
            })
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "k3y-for-the-shop-floor";

    #[test]
    fn only_the_token_itself_matches() {
        let token = Token::new(TEXT).unwrap();
        assert!(token.matches(TEXT));
        for wrong in [
            "",
            "k3y-for-the-shop-floo",
            "k3y-for-the-shop-floorX",
            "K3y-for-the-shop-floor",
            "k3y-for-the-shop-floo\0",
        ] {
            assert!(!token.matches(wrong), "{wrong:?}");
        }
        assert_eq!(format!("{token:?}"), "Token(…)");
    }

    #[test]
    fn weak_or_unsendable_tokens_are_refused() {
        assert_eq!(Token::new("short").unwrap_err(), TokenError::Short(5));
        assert_eq!(
            Token::new("with a space in it ok").unwrap_err(),
            TokenError::Character(' ')
        );
        assert_eq!(
            Token::new("semi;colon-token-long").unwrap_err(),
            TokenError::Character(';')
        );
    }

    #[test]
    fn other_hosts_need_a_token_loopback_does_not() {
        let token = Token::new(TEXT).unwrap();
        let lan: SocketAddr = "0.0.0.0:8480".parse().unwrap();
        let v6: SocketAddr = "[::]:8480".parse().unwrap();
        assert_eq!(check_listen(lan, None), Err(TokenError::Unprotected(lan)));
        assert_eq!(check_listen(v6, None), Err(TokenError::Unprotected(v6)));
        assert_eq!(check_listen(lan, Some(&token)), Ok(()));
        for local in ["127.0.0.1:8480", "[::1]:8480"] {
            assert_eq!(check_listen(local.parse().unwrap(), None), Ok(()));
        }
    }

    #[test]
    fn a_request_presents_the_token_by_header_bearer_or_cookie() {
        assert_eq!(presented(Some("a"), Some("Bearer b"), None), Some("a"));
        assert_eq!(presented(None, Some("Bearer b"), None), Some("b"));
        assert_eq!(presented(None, Some("Basic b"), None), None);
        assert_eq!(
            presented(None, None, Some("theme=dark; whirl_token=c; x=y")),
            Some("c")
        );
        assert_eq!(presented(None, None, Some("whirl_tokenx=c")), None);
        assert_eq!(presented(None, None, None), None);
    }
}
