//! The `[connection]` table: defaults, round trips, refusals naming the key, alone and in a
//! machine profile.

use std::net::SocketAddr;
use std::time::Duration;

use super::*;
use crate::config::machine::{MachineProfile, ProfileError};

/// The built-in simulated machine (grblHAL, max_line_length 255, X −5…160, Z ±300)
/// with `connection` as its `[connection]` table (its `[drives]` tables as
/// `[connection.drives]`).
fn profile_text(connection: &str) -> String {
    format!(
        "{}\n[connection]\n{}\n",
        include_str!("../../../machine-profiles/sim.toml"),
        connection.replace("[drives", "[connection.drives")
    )
}

fn load(connection: &str) -> Result<MachineProfile, ProfileError> {
    MachineProfile::from_toml(&profile_text(connection), "test.toml")
}

/// The key and problem of a connection that parses but does not validate.
fn refused(connection: &str) -> (String, String) {
    crate::config::machine::tests::invalid(&profile_text(connection))
}

/// The message of a connection that does not parse.
fn unparsed(connection: &str) -> String {
    match load(connection) {
        Err(error @ ProfileError::Toml { .. }) => error.to_string(),
        other => panic!("{connection}\n=> {other:?}"),
    }
}

const SLCAN: &str = r#"
transport = "can-slcan"
port = "/dev/ttyACM0"
[drives]
counts_per_mm = [10000.0, 10000.0]
counts_per_degree = 2912.711111111111
"#;

const SOCKETCAN: &str = r#"
transport = "can"
interface = "can0"
[drives]
counts_per_mm = [10000.0, 10000.0]
counts_per_degree = 2912.711111111111
"#;

#[test]
fn minimal_tables_take_the_defaults() {
    let serial: Connection = toml::from_str("transport = \"serial\"\nport = \"COM3\"").unwrap();
    assert_eq!(
        serial,
        Connection::Serial(SerialSettings {
            port: "COM3".into(),
            baud: 115_200,
            rx_buffer: None,
        })
    );
    let tcp: Connection =
        toml::from_str("transport = \"modbus-tcp\"\naddress = \"192.168.0.10:502\"").unwrap();
    assert_eq!(
        tcp,
        Connection::ModbusTcp(ModbusTcpSettings {
            address: "192.168.0.10:502".into(),
            unit: 1,
            timeout_ms: 500,
        })
    );
    let rtu: Connection =
        toml::from_str("transport = \"modbus-rtu\"\nport = \"/dev/ttyUSB0\"").unwrap();
    assert_eq!(
        rtu,
        Connection::ModbusRtu(ModbusRtuSettings {
            port: "/dev/ttyUSB0".into(),
            baud: 115_200,
            unit: 1,
            timeout_ms: 500,
        })
    );
    let drives = DriveSettings {
        nodes: [1, 2, 3],
        cycle_us: 4000,
        counts_per_mm: [10_000.0, 10_000.0],
        counts_per_degree: 1_048_576.0 / 360.0,
        heartbeat_ms: 50,
        heartbeat_timeout_ms: None,
        following_error_window: 10_000,
        spin_up_ms: 2000,
        mode: DriveMode::Csp,
        eds: None,
        data_sheets: None,
    };
    let slcan: Connection = toml::from_str(SLCAN).unwrap();
    assert_eq!(
        slcan,
        Connection::CanSlcan(SlcanSettings {
            port: "/dev/ttyACM0".into(),
            baud: 115_200,
            bitrate: 1_000_000,
            drives: drives.clone(),
        })
    );
    let can: Connection = toml::from_str(SOCKETCAN).unwrap();
    assert_eq!(
        can,
        Connection::Can(SocketCanSettings {
            interface: "can0".into(),
            drives,
        })
    );
    for (connection, name) in [
        (serial, "serial"),
        (tcp, "modbus-tcp"),
        (rtu, "modbus-rtu"),
        (slcan, "can-slcan"),
        (can, "can"),
    ] {
        assert_eq!(connection.transport_name(), name);
        assert!(TRANSPORTS.contains(&name));
        assert_eq!(
            connection.drives().is_some(),
            name.starts_with("can"),
            "{name}"
        );
        // And each loads as a profile's [connection].
        let text = toml::to_string(&connection).unwrap();
        let profile = load(&text).unwrap_or_else(|e| panic!("{text}\n=> {e}"));
        assert_eq!(profile.connection, Some(connection));
    }
}

#[test]
fn every_transport_round_trips_through_toml() {
    let texts = [
        "transport = \"serial\"\nport = \"/dev/ttyACM0\"\nbaud = 250000\nrx_buffer = 1024\n",
        "transport = \"modbus-tcp\"\naddress = \"[fe80::1]:1502\"\nunit = 255\ntimeout_ms = 250\n",
        "transport = \"modbus-rtu\"\nport = \"/dev/ttyUSB0\"\nbaud = 19200\nunit = 7\n\
         timeout_ms = 1000\n",
        "transport = \"can-slcan\"\nport = \"COM4\"\nbaud = 921600\nbitrate = 500000\n\
         [drives]\nnodes = [5, 6, 7]\ncycle_us = 2000\ncounts_per_mm = [8192.0, 4096.5]\n\
         counts_per_degree = 100.0\nheartbeat_ms = 20\nheartbeat_timeout_ms = 100\n\
         following_error_window = 5000\nspin_up_ms = 3000\n",
        "transport = \"can\"\ninterface = \"vcan0\"\n[drives]\ncounts_per_mm = [1.5, 2.5]\n\
         counts_per_degree = 2912.711111111111\n",
    ];
    for text in texts {
        let connection: Connection =
            toml::from_str(text).unwrap_or_else(|e| panic!("{text}\n=> {e}"));
        let written = toml::to_string(&connection).unwrap();
        assert!(
            written.starts_with(&format!(
                "transport = \"{}\"\n",
                connection.transport_name()
            )),
            "{written}"
        );
        let again: Connection =
            toml::from_str(&written).unwrap_or_else(|e| panic!("{written}\n=> {e}"));
        assert_eq!(again, connection, "{written}");
        // Every value given was read, none left at its default.
        for line in text.lines().filter(|l| l.contains(" = ")) {
            let key = line.split(" = ").next().unwrap();
            assert!(written.contains(&format!("{key} = ")), "{key}: {written}");
        }
        // And in a profile, through MachineProfile's own round trip.
        let profile = load(text).unwrap_or_else(|e| panic!("{text}\n=> {e}"));
        let profile_text = toml::to_string(&profile).unwrap();
        let reloaded = MachineProfile::from_toml(&profile_text, "written").unwrap();
        assert_eq!(reloaded, profile);
    }
}

#[test]
fn unknown_keys_are_refused_with_the_tag_and_in_drives() {
    // The tag itself is no unknown key to the transport's settings (it is taken off
    // before they read the rest), but a key of another transport is.
    let cases = [
        (
            "transport = \"serial\"\nport = \"a\"\nbaudrate = 9600",
            "baudrate",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \"10.0.0.1:502\"\nport = \"/dev/ttyS0\"",
            "`port`",
        ),
        (
            "transport = \"modbus-rtu\"\nport = \"/dev/ttyS0\"\naddress = \"10.0.0.1:502\"",
            "`address`",
        ),
        (
            "transport = \"modbus-rtu\"\nport = \"/dev/ttyS0\"\nparity = \"even\"",
            "parity",
        ),
        (&format!("{SLCAN}\n[drives.extra]\na = 1"), "extra"),
        (
            &SLCAN.replace("\nport =", "\ninterface = \"can0\"\nport ="),
            "`interface`",
        ),
        (
            &SOCKETCAN.replace("[drives]", "bitrate = 500000\n[drives]"),
            "`bitrate`",
        ),
        (&format!("{SOCKETCAN}cycle_ms = 4"), "cycle_ms"),
    ];
    for (text, key) in cases {
        let message = unparsed(text);
        assert!(message.contains("unknown field"), "{message}");
        assert!(message.contains(key), "{message}");
        assert!(message.contains("connection"), "{message}");
        assert!(toml::from_str::<Connection>(text).is_err());
    }
    let message = unparsed(&format!("{SOCKETCAN}cycle_ms = 4"));
    assert!(
        message.starts_with("machine profile test.toml: "),
        "{message}"
    );
    assert!(
        message.contains("connection.drives: unknown field `cycle_ms`"),
        "{message}"
    );
}

#[test]
fn missing_or_mistyped_keys_are_refused_naming_the_key() {
    let cases = [
        (
            "port = \"/dev/ttyACM0\"",
            "connection: missing field `transport`",
        ),
        ("transport = \"serial\"", "missing field `port`"),
        (
            "transport = \"modbus-tcp\"\nunit = 1",
            "missing field `address`",
        ),
        ("transport = \"modbus-rtu\"", "missing field `port`"),
        (
            "transport = \"can-slcan\"\nport = \"a\"",
            "missing field `drives`",
        ),
        (
            &SLCAN.replace("port = \"/dev/ttyACM0\"\n", ""),
            "missing field `port`",
        ),
        (
            &SOCKETCAN.replace("interface = \"can0\"\n", ""),
            "missing field `interface`",
        ),
        (
            &SOCKETCAN.replace("counts_per_mm = [10000.0, 10000.0]\n", ""),
            "connection.drives: missing field `counts_per_mm`",
        ),
        (
            &SOCKETCAN.replace("counts_per_degree = 2912.711111111111\n", ""),
            "connection.drives: missing field `counts_per_degree`",
        ),
        (
            "transport = \"modbus\"\nport = \"a\"",
            "connection.transport: unknown transport `modbus`, expected one of `serial`",
        ),
        (
            "transport = 3\nport = \"a\"",
            "connection.transport: 3 must be a string",
        ),
        (
            "transport = \"modbus-rtu\"\nport = \"a\"\nunit = 300",
            "connection.unit: invalid value: integer `300`, expected u8",
        ),
        (
            "transport = \"serial\"\nport = \"a\"\nbaud = \"fast\"",
            "connection.baud: invalid type: string \"fast\"",
        ),
        (
            &SOCKETCAN.replace("[10000.0, 10000.0]", "[10000.0]"),
            "connection.drives.counts_per_mm: invalid length 1",
        ),
        (
            &format!("{SOCKETCAN}nodes = [1, 2, 3, 4]"),
            "connection.drives.nodes: invalid length 4",
        ),
        (
            &format!("{SOCKETCAN}heartbeat_ms = 70000"),
            "connection.drives.heartbeat_ms: invalid value: integer `70000`",
        ),
    ];
    for (text, expected) in cases {
        let message = unparsed(text);
        assert!(message.contains(expected), "{expected}\n{message}");
    }
}

#[test]
fn values_are_validated_and_errors_name_the_key() {
    let slcan_with = |key: &str| format!("{SLCAN}{key}\n");
    let can_with = |key: &str| format!("{SOCKETCAN}{key}\n");
    let cases: Vec<(String, &str, &str)> = vec![
        // serial
        (
            "transport = \"serial\"\nport = \" \"".into(),
            "connection.port",
            "serial device",
        ),
        (
            "transport = \"serial\"\nport = \"a\"\nbaud = 0".into(),
            "connection.baud",
            "above zero",
        ),
        (
            "transport = \"serial\"\nport = \"a\"\nrx_buffer = 128".into(),
            "connection.rx_buffer",
            "at least 257",
        ),
        // modbus-tcp
        (
            "transport = \"modbus-tcp\"\naddress = \"192.168.0.10\"".into(),
            "connection.address",
            "no port",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \"192.168.0.10:0\"".into(),
            "connection.address",
            "1 to 65535",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \"192.168.0.10:70000\"".into(),
            "connection.address",
            "1 to 65535",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \":502\"".into(),
            "connection.address",
            "no host",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \"fe80::1:502\"".into(),
            "connection.address",
            "in brackets",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \"[fe80::1:502\"".into(),
            "connection.address",
            "closing",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \"[fe80::zz]:502\"".into(),
            "connection.address",
            "IPv6",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \"plc 3:502\"".into(),
            "connection.address",
            "host name",
        ),
        (
            "transport = \"modbus-tcp\"\naddress = \"10.0.0.1:502\"\ntimeout_ms = 0".into(),
            "connection.timeout_ms",
            "1 to 60000",
        ),
        // modbus-rtu
        (
            "transport = \"modbus-rtu\"\nport = \"\"".into(),
            "connection.port",
            "serial device",
        ),
        (
            "transport = \"modbus-rtu\"\nport = \"a\"\nbaud = 100000".into(),
            "connection.baud",
            "19200",
        ),
        (
            "transport = \"modbus-rtu\"\nport = \"a\"\nunit = 0".into(),
            "connection.unit",
            "1 to 247",
        ),
        (
            "transport = \"modbus-rtu\"\nport = \"a\"\nunit = 248".into(),
            "connection.unit",
            "1 to 247",
        ),
        (
            "transport = \"modbus-rtu\"\nport = \"a\"\ntimeout_ms = 60001".into(),
            "connection.timeout_ms",
            "1 to 60000",
        ),
        // can-slcan
        (
            SLCAN.replace("\"/dev/ttyACM0\"", "\"\""),
            "connection.port",
            "serial device",
        ),
        (
            SLCAN.replace("[drives]", "baud = 0\n[drives]"),
            "connection.baud",
            "above zero",
        ),
        (
            SLCAN.replace("[drives]", "bitrate = 300000\n[drives]"),
            "connection.bitrate",
            "S0-S8",
        ),
        // can
        (
            SOCKETCAN.replace("\"can0\"", "\"\""),
            "connection.interface",
            "1 to 15",
        ),
        (
            SOCKETCAN.replace("\"can0\"", "\"can0 \""),
            "connection.interface",
            "white space",
        ),
        (
            SOCKETCAN.replace("\"can0\"", "\"a-very-long-can-name\""),
            "connection.interface",
            "1 to 15",
        ),
        (
            SOCKETCAN.replace("\"can0\"", "\"/dev/can0\""),
            "connection.interface",
            "`/`",
        ),
        // drives, through either CAN transport
        (
            slcan_with("nodes = [0, 2, 3]"),
            "connection.drives.nodes",
            "1 to 127",
        ),
        (
            can_with("nodes = [1, 2, 128]"),
            "connection.drives.nodes",
            "C drive's",
        ),
        (
            can_with("nodes = [1, 2, 1]"),
            "connection.drives.nodes",
            "distinct",
        ),
        (
            slcan_with("cycle_us = 249"),
            "connection.drives.cycle_us",
            "250 to 100000",
        ),
        (
            can_with("cycle_us = 100001"),
            "connection.drives.cycle_us",
            "250 to 100000",
        ),
        (
            SLCAN.replace("[10000.0, 10000.0]", "[10000.0, 0.0]"),
            "connection.drives.counts_per_mm",
            "(Z) must be a finite number above zero",
        ),
        (
            SOCKETCAN.replace("[10000.0, 10000.0]", "[-1.0, 10000.0]"),
            "connection.drives.counts_per_mm",
            "(X)",
        ),
        (
            SOCKETCAN.replace("[10000.0, 10000.0]", "[inf, 10000.0]"),
            "connection.drives.counts_per_mm",
            "finite",
        ),
        (
            SOCKETCAN.replace("2912.711111111111", "nan"),
            "connection.drives.counts_per_degree",
            "finite",
        ),
        (
            SLCAN.replace("2912.711111111111", "0.0"),
            "connection.drives.counts_per_degree",
            "above zero",
        ),
        (
            can_with("heartbeat_ms = 0"),
            "connection.drives.heartbeat_ms",
            "above zero",
        ),
        (
            can_with("heartbeat_ms = 100\nheartbeat_timeout_ms = 100"),
            "connection.drives.heartbeat_timeout_ms",
            "exceed drives.heartbeat_ms (100 ms)",
        ),
        (
            slcan_with("heartbeat_timeout_ms = 40"),
            "connection.drives.heartbeat_timeout_ms",
            "exceed",
        ),
        (
            can_with("following_error_window = 0"),
            "connection.drives.following_error_window",
            "trips at once",
        ),
        (
            can_with("following_error_window = 4294967295"),
            "connection.drives.following_error_window",
            "switches the check off",
        ),
        (
            slcan_with("spin_up_ms = 0"),
            "connection.drives.spin_up_ms",
            "1 to 60000",
        ),
        (
            can_with("spin_up_ms = 60001"),
            "connection.drives.spin_up_ms",
            "1 to 60000",
        ),
        // sim.toml's Z reaches 300 mm: 300 × 10⁷ counts is beyond INTEGER32.
        (
            SOCKETCAN.replace("[10000.0, 10000.0]", "[10000.0, 10000000.0]"),
            "connection.drives.counts_per_mm",
            "Z's travel (300 mm, axes.z)",
        ),
    ];
    for (text, key, problem_part) in cases {
        let (found, problem) = refused(&text);
        assert_eq!(found, key, "{text}\n{problem}");
        assert!(
            problem.contains(problem_part),
            "{problem_part:?} not in {problem:?}"
        );
        let message = load(&text).unwrap_err().to_string();
        assert!(
            message.starts_with(&format!("machine profile test.toml: {key}: ")),
            "{message}"
        );
    }
    // A serial connection needs grbl's streaming protocol: not LinuxCNC.
    let linuxcnc = profile_text("transport = \"serial\"\nport = \"a\"")
        .replace("dialect = \"grblhal\"", "dialect = \"linuxcnc\"");
    match MachineProfile::from_toml(&linuxcnc, "test.toml") {
        Err(ProfileError::Invalid { key, problem, .. }) => {
            assert_eq!(key, "connection.transport");
            assert!(problem.contains("grblHAL"), "{problem}");
        }
        other => panic!("{other:?}"),
    }
    // The edges that are allowed.
    for text in [
        "transport = \"serial\"\nport = \"a\"\nrx_buffer = 257".to_owned(),
        "transport = \"modbus-tcp\"\naddress = \"plc-3.local:502\"\ntimeout_ms = 60000".to_owned(),
        "transport = \"modbus-tcp\"\naddress = \"[::1]:65535\"\nunit = 0".to_owned(),
        "transport = \"modbus-rtu\"\nport = \"a\"\nbaud = 1200\nunit = 247".to_owned(),
        SLCAN.replace("[drives]", "bitrate = 10000\n[drives]"),
        can_with("nodes = [127, 1, 64]\ncycle_us = 250"),
        can_with("cycle_us = 100000\nheartbeat_ms = 1\nheartbeat_timeout_ms = 2"),
        can_with("following_error_window = 4294967294\nspin_up_ms = 60000"),
        SOCKETCAN.replace("\"can0\"", "\"can_fifteen_chr\""),
    ] {
        load(&text).unwrap_or_else(|e| panic!("{text}\n=> {e}"));
    }
}

#[test]
fn drive_settings_give_the_cycle_scales_and_supervision() {
    let Connection::CanSlcan(slcan) = toml::from_str(SLCAN).unwrap() else {
        panic!("can-slcan");
    };
    assert_eq!(slcan.bitrate, 1_000_000);
    let drives = &slcan.drives;
    assert_eq!(drives.period(), Duration::from_micros(4000));
    assert_eq!(
        drives.counts_per_unit(),
        [10_000.0, 10_000.0, 1_048_576.0 / 360.0]
    );
    assert_eq!(drives.heartbeat_timeout(), Duration::from_millis(150));
    assert_eq!(drives.spin_up(), Duration::from_secs(2));
    let mut other = drives.clone();
    other.heartbeat_ms = 20;
    other.heartbeat_timeout_ms = Some(70);
    assert_eq!(other.heartbeat_timeout(), Duration::from_millis(70));
    other.heartbeat_timeout_ms = None;
    assert_eq!(other.heartbeat_timeout(), Duration::from_millis(60));

    // The drives' own refusals, naming the key.
    for (change, key) in [
        (
            (|d: &mut DriveSettings| d.nodes = [1, 0, 3]) as fn(&mut DriveSettings),
            "connection.drives.nodes",
        ),
        (|d| d.nodes = [4, 4, 5], "connection.drives.nodes"),
        (|d| d.heartbeat_ms = 0, "connection.drives.heartbeat_ms"),
        (|d| d.cycle_us = 0, "connection.drives.cycle_us"),
    ] {
        let mut bad = drives.clone();
        change(&mut bad);
        assert_eq!(bad.validate().unwrap_err().key, key);
    }

    let mut rate = slcan.clone();
    rate.bitrate = 125_000;
    assert_eq!(rate.validate(), Ok(()));
    rate.bitrate = 1_000;
    assert_eq!(rate.validate().unwrap_err().key, "connection.bitrate");
}

#[test]
fn the_drives_mode_is_csp_or_ip() {
    // Absent: cyclic synchronous position, as before the key existed.
    let drives = |text: &str| {
        let connection: Connection = toml::from_str(text).unwrap();
        connection.drives().unwrap().clone()
    };
    let csp = drives(SLCAN);
    assert_eq!(csp.mode, DriveMode::Csp);
    assert_eq!(drives(&format!("{SLCAN}mode = \"csp\"\n")), csp);
    // "ip": interpolated position, everything else alike.
    let text = format!("{SOCKETCAN}mode = \"ip\"\n");
    let ip = drives(&text);
    assert_eq!(
        ip,
        DriveSettings {
            mode: DriveMode::Ip,
            ..csp
        }
    );
    assert_eq!(
        DriveMode::NAMES.map(|n| format!("{n:?}")),
        ["\"csp\"", "\"ip\""]
    );
    // Written back as the profile spells it, and loaded in a profile.
    let connection: Connection = toml::from_str(&text).unwrap();
    let written = toml::to_string(&connection).unwrap();
    assert!(written.contains("mode = \"ip\""), "{written}");
    let profile = load(&text).unwrap();
    assert_eq!(profile.connection, Some(connection));
    // Anything else is refused, naming the key and the two values.
    for (value, shown) in [("\"pp\"", "\"pp\""), ("\"IP\"", "\"IP\""), ("7", "")] {
        let message = unparsed(&format!("{SLCAN}mode = {value}\n"));
        assert!(
            message.contains("connection.drives.mode: "),
            "{value}: {message}"
        );
        if !shown.is_empty() {
            assert!(
                message.contains(&format!(
                    "{shown} must be \"csp\" (cyclic synchronous position, CiA 402 \
                     mode 8) or \"ip\" (interpolated position, mode 7)"
                )),
                "{message}"
            );
        }
    }
}

#[test]
fn modbus_settings_give_the_address_and_timeout() {
    let tcp = ModbusTcpSettings {
        address: "192.168.0.10:502".into(),
        unit: 1,
        timeout_ms: 250,
    };
    assert_eq!(
        tcp.socket_addr(),
        Some(SocketAddr::from(([192, 168, 0, 10], 502)))
    );
    assert_eq!(tcp.timeout(), Duration::from_millis(250));
    let v6 = ModbusTcpSettings {
        address: "[::1]:1502".into(),
        ..tcp.clone()
    };
    assert_eq!(
        v6.socket_addr(),
        Some(SocketAddr::from((std::net::Ipv6Addr::LOCALHOST, 1502)))
    );
    // A host name is valid, but for the transport to resolve.
    let named = ModbusTcpSettings {
        address: "plc-3.local:502".into(),
        ..tcp
    };
    assert_eq!(named.socket_addr(), None);
    let rtu = ModbusRtuSettings {
        port: "/dev/ttyUSB0".into(),
        baud: 19_200,
        unit: 1,
        timeout_ms: 1000,
    };
    assert_eq!(rtu.timeout(), Duration::from_secs(1));
}

/// The test drive's EDS, which python-canopen reads too.
const DRIVE_EDS: &str = include_str!("../../../tests/data/cia402-drive.eds");

/// A profile with the slcan drives and `eds` written to `dir/profile.toml`, loaded.
fn load_with_eds(dir: &std::path::Path, eds: &str) -> Result<MachineProfile, ProfileError> {
    let path = dir.join("profile.toml");
    std::fs::write(&path, profile_text(&format!("{SLCAN}eds = {eds}\n"))).unwrap();
    MachineProfile::load(&path)
}

#[test]
fn the_drives_eds_is_read_from_the_profiles_folder_once_or_per_drive() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir(dir.path().join("drives")).unwrap();
    std::fs::write(dir.path().join("drives/servo.eds"), DRIVE_EDS).unwrap();
    std::fs::write(dir.path().join("spindle.eds"), DRIVE_EDS).unwrap();
    // One file for all three drives: read once, from the profile's folder (not the
    // working directory, where drives/servo.eds is not).
    let profile = load_with_eds(dir.path(), "\"drives/servo.eds\"").unwrap();
    let drives = profile.connection.as_ref().unwrap().drives().unwrap();
    assert_eq!(drives.eds, Some(EdsFiles::All("drives/servo.eds".into())));
    let [x, z, c] = drives.data_sheets.clone().expect("read at load");
    assert!(std::sync::Arc::ptr_eq(&x, &z) && std::sync::Arc::ptr_eq(&z, &c));
    assert_eq!(x.path(), dir.path().join("drives/servo.eds"));
    assert!(x.object(0x607A, 0).is_some());
    // One each, X, Z, C: the same path read once.
    let profile = load_with_eds(
        dir.path(),
        "[\"drives/servo.eds\", \"drives/servo.eds\", \"spindle.eds\"]",
    )
    .unwrap();
    let drives = profile.connection.as_ref().unwrap().drives().unwrap();
    let [x, z, c] = drives.data_sheets.clone().unwrap();
    assert!(std::sync::Arc::ptr_eq(&x, &z) && !std::sync::Arc::ptr_eq(&z, &c));
    assert_eq!(c.path(), dir.path().join("spindle.eds"));
    // Written back as given.
    let written = toml::to_string(profile.connection.as_ref().unwrap()).unwrap();
    assert!(
        written.contains("eds = [\"drives/servo.eds\", \"drives/servo.eds\", \"spindle.eds\"]"),
        "{written}"
    );
    // Without `eds`, nothing is read.
    let drives = toml::from_str::<Connection>(SLCAN).unwrap();
    assert_eq!(drives.drives().unwrap().data_sheets, None);
}

#[test]
fn an_eds_that_cannot_be_read_is_refused_at_load_naming_the_file_and_line() {
    let dir = tempfile::tempdir().unwrap();
    let message = load_with_eds(dir.path(), "\"absent.eds\"")
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("connection.drives.eds: cannot read EDS file")
            && message.contains(&dir.path().join("absent.eds").display().to_string()),
        "{message}"
    );
    std::fs::write(
        dir.path().join("broken.eds"),
        "[FileInfo]\nFileName broken.eds\n",
    )
    .unwrap();
    let message = load_with_eds(
        dir.path(),
        "[\"broken.eds\", \"broken.eds\", \"broken.eds\"]",
    )
    .unwrap_err()
    .to_string();
    assert!(
        message.contains(&format!(
            "connection.drives.eds: EDS file {}, line 2: ",
            dir.path().join("broken.eds").display()
        )),
        "{message}"
    );
}

#[test]
fn eds_is_one_path_or_three() {
    for value in ["7", "[\"a.eds\", \"b.eds\"]", "[\"a.eds\", 1, \"c.eds\"]"] {
        let message = unparsed(&format!("{SLCAN}eds = {value}\n"));
        assert!(
            message.contains("connection.drives.eds: ")
                && message.contains("must be a path")
                && message.contains("three, X, Z and C"),
            "{value}: {message}"
        );
    }
}
