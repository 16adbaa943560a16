//! A program's provenance: what it was planned from, so that a program whose job or machine
//! profile has changed since, or that was planned for another machine, is refused before it
//! is sent (`whirl stream`, docs/streaming.md#provenance).
//!
//! `whirl plan` writes it as comments at the top of the program, one `key=value` a line
//! after the words `whirl provenance:` ([`Provenance::fields`]); the G-code post puts them
//! in its dialect's comments (`crate::post::gcode::header`), and the Modbus and CANopen
//! paths read the same G-code file. What is hashed: the job file's bytes, the profile
//! points file's bytes if the job names one, and the machine profile file's bytes, each
//! alone, with SHA-256 ([`sha256_hex`], the hash the run records keep of the same files).
//! The program's own text is not hashed into it (it could not be: its header would change
//! its hash); the run records keep the hash of the program as sent.
//!
//! Nothing here reads a file: the caller hands the bytes and paths in, and compares.

use serde::Serialize;
use sha2::{Digest, Sha256};
use thiserror::Error;

/// The words every provenance comment starts with.
pub const MARK: &str = "whirl provenance:";

/// A file a program was planned from.
#[derive(Debug, Clone, PartialEq, Eq, Serialize)]
pub struct Source {
    /// Where it was: in a header, relative to the program's folder; for a program planned
    /// and run at once, as the run found it (the command line: from its working directory);
    /// for a built-in machine profile, [`BUILT_IN`] and its repository path.
    pub path: String,
    /// SHA-256 of its bytes, 64 lower-case hex digits.
    pub sha256: String,
}

impl Source {
    /// The file at `path` whose bytes are `bytes`.
    pub fn of(path: impl Into<String>, bytes: &[u8]) -> Source {
        Source {
            path: path.into(),
            sha256: sha256_hex(bytes),
        }
    }
}

/// How a built-in machine profile's path begins (`built-in:machine-profiles/sim.toml`).
pub const BUILT_IN: &str = "built-in:";

/// What a program was planned from, and at what.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Provenance {
    /// The whirl that planned it (`CARGO_PKG_VERSION`).
    pub version: String,
    /// The job file.
    pub job: Source,
    /// The profile points file the job names, if it names one.
    pub points: Option<Source>,
    /// The machine profile's name.
    pub machine_name: String,
    /// The machine profile file.
    pub machine: Source,
    /// The allowable error Δ, mm.
    pub delta_mm: f64,
    /// The installation angle planned at, degrees (the job's, or the window's choice).
    pub installation_angle_deg: f64,
    /// The axial feed planned at, mm per workpiece revolution.
    pub axial_feed_mm: f64,
    /// Planned with `whirl plan --fastest` (a job that says `axial_feed = "auto"` searches
    /// the fastest feed by itself): planning again needs the flag again.
    pub fastest: bool,
}

/// The keys of a provenance header, in the order they are written.
const KEYS: [&str; 12] = [
    "version",
    "job",
    "job-sha256",
    "points",
    "points-sha256",
    "machine",
    "machine-file",
    "machine-sha256",
    "delta-mm",
    "installation-angle-deg",
    "axial-feed-mm-per-rev",
    "fastest",
];

/// Why a provenance header could not be read: each names the program line (1-based).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ProvenanceError {
    /// A provenance comment that is not `key=value`.
    #[error("line {line}: \"{text}\" is not key=value")]
    NotKeyValue {
        /// The program line.
        line: usize,
        /// The comment after [`MARK`].
        text: String,
    },
    /// A key this whirl does not write.
    #[error("line {line}: unknown provenance key \"{key}\"")]
    UnknownKey {
        /// The program line.
        line: usize,
        /// The key.
        key: String,
    },
    /// A key given twice.
    #[error("line {line}: provenance key \"{key}\" given again")]
    Repeated {
        /// The program line.
        line: usize,
        /// The key.
        key: String,
    },
    /// A key that must be there is not.
    #[error("the provenance header has no \"{0}\"")]
    Missing(&'static str),
    /// A value that does not read as its key says.
    #[error("line {line}: {key}={value}: {why}")]
    BadValue {
        /// The program line.
        line: usize,
        /// The key.
        key: String,
        /// The value as written.
        value: String,
        /// What is wrong.
        why: &'static str,
    },
}

impl Provenance {
    /// The header's comments, each `whirl provenance: key=value`, in the order of its keys.
    /// Paths and the machine's name are written with every byte outside `A-Z a-z 0-9`, the
    /// space and `. _ - / : + @` as `%XX`, so that no controller's comment rules change them (grbl's
    /// real-time characters, parentheses, LinuxCNC's active comments, non-ASCII).
    pub fn fields(&self) -> Vec<String> {
        let mut fields = vec![
            ("version", encode(&self.version)),
            ("job", encode(&self.job.path)),
            ("job-sha256", self.job.sha256.clone()),
        ];
        if let Some(points) = &self.points {
            fields.push(("points", encode(&points.path)));
            fields.push(("points-sha256", points.sha256.clone()));
        }
        fields.extend([
            ("machine", encode(&self.machine_name)),
            ("machine-file", encode(&self.machine.path)),
            ("machine-sha256", self.machine.sha256.clone()),
            ("delta-mm", self.delta_mm.to_string()),
            (
                "installation-angle-deg",
                self.installation_angle_deg.to_string(),
            ),
            ("axial-feed-mm-per-rev", self.axial_feed_mm.to_string()),
            ("fastest", self.fastest.to_string()),
        ]);
        fields
            .into_iter()
            .map(|(key, value)| format!("{MARK} {key}={value}"))
            .collect()
    }

    /// The provenance the comments `texts` give, each with its program line, each text the
    /// comment's inside that starts with [`MARK`]. Refused, naming the line: a comment that
    /// is not `key=value`, an unknown or repeated key, a missing one, a hash that is not 64
    /// hex digits, a number that does not read, a path whose `%XX` does not decode.
    pub fn from_fields<'a>(
        texts: impl IntoIterator<Item = (usize, &'a str)>,
    ) -> Result<Provenance, ProvenanceError> {
        let mut values: [Option<(usize, String)>; KEYS.len()] = Default::default();
        for (line, text) in texts {
            let text = text.trim_start();
            let rest = text.strip_prefix(MARK).unwrap_or(text).trim_start();
            let Some((key, value)) = rest.split_once('=') else {
                return Err(ProvenanceError::NotKeyValue {
                    line,
                    text: rest.to_owned(),
                });
            };
            // The value as written: a name or a path may end in a space.
            let key = key.trim();
            let Some(slot) = KEYS.iter().position(|k| *k == key) else {
                return Err(ProvenanceError::UnknownKey {
                    line,
                    key: key.to_owned(),
                });
            };
            if values[slot].is_some() {
                return Err(ProvenanceError::Repeated {
                    line,
                    key: key.to_owned(),
                });
            }
            values[slot] = Some((line, value.to_owned()));
        }
        let mut fields = Fields(values);
        let job = Source {
            path: fields.text("job")?,
            sha256: fields.hash("job-sha256")?,
        };
        let points = match (fields.take("points"), fields.take("points-sha256")) {
            (None, None) => None,
            (Some(_), None) => return Err(ProvenanceError::Missing("points-sha256")),
            (None, Some(_)) => return Err(ProvenanceError::Missing("points")),
            (Some(path), Some(hash)) => Some(Source {
                path: decode("points", path)?,
                sha256: check_hash("points-sha256", hash)?,
            }),
        };
        Ok(Provenance {
            version: fields.text("version")?,
            job,
            points,
            machine_name: fields.text("machine")?,
            machine: Source {
                path: fields.text("machine-file")?,
                sha256: fields.hash("machine-sha256")?,
            },
            delta_mm: fields.number("delta-mm")?,
            installation_angle_deg: fields.number("installation-angle-deg")?,
            axial_feed_mm: fields.number("axial-feed-mm-per-rev")?,
            fastest: match fields.required("fastest")? {
                (_, v) if v == "true" => true,
                (_, v) if v == "false" => false,
                (line, value) => {
                    return Err(ProvenanceError::BadValue {
                        line,
                        key: "fastest".into(),
                        value,
                        why: "must be true or false",
                    })
                }
            },
        })
    }
}

/// The values of a header, by [`KEYS`]' slot, each with its line.
struct Fields([Option<(usize, String)>; KEYS.len()]);

impl Fields {
    fn take(&mut self, key: &'static str) -> Option<(usize, String)> {
        let slot = KEYS.iter().position(|k| *k == key).expect("a known key");
        self.0[slot].take()
    }

    fn required(&mut self, key: &'static str) -> Result<(usize, String), ProvenanceError> {
        self.take(key).ok_or(ProvenanceError::Missing(key))
    }

    fn text(&mut self, key: &'static str) -> Result<String, ProvenanceError> {
        decode(key, self.required(key)?)
    }

    fn hash(&mut self, key: &'static str) -> Result<String, ProvenanceError> {
        check_hash(key, self.required(key)?)
    }

    fn number(&mut self, key: &'static str) -> Result<f64, ProvenanceError> {
        let (line, value) = self.required(key)?;
        match value.parse::<f64>() {
            Ok(number) if number.is_finite() => Ok(number),
            _ => Err(ProvenanceError::BadValue {
                line,
                key: key.into(),
                value,
                why: "not a finite number",
            }),
        }
    }
}

/// A SHA-256 as the header holds it: 64 lower-case hex digits.
fn check_hash(key: &str, (line, value): (usize, String)) -> Result<String, ProvenanceError> {
    let hex = value
        .chars()
        .all(|c| c.is_ascii_digit() || ('a'..='f').contains(&c));
    if value.len() == 64 && hex {
        Ok(value)
    } else {
        Err(ProvenanceError::BadValue {
            line,
            key: key.into(),
            value,
            why: "a SHA-256 is 64 lower-case hex digits",
        })
    }
}

/// Whether `byte` is written as it is in a header's path or name.
fn plain(byte: u8) -> bool {
    byte.is_ascii_alphanumeric() || b" ._-/:+@".contains(&byte)
}

/// `text` with every byte that is not [`plain`] as `%XX`.
fn encode(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for &byte in text.as_bytes() {
        if plain(byte) {
            out.push(char::from(byte));
        } else {
            out.push_str(&format!("%{byte:02X}"));
        }
    }
    out
}

/// The text `%XX`-encoded in `value`.
fn decode(key: &str, (line, value): (usize, String)) -> Result<String, ProvenanceError> {
    let bad = |why| ProvenanceError::BadValue {
        line,
        key: key.into(),
        value: value.clone(),
        why,
    };
    let bytes = value.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        match bytes[i] {
            b'%' => {
                let byte = bytes
                    .get(i + 1..i + 3)
                    .and_then(|h| std::str::from_utf8(h).ok())
                    .and_then(|h| u8::from_str_radix(h, 16).ok())
                    .ok_or_else(|| bad("a % is not followed by two hex digits"))?;
                out.push(byte);
                i += 3;
            }
            byte if plain(byte) => {
                out.push(byte);
                i += 1;
            }
            _ => return Err(bad("a character whirl writes as %XX is written as it is")),
        }
    }
    String::from_utf8(out).map_err(|_| bad("its %XX bytes are not UTF-8"))
}

/// The profile file the job text `job` names: its points (`[groove.profile] points`) or its
/// drawing (`dxf`), which a program is planned from as much as from the job, as it names it
/// (relative to the job's folder); `None` if it names none or is not TOML.
pub fn points_named(job: &str) -> Option<String> {
    let table: toml::Table = toml::from_str(job).ok()?;
    let profile = table.get("groove")?.get("profile")?;
    let file = profile.get("points").or_else(|| profile.get("dxf"))?;
    file.as_str().map(str::to_owned)
}

/// SHA-256 of `bytes`, lower-case hex: the one hash of the files a program is planned from
/// and a run reads (the run records keep the same, `crate::records`).
pub fn sha256_hex(bytes: &[u8]) -> String {
    hex(&Sha256::digest(bytes))
}

/// `bytes` as lower-case hex.
pub fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Provenance {
        Provenance {
            version: "0.1.0".into(),
            job: Source::of("../jobs/a (copy)/job?.toml", b"job"),
            points: Some(Source::of("profile.csv", b"points")),
            machine_name: "Lathe 2, bay 3".into(),
            machine: Source::of("built-in:machine-profiles/sim.toml", b"machine"),
            delta_mm: 0.005,
            installation_angle_deg: 17.07,
            axial_feed_mm: 0.1,
            fastest: false,
        }
    }

    fn lines(fields: &[String]) -> Vec<(usize, &str)> {
        fields
            .iter()
            .enumerate()
            .map(|(i, f)| (i + 1, f.as_str()))
            .collect()
    }

    #[test]
    fn a_header_reads_back_as_written() {
        let p = sample();
        let fields = p.fields();
        assert_eq!(fields.len(), KEYS.len());
        assert!(fields.iter().all(|f| f.starts_with(MARK)));
        // Nothing a controller would change or act on inside a comment.
        for f in &fields {
            assert!(
                f.bytes().all(|b| b.is_ascii_graphic() || b == b' ')
                    && !f.contains(['(', ')', '?', '!', '~', ',']),
                "{f}"
            );
        }
        assert!(fields.contains(&format!("{MARK} job=../jobs/a %28copy%29/job%3F.toml")));
        assert_eq!(Provenance::from_fields(lines(&fields)), Ok(p.clone()));
        let without_points = Provenance { points: None, ..p };
        let fields = without_points.fields();
        assert_eq!(Provenance::from_fields(lines(&fields)), Ok(without_points));
    }

    #[test]
    fn a_mangled_header_is_refused_naming_its_line() {
        let fields = sample().fields();
        let with = |i: usize, text: &str| {
            let mut f = fields.clone();
            f[i] = text.to_owned();
            Provenance::from_fields(lines(&f)).unwrap_err()
        };
        let short = format!("{MARK} job-sha256={}", "ab".repeat(31));
        assert_eq!(
            with(2, &short),
            ProvenanceError::BadValue {
                line: 3,
                key: "job-sha256".into(),
                value: "ab".repeat(31),
                why: "a SHA-256 is 64 lower-case hex digits",
            }
        );
        let upper = format!("{MARK} job-sha256={}", "AB".repeat(32));
        assert!(matches!(with(2, &upper), ProvenanceError::BadValue { .. }));
        assert_eq!(
            with(0, &format!("{MARK} version")),
            ProvenanceError::NotKeyValue {
                line: 1,
                text: "version".into()
            }
        );
        assert_eq!(
            with(0, &format!("{MARK} colour=red")),
            ProvenanceError::UnknownKey {
                line: 1,
                key: "colour".into()
            }
        );
        assert_eq!(
            with(0, &fields[1]),
            ProvenanceError::Repeated {
                line: 2,
                key: "job".into()
            }
        );
        assert!(matches!(
            with(8, &format!("{MARK} delta-mm=NaN")),
            ProvenanceError::BadValue { line: 9, .. }
        ));
        assert!(matches!(
            with(1, &format!("{MARK} job=a%2")),
            ProvenanceError::BadValue { line: 2, .. }
        ));
        let mut missing = fields.clone();
        missing.remove(7);
        assert_eq!(
            Provenance::from_fields(lines(&missing)),
            Err(ProvenanceError::Missing("machine-sha256"))
        );
        let mut half = fields;
        half.remove(4);
        assert_eq!(
            Provenance::from_fields(lines(&half)),
            Err(ProvenanceError::Missing("points-sha256"))
        );
    }

    #[test]
    fn a_jobs_drawing_is_its_profile_file_as_points_are() {
        let job = |key: &str| format!("[groove.profile]\n{key} = \"groove.file\"\n");
        assert_eq!(points_named(&job("points")).as_deref(), Some("groove.file"));
        assert_eq!(points_named(&job("dxf")).as_deref(), Some("groove.file"));
        assert_eq!(points_named(&job("standard")), None);
    }

    #[test]
    fn hashes_are_sha_256_of_the_bytes() {
        // FIPS 180-2's test vector "abc".
        assert_eq!(
            sha256_hex(b"abc"),
            "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad"
        );
    }
}
