//! Numbers both command lines take (`whirl` and `whirl-sim`, which includes this file),
//! each checked when clap parses it, so a wrong one is refused naming its option before
//! anything starts.

/// A number, which may still be NaN or infinite: each caller's range refuses those.
pub fn number(text: &str) -> Result<f64, String> {
    text.trim()
        .parse()
        .map_err(|_| format!("{text:?} is not a number"))
}

/// A whole number from `low` to `high`, `what` (" bytes") saying what it counts.
pub fn whole_in<T>(text: &str, low: T, high: T, what: &str) -> Result<T, String>
where
    T: std::str::FromStr + PartialOrd + std::fmt::Display,
{
    let value: T = text
        .trim()
        .parse()
        .map_err(|_| format!("{text:?} is not a whole number"))?;
    if value >= low && value <= high {
        Ok(value)
    } else {
        Err(format!("must be a whole number from {low} to {high}{what}"))
    }
}

/// `--time-scale`: simulated seconds per wall second, 0.001 to 10000; 0: as fast as the
/// host allows.
pub fn time_scale(text: &str) -> Result<f64, String> {
    let scale = number(text)?;
    if scale == 0.0 || (1e-3..=1e4).contains(&scale) {
        Ok(scale)
    } else {
        Err(
            "must be 0 (as fast as the host allows) or a number from 0.001 to 10000 simulated \
             seconds per wall second"
                .into(),
        )
    }
}

/// `--baud`: bits per second, 300 to 10 000 000.
pub fn baud(text: &str) -> Result<u32, String> {
    whole_in(text, 300, 10_000_000, " bits per second")
}

/// `--rx`: a controller's receive buffer, 128 (grbl on an AVR) to 65536 bytes.
pub fn rx(text: &str) -> Result<usize, String> {
    whole_in(text, 128, 65_536, " bytes")
}
