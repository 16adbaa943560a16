//! The small grammar the designation readers share: numbers as drawings write them, the
//! left-hand mark, and a refusal's words.

use super::designation::DesignationError;

/// A refusal of `text`, saying what is wrong in the standard's terms.
pub(super) fn refuse(text: &str, why: impl Into<String>) -> DesignationError {
    DesignationError::Refused {
        text: text.to_string(),
        why: why.into(),
    }
}

/// A number as a drawing writes it: `40`, `1.5`, `.500`, or with ISO's decimal comma `1,5`.
/// `what` names it in the refusal.
pub(super) fn number(word: &str, what: &str) -> Result<f64, String> {
    let word = word.trim();
    match word.replace(',', ".").parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        _ => Err(format!("the {what} `{word}` is not a number above zero")),
    }
}

/// Takes the left-hand mark `LH` off the end of `body`: `(rest, true)` when it is there once,
/// a refusal when it is given twice or stands anywhere but at the end.
pub(super) fn left_hand(body: &str) -> Result<(&str, bool), String> {
    match body.matches("LH").count() {
        0 => Ok((body, false)),
        1 => body
            .strip_suffix("LH")
            .map(|rest| (rest, true))
            .ok_or_else(|| "LH (left hand) must follow the pitch".to_string()),
        _ => Err("LH (left hand) is given twice".to_string()),
    }
}

/// The number of starts of a thread of `lead` and `pitch`: the lead must be a whole number of
/// pitches (a thread of n starts advances n pitches per turn).
pub(super) fn starts(lead: f64, pitch: f64, unit: &str) -> Result<u32, String> {
    let n = lead / pitch;
    let whole = n.round();
    if whole >= 1.0 && (n - whole).abs() <= 1e-9 * n && whole <= f64::from(u32::MAX) {
        Ok(whole as u32)
    } else {
        Err(format!(
            "the lead {lead} {unit} is not a whole number of pitches {pitch} {unit} (the lead \
             of an n-start thread is n pitches)"
        ))
    }
}

/// Numbers for a message, separated by commas.
pub(super) fn list(values: impl IntoIterator<Item = f64>) -> String {
    values
        .into_iter()
        .map(|v| v.to_string())
        .collect::<Vec<_>>()
        .join(", ")
}

/// A size in inches: a decimal (`0.5`, `.500`), a fraction (`1/2`) or a whole number and a
/// fraction (`1 1/2`, written `1-1/2` too).
pub(super) fn size_inches(size: &str) -> Result<f64, String> {
    let fraction = |word: &str| -> Result<f64, String> {
        match word.split_once('/') {
            Some((num, den)) => Ok(number(num, "size (in)")? / number(den, "size (in)")?),
            None => number(word, "size (in)"),
        }
    };
    let words: Vec<&str> = size.split_whitespace().collect();
    match words.as_slice() {
        [one] => fraction(one),
        [whole, part] if part.contains('/') && !whole.contains('/') => {
            Ok(number(whole, "size (in)")? + fraction(part)?)
        }
        _ => Err(format!("the size `{size}` is not a size in inches")),
    }
}

/// A lead screw's size as ISO and DIN write it (ISO 2903 for Tr, DIN 513 for S).
pub(super) struct LeadScrewSize {
    /// Nominal diameter, mm.
    pub d: f64,
    /// Lead, mm: the pitch, or `Ph` for several starts.
    pub lead: f64,
    /// Pitch, mm.
    pub pitch: f64,
    /// `LH` after it.
    pub left_hand: bool,
}

/// Reads `d x P`, or `d x Ph P P` for several starts (also `d x Ph(P P)`), with `LH` after
/// it, the spaces and the `×` a drawing writes; `example` shows the form in a refusal.
pub(super) fn lead_screw_size(body: &str, example: &str) -> Result<LeadScrewSize, String> {
    let body: String = body
        .chars()
        .filter(|c| !c.is_whitespace() && *c != '(' && *c != ')')
        .map(|c| if c == '×' || c == 'X' { 'x' } else { c })
        .collect();
    let (body, left_hand) = left_hand(&body)?;
    let Some((d, pitches)) = body.split_once('x') else {
        return Err(format!(
            "write the size as diameter x pitch, as in `{example}`"
        ));
    };
    let d = number(d, "nominal diameter")?;
    let (lead, pitch) = match pitches.split_once('P') {
        Some((lead, pitch)) => (number(lead, "lead")?, number(pitch, "pitch")?),
        None => {
            let p = number(pitches, "pitch")?;
            (p, p)
        }
    };
    Ok(LeadScrewSize {
        d,
        lead,
        pitch,
        left_hand,
    })
}
