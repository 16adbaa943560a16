//! The console's access token, and when one is required.
//!
//! On loopback the console serves whoever is at the machine's own keyboard; on any other
//! address it is on the shop's network, and [`check_listen`] refuses to start it without a
//! token. With a token, every request that moves the machine, plans or writes carries it
//! (a header, or the session the login form opened: [`super::login`]), and
//! [`Token::matches`] compares it in time that does not depend on where the first wrong
//! character is.

use std::net::SocketAddr;

/// The header a request may carry the token in.
pub const HEADER: &str = "x-whirl-token";

/// The fewest characters a token has: guessing it online is hopeless.
pub const MIN_LEN: usize = 16;

/// The fewest different characters a token has: sixteen of one letter, or two letters
/// repeated, is guessed before anything random.
pub const MIN_DISTINCT: usize = 8;

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
    /// Too few different characters.
    #[error(
        "the access token (--token) has only {0} different characters: give at least \
         {MIN_DISTINCT} (a random one, such as 32 hexadecimal digits from `openssl rand -hex \
         16`)"
    )]
    Weak(usize),
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
        let distinct = text
            .bytes()
            .collect::<std::collections::BTreeSet<u8>>()
            .len();
        if distinct < MIN_DISTINCT {
            return Err(TokenError::Weak(distinct));
        }
        Ok(Token(text.to_owned()))
    }

    /// Whether `given` is the token, compared over the token's whole length whatever
    /// `given` is.
    pub fn matches(&self, given: &str) -> bool {
        super::gate::same(given, &self.0)
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

/// The token a request carries: the [`HEADER`], else `Authorization: Bearer`.
pub fn presented<'a>(header: Option<&'a str>, authorization: Option<&'a str>) -> Option<&'a str> {
    header.or_else(|| authorization.and_then(|a| a.strip_prefix("Bearer ")))
}

/// The name of the session cookie of the console on `port`: the host's cookies are shared
/// by all its ports, and two consoles' sessions must not overwrite each other.
pub fn cookie_name(port: u16) -> String {
    format!("whirl_session_{port}")
}

/// The value of the cookie `name` among `cookies` (a `Cookie` header's value).
pub fn cookie<'a>(cookies: Option<&'a str>, name: &str) -> Option<&'a str> {
    cookies?.split(';').find_map(|c| {
        let (n, value) = c.trim().split_once('=')?;
        (n == name).then_some(value)
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
            Token::new("aaaaaaaaaaaaaaaa").unwrap_err(),
            TokenError::Weak(1)
        );
        assert_eq!(
            Token::new("abcabcabcabcabcabc").unwrap_err(),
            TokenError::Weak(3)
        );
        assert!(Token::new("3f9c0a17be52d846").is_ok());
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
    fn a_request_presents_the_token_by_header_or_bearer_and_a_session_by_its_cookie() {
        assert_eq!(presented(Some("a"), Some("Bearer b")), Some("a"));
        assert_eq!(presented(None, Some("Bearer b")), Some("b"));
        assert_eq!(presented(None, Some("Basic b")), None);
        assert_eq!(presented(None, None), None);
        let name = cookie_name(8480);
        assert_eq!(name, "whirl_session_8480");
        assert_eq!(
            cookie(Some("theme=dark; whirl_session_8480=c; x=y"), &name),
            Some("c")
        );
        // Another console's session on another port is not this one's.
        assert_eq!(cookie(Some("whirl_session_8481=c"), &name), None);
        assert_eq!(cookie(None, &name), None);
    }
}
