//! The feed override over grbl's real-time bytes, sans I/O: which byte to send next to reach
//! the value asked, read back from the status reports' `Ov:` field.
//!
//! grbl 1.1 keeps its override bytes as flags until its main loop next runs (`protocol.c`:
//! two +10 % bytes in one pass count once), and grblHAL queues them; grblHAL's reports and
//! grbl's show `Ov:` in the report after a change and otherwise every 10 to 20 reports
//! (`REPORT_OVR_REFRESH_*_COUNT`). So one byte goes out at a time, and the next only once a
//! report shows the value it made: the same sequence reaches the same value on both, and a
//! byte the controller did not take is not followed by another. The bytes never overshoot
//! the value asked, so grbl's clamping at 10 and 200 % never comes into it.

/// 0x90: feed override back to 100 %.
pub const RESET: u8 = 0x90;
/// 0x91: +10 %.
pub const COARSE_PLUS: u8 = 0x91;
/// 0x92: −10 %.
pub const COARSE_MINUS: u8 = 0x92;
/// 0x93: +1 %.
pub const FINE_PLUS: u8 = 0x93;
/// 0x94: −1 %.
pub const FINE_MINUS: u8 = 0x94;

/// Reports after a byte in which `Ov:` must show its effect: grbl shows `Ov:` at least
/// every 20 reports while busy (and at once after a change), so a controller that has not
/// in 21 either does not report it or did not take the byte.
pub const UNCONFIRMED_REPORTS: u32 = 21;

/// The next byte on the way from `from` (`None`: not known) to `to`, percent; `None` once
/// there. Unknown, or `to` nearer 100 than `from` in steps, goes through 0x90 first.
pub fn next_byte(from: Option<u16>, to: u16) -> Option<u8> {
    let Some(from) = from else {
        return Some(RESET);
    };
    if from == to {
        return None;
    }
    let steps = |a: u16, b: u16| {
        let d = a.abs_diff(b);
        d / 10 + d % 10
    };
    if 1 + steps(100, to) < steps(from, to) || to == 100 {
        return Some(RESET);
    }
    let d = i32::from(to) - i32::from(from);
    Some(match d {
        10.. => COARSE_PLUS,
        1..=9 => FINE_PLUS,
        -9..=-1 => FINE_MINUS,
        _ => COARSE_MINUS,
    })
}

/// The feed override from a status report's fields not otherwise parsed (`Ov:feed,rapid,
/// spindle`), percent; `None` if the report has none or it does not read.
pub fn reported(fields: &[String]) -> Option<u16> {
    fields
        .iter()
        .find_map(|f| f.strip_prefix("Ov:"))
        .and_then(|ov| ov.split(',').next())
        .and_then(|feed| feed.trim().parse().ok())
}

/// What the controller did about the feed override.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Change {
    /// `Ov:` shows a new feed override (or the first one seen), percent.
    Reported(u16),
    /// The value asked was not reached: the controller does not report `Ov:`
    /// (`reported` is `None`), or did not take the last byte (it stays at `reported`).
    NotTaken {
        /// Asked, percent.
        asked: u16,
        /// What the controller last reported, percent.
        reported: Option<u16>,
    },
}

/// The override asked and what the controller says; one byte in flight at a time.
#[derive(Debug, Clone, Default)]
pub struct FeedOverride {
    asked: Option<u16>,
    reported: Option<u16>,
    /// A byte sent and not yet seen in `Ov:`: the value before it, and reports since.
    in_flight: Option<(Option<u16>, u32)>,
}

impl FeedOverride {
    /// Asks for `percent`: the byte to send now, if one may go.
    pub fn ask(&mut self, percent: u16) -> Option<u8> {
        self.asked = Some(percent);
        self.step()
    }

    /// The value asked and not yet reached.
    pub fn asked(&self) -> Option<u16> {
        self.asked
    }

    /// The feed override the controller last reported.
    pub fn reported(&self) -> Option<u16> {
        self.reported
    }

    /// Takes a status report's `Ov:` feed value (`None`: the report had none): the next
    /// byte to send, and what changed.
    pub fn on_report(&mut self, ov: Option<u16>) -> (Option<u8>, Option<Change>) {
        let mut change = None;
        if let Some(v) = ov {
            if self.reported != Some(v) {
                change = Some(Change::Reported(v));
            }
            self.reported = Some(v);
        }
        if let Some((from, reports)) = self.in_flight {
            let confirmed = ov.is_some_and(|v| from != Some(v));
            if confirmed {
                self.in_flight = None;
            } else if reports + 1 >= UNCONFIRMED_REPORTS {
                self.in_flight = None;
                let asked = self.asked.take().unwrap_or(100);
                return (
                    None,
                    Some(Change::NotTaken {
                        asked,
                        reported: self.reported,
                    }),
                );
            } else {
                self.in_flight = Some((from, reports + 1));
                return (None, change);
            }
        }
        (self.step(), change)
    }

    /// The byte towards the value asked, if none is in flight; clears the value asked once
    /// reached.
    fn step(&mut self) -> Option<u8> {
        if self.in_flight.is_some() {
            return None;
        }
        let asked = self.asked?;
        match next_byte(self.reported, asked) {
            Some(byte) => {
                self.in_flight = Some((self.reported, 0));
                Some(byte)
            }
            None => {
                self.asked = None;
                None
            }
        }
    }
}

#[cfg(test)]
mod tests;
