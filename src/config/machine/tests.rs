//! Tests of machine profiles, kept apart from them for length: every profile file loads,
//! values and schema errors name the file and the key; `invalid` serves other modules' tests.

use super::*;

#[test]
fn every_profile_file_loads() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("machine-profiles");
    let mut names = Vec::new();
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let profile = MachineProfile::load(&path).unwrap_or_else(|e| panic!("{e}"));
            names.push((
                path.file_name().unwrap().to_string_lossy().into_owned(),
                profile,
            ));
        }
    }
    names.sort_by(|a, b| a.0.cmp(&b.0));
    let files: Vec<&str> = names.iter().map(|(n, _)| n.as_str()).collect();
    assert_eq!(
        files,
        [
            "canopen-drives.toml",
            "grblhal-lathe.toml",
            "linuxcnc-lathe.toml",
            "modbus-plc.toml",
            "sim.toml"
        ]
    );
    let sim = &names[4].1;
    assert_eq!(sim.dialect, Dialect::GrblHal);
    assert_eq!(sim.number, NumberType::F32);
    assert_eq!(sim.x_mode, XMode::Radius);
    let linuxcnc = &names[2].1;
    assert_eq!(linuxcnc.dialect, Dialect::LinuxCnc);
    assert_eq!(linuxcnc.blend_tolerance_mm, Some(0.001));
    assert_eq!(linuxcnc.x_mode, XMode::Diameter);
    assert!(linuxcnc.x_diameter());
    assert_eq!(&MachineProfile::builtin_sim().unwrap(), sim);
    // The G-code machines leave the connection to the caller.
    for (_, profile) in names
        .iter()
        .filter(|(n, _)| n.contains("lathe") || n == "sim.toml")
    {
        assert_eq!(profile.connection, None, "{}", profile.name);
    }

    // A PLC on Modbus TCP: segments carry radius X and machine positions, exact.
    let plc = &names[3].1;
    assert_eq!(plc.dialect, Dialect::LinuxCnc);
    assert_eq!(plc.number, NumberType::F64);
    assert_eq!(plc.x_mode, XMode::Radius);
    assert_eq!(plc.blend_tolerance_mm, None);
    let Some(Connection::ModbusTcp(tcp)) = &plc.connection else {
        panic!("{:?}", plc.connection);
    };
    assert_eq!(
        tcp.socket_addr(),
        Some(std::net::SocketAddr::from(([192, 168, 0, 10], 502)))
    );
    // The unit the register map serves (docs/modbus.md).
    assert_eq!(tcp.unit, 1);
    assert_eq!(tcp.timeout(), std::time::Duration::from_millis(500));

    // CiA 402 drives through a CANable: 4 ms, 0.1 µm on X and Z, 2^20 counts a turn of C.
    let drives_profile = &names[0].1;
    assert_eq!(drives_profile.dialect, Dialect::LinuxCnc);
    assert_eq!(drives_profile.number, NumberType::F64);
    assert_eq!(drives_profile.x_mode, XMode::Radius);
    let Some(Connection::CanSlcan(slcan)) = &drives_profile.connection else {
        panic!("{:?}", drives_profile.connection);
    };
    assert_eq!(slcan.port, "/dev/ttyACM0");
    assert_eq!(slcan.bitrate, 1_000_000);
    let drives = &slcan.drives;
    assert_eq!(drives.nodes, [1, 2, 3]);
    assert_eq!(drives.period(), std::time::Duration::from_millis(4));
    assert_eq!(
        drives.counts_per_unit(),
        [10_000.0, 10_000.0, f64::from(1u32 << 20) / 360.0]
    );
    // The drives' defaults: 50 ms heartbeats, supervised at three, a 10 000-count
    // window, cyclic synchronous position.
    assert_eq!(
        drives.heartbeat_timeout(),
        std::time::Duration::from_millis(150)
    );
    assert_eq!(drives.following_error_window, 10_000);
    assert_eq!(drives.mode, crate::config::connection::DriveMode::Csp);
    assert_eq!(drives.spin_up(), std::time::Duration::from_secs(2));
}

#[test]
fn a_bad_connection_is_refused_naming_its_key() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let text = std::fs::read_to_string(root.join("machine-profiles/canopen-drives.toml")).unwrap();
    let bad = text.replacen("cycle_us = 4000", "cycle_us = 100", 1);
    assert_ne!(bad, text);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bad.toml");
    std::fs::write(&path, bad).unwrap();
    let error = MachineProfile::load(&path).unwrap_err();
    let message = error.to_string();
    assert!(
        matches!(&error, ProfileError::Invalid { key, .. } if key == "connection.drives.cycle_us"),
        "{message}"
    );
    assert!(
        message.contains("bad.toml: connection.drives.cycle_us: 100 µs must be 250 to"),
        "{message}"
    );
    // A key the table does not know is a schema error that names it.
    let unknown = text.replacen("cycle_us = 4000", "cycle_ms = 4", 1);
    let message = MachineProfile::from_toml(&unknown, "x.toml")
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("connection.drives: unknown field `cycle_ms`"),
        "{message}"
    );
}

#[test]
fn a_profiles_telemetry_is_read_and_a_bad_one_refused_naming_its_key() {
    let good =
        format!("{SIM}\n[telemetry]\nmqtt = \"mqtt://broker:1884\"\nmachine = \"Lathe 3\"\n");
    let profile = MachineProfile::from_toml(&good, "lathe.toml").unwrap();
    let telemetry = profile.telemetry.unwrap();
    assert_eq!(telemetry.broker().unwrap().unwrap().port, 1884);
    assert_eq!(telemetry.topic_root(&profile.name), "whirl/lathe-3");
    let bad = good.replace("mqtt://broker:1884", "tcp://broker:1884");
    let error = MachineProfile::from_toml(&bad, "lathe.toml").unwrap_err();
    assert!(
        matches!(&error, ProfileError::Invalid { key, .. } if key == "telemetry.mqtt"),
        "{error}"
    );
}

#[test]
fn a_profiles_tls_files_are_found_beside_it_and_read_only_when_telemetry_starts() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("lathe3.toml");
    std::fs::write(
        &path,
        format!(
            "{SIM}\n[telemetry]\nmqtt = \"mqtts://broker.shop.lan\"\ntls_ca = \"pki/ca.pem\"\n\
             tls_cert = \"/etc/whirl/lathe3.crt\"\ntls_key = \"/etc/whirl/lathe3.key\"\n"
        ),
    )
    .unwrap();
    // None of the files exists: the profile loads all the same (`whirl plan` needs none).
    let telemetry = MachineProfile::load(&path).unwrap().telemetry.unwrap();
    assert_eq!(telemetry.tls_ca, Some(dir.path().join("pki/ca.pem")));
    assert_eq!(
        telemetry.tls_cert,
        Some(PathBuf::from("/etc/whirl/lathe3.crt"))
    );
    let error = telemetry.tls().unwrap_err();
    assert_eq!(error.key, "tls_ca");
    assert!(
        error
            .problem
            .contains(&dir.path().join("pki/ca.pem").display().to_string()),
        "{error}"
    );
    // A TLS key with a broker spoken to without TLS is refused at load, naming it.
    let plain = std::fs::read_to_string(&path)
        .unwrap()
        .replace("mqtts://", "mqtt://");
    let error = MachineProfile::from_toml(&plain, "lathe3.toml").unwrap_err();
    assert!(
        matches!(&error, ProfileError::Invalid { key, .. } if key == "telemetry.tls_ca"),
        "{error}"
    );
}

const SIM: &str = r#"
name = "sim"
dialect = "grblhal"
number = "f32"
x_mode = "radius"
max_line_length = 256
[axes.x]
min = -5.0
max = 160.0
max_rate = 3000.0
accel = 500.0
[axes.z]
min = -300.0
max = 300.0
max_rate = 3000.0
accel = 500.0
[axes.c]
max_rate = 72000.0
accel = 7200.0
"#;

/// The key and problem of a profile `text` that parses but does not validate.
pub(crate) fn invalid(text: &str) -> (String, String) {
    match MachineProfile::from_toml(text, "test.toml") {
        Err(ProfileError::Invalid {
            origin,
            key,
            problem,
        }) => {
            assert_eq!(origin, "test.toml");
            (key, problem)
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn values_are_validated_and_errors_name_the_key() {
    assert!(MachineProfile::from_toml(SIM, "sim").is_ok());
    let cases = [
        ("min = -5.0", "min = 170.0", "axes.x.min"),
        ("max = 300.0", "max = -300.0", "axes.z.min"),
        (
            "max_rate = 3000.0\naccel = 500.0\n[axes.z]",
            "max_rate = 0.0\naccel = 500.0\n[axes.z]",
            "axes.x.max_rate",
        ),
        ("accel = 7200.0", "accel = -1.0", "axes.c.accel"),
        ("max_rate = 72000.0", "max_rate = inf", "axes.c.max_rate"),
        (
            "max_line_length = 256",
            "max_line_length = 31",
            "max_line_length",
        ),
        (
            "accel = 7200.0",
            "accel = 7200.0\nmin = 10.0\nmax = -10.0",
            "axes.c.min",
        ),
        ("accel = 7200.0", "accel = 7200.0\nmin = nan", "axes.c.min"),
        (
            "max_line_length = 256",
            "max_line_length = 256\nblend_tolerance_mm = 0.001",
            "blend_tolerance_mm",
        ),
        ("name = \"sim\"", "name = \" \"", "name"),
        (
            "max_line_length = 256",
            "max_line_length = 256\n[spindle]\nmin_rpm = 600.0\nmax_rpm = 500.0",
            "spindle.min_rpm",
        ),
        (
            "max_line_length = 256",
            "max_line_length = 256\n[spindle]\nmin_rpm = 0.0\nmax_rpm = 500.0",
            "spindle.min_rpm",
        ),
    ];
    for (from, to, key) in cases {
        let text = SIM.replacen(from, to, 1);
        assert_ne!(text, SIM);
        let (found, problem) = invalid(&text);
        assert_eq!(found, key, "{problem}");
    }
    let linuxcnc = SIM.replace("\"grblhal\"", "\"linuxcnc\"").replace(
        "max_line_length = 256",
        "max_line_length = 256\nblend_tolerance_mm = 0.0",
    );
    assert_eq!(invalid(&linuxcnc).0, "blend_tolerance_mm");
}

#[test]
fn schema_errors_name_the_file_and_the_key() {
    for (text, key) in [
        (
            SIM.replace("accel = 500.0", "accel = 500.0\nacel = 1.0"),
            "acel",
        ),
        (
            SIM.replace("dialect = \"grblhal\"", "dialect = \"mach3\""),
            "mach3",
        ),
        (SIM.replace("number = \"f32\"\n", ""), "number"),
        (
            SIM.replace("x_mode = \"radius\"", "x_mode = \"radial\""),
            "radial",
        ),
        (
            SIM.replace(
                "max_line_length = 256",
                "max_line_length = 256\nc_rebase_turns = 5",
            ),
            "c_rebase_turns",
        ),
    ] {
        let error = MachineProfile::from_toml(&text, "machine-profiles/x.toml").unwrap_err();
        let message = error.to_string();
        assert!(matches!(error, ProfileError::Toml { .. }));
        assert!(
            message.starts_with("machine profile machine-profiles/x.toml: "),
            "{message}"
        );
        assert!(message.contains(key), "{message}");
    }
    let missing = Path::new("/nonexistent/profile.toml");
    let error = MachineProfile::load(missing).unwrap_err();
    assert!(error.to_string().contains("/nonexistent/profile.toml"));
}

#[test]
fn f32_spacing_matches_ieee754() {
    // 2^17 ≤ 180 000 < 2^18: the gap is 2^(17-23) = 2^-6.
    assert_eq!(NumberType::F32.spacing_at(180_000.0), 0.015625);
    assert_eq!(NumberType::F32.spacing_at(-1.0), f64::from(f32::EPSILON));
    assert_eq!(NumberType::F64.spacing_at(1.0), f64::EPSILON);
    assert_eq!(NumberType::F32.spacing_at(1e39), f64::INFINITY);
    assert_eq!(NumberType::F64.spacing_at(f64::NAN), f64::INFINITY);
}
