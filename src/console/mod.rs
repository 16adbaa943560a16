//! The operator's console: `whirl serve`'s web page beside the machine.
//!
//! The top layer: it plans and verifies jobs ([`crate::plan`], [`crate::judge::verify`]),
//! dry-runs them on the simulator ([`crate::judge::dry_run`]) with the library's control
//! handle ([`mod@crate::transport::control`]), and shows the groove as it is cut
//! ([`groove`]). What decides is plain code, testable without a browser or a socket:
//!
//! - [`paths`]: the job files it may read, only under `--jobs`;
//! - [`gate`]: the hosts it answers to, and how an action proves it comes from its own page;
//! - [`token`]: when an access token is required, and its constant-time check;
//! - [`login`]: the sessions the login opens, and how fast wrong tokens may be tried;
//! - [`lock`]: one run per machine or port, across processes (`whirl stream` takes the same
//!   lock);
//! - [`registry`]: the runs, one slot per machine, which live in the server, not the page;
//! - [`runner`]: a run from request to end, on a thread of its own;
//! - [`remote`]: the shop overview's Hold, taken from the broker with the console's token;
//! - [`resume`]: a stopped dry run resumed where it stopped, re-entering along the groove,
//!   over the transport it ran on;
//! - [`record`]: the runs in the run records ([`crate::records`]);
//! - [`history`]: the records searched for the history page;
//! - [`shop`]: the shop overview (`whirl serve --shop`), every machine as the broker says it.
//!
//! [`http`] is the edge: axum routes, the page (embedded, no build step, nothing fetched
//! from the internet) and the server-sent events that push every change to it.

pub mod gate;
pub mod groove;
pub mod history;
pub mod http;
pub mod lock;
pub mod login;
pub mod paths;
pub mod record;
pub mod registry;
pub mod remote;
pub mod resume;
pub mod runner;
pub mod shop;
pub mod token;

use crate::config::machine::MachineProfile;
use crate::transport::can::CanLink;
use crate::transport::modbus::ModbusLink;
use crate::transport::Link;
use std::collections::BTreeMap;
use std::path::PathBuf;

pub use runner::Console;

/// The lock name of the machine or port `link` reaches: a serial port by its real path,
/// so that two names of one device are one lock.
pub fn link_key(link: &Link) -> String {
    let port = |path: &str| {
        let real = std::fs::canonicalize(path).unwrap_or_else(|_| PathBuf::from(path));
        format!("serial port {}", real.display())
    };
    match link {
        Link::Serial { port: path, .. } => port(path),
        Link::Modbus {
            link: ModbusLink::Tcp(address),
            ..
        } => format!("Modbus controller {address}"),
        Link::Modbus {
            link: ModbusLink::Rtu { path, .. },
            ..
        } => port(path),
        Link::Can {
            link: CanLink::Slcan { path, .. },
            ..
        } => port(path),
        Link::Can {
            link: CanLink::SocketCan { interface },
            ..
        } => format!("CAN interface {interface}"),
        Link::Linuxcnc(settings) => format!("LinuxCNC at {}", settings.address),
    }
}

/// The lock name of `machine`: the port its profile's `[connection]` reaches (what a
/// `whirl stream` to it locks), else its name.
pub fn machine_key(machine: &MachineProfile) -> String {
    Link::resolve(machine, None, None, None)
        .map(|link| link_key(&link))
        .unwrap_or_else(|_| format!("machine {}", machine.name))
}

/// The machines a console serves, by name; two profiles of one name are refused.
pub fn machines(profiles: Vec<MachineProfile>) -> Result<BTreeMap<String, MachineProfile>, String> {
    let mut machines = BTreeMap::new();
    for profile in profiles {
        let name = profile.name.clone();
        if machines.insert(name.clone(), profile).is_some() {
            return Err(format!(
                "two machine profiles are named \"{name}\": a console tells its machines \
                 apart by name"
            ));
        }
    }
    Ok(machines)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_machine_locks_the_port_its_profile_names_else_its_name() {
        let sim = MachineProfile::builtin_sim().unwrap();
        assert_eq!(machine_key(&sim), format!("machine {}", sim.name));
        let dir = tempfile::tempdir().unwrap();
        let device = dir.path().join("ttyUSB0");
        std::fs::write(&device, "").unwrap();
        let alias = dir.path().join("by-id");
        std::os::unix::fs::symlink(&device, &alias).unwrap();
        let text = format!(
            "{}\n[connection]\ntransport = \"serial\"\nport = \"{}\"\n",
            include_str!("../../machine-profiles/sim.toml"),
            alias.display()
        );
        let lathe = MachineProfile::from_toml(&text, "lathe.toml").unwrap();
        let real = device.canonicalize().unwrap();
        assert_eq!(
            machine_key(&lathe),
            format!("serial port {}", real.display())
        );
        let direct = Link::Serial {
            port: device.display().to_string(),
            baud: 115_200,
        };
        assert_eq!(link_key(&direct), machine_key(&lathe));
    }

    #[test]
    fn two_machines_of_one_name_are_refused() {
        let sim = MachineProfile::builtin_sim().unwrap();
        let error = machines(vec![sim.clone(), sim]).unwrap_err();
        assert!(error.contains("two machine profiles are named"), "{error}");
    }
}
