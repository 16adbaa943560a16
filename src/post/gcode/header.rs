//! The provenance header: [`Provenance::fields`] as comments at the top of a written
//! program, and read back from a program's text.
//!
//! The header is the program's first lines: after LinuxCNC's opening `%`, before the
//! preamble (`G21 G90 …`). Each field is one comment, `(whirl provenance: key=value)`, on a
//! line of its own; on grblHAL numbered like every line, the program's own lines numbered
//! on after it (their N words are their file lines, which status reports and resumes name).
//! The fields hold only characters every dialect keeps inside a comment
//! ([`Provenance::fields`]), so they are written as they are: no grbl real-time character,
//! no parenthesis, no comma that LinuxCNC could read as an active comment. A field that
//! would make a line longer than the controller takes is refused, not split: a header must
//! read back whole.

use crate::config::machine::Dialect;
use crate::config::provenance::{Provenance, ProvenanceError, MARK};

use super::writer::PostError;

/// `text`, a program as [`super::write`] wrote it for `dialect`, with `provenance`'s header
/// at its top; every line at most `max_line_length` characters, or [`PostError::HeaderTooLong`].
pub fn stamp(
    text: &str,
    dialect: Dialect,
    max_line_length: usize,
    provenance: &Provenance,
) -> Result<String, PostError> {
    let fields = provenance.fields();
    let mut out = String::with_capacity(text.len() + fields.len() * 96);
    let mut push = |line: String| -> Result<(), PostError> {
        let length = line.chars().count();
        if length > max_line_length {
            return Err(PostError::HeaderTooLong {
                line,
                length,
                max: max_line_length,
            });
        }
        out.push_str(&line);
        out.push('\n');
        Ok(())
    };
    match dialect {
        Dialect::LinuxCnc => {
            let body = text.strip_prefix("%\n").unwrap_or(text);
            push("%".into())?;
            for field in fields {
                push(format!("({field})"))?;
            }
            out.push_str(body);
        }
        Dialect::GrblHal => {
            let shift = fields.len();
            for (i, field) in fields.into_iter().enumerate() {
                push(format!("N{} ({field})", i + 1))?;
            }
            for (i, line) in text.lines().enumerate() {
                let block = unnumbered(line).unwrap_or(line);
                push(format!("N{} {block}", i + 1 + shift))?;
            }
        }
    }
    Ok(out)
}

/// `line` without its leading N word and the spaces after it; `None` if it has none.
fn unnumbered(line: &str) -> Option<&str> {
    let rest = line.trim_start().strip_prefix(['N', 'n'])?;
    let digits = rest.len() - rest.trim_start_matches(|c: char| c.is_ascii_digit()).len();
    (digits > 0).then(|| rest[digits..].trim_start())
}

/// The inside of `line` if the line is one comment in parentheses and nothing else (an N
/// word before it aside).
fn comment(line: &str) -> Option<&str> {
    let line = line.trim();
    let block = unnumbered(line).unwrap_or(line);
    block.strip_prefix('(')?.strip_suffix(')')
}

/// The provenance in the header of the program `text`: `None` if its first lines (those
/// before the first line that is not a comment, `%` and blank lines passed over) hold no
/// provenance comment; an error naming the line if they hold one that does not read.
pub fn read(text: &str) -> Result<Option<Provenance>, ProvenanceError> {
    let mut fields = Vec::new();
    for (i, line) in text.lines().enumerate() {
        let trimmed = line.trim();
        if trimmed.is_empty() || trimmed == "%" {
            continue;
        }
        let Some(inside) = comment(trimmed) else {
            break;
        };
        if inside.trim_start().starts_with(MARK) {
            fields.push((i + 1, inside));
        }
    }
    if fields.is_empty() {
        return Ok(None);
    }
    Provenance::from_fields(fields).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::provenance::Source;
    use crate::post::gcode::{write, PostSettings};
    use crate::program::{Move, Program};

    fn provenance() -> Provenance {
        Provenance {
            version: "0.1.0".into(),
            job: Source::of("../jobs/job (2).toml", b"job"),
            points: None,
            machine_name: "grblHAL test lathe".into(),
            machine: Source::of("lathe.toml", b"machine"),
            delta_mm: 0.005,
            installation_angle_deg: -1.5,
            axial_feed_mm: 0.1,
            fastest: true,
        }
    }

    fn settings(dialect: Dialect) -> PostSettings {
        PostSettings {
            dialect,
            linear_decimals: 3,
            angular_decimals: 3,
            x_diameter: false,
            blend_tolerance_mm: None,
            max_line_length: 256,
        }
    }

    fn program() -> Program {
        Program {
            moves: vec![
                Move::Comment("whirl test".into()),
                Move::Rapid {
                    x: Some(30.0),
                    z: None,
                    c: None,
                },
                Move::Feed {
                    x: Some(20.0),
                    z: None,
                    c: None,
                    feed: 50.0,
                },
            ],
        }
    }

    #[test]
    fn grbl_header_is_numbered_and_the_program_numbered_on_after_it() {
        let s = settings(Dialect::GrblHal);
        let plain = write(&program(), &s).unwrap();
        let stamped = stamp(&plain, Dialect::GrblHal, 256, &provenance()).unwrap();
        let n = provenance().fields().len();
        let lines: Vec<&str> = stamped.lines().collect();
        assert_eq!(lines.len(), plain.lines().count() + n);
        // Every line's N word is its file line, as grblHAL's Ln: reports name it.
        for (i, line) in lines.iter().enumerate() {
            assert!(line.starts_with(&format!("N{} ", i + 1)), "{line}");
        }
        assert_eq!(lines[0], "N1 (whirl provenance: version=0.1.0)");
        assert_eq!(
            lines[1],
            "N2 (whirl provenance: job=../jobs/job %282%29.toml)"
        );
        // The program's own blocks follow unchanged.
        let blocks = |t: &str| -> Vec<String> {
            t.lines()
                .map(|l| unnumbered(l).unwrap().to_owned())
                .collect()
        };
        assert_eq!(blocks(&stamped)[n..], blocks(&plain)[..]);
        assert_eq!(read(&stamped), Ok(Some(provenance())));
        assert_eq!(read(&plain), Ok(None));
    }

    #[test]
    fn linuxcnc_header_follows_the_percent_and_is_no_active_comment() {
        let s = settings(Dialect::LinuxCnc);
        let plain = write(&program(), &s).unwrap();
        let stamped = stamp(&plain, Dialect::LinuxCnc, 255, &provenance()).unwrap();
        let lines: Vec<&str> = stamped.lines().collect();
        assert_eq!(lines[0], "%");
        let n = provenance().fields().len();
        for line in &lines[1..=n] {
            // LinuxCNC acts on a comment that opens with a word and a comma: none here.
            assert!(line.starts_with("(whirl provenance: ") && !line.contains(','));
        }
        assert_eq!(lines[n + 1..], plain.lines().collect::<Vec<_>>()[1..]);
        assert_eq!(read(&stamped), Ok(Some(provenance())));
    }

    #[test]
    fn a_header_line_over_the_controllers_limit_is_refused() {
        let mut long = provenance();
        long.job.path = "j/".repeat(200) + "job.toml";
        let plain = write(&program(), &settings(Dialect::GrblHal)).unwrap();
        let error = stamp(&plain, Dialect::GrblHal, 256, &long).unwrap_err();
        assert!(
            matches!(error, PostError::HeaderTooLong { length, max: 256, .. } if length > 256),
            "{error}"
        );
    }

    #[test]
    fn a_mangled_header_is_an_error_naming_its_line() {
        let plain = write(&program(), &settings(Dialect::GrblHal)).unwrap();
        let stamped = stamp(&plain, Dialect::GrblHal, 256, &provenance()).unwrap();
        let wrong_length =
            stamped.replacen(&provenance().job.sha256, &provenance().job.sha256[..40], 1);
        assert!(matches!(
            read(&wrong_length),
            Err(ProvenanceError::BadValue { line: 3, .. })
        ));
        // A header with a line taken out is no header: a key is missing.
        let cut: Vec<&str> = stamped
            .lines()
            .filter(|l| !l.contains("delta-mm"))
            .collect();
        assert_eq!(
            read(&cut.join("\n")),
            Err(ProvenanceError::Missing("delta-mm"))
        );
        // Provenance comments below the first block are not the header.
        let late = "G21\n(whirl provenance: version=9)\n";
        assert_eq!(read(late), Ok(None));
    }
}
