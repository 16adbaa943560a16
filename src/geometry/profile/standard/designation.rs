//! A thread as a drawing names it: `Tr 40x7`, `Tr 40 x 14 P7 LH`, `S 48x8`, `1/4-20 UNC-2A`, `ZI m2 z1 q10`.
//!
//! Each family reads its own designations (`FAMILIES`): a family that does not recognise the
//! text says `None` and the next one is asked; one that recognises it either builds the form
//! from its standard's tables or refuses it naming what is wrong (a size the table does not
//! have, a pitch that does not belong to the size, a malformed number).

use super::{acme_series, buttress, iso2902, metric, unified, StandardError, StandardProfile};

/// What a designation fixes: the form, and the lead, starts and hand where it says them.
#[derive(Debug, Clone, PartialEq)]
pub struct Designation {
    /// The form, with every dimension the standard gives it.
    pub form: StandardProfile,
    /// Lead (mm), where the designation fixes it (`Tr 40x7`: 7 mm).
    pub lead: Option<f64>,
    /// Number of starts, where the designation fixes it (`Tr 40x14 P7`: 2).
    pub starts: Option<u32>,
    /// Left hand (`LH`); right hand otherwise.
    pub left_hand: bool,
    /// The tolerance class, where the designation gives one (`7e`, `2G`).
    pub class: Option<String>,
    /// The table row the dimensions come from (standard, edition, table, row), for
    /// `whirl profile` to show.
    pub row: String,
}

/// Why a designation is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DesignationError {
    /// No family reads this text.
    #[error(
        "`{text}` is not a designation whirl reads; it reads, for example, `Tr 40x7`, \
         `Tr 40x14 P7 LH`, `S 48x8`, `1/2-10 ACME-2G`, `1/4-20 UNC-2A`, `M20x2.5`, \
         `ZI m2 z1 q10`"
    )]
    Unknown {
        /// The text given.
        text: String,
    },
    /// A family read the text but refuses it.
    #[error("`{text}`: {why}")]
    Refused {
        /// The text given.
        text: String,
        /// What is wrong, in the standard's terms.
        why: String,
    },
    /// The form the designation names has impossible dimensions.
    #[error("`{text}`: {error}")]
    Form {
        /// The text given.
        text: String,
        /// Why the form is refused.
        error: StandardError,
    },
}

/// A family's reader: `None` when the text is not one of its designations.
type Reader = fn(&str) -> Option<Result<Designation, DesignationError>>;

/// The families asked in turn, most specific first.
const FAMILIES: &[Reader] = &[
    iso2902::read,
    buttress::read,
    acme_series::read,
    unified::read,
    metric::read,
    super::worm::read_designation,
];

impl Designation {
    /// Whether the designation names an internal thread (a nut): ISO's tolerance classes
    /// write the internal thread's tolerance position in capitals (ISO 2903: `7H`, ISO 965-1:
    /// `6H`), the external's in small letters (`7e`, `6g`); ASME B1.1's end in B for the
    /// internal thread (`2B`), A for the external (`2A`). (ASME's Acme classes, `2G`, name
    /// both; a job says which it cuts.)
    pub fn internal(&self) -> bool {
        let Some(class) = self.class.as_deref() else {
            return false;
        };
        match self.form {
            StandardProfile::IsoTrapezoidal(_) | StandardProfile::IsoMetric(_) => {
                class.chars().any(|c| c.is_ascii_uppercase())
            }
            StandardProfile::Unified(_) => class.ends_with('B'),
            _ => false,
        }
    }
}

/// Reads a designation, as a drawing writes it.
pub fn parse(text: &str) -> Result<Designation, DesignationError> {
    let text = text.trim();
    FAMILIES
        .iter()
        .find_map(|read| read(text))
        .unwrap_or_else(|| {
            Err(DesignationError::Unknown {
                text: text.to_string(),
            })
        })
}
