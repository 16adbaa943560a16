//! The login of a console with an access token: the sessions it opened, and how fast wrong
//! tokens may be tried.
//!
//! A browser that logs in gets a session cookie holding a random session id, never the
//! token itself: a cookie can leak (to another port of the same host, which shares the
//! host's cookies; to a proxy's log), and a leaked session ends with the console, while a
//! leaked token would open every later one. Wrong tokens are limited by a token bucket, so
//! guessing online is hopeless even for a token at the shortest length allowed.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// The most sessions a console keeps; the oldest is forgotten when another logs in.
pub const MAX_SESSIONS: usize = 32;

/// Wrong tokens that may be tried in a burst.
pub const GUESS_BURST: u32 = 5;

/// After the burst, one more wrong token may be tried every this long.
pub const GUESS_EVERY: Duration = Duration::from_secs(2);

/// The sessions a console's login opened, newest last.
#[derive(Debug, Default)]
pub struct Sessions {
    ids: VecDeque<String>,
}

impl Sessions {
    /// Keeps `id` (a random session id) as a session, forgetting the oldest past
    /// [`MAX_SESSIONS`].
    pub fn open(&mut self, id: String) {
        if self.ids.len() == MAX_SESSIONS {
            self.ids.pop_front();
        }
        self.ids.push_back(id);
    }

    /// Whether `id` is a session this console opened, compared in constant time.
    pub fn holds(&self, id: &str) -> bool {
        self.ids
            .iter()
            .fold(false, |found, kept| found | super::gate::same(id, kept))
    }
}

/// How many wrong tokens may still be tried: a bucket of [`GUESS_BURST`] that fills by one
/// every [`GUESS_EVERY`]. Time is given, not read, so the rule is tested without waiting.
#[derive(Debug)]
pub struct Guesses {
    /// Tries left, fractions included.
    left: f64,
    /// When `left` was counted.
    at: Instant,
}

impl Guesses {
    /// A full bucket at `now`.
    pub fn new(now: Instant) -> Guesses {
        Guesses {
            left: f64::from(GUESS_BURST),
            at: now,
        }
    }

    /// Whether a login may be tried at `now`; `Err`: how long until one may.
    pub fn allow(&mut self, now: Instant) -> Result<(), Duration> {
        self.fill(now);
        if self.left >= 1.0 {
            Ok(())
        } else {
            Err(GUESS_EVERY.mul_f64(1.0 - self.left))
        }
    }

    /// A wrong token was tried at `now`.
    pub fn wrong(&mut self, now: Instant) {
        self.fill(now);
        self.left = (self.left - 1.0).max(0.0);
    }

    fn fill(&mut self, now: Instant) {
        let earned =
            now.saturating_duration_since(self.at).as_secs_f64() / GUESS_EVERY.as_secs_f64();
        self.left = (self.left + earned).min(f64::from(GUESS_BURST));
        self.at = self.at.max(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_session_is_held_until_newer_ones_push_it_out() {
        let mut sessions = Sessions::default();
        sessions.open("first".into());
        assert!(sessions.holds("first"));
        assert!(!sessions.holds("firs"));
        assert!(!sessions.holds(""));
        for k in 0..MAX_SESSIONS {
            sessions.open(format!("later-{k}"));
        }
        assert!(!sessions.holds("first"));
        assert!(sessions.holds("later-0"));
    }

    #[test]
    fn wrong_tokens_come_in_a_burst_then_one_every_two_seconds() {
        let start = Instant::now();
        let mut guesses = Guesses::new(start);
        for _ in 0..GUESS_BURST {
            assert_eq!(guesses.allow(start), Ok(()));
            guesses.wrong(start);
        }
        // The burst is spent: the next may come two seconds after the first wrong one.
        assert_eq!(guesses.allow(start), Err(GUESS_EVERY));
        let half = start + GUESS_EVERY / 2;
        assert_eq!(guesses.allow(half), Err(GUESS_EVERY / 2));
        let later = start + GUESS_EVERY;
        assert_eq!(guesses.allow(later), Ok(()));
        guesses.wrong(later);
        assert!(guesses.allow(later).is_err());
        // A minute of guessing at the limit: at most 5 + 30 tries, whatever the attacker's
        // speed.
        let mut tried = GUESS_BURST + 1;
        let mut now = later;
        while now < start + Duration::from_secs(60) {
            now += Duration::from_millis(10);
            if guesses.allow(now).is_ok() {
                guesses.wrong(now);
                tried += 1;
            }
        }
        assert!(tried <= GUESS_BURST + 30, "{tried}");
        // Left alone, the bucket fills again, and no further.
        let rested = now + GUESS_EVERY * 100;
        for _ in 0..GUESS_BURST {
            assert_eq!(guesses.allow(rested), Ok(()));
            guesses.wrong(rested);
        }
        assert!(guesses.allow(rested).is_err());
    }
}
