//! A drive's EDS (`connection.drives.eds`) through the real `whirl` binary: a profile
//! whose drives' EDS makes target position 607Ah read-only (CiA 402 has the master write
//! it every cycle through an RPDO) is refused before anything is opened, naming the file,
//! the object and the line; the same profile with the test drive's EDS runs on the
//! simulated drives.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use crate::util::{self, Sim};

/// The example CAN profile written to `dir` with `eds = "drive.eds"` in its
/// `[connection.drives]` and `eds` (a file of `tests/data/`) copied beside it as
/// `drive.eds`: the key's path is relative to the profile's folder. Its heartbeat is
/// watched for a second rather than 150 ms: the drives run in another process on a host
/// whose two cores other builds keep busy, and these tests are about the data sheet.
fn profile_with_eds(dir: &Path, eds: &str) -> PathBuf {
    std::fs::copy(
        util::root().join("tests/data").join(eds),
        dir.join("drive.eds"),
    )
    .unwrap();
    let text =
        std::fs::read_to_string(util::root().join("machine-profiles/canopen-drives.toml")).unwrap();
    assert!(
        text.trim_end().ends_with("+ margin"),
        "[connection.drives] is the example profile's last table"
    );
    let text = text.replace("heartbeat_timeout_ms = 150", "heartbeat_timeout_ms = 1000")
        + "eds = \"drive.eds\"\n";
    util::write(dir, "drives.toml", &text)
}

/// `whirl stream` of a short hand-written program (a rapid to the origin, X out 1 mm and back) to the drives at
/// `port` on `profile`, logging to `dir/exec.jsonl`; its output once it ends.
fn stream(dir: &Path, profile: &Path, port: &Path) -> Output {
    let program = util::write(
        dir,
        "job.nc",
        "G21 G90 G94\nG0 X0 Z0 C0\nG1 X1 F600\nG1 X0\nM2\n",
    );
    Command::new(env!("CARGO_BIN_EXE_whirl"))
        .env("WHIRL_DB", dir.join("runs.sqlite"))
        .arg("stream")
        .arg(&program)
        .arg("--machine")
        .arg(profile)
        .args(["--transport", "can-slcan", "--port"])
        .arg(port)
        .arg("--log")
        .arg(dir.join("exec.jsonl"))
        // Written by hand: it carries no provenance.
        .arg("--no-provenance-check")
        .output()
        .expect("whirl runs")
}

#[test]
fn a_drive_eds_with_a_read_only_target_position_is_refused_before_anything_is_opened() {
    let dir = tempfile::tempdir().unwrap();
    let profile = profile_with_eds(dir.path(), "cia402-drive-target-read-only.eds");
    // No adapter there: had whirl opened the port before the check, the error would be
    // the port's.
    let port = dir.path().join("no-adapter");
    let run = stream(dir.path(), &profile, &port);
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success(), "{stderr}");
    let eds = dir.path().join("drive.eds");
    let line = std::fs::read_to_string(&eds)
        .unwrap()
        .lines()
        .position(|l| l == "[607A]")
        .unwrap()
        + 1;
    for said in [
        "connection.drives.eds".to_owned(),
        format!("EDS file {} does not fit", eds.display()),
        "the X, Z, C drives (nodes 1, 2, 3, in cyclic synchronous position (mode 8))".into(),
        format!(
            "607Ah:00 target position: whirl maps it into RPDO1 (written by the master), \
             which needs AccessType wo, rw or rww; the EDS says AccessType=ro (line {line})"
        ),
    ] {
        assert!(stderr.contains(&said), "{said:?} not in: {stderr}");
    }
    assert!(!stderr.contains("no-adapter"), "{stderr}");
    // Refused before the run's log was opened: nothing was sent to log.
    assert!(!dir.path().join("exec.jsonl").exists());
}

#[test]
fn a_drive_eds_that_fits_lets_the_job_run() {
    let dir = tempfile::tempdir().unwrap();
    let profile = profile_with_eds(dir.path(), "cia402-drive.eds");
    let link = dir.path().join("slcan");
    let _sim = Sim::serving(
        OsStr::new("--can-slcan"),
        &link,
        &[
            OsStr::new("--machine"),
            profile.as_os_str(),
            OsStr::new("--idle-exit"),
            OsStr::new("30"),
        ],
    );
    let run = stream(dir.path(), &profile, &link);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let read = whirl::log::read(&dir.path().join("exec.jsonl")).expect("the log reads back");
    let ended = read.records.iter().find_map(|r| match &r.event {
        whirl::log::Event::End { completed, .. } => Some(*completed),
        _ => None,
    });
    assert_eq!(ended, Some(true));
}
