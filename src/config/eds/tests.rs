//! The EDS reader and the check, against CiA 301's data type indices (table 44), CiA 306's
//! syntax and access words, and the objects CiA 301 and 402 define.

use std::path::{Path, PathBuf};

use super::*;

/// The test drive's EDS (`tests/data/cia402-drive.eds`), which python-canopen reads too.
const DRIVE: &str = include_str!("../../../tests/data/cia402-drive.eds");

fn path() -> PathBuf {
    PathBuf::from("drive.eds")
}

fn parse(text: &str) -> Result<Eds, EdsError> {
    Eds::parse(text, &path())
}

/// The drive's EDS with `key` of `[section]` set to `value` (`None`: the key left out).
fn edited(section: &str, key: &str, value: Option<&str>) -> String {
    let mut inside = false;
    let mut found = false;
    let mut lines = Vec::new();
    for line in DRIVE.lines() {
        if line.starts_with('[') {
            inside = line.eq_ignore_ascii_case(&format!("[{section}]"));
        } else if inside && line.starts_with(&format!("{key}=")) {
            found = true;
            if let Some(value) = value {
                lines.push(format!("{key}={value}"));
            }
            continue;
        }
        lines.push(line.to_owned());
    }
    assert!(found, "[{section}] {key} is in the test EDS");
    lines.join("\n")
}

/// The (1-based) line of `[section]` in the drive's EDS.
fn line_of(section: &str) -> usize {
    DRIVE
        .lines()
        .position(|l| l == format!("[{section}]"))
        .expect("the section")
        + 1
}

fn var(index: u16, sub: u8, data_type: DataType, how: Use) -> ObjectUse {
    ObjectUse {
        index,
        sub,
        name: format!("object {index:04X}h"),
        data_type,
        how,
    }
}

#[test]
fn data_types_are_cia_301_table_44s_indices() {
    for (index, name, bits) in [
        (0x0001, "BOOLEAN", None),
        (0x0002, "INTEGER8", Some(8)),
        (0x0003, "INTEGER16", Some(16)),
        (0x0004, "INTEGER32", Some(32)),
        (0x0005, "UNSIGNED8", Some(8)),
        (0x0006, "UNSIGNED16", Some(16)),
        (0x0007, "UNSIGNED32", Some(32)),
        (0x0008, "REAL32", None),
        (0x0009, "VISIBLE_STRING", None),
        (0x000F, "DOMAIN", None),
        (0x0015, "INTEGER64", None),
        (0x001B, "UNSIGNED64", None),
    ] {
        let data_type = DataType(index);
        assert_eq!(data_type.name(), Some(name));
        assert_eq!(data_type.bits(), bits, "{name}");
        assert_eq!(data_type.to_string(), format!("{name} (0x{index:04X})"));
    }
    assert_eq!(DataType::UNSIGNED32, DataType(7));
    assert_eq!(DataType::INTEGER8, DataType(2));
    // 000Eh is not used in table 44; shown as its index.
    assert_eq!(DataType(0x000E).name(), None);
    assert_eq!(DataType(0x000E).to_string(), "0x000E");
}

#[test]
fn access_words_are_cia_306s_in_any_case() {
    // ro and const read only; wo write only; rw, rwr, rww both.
    let table = [
        ("ro", true, false),
        ("wo", false, true),
        ("rw", true, true),
        ("rwr", true, true),
        ("rww", true, true),
        ("const", true, false),
    ];
    for (word, readable, writable) in table {
        let access = Access::parse(word).unwrap();
        assert_eq!(access.word(), word);
        assert_eq!(Access::parse(&word.to_uppercase()), Some(access));
        assert_eq!(access.readable(), readable, "{word}");
        assert_eq!(access.writable(), writable, "{word}");
    }
    assert_eq!(Access::parse("r"), None);
    // rww writes a process output: an RPDO's, never a TPDO's; rwr reads a process input:
    // a TPDO's, never an RPDO's.
    assert!(Access::ReadWriteOutput.allows(Use::Rpdo(1)));
    assert!(!Access::ReadWriteOutput.allows(Use::Tpdo(1)));
    assert!(Access::ReadWriteInput.allows(Use::Tpdo(1)));
    assert!(!Access::ReadWriteInput.allows(Use::Rpdo(1)));
    assert_eq!(Access::allowed_words(Use::Rpdo(1)), "wo, rw or rww");
    assert_eq!(Access::allowed_words(Use::Tpdo(1)), "ro, rw, rwr or const");
    assert_eq!(Access::allowed_words(Use::SdoWrite), "wo, rw, rwr or rww");
    assert_eq!(
        Access::allowed_words(Use::SdoRead),
        "ro, rw, rwr, rww or const"
    );
}

#[test]
fn numbers_are_decimal_hexadecimal_or_octal() {
    assert_eq!(number("7"), Some(7));
    assert_eq!(number("0x0007"), Some(7));
    assert_eq!(number("0X1b"), Some(0x1B));
    assert_eq!(number("010"), Some(8));
    assert_eq!(number("0"), Some(0));
    assert_eq!(number(" 12 "), Some(12));
    assert_eq!(number("09"), None);
    assert_eq!(number("seven"), None);
}

#[test]
fn section_names_give_index_and_sub_index_in_hex() {
    assert_eq!(object_key("6040"), Some((0x6040, None)));
    assert_eq!(object_key("1A00sub1"), Some((0x1A00, Some(1))));
    assert_eq!(object_key("1a00SUBa"), Some((0x1A00, Some(10))));
    assert_eq!(object_key("1600sub1F"), Some((0x1600, Some(0x1F))));
    assert_eq!(object_key("FileInfo"), None);
    assert_eq!(object_key("1018Name"), None);
    assert_eq!(object_key("1600sub"), None);
    assert_eq!(object_key("1600sub123"), None);
    assert_eq!(object_key("60400"), None);
}

#[test]
fn the_test_drives_eds_has_cia_402s_objects() {
    let eds = parse(DRIVE).unwrap();
    assert_eq!(eds.path(), Path::new("drive.eds"));
    // A VAR is its own sub-index 0.
    let controlword = eds.object(0x6040, 0).unwrap();
    assert_eq!(controlword.name, "Controlword");
    assert_eq!(controlword.data_type, Some(DataType::UNSIGNED16));
    assert_eq!(controlword.access, Some(Access::ReadWriteOutput));
    assert!(controlword.pdo_mapping);
    assert_eq!(controlword.line, line_of("6040"));
    let statusword = eds.object(0x6041, 0).unwrap();
    assert_eq!(statusword.access, Some(Access::ReadOnly));
    assert_eq!(
        eds.object(0x607A, 0).unwrap().data_type,
        Some(DataType::INTEGER32)
    );
    assert_eq!(
        eds.object(0x6060, 0).unwrap().data_type,
        Some(DataType::INTEGER8)
    );
    // A VAR has no sub-index 1.
    assert!(eds.object(0x6040, 1).is_none());
    // A RECORD's sub-indices are their own sections; the RECORD is no sub-index 0.
    let identity = eds.object(0x1018, 1).unwrap();
    assert_eq!(identity.data_type, Some(DataType::UNSIGNED32));
    assert_eq!(identity.access, Some(Access::ReadOnly));
    assert_eq!(eds.object(0x1018, 0).unwrap().line, line_of("1018sub0"));
    assert_eq!(
        eds.object(0x60C2, 2).unwrap().data_type,
        Some(DataType::INTEGER8)
    );
    assert!(eds.object(0x60C1, 2).is_none());
    assert!(eds.object(0x2000, 0).is_none());
}

#[test]
fn comments_case_and_line_ends_are_cia_306s() {
    let text = "; a drive\r\n[DeviceInfo]\r\nVendorName=x\r\n\r\n[607a]\r\n; set-point\r\n\
                parametername = Target position\r\ndatatype=0x0004\r\nACCESSTYPE=RWW\r\n\
                pdomapping=1\r\n";
    let eds = parse(text).unwrap();
    let target = eds.object(0x607A, 0).unwrap();
    assert_eq!(target.name, "Target position");
    assert_eq!(target.data_type, Some(DataType::INTEGER32));
    assert_eq!(target.access, Some(Access::ReadWriteOutput));
    assert!(target.pdo_mapping);
    assert_eq!(target.line, 5);
    // PDOMapping absent: not mappable.
    let eds = parse("[6041]\nDataType=6\nAccessType=ro\n").unwrap();
    assert!(!eds.object(0x6041, 0).unwrap().pdo_mapping);
}

/// The line and problem of a text the reader refuses.
fn refused(text: &str) -> (usize, String) {
    match parse(text) {
        Err(EdsError::Syntax {
            path,
            line,
            problem,
        }) => {
            assert_eq!(path, Path::new("drive.eds"));
            (line, problem)
        }
        other => panic!("{text}\n=> {other:?}"),
    }
}

#[test]
fn lines_that_are_not_cia_306s_syntax_are_refused_by_line() {
    let (line, problem) = refused("[FileInfo]\nFileName=x\nEDSVersion 4.0\n");
    assert_eq!(line, 3);
    assert!(problem.contains("\"EDSVersion 4.0\""), "{problem}");
    let (line, problem) = refused("; header\nFileName=x\n[FileInfo]\n");
    assert_eq!(line, 2);
    assert!(problem.contains("before any [section]"), "{problem}");
    let (line, problem) = refused("[FileInfo]\n[6040\nDataType=6\n");
    assert_eq!(line, 2);
    assert!(problem.contains("not a section header"), "{problem}");
    assert_eq!(refused("[]\n").0, 1);
    let (line, problem) = refused("[FileInfo]\n=4.0\n");
    assert_eq!(line, 2);
    assert!(problem.contains("no key"), "{problem}");
}

#[test]
fn a_section_or_key_given_twice_is_refused_naming_both_lines() {
    let (line, problem) =
        refused("[6041]\nDataType=6\nAccessType=ro\n\n[6041]\nDataType=6\nAccessType=ro\n");
    assert_eq!(line, 5);
    assert!(problem.contains("first on line 1"), "{problem}");
    // Names are case-insensitive: [1a00] is [1A00].
    assert_eq!(refused("[1A00]\nObjectType=9\n[1a00]\n").0, 3);
    let (line, problem) = refused("[6041]\nDataType=6\nAccessType=ro\ndatatype=7\n");
    assert_eq!(line, 4);
    assert!(problem.contains("first on line 2"), "{problem}");
}

#[test]
fn values_an_object_key_does_not_take_are_refused_by_line() {
    let at = |section: &str, key: &str| {
        let start = line_of(section);
        DRIVE
            .lines()
            .skip(start)
            .position(|l| l.starts_with(key))
            .unwrap()
            + start
            + 1
    };
    for (section, key, value, says) in [
        ("607A", "DataType", "INT32", "a data type index"),
        ("607A", "DataType", "0x10000", "a data type index"),
        (
            "607A",
            "AccessType",
            "readwrite",
            "ro, wo, rw, rwr, rww, const",
        ),
        ("607A", "PDOMapping", "2", "0 or 1"),
        ("607A", "ObjectType", "VAR", "an object code"),
        ("1018", "ObjectType", "0x100", "an object code"),
    ] {
        let text = edited(section, key, Some(value));
        let (line, problem) = refused(&text);
        assert_eq!(line, at(section, key), "{section} {key}={value}");
        assert!(
            problem.contains(&format!("[{section}] {key}={value} must be"))
                && problem.contains(says),
            "{problem}"
        );
    }
}

#[test]
fn a_variable_without_type_or_access_is_refused_at_its_section() {
    for key in ["DataType", "AccessType"] {
        let (line, problem) = refused(&edited("607A", key, None));
        assert_eq!(line, line_of("607A"));
        assert!(
            problem.contains(&format!("[607A] has no {key}")),
            "{problem}"
        );
        // A RECORD's sub-index is a variable too.
        let (line, _) = refused(&edited("60C2sub1", key, None));
        assert_eq!(line, line_of("60C2sub1"));
    }
    // A RECORD's own section has neither, and needs neither.
    assert!(parse(DRIVE).unwrap().object(0x1018, 0).is_some());
}

#[test]
fn a_missing_file_is_refused_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("absent.eds");
    match Eds::load(&path) {
        Err(error @ EdsError::Read { .. }) => {
            assert!(error.to_string().contains("absent.eds"), "{error}")
        }
        other => panic!("{other:?}"),
    }
    // A syntax error in a file names the file and the line.
    let path = dir.path().join("broken.eds");
    std::fs::write(&path, "[6041]\nDataType\n").unwrap();
    let message = Eds::load(&path).unwrap_err().to_string();
    assert!(
        message.starts_with(&format!("EDS file {}, line 2: ", path.display())),
        "{message}"
    );
}

#[test]
fn objects_used_as_the_eds_allows_pass() {
    let eds = parse(DRIVE).unwrap();
    let uses = [
        var(0x1000, 0, DataType::UNSIGNED32, Use::SdoRead),
        var(0x1017, 0, DataType::UNSIGNED16, Use::SdoWrite),
        var(0x6040, 0, DataType::UNSIGNED16, Use::Rpdo(1)),
        var(0x6041, 0, DataType::UNSIGNED16, Use::Tpdo(1)),
        var(0x1A00, 1, DataType::UNSIGNED32, Use::SdoWrite),
        var(0x60C2, 2, DataType::INTEGER8, Use::SdoWrite),
    ];
    assert_eq!(eds.check(&uses), Ok(()));
}

/// The one misfit of `uses` on `text`.
fn misfit(text: &str, used: ObjectUse) -> Mismatch {
    let error = parse(text).unwrap().check(&[used]).unwrap_err();
    assert_eq!(error.path, path());
    assert_eq!(error.mismatches.len(), 1, "{error}");
    error.mismatches[0].clone()
}

#[test]
fn an_object_the_eds_lacks_is_named_with_what_it_has() {
    let used = var(0x2000, 0, DataType::UNSIGNED8, Use::SdoRead);
    let m = misfit(DRIVE, used.clone());
    assert_eq!(m.object, used);
    assert_eq!(m.line, None);
    assert_eq!(m.needs, "a section [2000] or [2000sub0]");
    assert_eq!(m.found, "nothing of 2000h");
    // A RECORD without the sub-index.
    let m = misfit(DRIVE, var(0x60C1, 2, DataType::INTEGER32, Use::Rpdo(1)));
    assert_eq!(m.needs, "a section [60C1sub2]");
    assert!(m.found.contains("without sub-index 2"), "{}", m.found);
    // An object in compact form is not expanded.
    let compact = "[1016]\nObjectType=0x8\nCompactSubObj=2\nDataType=7\nAccessType=rw\n";
    let m = misfit(compact, var(0x1016, 1, DataType::UNSIGNED32, Use::SdoWrite));
    assert!(m.found.contains("CompactSubObj, line 1"), "{}", m.found);
}

#[test]
fn a_data_type_other_than_the_use_is_named() {
    let text = edited("607A", "DataType", Some("0x0007"));
    let m = misfit(&text, var(0x607A, 0, DataType::INTEGER32, Use::Rpdo(1)));
    assert_eq!(m.needs, "DataType INTEGER32 (0x0004)");
    assert_eq!(m.found, "DataType UNSIGNED32 (0x0007)");
    assert_eq!(m.line, Some(line_of("607A")));
}

#[test]
fn access_is_checked_for_what_the_master_does() {
    for (section, access, used, needs) in [
        // A write needs a writable object…
        ("6065", "ro", Use::SdoWrite, "wo, rw, rwr or rww"),
        ("6065", "const", Use::SdoWrite, "wo, rw, rwr or rww"),
        // …a read a readable one…
        ("1000", "wo", Use::SdoRead, "ro, rw, rwr, rww or const"),
        // …an RPDO's object one the master may write, and no process input…
        ("607A", "ro", Use::Rpdo(1), "wo, rw or rww"),
        ("607A", "rwr", Use::Rpdo(1), "wo, rw or rww"),
        // …a TPDO's one the drive may read, and no process output.
        ("6041", "wo", Use::Tpdo(1), "ro, rw, rwr or const"),
        ("6041", "rww", Use::Tpdo(1), "ro, rw, rwr or const"),
    ] {
        let text = edited(section, "AccessType", Some(access));
        let eds = parse(&text).unwrap();
        let index = u16::from_str_radix(section, 16).unwrap();
        let data_type = eds.object(index, 0).unwrap().data_type.unwrap();
        let m = misfit(&text, var(index, 0, data_type, used));
        assert_eq!(m.needs, format!("AccessType {needs}"), "{section} {access}");
        assert_eq!(m.found, format!("AccessType={access}"));
        assert_eq!(m.line, Some(line_of(section)));
    }
}

#[test]
fn a_pdo_needs_a_mappable_object() {
    for (section, used) in [("607A", Use::Rpdo(1)), ("6064", Use::Tpdo(1))] {
        let text = edited(section, "PDOMapping", Some("0"));
        let index = u16::from_str_radix(section, 16).unwrap();
        let m = misfit(&text, var(index, 0, DataType::INTEGER32, used));
        assert_eq!(
            (m.needs.as_str(), m.found.as_str()),
            ("PDOMapping=1", "PDOMapping=0")
        );
        // The same object by SDO needs no mapping.
        let sdo = if used == Use::Tpdo(1) {
            Use::SdoRead
        } else {
            Use::SdoWrite
        };
        let eds = parse(&text).unwrap();
        assert_eq!(
            eds.check(&[var(index, 0, DataType::INTEGER32, sdo)]),
            Ok(())
        );
    }
}

#[test]
fn every_misfit_is_named_at_once_with_the_file_object_and_line() {
    let text = edited("607A", "AccessType", Some("ro")).replace(
        "[6041]\nParameterName=Statusword\nObjectType=0x7\nDataType=0x0006",
        "[6041]\nParameterName=Statusword\nObjectType=0x7\nDataType=0x0007",
    );
    let mut target = var(0x607A, 0, DataType::INTEGER32, Use::Rpdo(1));
    target.name = "target position".into();
    let statusword = var(0x6041, 0, DataType::UNSIGNED16, Use::Tpdo(1));
    let error = parse(&text)
        .unwrap()
        .check(&[target, statusword])
        .unwrap_err();
    assert_eq!(error.mismatches.len(), 2);
    let message = error.to_string();
    assert!(
        message.starts_with("EDS file drive.eds does not fit:"),
        "{message}"
    );
    assert!(
        message.contains(&format!(
            "\n  - 607Ah:00 target position: whirl maps it into RPDO1 (written by the \
             master), which needs AccessType wo, rw or rww; the EDS says AccessType=ro \
             (line {})",
            line_of("607A")
        )),
        "{message}"
    );
    assert!(message.contains("6041h:00"), "{message}");
}
