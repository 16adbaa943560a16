//! A drive's electronic data sheet (EDS, CiA 306): which objects its dictionary has, of
//! which data type and access, and whether they may be mapped into PDOs; and the check
//! that the objects a CANopen master uses on the drive are there as it uses them.
//!
//! This is how a real drive is commissioned: its maker ships an EDS, and a master that
//! writes an object the drive lacks, or maps a read-only one into an RPDO, learns it from
//! an SDO abort halfway through the configuration, or not at all (a drive that ignores a
//! mapped value). Checked against the EDS, the same mistake is refused before the first
//! frame, naming the file, the object and what differs.
//!
//! An EDS is an INI file. This module reads it itself (about a hundred lines) rather than
//! through an INI crate: the crates at hand (rust-ini, configparser) give no line numbers
//! for the sections and keys they return, and a refusal here names the line to fix; CiA
//! 306's syntax is the plain subset (`[section]`, `key=value`, `;` comments, names
//! case-insensitive) that needs no more.
//!
//! What is read, per CiA 306:
//!
//! - an object is a section named by its index in hex (`[6040]`), a sub-index of an ARRAY
//!   or RECORD one named `[IIIIsubS]` with the sub-index in hex (`[1A00sub1]`);
//! - `ObjectType`: 7 VAR (the default), 8 ARRAY, 9 RECORD (CiA 301's object codes);
//! - `DataType`: CiA 301's data type index (table 44: 0x0007 UNSIGNED32 …);
//! - `AccessType`: `ro`, `wo`, `rw`, `rwr` (read/write, a process input: TPDO-mappable),
//!   `rww` (read/write, a process output: RPDO-mappable) or `const`;
//! - `PDOMapping`: 1 if the object may be mapped into a PDO, 0 (the default) if not;
//! - `ParameterName`, named in errors.
//!
//! Numbers are decimal, hexadecimal with `0x`, or octal with a leading `0`, as CiA 306
//! writes them. Every object section is checked when the file is read; other sections
//! (`[FileInfo]`, `[DeviceInfo]`, …) only for their syntax. Objects given in compact form
//! (`CompactSubObj`) are not expanded: an object the master uses must have a section of
//! its own.

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

use thiserror::Error;

/// A CiA 301 data type, by its index in the object dictionary (CiA 301, table 44).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct DataType(pub u16);

impl DataType {
    /// 0001h BOOLEAN.
    pub const BOOLEAN: DataType = DataType(0x0001);
    /// 0002h INTEGER8.
    pub const INTEGER8: DataType = DataType(0x0002);
    /// 0003h INTEGER16.
    pub const INTEGER16: DataType = DataType(0x0003);
    /// 0004h INTEGER32.
    pub const INTEGER32: DataType = DataType(0x0004);
    /// 0005h UNSIGNED8.
    pub const UNSIGNED8: DataType = DataType(0x0005);
    /// 0006h UNSIGNED16.
    pub const UNSIGNED16: DataType = DataType(0x0006);
    /// 0007h UNSIGNED32.
    pub const UNSIGNED32: DataType = DataType(0x0007);

    /// CiA 301's name for the type; `None` for an index table 44 does not name.
    pub fn name(self) -> Option<&'static str> {
        Some(match self.0 {
            0x0001 => "BOOLEAN",
            0x0002 => "INTEGER8",
            0x0003 => "INTEGER16",
            0x0004 => "INTEGER32",
            0x0005 => "UNSIGNED8",
            0x0006 => "UNSIGNED16",
            0x0007 => "UNSIGNED32",
            0x0008 => "REAL32",
            0x0009 => "VISIBLE_STRING",
            0x000A => "OCTET_STRING",
            0x000B => "UNICODE_STRING",
            0x000C => "TIME_OF_DAY",
            0x000D => "TIME_DIFFERENCE",
            0x000F => "DOMAIN",
            0x0010 => "INTEGER24",
            0x0011 => "REAL64",
            0x0012 => "INTEGER40",
            0x0013 => "INTEGER48",
            0x0014 => "INTEGER56",
            0x0015 => "INTEGER64",
            0x0016 => "UNSIGNED24",
            0x0018 => "UNSIGNED40",
            0x0019 => "UNSIGNED48",
            0x001A => "UNSIGNED56",
            0x001B => "UNSIGNED64",
            _ => return None,
        })
    }

    /// The width of a value, bits, for the fixed-width integer types; `None` otherwise.
    pub fn bits(self) -> Option<u8> {
        Some(match self {
            DataType::INTEGER8 | DataType::UNSIGNED8 => 8,
            DataType::INTEGER16 | DataType::UNSIGNED16 => 16,
            DataType::INTEGER32 | DataType::UNSIGNED32 => 32,
            _ => return None,
        })
    }
}

impl fmt::Display for DataType {
    /// `UNSIGNED32 (0x0007)`, or the bare index for one CiA 301 does not name.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.name() {
            Some(name) => write!(f, "{name} (0x{:04X})", self.0),
            None => write!(f, "0x{:04X}", self.0),
        }
    }
}

/// An object's `AccessType` (CiA 306).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Access {
    /// `ro`: read only.
    ReadOnly,
    /// `wo`: write only.
    WriteOnly,
    /// `rw`: read and write.
    ReadWrite,
    /// `rwr`: read and write, reading a process input (mappable into a TPDO).
    ReadWriteInput,
    /// `rww`: read and write, writing a process output (mappable into an RPDO).
    ReadWriteOutput,
    /// `const`: read only, never changing.
    Const,
}

impl Access {
    /// The words, as an EDS spells them.
    pub const WORDS: [&'static str; 6] = ["ro", "wo", "rw", "rwr", "rww", "const"];

    /// The access a word names, in any case (`RW` as `rw`).
    pub fn parse(word: &str) -> Option<Access> {
        Some(match word.to_ascii_lowercase().as_str() {
            "ro" => Access::ReadOnly,
            "wo" => Access::WriteOnly,
            "rw" => Access::ReadWrite,
            "rwr" => Access::ReadWriteInput,
            "rww" => Access::ReadWriteOutput,
            "const" => Access::Const,
            _ => return None,
        })
    }

    /// The word.
    pub fn word(self) -> &'static str {
        match self {
            Access::ReadOnly => "ro",
            Access::WriteOnly => "wo",
            Access::ReadWrite => "rw",
            Access::ReadWriteInput => "rwr",
            Access::ReadWriteOutput => "rww",
            Access::Const => "const",
        }
    }

    /// Whether an SDO upload may read it.
    pub fn readable(self) -> bool {
        self != Access::WriteOnly
    }

    /// Whether an SDO download may write it.
    pub fn writable(self) -> bool {
        !matches!(self, Access::ReadOnly | Access::Const)
    }

    /// Whether a use may have it: readable for a read, writable for a write; for an RPDO
    /// writable and no process input (`rwr`), for a TPDO readable and no process output
    /// (`rww`).
    fn allows(self, how: Use) -> bool {
        match how {
            Use::SdoRead => self.readable(),
            Use::SdoWrite => self.writable(),
            Use::Rpdo(_) => self.writable() && self != Access::ReadWriteInput,
            Use::Tpdo(_) => self.readable() && self != Access::ReadWriteOutput,
        }
    }

    /// The words [`Access::allows`] takes for `how`.
    fn allowed_words(how: Use) -> String {
        let all = [
            Access::ReadOnly,
            Access::WriteOnly,
            Access::ReadWrite,
            Access::ReadWriteInput,
            Access::ReadWriteOutput,
            Access::Const,
        ];
        let words: Vec<_> = all
            .into_iter()
            .filter(|a| a.allows(how))
            .map(Access::word)
            .collect();
        match words.split_last() {
            Some((last, rest)) if !rest.is_empty() => format!("{} or {last}", rest.join(", ")),
            _ => words.join(""),
        }
    }
}

/// How a master uses an object of the drive.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Use {
    /// Read by SDO upload.
    SdoRead,
    /// Written by SDO download.
    SdoWrite,
    /// Mapped into this RPDO (1–512): the master writes it every time it sends the PDO.
    Rpdo(u16),
    /// Mapped into this TPDO (1–512): the drive sends it.
    Tpdo(u16),
}

impl fmt::Display for Use {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Use::SdoRead => write!(f, "reads it by SDO"),
            Use::SdoWrite => write!(f, "writes it by SDO"),
            Use::Rpdo(n) => write!(f, "maps it into RPDO{n} (written by the master)"),
            Use::Tpdo(n) => write!(f, "maps it into TPDO{n} (sent by the drive)"),
        }
    }
}

/// An object a master uses on a drive: where, what it is (CiA 301/402's name and type)
/// and how it is used.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectUse {
    /// Object index.
    pub index: u16,
    /// Sub-index.
    pub sub: u8,
    /// The object's name in CiA 301 or 402 (`target position`).
    pub name: String,
    /// The type the master reads or writes it as.
    pub data_type: DataType,
    /// What the master does with it.
    pub how: Use,
}

/// One object of an EDS, as its section says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EdsObject {
    /// `ParameterName` (empty if absent).
    pub name: String,
    /// `ObjectType`: 7 VAR, 8 ARRAY, 9 RECORD, …
    pub object_type: u8,
    /// `DataType`; every VAR has one.
    pub data_type: Option<DataType>,
    /// `AccessType`; every VAR has one.
    pub access: Option<Access>,
    /// `PDOMapping`.
    pub pdo_mapping: bool,
    /// A non-zero `CompactSubObj`: sub-indices without sections of their own.
    pub compact: bool,
    /// The line of the section's header.
    pub line: usize,
}

/// CiA 301's object code of a VAR.
const VAR: u8 = 0x7;

/// A drive's EDS, read and checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Eds {
    path: PathBuf,
    /// Objects by (index, sub-index); `None` is the index's own section.
    objects: BTreeMap<(u16, Option<u8>), EdsObject>,
}

/// Why an EDS could not be read.
#[derive(Debug, Error)]
pub enum EdsError {
    /// The file could not be read.
    #[error("cannot read EDS file {}: {error}", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// The I/O error.
        error: std::io::Error,
    },
    /// A line that is not CiA 306's syntax, or a value that is not what its key takes.
    #[error("EDS file {}, line {line}: {problem}", path.display())]
    Syntax {
        /// The file.
        path: PathBuf,
        /// The line, from 1.
        line: usize,
        /// What is wrong.
        problem: String,
    },
}

/// One way an EDS does not fit an object's use.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mismatch {
    /// The object, as the master uses it.
    pub object: ObjectUse,
    /// What the use needs (`AccessType ro, rw, rwr or const`).
    pub needs: String,
    /// What the EDS says instead (`AccessType=wo`).
    pub found: String,
    /// The line the EDS says it on; `None` where the object has no section.
    pub line: Option<usize>,
}

impl fmt::Display for Mismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let o = &self.object;
        write!(
            f,
            "{:04X}h:{:02X} {}: whirl {}, which needs {}; the EDS says {}",
            o.index, o.sub, o.name, o.how, self.needs, self.found
        )?;
        match self.line {
            Some(line) => write!(f, " (line {line})"),
            None => Ok(()),
        }
    }
}

/// The objects of an EDS that do not fit how a master uses them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct EdsMismatch {
    /// The EDS file.
    pub path: PathBuf,
    /// Every misfit, in the order of the uses.
    pub mismatches: Vec<Mismatch>,
}

impl fmt::Display for EdsMismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "EDS file {} does not fit:", self.path.display())?;
        for mismatch in &self.mismatches {
            write!(f, "\n  - {mismatch}")?;
        }
        Ok(())
    }
}

impl std::error::Error for EdsMismatch {}

impl Eds {
    /// Reads and checks the EDS at `path`.
    pub fn load(path: &Path) -> Result<Eds, EdsError> {
        let bytes = std::fs::read(path).map_err(|error| EdsError::Read {
            path: path.to_owned(),
            error,
        })?;
        // CiA 306 files are ASCII; a maker's name in Latin-1 is no reason to refuse one.
        Eds::parse(&String::from_utf8_lossy(&bytes), path)
    }

    /// Reads and checks an EDS's text; `path` names it in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Eds, EdsError> {
        let syntax = |line: usize, problem: String| EdsError::Syntax {
            path: path.to_owned(),
            line,
            problem,
        };
        let mut objects = BTreeMap::new();
        for section in sections(text).map_err(|(line, problem)| syntax(line, problem))? {
            if let Some(key) = object_key(&section.name) {
                let object = section.object().map_err(|(line, p)| syntax(line, p))?;
                objects.insert(key, object);
            }
        }
        Ok(Eds {
            path: path.to_owned(),
            objects,
        })
    }

    /// The file it was read from.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// The object at `index`:`sub`: its sub-index section, or for sub-index 0 a VAR's own
    /// section.
    pub fn object(&self, index: u16, sub: u8) -> Option<&EdsObject> {
        self.objects.get(&(index, Some(sub))).or_else(|| {
            self.objects
                .get(&(index, None))
                .filter(|o| sub == 0 && o.object_type == VAR)
        })
    }

    /// Checks that every object of `uses` is in the EDS with the data type it is used as,
    /// the access its use needs, and for a PDO `PDOMapping=1`; every misfit is named.
    pub fn check(&self, uses: &[ObjectUse]) -> Result<(), EdsMismatch> {
        let mut mismatches = Vec::new();
        for used in uses {
            let mut misfit = |needs: String, found: String, line| {
                mismatches.push(Mismatch {
                    object: used.clone(),
                    needs,
                    found,
                    line,
                })
            };
            let Some(object) = self.object(used.index, used.sub) else {
                let (needs, found) = self.absence(used.index, used.sub);
                misfit(needs, found, None);
                continue;
            };
            // Parsing gave every VAR (and every sub-index section) its type and access.
            let (Some(data_type), Some(access)) = (object.data_type, object.access) else {
                misfit(
                    "a DataType and an AccessType".into(),
                    "neither".into(),
                    Some(object.line),
                );
                continue;
            };
            if data_type != used.data_type {
                misfit(
                    format!("DataType {}", used.data_type),
                    format!("DataType {data_type}"),
                    Some(object.line),
                );
            }
            if !access.allows(used.how) {
                misfit(
                    format!("AccessType {}", Access::allowed_words(used.how)),
                    format!("AccessType={}", access.word()),
                    Some(object.line),
                );
            }
            if matches!(used.how, Use::Rpdo(_) | Use::Tpdo(_)) && !object.pdo_mapping {
                misfit(
                    "PDOMapping=1".into(),
                    "PDOMapping=0".into(),
                    Some(object.line),
                );
            }
        }
        if mismatches.is_empty() {
            Ok(())
        } else {
            Err(EdsMismatch {
                path: self.path.clone(),
                mismatches,
            })
        }
    }

    /// What an absent `index`:`sub` needs and what the EDS has instead.
    fn absence(&self, index: u16, sub: u8) -> (String, String) {
        let wanted = if sub == 0 {
            format!("a section [{index:04X}] or [{index:04X}sub0]")
        } else {
            format!("a section [{index:04X}sub{sub:X}]")
        };
        let found = match self.objects.get(&(index, None)) {
            None => format!("nothing of {index:04X}h"),
            Some(o) if o.compact => format!(
                "[{index:04X}] in compact form (CompactSubObj, line {}), which whirl does not \
                 expand",
                o.line
            ),
            Some(o) => format!("[{index:04X}] (line {}) without sub-index {sub}", o.line),
        };
        (wanted, found)
    }
}

/// A section of the file: its name, the line of its header, its keys (lower case) with
/// their values and lines.
struct Section {
    name: String,
    line: usize,
    keys: BTreeMap<String, (String, usize)>,
}

/// The file's sections, in order; (line, problem) for a line that is not a section header,
/// a `key=value` or a comment, a key before any section, and a section or key given twice.
fn sections(text: &str) -> Result<Vec<Section>, (usize, String)> {
    let mut sections: Vec<Section> = Vec::new();
    let mut seen: BTreeMap<String, usize> = BTreeMap::new();
    for (number, raw) in text.lines().enumerate() {
        let line = number + 1;
        let content = raw.trim();
        if content.is_empty() || content.starts_with(';') {
            continue;
        }
        if let Some(rest) = content.strip_prefix('[') {
            let name = rest
                .strip_suffix(']')
                .map(str::trim)
                .filter(|name| !name.is_empty() && !name.contains(['[', ']']))
                .ok_or_else(|| {
                    (
                        line,
                        format!("{content:?} is not a section header ([name])"),
                    )
                })?;
            if let Some(first) = seen.insert(name.to_ascii_lowercase(), line) {
                return Err((
                    line,
                    format!("section [{name}] again (first on line {first})"),
                ));
            }
            sections.push(Section {
                name: name.to_owned(),
                line,
                keys: BTreeMap::new(),
            });
            continue;
        }
        let Some((key, value)) = content.split_once('=') else {
            return Err((
                line,
                format!("{content:?} is neither a [section], a key=value nor a ; comment"),
            ));
        };
        let key = key.trim();
        if key.is_empty() {
            return Err((line, format!("{content:?} has no key before its =")));
        }
        let Some(section) = sections.last_mut() else {
            return Err((line, format!("{key} comes before any [section]")));
        };
        let previous = section
            .keys
            .insert(key.to_ascii_lowercase(), (value.trim().to_owned(), line));
        if let Some((_, first)) = previous {
            return Err((
                line,
                format!("{key} again in [{}] (first on line {first})", section.name),
            ));
        }
    }
    Ok(sections)
}

/// (index, sub-index) of an object section's name (`6040`, `1A00sub1`, in any case);
/// `None` for any other section.
fn object_key(name: &str) -> Option<(u16, Option<u8>)> {
    let hex = |digits: &str| digits.chars().all(|c| c.is_ascii_hexdigit());
    let index = name.get(..4).filter(|d| hex(d))?;
    let index = u16::from_str_radix(index, 16).ok()?;
    let rest = &name[4..];
    if rest.is_empty() {
        return Some((index, None));
    }
    let sub = rest
        .get(..3)
        .filter(|s| s.eq_ignore_ascii_case("sub"))
        .and(rest.get(3..))
        .filter(|d| (1..=2).contains(&d.len()) && hex(d))?;
    Some((index, Some(u8::from_str_radix(sub, 16).ok()?)))
}

/// A CiA 306 number: `0x` hexadecimal, a leading `0` octal, else decimal.
fn number(text: &str) -> Option<u64> {
    let text = text.trim();
    if let Some(hex) = text.strip_prefix("0x").or_else(|| text.strip_prefix("0X")) {
        u64::from_str_radix(hex, 16).ok()
    } else if text.len() > 1 && text.starts_with('0') {
        u64::from_str_radix(&text[1..], 8).ok()
    } else {
        text.parse().ok()
    }
}

impl Section {
    /// The object this section describes; (line, problem) for a value its key does not
    /// take, or a VAR without a data type or access.
    fn object(&self) -> Result<EdsObject, (usize, String)> {
        let section = &self.name;
        let value = |key: &str| self.keys.get(&key.to_ascii_lowercase());
        let numeric = |key: &str, max: u64, what: &str| -> Result<Option<u64>, (usize, String)> {
            match value(key) {
                None => Ok(None),
                Some((text, line)) => match number(text).filter(|&n| n <= max) {
                    Some(n) => Ok(Some(n)),
                    None => Err((*line, format!("[{section}] {key}={text} must be {what}"))),
                },
            }
        };
        let object_type = numeric(
            "ObjectType",
            0xFF,
            "an object code (7 VAR, 8 ARRAY, 9 RECORD)",
        )?
        .map_or(VAR, |n| n as u8);
        let data_type = numeric("DataType", 0xFFFF, "a data type index (0x0007 UNSIGNED32)")?
            .map(|n| DataType(n as u16));
        let pdo_mapping = numeric("PDOMapping", 1, "0 or 1")? == Some(1);
        let compact = numeric("CompactSubObj", 0xFE, "a number of sub-indices, 0 to 254")?
            .is_some_and(|n| n > 0);
        let access = match value("AccessType") {
            None => None,
            Some((text, line)) => Some(Access::parse(text).ok_or_else(|| {
                (
                    *line,
                    format!(
                        "[{section}] AccessType={text} must be one of {}",
                        Access::WORDS.join(", ")
                    ),
                )
            })?),
        };
        let is_sub = section.len() > 4;
        if (is_sub || object_type == VAR) && !compact {
            for (key, present) in [
                ("DataType", data_type.is_some()),
                ("AccessType", access.is_some()),
            ] {
                if !present {
                    return Err((
                        self.line,
                        format!("[{section}] has no {key}, which every variable needs"),
                    ));
                }
            }
        }
        Ok(EdsObject {
            name: value("ParameterName").map_or_else(String::new, |(v, _)| v.clone()),
            object_type,
            data_type,
            access,
            pdo_mapping,
            compact,
            line: self.line,
        })
    }
}

#[cfg(test)]
mod tests;
