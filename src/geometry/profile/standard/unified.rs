//! The unified inch screw thread (UN) of ASME B1.1 by designation: `1/4-20 UNC-2A`,
//! `#10-32 UNF-3B`, `1 1/2-6 UNC-2A-LH`, `1/4-32 UNEF`, `2-8 UN-2A`, `0.500-24 UNS-2A`, read
//! against B1.1's coarse, fine and extra-fine series and its constant-pitch series; the
//! special series (UNS) takes any size and pitch.

use super::designation::{Designation, DesignationError};
use super::reading::{left_hand, number, refuse, size_inches};
use super::{IsoMetric, StandardProfile, MM_PER_INCH};

/// A unified inch thread: ASME B1.1's basic profile is ISO 68-1's (60°, `H = √3/2·P`, crest
/// flat `P/8` at the basic major diameter, basic minor diameter `D − 1.082532·P`, pitch
/// diameter `E = D − 0.649519·P`), so the form is the metric one on inch sizes; the
/// external thread is cut with B1.1's rounded (UNR) root, whose radius may run from
/// `0.108·P` to `0.144·P`: whirl cuts the full `H/6 = 0.1443·P`, reaching `D − 1.22687·P`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Unified {
    /// The same form in mm.
    pub(super) metric: IsoMetric,
    /// The basic major diameter, inches.
    inches: f64,
}

impl Unified {
    /// The form of basic major diameter `inches`.
    fn new(inches: f64) -> Result<Unified, String> {
        Ok(Unified {
            metric: IsoMetric::new(inches * MM_PER_INCH).map_err(|e| e.to_string())?,
            inches,
        })
    }

    /// The same form in mm.
    pub fn metric(&self) -> &IsoMetric {
        &self.metric
    }

    /// The basic major diameter, inches.
    pub fn inches(&self) -> f64 {
        self.inches
    }
}

/// A series row: nominal size, basic major diameter (in), threads per inch.
type Row = (&'static str, f64, f64);

/// ASME B1.1-2019 Table 2 (standard series), coarse-thread series UNC.
pub const UNC: &[Row] = &[
    ("#1", 0.073, 64.0),
    ("#2", 0.086, 56.0),
    ("#3", 0.099, 48.0),
    ("#4", 0.112, 40.0),
    ("#5", 0.125, 40.0),
    ("#6", 0.138, 32.0),
    ("#8", 0.164, 32.0),
    ("#10", 0.19, 24.0),
    ("#12", 0.216, 24.0),
    ("1/4", 0.25, 20.0),
    ("5/16", 0.3125, 18.0),
    ("3/8", 0.375, 16.0),
    ("7/16", 0.4375, 14.0),
    ("1/2", 0.5, 13.0),
    ("9/16", 0.5625, 12.0),
    ("5/8", 0.625, 11.0),
    ("3/4", 0.75, 10.0),
    ("7/8", 0.875, 9.0),
    ("1", 1.0, 8.0),
    ("1 1/8", 1.125, 7.0),
    ("1 1/4", 1.25, 7.0),
    ("1 3/8", 1.375, 6.0),
    ("1 1/2", 1.5, 6.0),
    ("1 3/4", 1.75, 5.0),
    ("2", 2.0, 4.5),
    ("2 1/4", 2.25, 4.5),
    ("2 1/2", 2.5, 4.0),
    ("2 3/4", 2.75, 4.0),
    ("3", 3.0, 4.0),
    ("3 1/4", 3.25, 4.0),
    ("3 1/2", 3.5, 4.0),
    ("3 3/4", 3.75, 4.0),
    ("4", 4.0, 4.0),
];

/// ASME B1.1-2019 Table 2, fine-thread series UNF.
pub const UNF: &[Row] = &[
    ("#0", 0.06, 80.0),
    ("#1", 0.073, 72.0),
    ("#2", 0.086, 64.0),
    ("#3", 0.099, 56.0),
    ("#4", 0.112, 48.0),
    ("#5", 0.125, 44.0),
    ("#6", 0.138, 40.0),
    ("#8", 0.164, 36.0),
    ("#10", 0.19, 32.0),
    ("#12", 0.216, 28.0),
    ("1/4", 0.25, 28.0),
    ("5/16", 0.3125, 24.0),
    ("3/8", 0.375, 24.0),
    ("7/16", 0.4375, 20.0),
    ("1/2", 0.5, 20.0),
    ("9/16", 0.5625, 18.0),
    ("5/8", 0.625, 18.0),
    ("3/4", 0.75, 16.0),
    ("7/8", 0.875, 14.0),
    ("1", 1.0, 12.0),
    ("1 1/8", 1.125, 12.0),
    ("1 1/4", 1.25, 12.0),
    ("1 3/8", 1.375, 12.0),
    ("1 1/2", 1.5, 12.0),
];

/// ASME B1.1-2019 Table 2, extra-fine series UNEF.
///
/// Source: the "Table for unified Thread, Type and Number of thread" (UNC, UNF, UNEF and the
/// constant-pitch columns) of Eisen's SPU gauge page,
/// <https://eisen.gr.jp/e/products/pin/pin_02.php?pgid=SPU>, which gives every row below.
/// Checked against: NBK's unified thread size chart
/// (<https://alb02.internal.nbk1560.com/en/resources/specialscrew/article/Screw_Size_Chart/>,
/// #12 to 7/8 in, which prints the 1/2-28 row as "UNF": a misprint, B1.1's 1/2 UNF being 20
/// threads per inch); eFunda's ASME B1.1 standard series
/// (<http://www.efunda.com/DesignStandards/screws/unified.cfm>; 15/16-20 UNEF on its page
/// `unified.cfm?start=228&finish=301`, 5/8-24 and 11/16-24 UNEF in a copy of its 5/8 to 7/8 in
/// page); the microadvances class 2A/2B chart (<http://microadvances.com/drillchart.htm>:
/// 12-32 UNEF). FreeCAD's hole table (FreeCAD/FreeCAD,
/// `src/Mod/PartDesign/App/FeatureHole.cpp`) has the same pitches but no 1 3/16 row, which
/// Eisen's table has. Eisen's table has no UNEF size above 1 11/16 (its 1 3/4 and 2 in take
/// 16 threads per inch in the 16-UN column only), so neither does this one.
pub const UNEF: &[Row] = &[
    ("#12", 0.216, 32.0),
    ("1/4", 0.25, 32.0),
    ("5/16", 0.3125, 32.0),
    ("3/8", 0.375, 32.0),
    ("7/16", 0.4375, 28.0),
    ("1/2", 0.5, 28.0),
    ("9/16", 0.5625, 24.0),
    ("5/8", 0.625, 24.0),
    ("11/16", 0.6875, 24.0),
    ("3/4", 0.75, 20.0),
    ("13/16", 0.8125, 20.0),
    ("7/8", 0.875, 20.0),
    ("15/16", 0.9375, 20.0),
    ("1", 1.0, 20.0),
    ("1 1/16", 1.0625, 18.0),
    ("1 1/8", 1.125, 18.0),
    ("1 3/16", 1.1875, 18.0),
    ("1 1/4", 1.25, 18.0),
    ("1 5/16", 1.3125, 18.0),
    ("1 3/8", 1.375, 18.0),
    ("1 7/16", 1.4375, 18.0),
    ("1 1/2", 1.5, 18.0),
    ("1 9/16", 1.5625, 18.0),
    ("1 5/8", 1.625, 18.0),
    ("1 11/16", 1.6875, 18.0),
];

/// B1.1's constant-pitch series (4-UN to 32-UN): threads per inch, any size.
pub const CONSTANT_PITCHES: &[f64] = &[4.0, 6.0, 8.0, 12.0, 16.0, 20.0, 28.0, 32.0];

/// B1.1's classes: 1A, 2A, 3A for the external thread, 1B, 2B, 3B for the internal.
pub const CLASSES: &[&str] = &["1A", "2A", "3A", "1B", "2B", "3B"];

/// The series marks, longest first (`UNRC` is UNC cut with the rounded root). `UNS` (`UNRS`)
/// is B1.1's special series: a size and pitch of no standard series, on the same basic
/// profile (the symbols as <http://www.gaugestools.com/fine-thread-series/> quotes them).
const SERIES: &[&str] = &[
    "UNREF", "UNRC", "UNRF", "UNRS", "UNEF", "UNC", "UNF", "UNS", "UNR", "UN",
];

/// Reads `size-tpi SERIES[-class][-LH]`. `None` when no series mark stands as a word.
pub fn read(text: &str) -> Option<Result<Designation, DesignationError>> {
    let upper = text.to_ascii_uppercase();
    let (at, series) = SERIES.iter().find_map(|mark| {
        upper.match_indices(mark).find_map(|(at, _)| {
            let before = upper[..at].chars().next_back();
            let after = upper[at + mark.len()..].chars().next();
            let edge = |c: Option<char>| c.is_none_or(|c| c == '-' || c.is_whitespace());
            (before.is_some() && edge(before) && edge(after)).then_some((at, *mark))
        })
    })?;
    let head = text[..at].trim().trim_end_matches('-').trim();
    let tail = &upper[at + series.len()..];
    Some(read_parts(head, series, tail).map_err(|why| refuse(text, why)))
}

/// The size and threads per inch before the series mark, the class and hand after it.
fn read_parts(head: &str, series: &str, tail: &str) -> Result<Designation, String> {
    let words: String = tail
        .split(|c: char| c == '-' || c.is_whitespace())
        .filter(|w| !w.is_empty())
        .collect();
    let (rest, left) = left_hand(&words)?;
    let class = match rest {
        "" => None,
        c if CLASSES.contains(&c) => Some(c.to_string()),
        c => {
            return Err(format!(
                "`{c}` is not a class of ASME B1.1, which has {}",
                CLASSES.join(", ")
            ))
        }
    };
    let Some((size, tpi)) = head.rsplit_once('-') else {
        return Err("write size-threads per inch, as in `1/4-20 UNC-2A`".into());
    };
    let tpi = number(tpi, "threads per inch")?;
    let size = size.trim().replace('-', " ");
    let table = match series {
        "UNC" | "UNRC" => Some(UNC),
        "UNF" | "UNRF" => Some(UNF),
        "UNEF" | "UNREF" => Some(UNEF),
        _ => None,
    };
    let (name, form) = match table {
        Some(table) => {
            let row = lookup(table, &size, tpi, series)?;
            (row.0.to_string(), Unified::new(row.1)?)
        }
        None if series == "UNS" || series == "UNRS" => {
            let (name, inches) = special_size(&size)?;
            (name, Unified::new(inches)?)
        }
        None => {
            if !CONSTANT_PITCHES.contains(&tpi) {
                return Err(format!(
                    "B1.1's constant-pitch series has {} threads per inch, not {tpi}",
                    CONSTANT_PITCHES
                        .iter()
                        .map(f64::to_string)
                        .collect::<Vec<_>>()
                        .join(", ")
                ));
            }
            (size.clone(), Unified::new(size_inches(&size)?)?)
        }
    };
    let pitch = MM_PER_INCH / tpi;
    // A size and pitch no table fixes (UN, UNS) may be no thread at all: the form says why
    // (the thread deeper than the major radius), for the screw or, class B, the nut.
    let internal = class.as_deref().is_some_and(|c| c.ends_with('B'));
    let section = if internal {
        form.metric.internal_pieces(pitch)
    } else {
        form.metric.pieces(pitch)
    };
    section.map_err(|e| format!("{name} in at {tpi} threads per inch is not a thread: {e}"))?;
    Ok(Designation {
        row: format!("ASME B1.1-2019, {series}: {name} in, {tpi} threads per inch"),
        form: StandardProfile::Unified(form),
        lead: Some(pitch),
        starts: Some(1),
        left_hand: left,
        class,
    })
}

/// The name and basic major diameter (in) of a special-series size: a size in inches, or one
/// of B1.1's number sizes (`#10`, with the diameter its tables give). A bare whole number that
/// is both (`10`: #10 or 10 in) is refused: no table's pitch tells them apart here.
fn special_size(size: &str) -> Result<(String, f64), String> {
    let numbered = |n: &str| {
        let name = format!("#{n}");
        UNF.iter().chain(UNC).find(|row| row.0 == name).copied()
    };
    if let Some(n) = size.strip_prefix('#') {
        return numbered(n)
            .map(|row| (row.0.to_string(), row.1))
            .ok_or_else(|| {
                // UNF has every number size, #0 to #12.
                let sizes: Vec<&str> = UNF
                    .iter()
                    .map(|row| row.0)
                    .filter(|n| n.starts_with('#'))
                    .collect();
                format!(
                    "ASME B1.1 has no number size #{n}; its number sizes are {}",
                    sizes.join(", ")
                )
            });
    }
    let inches = size_inches(size);
    match (numbered(size), inches) {
        (Some(row), Ok(inches)) => Err(format!(
            "`{size}` is both B1.1's number size {} ({} in) and {inches} in: write `{}` or \
             `{inches:.3}`",
            row.0, row.1, row.0
        )),
        (Some(row), Err(_)) => Ok((row.0.to_string(), row.1)),
        (None, inches) => Ok((size.to_string(), inches?)),
    }
}

/// The row of `table` for `size` at `tpi`: a number size (`#10`, or `10` where the table
/// has no 10 in size at that pitch) or a size in inches.
fn lookup(table: &[Row], size: &str, tpi: f64, series: &str) -> Result<Row, String> {
    let numbered = format!("#{}", size.trim_start_matches('#'));
    let inches = if size.starts_with('#') {
        None
    } else {
        Some(size_inches(size)?)
    };
    let rows: Vec<&Row> = table
        .iter()
        .filter(|(name, d, _)| {
            *name == numbered
                || inches.is_some_and(|i| !name.starts_with('#') && (d - i).abs() < 1e-9)
        })
        .collect();
    match rows.iter().find(|row| row.2 == tpi) {
        Some(row) => Ok(**row),
        None if rows.is_empty() => Err(format!(
            "ASME B1.1's {series} series has no size {size}; its sizes run {} to {} in",
            table[0].0,
            table[table.len() - 1].0
        )),
        None => Err(format!(
            "ASME B1.1's {series} series gives size {size} {} threads per inch, not {tpi}",
            rows.iter()
                .map(|row| row.2.to_string())
                .collect::<Vec<_>>()
                .join(" or ")
        )),
    }
}

#[cfg(test)]
mod tests;
