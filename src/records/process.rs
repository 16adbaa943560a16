//! Whose a running record is, and whether that process still runs.
//!
//! A record is opened by one process on one host and closed by the same process when its
//! run ends. A process killed outright (SIGKILL, a power cut) never closes it, so a record
//! left `running` is judged by the process it names: on the same host, since the same boot,
//! a process with that pid that started at the same instant is the one that opened it, and
//! it is still at work; anything else (no such process, a zombie, or a pid reused by a
//! process that started later, or a host rebooted since) means the run is over. A record of
//! another host is left to that host to judge. The facts come from Linux's `/proc`.

use std::path::Path;

/// A process, as a record names it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Process {
    /// The host's name (`/proc/sys/kernel/hostname`).
    pub host: String,
    /// The process id.
    pub pid: u32,
    /// When it started, in clock ticks since the host booted (`/proc/PID/stat`'s 22nd
    /// field): with the pid, the process itself, since no two processes of one boot share
    /// both.
    pub started: Option<u64>,
    /// The boot it runs in (`/proc/sys/kernel/random/boot_id`).
    pub boot: Option<String>,
}

/// Whether the process a record names still runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Liveness {
    /// The same process is at work: its record is open.
    Running,
    /// It is gone (or its pid is another process's now): its record will never be
    /// closed by it.
    Gone,
    /// It ran on another host, which alone can tell.
    Elsewhere,
}

impl Process {
    /// This process.
    pub fn current() -> Process {
        let pid = std::process::id();
        Process {
            host: host(),
            pid,
            started: stat(Path::new("/proc/self/stat")).map(|s| s.started),
            boot: boot(),
        }
    }

    /// Whether `self` still runs, judged from `here` (the judging process, on its host).
    pub fn liveness(&self, here: &Process) -> Liveness {
        if self.host != here.host {
            return Liveness::Elsewhere;
        }
        if self.boot.is_some() && self.boot != here.boot {
            return Liveness::Gone;
        }
        match stat(&Path::new("/proc").join(self.pid.to_string()).join("stat")) {
            Some(now) if !now.dead && self.started.is_none_or(|s| s == now.started) => {
                Liveness::Running
            }
            _ => Liveness::Gone,
        }
    }
}

/// What `/proc/PID/stat` says of a process.
struct Stat {
    /// Its start, clock ticks after boot.
    started: u64,
    /// A zombie (exited, not yet reaped) or dead: it will do nothing more.
    dead: bool,
}

/// `/proc/PID/stat`: the fields after the command name (which is in parentheses and may
/// hold spaces or parentheses itself, so the last `)` ends it). The state is the 3rd
/// field, the start time the 22nd.
fn stat(path: &Path) -> Option<Stat> {
    parse_stat(&std::fs::read_to_string(path).ok()?)
}

fn parse_stat(text: &str) -> Option<Stat> {
    let after = &text[text.rfind(')')? + 1..];
    let fields: Vec<&str> = after.split_whitespace().collect();
    let state = fields.first()?;
    Some(Stat {
        started: fields.get(19)?.parse().ok()?,
        dead: matches!(*state, "Z" | "X" | "x"),
    })
}

/// The host's name, or "unknown" where the kernel does not say.
fn host() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .map(|h| h.trim().to_owned())
        .ok()
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "unknown".to_owned())
}

fn boot() -> Option<String> {
    std::fs::read_to_string("/proc/sys/kernel/random/boot_id")
        .ok()
        .map(|b| b.trim().to_owned())
        .filter(|b| !b.is_empty())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stat_line_gives_the_start_and_whether_it_is_a_zombie() {
        // A command name with a space and a parenthesis, as a process may name itself.
        let line = "4242 (my (odd) cmd) S 1 4242 4242 0 -1 4194560 1 0 0 0 3 1 0 0 20 0 1 0 \
                    987654 1000 10 18446744073709551615";
        let stat = parse_stat(line).unwrap();
        assert_eq!(stat.started, 987_654);
        assert!(!stat.dead);
        let zombie = line.replace(") S 1", ") Z 1");
        assert!(parse_stat(&zombie).unwrap().dead);
        assert!(parse_stat("4242 (cut short) S 1").is_none());
    }

    #[test]
    fn this_process_runs_and_a_changed_start_or_host_or_boot_is_not_it() {
        let here = Process::current();
        assert!(here.started.is_some(), "Linux's /proc gives the start");
        assert_eq!(here.liveness(&here), Liveness::Running);
        let reused = Process {
            started: here.started.map(|s| s + 1),
            ..here.clone()
        };
        assert_eq!(reused.liveness(&here), Liveness::Gone);
        let rebooted = Process {
            boot: Some("another boot".into()),
            ..here.clone()
        };
        assert_eq!(rebooted.liveness(&here), Liveness::Gone);
        let elsewhere = Process {
            host: format!("{}-other", here.host),
            ..here.clone()
        };
        assert_eq!(elsewhere.liveness(&here), Liveness::Elsewhere);
    }

    #[test]
    fn a_process_that_exited_is_gone() {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        let path = Path::new("/proc").join(pid.to_string()).join("stat");
        let started = stat(&path).map(|s| s.started);
        child.wait().unwrap();
        let exited = Process {
            pid,
            started,
            ..Process::current()
        };
        assert_eq!(exited.liveness(&Process::current()), Liveness::Gone);
    }
}
