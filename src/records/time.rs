//! A record's times: UTC, written as RFC 3339 text with milliseconds
//! (`2026-05-01T14:03:27.512Z`). Text of one fixed width sorts as time does, in SQLite and
//! in PostgreSQL alike, and reads the same in either's own shell, so the records need no
//! date type the two databases disagree on.

use std::time::{SystemTime, UNIX_EPOCH};

/// Milliseconds since 1970-01-01T00:00:00Z.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub struct Timestamp(pub i64);

impl Timestamp {
    /// Now, by the system clock.
    pub fn now() -> Timestamp {
        let since = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        Timestamp(i64::try_from(since.as_millis()).unwrap_or(i64::MAX))
    }

    /// `YYYY-MM-DDTHH:MM:SS.mmmZ`.
    pub fn to_text(self) -> String {
        let days = self.0.div_euclid(86_400_000);
        let ms = self.0.rem_euclid(86_400_000);
        let (y, m, d) = civil_from_days(days);
        format!(
            "{y:04}-{m:02}-{d:02}T{:02}:{:02}:{:02}.{:03}Z",
            ms / 3_600_000,
            ms / 60_000 % 60,
            ms / 1000 % 60,
            ms % 1000
        )
    }

    /// Reads a UTC date or time as `--since` takes it: `YYYY-MM-DD` (the day's start),
    /// `YYYY-MM-DDTHH:MM`, `YYYY-MM-DDTHH:MM:SS` or the full form [`Timestamp::to_text`]
    /// writes, a space allowed for the `T` and a `Z` at the end. The error says what is
    /// wrong with the text.
    pub fn parse(text: &str) -> Result<Timestamp, String> {
        let wrong = || {
            format!(
                "\"{text}\" is not a UTC date or time: write YYYY-MM-DD, YYYY-MM-DDTHH:MM or \
                 YYYY-MM-DDTHH:MM:SS"
            )
        };
        let trimmed = text.trim().trim_end_matches('Z');
        let (date, time) = match trimmed.split_once(['T', ' ']) {
            Some((date, time)) => (date, Some(time)),
            None => (trimmed, None),
        };
        let number = |s: &str, digits: usize| -> Result<i64, String> {
            if s.len() == digits && s.bytes().all(|b| b.is_ascii_digit()) {
                Ok(s.parse().expect("digits"))
            } else {
                Err(wrong())
            }
        };
        let mut parts = date.split('-');
        let (Some(y), Some(m), Some(d), None) =
            (parts.next(), parts.next(), parts.next(), parts.next())
        else {
            return Err(wrong());
        };
        let (y, m, d) = (number(y, 4)?, number(m, 2)?, number(d, 2)?);
        if !(1..=12).contains(&m) || d < 1 || d > days_in_month(y, m) {
            return Err(format!("{text}: there is no day {y:04}-{m:02}-{d:02}"));
        }
        let mut ms = 0;
        if let Some(time) = time {
            let (hms, fraction) = match time.split_once('.') {
                Some((hms, fraction)) => (hms, Some(fraction)),
                None => (time, None),
            };
            let fields: Vec<&str> = hms.split(':').collect();
            let (h, min, s) = match fields.as_slice() {
                [h, min] => (number(h, 2)?, number(min, 2)?, 0),
                [h, min, s] => (number(h, 2)?, number(min, 2)?, number(s, 2)?),
                _ => return Err(wrong()),
            };
            if h > 23 || min > 59 || s > 59 {
                return Err(format!("{text}: there is no time {h:02}:{min:02}:{s:02}"));
            }
            ms = ((h * 60 + min) * 60 + s) * 1000;
            if let Some(fraction) = fraction {
                if fraction.is_empty() || fraction.len() > 3 || fields.len() != 3 {
                    return Err(wrong());
                }
                ms += number(fraction, fraction.len())? * 10_i64.pow(3 - fraction.len() as u32);
            }
        }
        Ok(Timestamp(days_from_civil(y, m, d) * 86_400_000 + ms))
    }
}

fn days_in_month(y: i64, m: i64) -> i64 {
    match m {
        2 if y % 4 == 0 && (y % 100 != 0 || y % 400 == 0) => 29,
        2 => 28,
        4 | 6 | 9 | 11 => 30,
        _ => 31,
    }
}

/// Days since 1970-01-01 of a proleptic Gregorian date (H. Hinnant's `days_from_civil`).
fn days_from_civil(y: i64, m: i64, d: i64) -> i64 {
    let y = if m <= 2 { y - 1 } else { y };
    let era = y.div_euclid(400);
    let yoe = y - era * 400;
    let doy = (153 * (if m > 2 { m - 3 } else { m + 9 }) + 2) / 5 + d - 1;
    let doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
    era * 146_097 + doe - 719_468
}

/// The date of a day since 1970-01-01 (H. Hinnant's `civil_from_days`).
fn civil_from_days(z: i64) -> (i64, i64, i64) {
    let z = z + 719_468;
    let era = z.div_euclid(146_097);
    let doe = z - era * 146_097;
    let yoe = (doe - doe / 1460 + doe / 36_524 - doe / 146_096) / 365;
    let doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
    let mp = (5 * doy + 2) / 153;
    let d = doy - (153 * mp + 2) / 5 + 1;
    let m = if mp < 10 { mp + 3 } else { mp - 9 };
    (
        if m <= 2 {
            yoe + era * 400 + 1
        } else {
            yoe + era * 400
        },
        m,
        d,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_instants_are_written_as_the_calendar_says() {
        // The epoch; the first leap day of 2000 (a leap year though divisible by 100);
        // 2100-03-01, the day after a 28-day February (divisible by 100, not by 400).
        assert_eq!(Timestamp(0).to_text(), "1970-01-01T00:00:00.000Z");
        assert_eq!(
            Timestamp(951_782_400_000).to_text(),
            "2000-02-29T00:00:00.000Z"
        );
        assert_eq!(
            Timestamp(4_107_542_400_000 + 1).to_text(),
            "2100-03-01T00:00:00.001Z"
        );
        // One millisecond before the epoch.
        assert_eq!(Timestamp(-1).to_text(), "1969-12-31T23:59:59.999Z");
    }

    #[test]
    fn what_is_written_reads_back_and_sorts_as_time_does() {
        let instants = [0, 951_782_400_000, 1_777_644_207_512, 4_107_542_400_001];
        let mut texts = Vec::new();
        for ms in instants {
            let text = Timestamp(ms).to_text();
            assert_eq!(Timestamp::parse(&text), Ok(Timestamp(ms)), "{text}");
            texts.push(text);
        }
        let mut sorted = texts.clone();
        sorted.sort();
        assert_eq!(sorted, texts);
    }

    #[test]
    fn dates_and_times_read_in_every_form_the_option_takes() {
        let day = Timestamp::parse("2026-05-01").unwrap();
        assert_eq!(day.to_text(), "2026-05-01T00:00:00.000Z");
        assert_eq!(
            Timestamp::parse("2026-05-01T14:03").unwrap().0 - day.0,
            (14 * 60 + 3) * 60_000
        );
        assert_eq!(
            Timestamp::parse("2026-05-01 14:03:27Z").unwrap().0 - day.0,
            ((14 * 60 + 3) * 60 + 27) * 1000
        );
        assert_eq!(
            Timestamp::parse("2026-05-01T14:03:27.5").unwrap().0 - day.0,
            ((14 * 60 + 3) * 60 + 27) * 1000 + 500
        );
    }

    #[test]
    fn a_date_that_is_not_one_is_refused_saying_why() {
        for bad in [
            "yesterday",
            "2026-5-1",
            "2026-05",
            "2026-05-01T14",
            "",
            "2026/05/01",
        ] {
            let error = Timestamp::parse(bad).unwrap_err();
            assert!(error.contains("YYYY-MM-DD"), "{bad}: {error}");
        }
        assert!(Timestamp::parse("2025-02-29")
            .unwrap_err()
            .contains("no day 2025-02-29"));
        assert!(Timestamp::parse("2026-13-01")
            .unwrap_err()
            .contains("no day"));
        assert!(Timestamp::parse("2026-05-01T24:00")
            .unwrap_err()
            .contains("no time 24:00:00"));
        assert!(Timestamp::parse("2024-02-29").is_ok());
    }
}
