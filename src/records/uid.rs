//! A run's key: 128 random bits in hex, the same in every database its record is written
//! to. A record's number is its database's own (a spool numbers the runs it keeps, and the
//! shop's database gives an uploaded run its next number), so the number cannot tell
//! whether a run is already in the shop's database; the key does, and an upload tried
//! again after a crash finds the run it made the first time and makes nothing twice.

use serde::Serialize;

use crate::config::provenance::hex;

/// A run's (or a note's) key in every database.
#[derive(Debug, Clone, PartialEq, Eq, Hash, Serialize)]
#[serde(transparent)]
pub struct Uid(String);

impl Uid {
    /// A new key, from the operating system's random bits.
    pub fn random() -> Result<Uid, getrandom::Error> {
        let mut bytes = [0u8; 16];
        getrandom::fill(&mut bytes)?;
        Ok(Uid(hex(&bytes)))
    }

    /// A key as a database holds it.
    pub fn from_text(text: String) -> Uid {
        Uid(text)
    }

    /// The key, as text.
    pub fn as_str(&self) -> &str {
        &self.0
    }

    /// The key of the `k`th note (from 0) of this run's ending. The same ending written
    /// twice (to the shop's database, whose answer was lost, then to the spool) gives its
    /// notes the same keys, so that they are added once; a note written as the run goes
    /// has a random key of its own.
    pub fn ending_note(&self, k: usize) -> Uid {
        Uid(format!("{}.end.{k}", self.0))
    }

    /// Whether `note` is a key [`Uid::ending_note`] gives this run's ending.
    pub fn is_ending_note(&self, note: &str) -> bool {
        note.strip_prefix(self.0.as_str())
            .and_then(|rest| rest.strip_prefix(".end."))
            .is_some_and(|k| k.parse::<usize>().is_ok())
    }
}

impl std::fmt::Display for Uid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_is_128_random_bits_in_hex_and_no_two_are_alike() {
        let keys: std::collections::HashSet<Uid> =
            (0..1000).map(|_| Uid::random().unwrap()).collect();
        assert_eq!(keys.len(), 1000);
        for key in &keys {
            assert_eq!(key.as_str().len(), 32);
            assert!(key.as_str().bytes().all(|b| b.is_ascii_hexdigit()));
        }
    }

    #[test]
    fn an_endings_notes_are_known_by_their_runs_key() {
        let run = Uid::from_text("ab12".into());
        assert_eq!(run.ending_note(2).as_str(), "ab12.end.2");
        assert!(run.is_ending_note("ab12.end.0"));
        assert!(!run.is_ending_note("ab13.end.0"));
        assert!(!run.is_ending_note("ab12.end."));
        assert!(!run.is_ending_note("ab12"));
        assert!(!Uid::from_text("ab".into()).is_ending_note("ab12.end.0"));
    }
}
