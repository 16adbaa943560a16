//! Where a stream goes: a machine profile's `[connection]`, with what the caller overrides.
//!
//! The transport is the caller's, else the profile's, else serial; the profile's settings
//! count only for its own transport (a `modbus-tcp` connection's address is no serial
//! port). The port and baud rate are the caller's, else the profile's (a baud rate else
//! 115 200); a Modbus connection's unit and answer timeout and an slcan adapter's bit rate
//! come from the profile; CAN drives' settings always do, since only a profile describes
//! the drives.

use std::fmt;
use std::time::Duration;

use thiserror::Error;

use super::can::CanLink;
use super::modbus::{ModbusLink, ModbusOptions};
use crate::config::connection::{Connection, DriveSettings, LinuxcncSettings, SettingError};
use crate::config::machine::MachineProfile;
use crate::protocol::canopen::session::SessionConfig;
use crate::protocol::canopen::slcan::Bitrate;

/// The transports, as a profile's `transport` key and the command line name them.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum TransportKind {
    /// G-code by grbl's character counting over a serial line.
    Serial,
    /// The Modbus register map over Modbus TCP.
    ModbusTcp,
    /// The Modbus register map over Modbus RTU.
    ModbusRtu,
    /// CiA 402 drives through an slcan adapter on a serial line.
    CanSlcan,
    /// CiA 402 drives on a SocketCAN interface.
    Can,
    /// A LinuxCNC machine through `linuxcncrsh`.
    Linuxcnc,
}

impl TransportKind {
    /// Every transport, in the profile's order.
    pub const ALL: [TransportKind; 6] = [
        TransportKind::Serial,
        TransportKind::ModbusTcp,
        TransportKind::ModbusRtu,
        TransportKind::CanSlcan,
        TransportKind::Can,
        TransportKind::Linuxcnc,
    ];

    /// The name a profile and the log use: `serial`, `modbus-tcp`, `modbus-rtu`,
    /// `can-slcan`, `can`, `linuxcnc`.
    pub fn name(self) -> &'static str {
        match self {
            TransportKind::Serial => "serial",
            TransportKind::ModbusTcp => "modbus-tcp",
            TransportKind::ModbusRtu => "modbus-rtu",
            TransportKind::CanSlcan => "can-slcan",
            TransportKind::Can => "can",
            TransportKind::Linuxcnc => "linuxcnc",
        }
    }

    /// The transport of a profile's `[connection]`.
    pub fn of(connection: &Connection) -> TransportKind {
        match connection {
            Connection::Serial(_) => TransportKind::Serial,
            Connection::ModbusTcp(_) => TransportKind::ModbusTcp,
            Connection::ModbusRtu(_) => TransportKind::ModbusRtu,
            Connection::CanSlcan(_) => TransportKind::CanSlcan,
            Connection::Can(_) => TransportKind::Can,
            Connection::Linuxcnc(_) => TransportKind::Linuxcnc,
        }
    }
}

impl fmt::Display for TransportKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A stream's way to the machine, every setting resolved.
#[derive(Debug, Clone, PartialEq)]
pub enum Link {
    /// A grbl-family controller on a serial port.
    Serial {
        /// The port: a device or a pseudo-terminal.
        port: String,
        /// Its baud rate.
        baud: u32,
    },
    /// A controller serving the Modbus register map.
    Modbus {
        /// Where it is.
        link: ModbusLink,
        /// Its unit id.
        unit: u8,
        /// The longest wait for one answer.
        timeout: Duration,
    },
    /// CiA 402 drives on a CAN bus.
    Can {
        /// Where the bus is.
        link: CanLink,
        /// The drives: nodes, cycle, scales, supervision.
        drives: DriveSettings,
    },
    /// A LinuxCNC machine's `linuxcncrsh`.
    Linuxcnc(LinuxcncSettings),
}

impl Link {
    /// Whether the link is a serial port that is a pseudo-terminal (a simulator's, or
    /// socat's): bytes cross it at the speed of memory, paced by no baud rate, so a share
    /// of a baud rate measures nothing of it (`whirl-sim` without `--baud` took 83 % of
    /// 115 200 baud from a 1× stream).
    pub fn is_pseudo_terminal(&self) -> bool {
        // Unix 98 pseudo-terminals' slave ends live in /dev/pts (devpts); a simulator's
        // link leads there.
        match self {
            Link::Serial { port, .. } => {
                std::fs::canonicalize(port).is_ok_and(|device| device.starts_with("/dev/pts"))
            }
            _ => false,
        }
    }
}

/// Why a link cannot be made from what was given.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum LinkError {
    /// Neither the caller nor the profile names a port.
    #[error(
        "no port given, and machine profile \"{machine}\" has no [connection] for {transport} \
         that names one"
    )]
    NoPort {
        /// The profile's name.
        machine: String,
        /// The transport.
        transport: TransportKind,
    },
    /// A Modbus TCP address that is not one.
    #[error("{0}: not a HOST:PORT address")]
    Address(String),
    /// CAN without drives' settings.
    #[error(
        "machine profile \"{0}\" has no CAN drives (a [connection] with transport can-slcan or \
         can, which gives their nodes, cycle and scales); use one that has, such as \
         machine-profiles/canopen-drives.toml"
    )]
    NoDrives(String),
    /// A CAN bit rate an slcan adapter cannot select.
    #[error("{0} bit/s is not one of slcan's S0-S8 rates")]
    Bitrate(u32),
    /// CAN drives the session refuses: their data sheets lack an object it uses as it
    /// uses it.
    #[error("machine profile \"{machine}\": {error}")]
    Drives {
        /// The profile's name.
        machine: String,
        /// The key and what is wrong.
        error: SettingError,
    },
}

impl Link {
    /// The link to `machine` over `kind` (else its profile's transport, else serial), with
    /// `port` and `baud` where given; see the module docs.
    pub fn resolve(
        machine: &MachineProfile,
        kind: Option<TransportKind>,
        port: Option<String>,
        baud: Option<u32>,
    ) -> Result<Link, LinkError> {
        let profile = machine.connection.as_ref();
        let kind = kind
            .or_else(|| profile.map(TransportKind::of))
            .unwrap_or(TransportKind::Serial);
        let same = profile.filter(|c| TransportKind::of(c) == kind);
        let (profile_port, profile_baud) = match same {
            Some(Connection::Serial(s)) => (Some(s.port.clone()), Some(s.baud)),
            Some(Connection::ModbusTcp(s)) => (Some(s.address.clone()), None),
            Some(Connection::ModbusRtu(s)) => (Some(s.port.clone()), Some(s.baud)),
            Some(Connection::CanSlcan(s)) => (Some(s.port.clone()), Some(s.baud)),
            Some(Connection::Can(s)) => (Some(s.interface.clone()), None),
            Some(Connection::Linuxcnc(s)) => (Some(s.address.clone()), None),
            None => (None, None),
        };
        // LinuxCNC's remote shell has a well-known home: this host, port 5007.
        let default_port =
            (kind == TransportKind::Linuxcnc).then(|| LinuxcncSettings::default().address);
        let port = port
            .or(profile_port)
            .or(default_port)
            .ok_or_else(|| LinkError::NoPort {
                machine: machine.name.clone(),
                transport: kind,
            })?;
        let baud = baud.or(profile_baud).unwrap_or(115_200);
        let defaults = ModbusOptions::default();
        Ok(match kind {
            TransportKind::Serial => Link::Serial { port, baud },
            TransportKind::ModbusTcp => Link::Modbus {
                link: ModbusLink::Tcp(port.parse().map_err(|_| LinkError::Address(port))?),
                unit: match same {
                    Some(Connection::ModbusTcp(s)) => s.unit,
                    _ => defaults.unit,
                },
                timeout: match same {
                    Some(Connection::ModbusTcp(s)) => s.timeout(),
                    _ => defaults.timeout,
                },
            },
            TransportKind::ModbusRtu => Link::Modbus {
                link: ModbusLink::Rtu { path: port, baud },
                unit: match same {
                    Some(Connection::ModbusRtu(s)) => s.unit,
                    _ => defaults.unit,
                },
                timeout: match same {
                    Some(Connection::ModbusRtu(s)) => s.timeout(),
                    _ => defaults.timeout,
                },
            },
            TransportKind::CanSlcan => {
                let (drives, bitrate) = can_bus(machine)?;
                Link::Can {
                    link: CanLink::Slcan {
                        path: port,
                        baud,
                        bitrate,
                    },
                    drives,
                }
            }
            TransportKind::Can => Link::Can {
                link: CanLink::SocketCan { interface: port },
                drives: can_bus(machine)?.0,
            },
            // The profile's passwords, power-on permission and program folder, at the
            // address given.
            TransportKind::Linuxcnc => Link::Linuxcnc(LinuxcncSettings {
                address: port,
                ..match same {
                    Some(Connection::Linuxcnc(s)) => s.clone(),
                    _ => LinuxcncSettings::default(),
                }
            }),
        })
    }

    /// Its transport.
    pub fn kind(&self) -> TransportKind {
        match self {
            Link::Serial { .. } => TransportKind::Serial,
            Link::Modbus {
                link: ModbusLink::Tcp(_),
                ..
            } => TransportKind::ModbusTcp,
            Link::Modbus { .. } => TransportKind::ModbusRtu,
            Link::Can {
                link: CanLink::Slcan { .. },
                ..
            } => TransportKind::CanSlcan,
            Link::Can { .. } => TransportKind::Can,
            Link::Linuxcnc(_) => TransportKind::Linuxcnc,
        }
    }
}

/// `machine`'s CAN drives and its slcan adapter's bit rate (1 Mbit/s where the profile
/// names no adapter): what only a profile can describe.
pub fn can_bus(machine: &MachineProfile) -> Result<(DriveSettings, Bitrate), LinkError> {
    let profile = machine.connection.as_ref();
    let drives = profile
        .and_then(Connection::drives)
        .cloned()
        .ok_or_else(|| LinkError::NoDrives(machine.name.clone()))?;
    let bits = match profile {
        Some(Connection::CanSlcan(s)) => s.bitrate,
        _ => Bitrate::M1.bits_per_second(),
    };
    let bitrate = Bitrate::from_bits_per_second(bits).ok_or(LinkError::Bitrate(bits))?;
    // Where a CAN run, a dry run or a resume takes its drives: the session they make is
    // refused here, before anything is planned, recorded or opened, for drives whose data
    // sheets (`connection.drives.eds`) lack an object it uses.
    SessionConfig::for_drives(&drives).map_err(|error| LinkError::Drives {
        machine: machine.name.clone(),
        error,
    })?;
    Ok((drives, bitrate))
}

impl fmt::Display for Link {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Link::Serial { port, baud } => write!(f, "{port} at {baud} baud"),
            Link::Modbus { link, .. } => write!(f, "{link}"),
            Link::Can { link, .. } => write!(f, "{link}"),
            Link::Linuxcnc(s) => write!(f, "linuxcncrsh at {}", s.address),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn profile(connection: &str) -> MachineProfile {
        let text = format!(
            "{}\n{connection}\n",
            include_str!("../../machine-profiles/sim.toml")
        );
        MachineProfile::from_toml(&text, "test.toml").unwrap()
    }

    const DRIVES: &str = "[connection.drives]\ncounts_per_mm = [10000.0, 10000.0]\n\
                          counts_per_degree = 3000.0";

    #[test]
    fn the_callers_choice_wins_then_the_profiles_then_serial() {
        let bare = MachineProfile::builtin_sim().unwrap();
        assert_eq!(
            Link::resolve(&bare, None, Some("/dev/ttyACM0".into()), None),
            Ok(Link::Serial {
                port: "/dev/ttyACM0".into(),
                baud: 115_200
            })
        );
        let serial =
            profile("[connection]\ntransport = \"serial\"\nport = \"COM3\"\nbaud = 250000");
        assert_eq!(
            Link::resolve(&serial, None, None, None),
            Ok(Link::Serial {
                port: "COM3".into(),
                baud: 250_000
            })
        );
        // The caller's port and baud rate over the profile's.
        assert_eq!(
            Link::resolve(&serial, None, Some("/tmp/pty".into()), Some(9600)),
            Ok(Link::Serial {
                port: "/tmp/pty".into(),
                baud: 9600
            })
        );
    }

    #[test]
    fn modbus_takes_the_profiles_unit_and_timeout_for_its_own_transport_only() {
        let tcp = profile(
            "[connection]\ntransport = \"modbus-tcp\"\naddress = \"127.0.0.1:1502\"\n\
             unit = 3\ntimeout_ms = 250",
        );
        let link = Link::resolve(&tcp, None, None, None).unwrap();
        assert_eq!(
            link,
            Link::Modbus {
                link: ModbusLink::Tcp("127.0.0.1:1502".parse().unwrap()),
                unit: 3,
                timeout: Duration::from_millis(250)
            }
        );
        assert_eq!(link.kind(), TransportKind::ModbusTcp);
        // Over RTU the TCP profile's settings do not count: the port must be given.
        assert_eq!(
            Link::resolve(&tcp, Some(TransportKind::ModbusRtu), None, None),
            Err(LinkError::NoPort {
                machine: tcp.name.clone(),
                transport: TransportKind::ModbusRtu
            })
        );
        let rtu = Link::resolve(
            &tcp,
            Some(TransportKind::ModbusRtu),
            Some("/dev/ttyUSB0".into()),
            None,
        )
        .unwrap();
        let defaults = ModbusOptions::default();
        assert_eq!(
            rtu,
            Link::Modbus {
                link: ModbusLink::Rtu {
                    path: "/dev/ttyUSB0".into(),
                    baud: 115_200
                },
                unit: defaults.unit,
                timeout: defaults.timeout
            }
        );
        let err = Link::resolve(&tcp, None, Some("plc".into()), None).unwrap_err();
        assert_eq!(err, LinkError::Address("plc".into()));
        assert_eq!(err.to_string(), "plc: not a HOST:PORT address");
    }

    #[test]
    fn can_needs_the_profiles_drives_and_an_slcan_rate() {
        let slcan = profile(&format!(
            "[connection]\ntransport = \"can-slcan\"\nport = \"/dev/ttyACM0\"\n\
             bitrate = 500000\n{DRIVES}"
        ));
        let Link::Can { link, drives } = Link::resolve(&slcan, None, None, None).unwrap() else {
            panic!("a CAN link");
        };
        assert_eq!(
            link,
            CanLink::Slcan {
                path: "/dev/ttyACM0".into(),
                baud: 115_200,
                bitrate: Bitrate::K500
            }
        );
        assert_eq!(drives.counts_per_mm, [10_000.0, 10_000.0]);
        // socketcan: the interface is the port, the drives still the profile's.
        let can =
            Link::resolve(&slcan, Some(TransportKind::Can), Some("can0".into()), None).unwrap();
        assert_eq!(can.kind(), TransportKind::Can);
        assert_eq!(can.to_string(), "socketcan can0");
        // No drives anywhere: refused, naming the profile.
        let bare = MachineProfile::builtin_sim().unwrap();
        let err = Link::resolve(
            &bare,
            Some(TransportKind::CanSlcan),
            Some("/dev/x".into()),
            None,
        )
        .unwrap_err();
        assert_eq!(err, LinkError::NoDrives(bare.name.clone()));
        assert!(err.to_string().contains("has no CAN drives"));
    }
}
