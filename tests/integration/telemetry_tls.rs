//! Live telemetry over TLS against a real broker: mosquitto with a TLS listener that takes
//! each client's certificate as its login (`require_certificate`,
//! `use_identity_as_username`), the shop's certificates made by the test. A run is
//! published with its profile's `tls_ca`, `tls_cert` and `tls_key` (found beside the
//! profile) and read by an independent subscriber (mosquitto_sub) and by the shop overview;
//! a broker that refuses the bridge's certificate, or whose own does not verify, is said
//! once and the run goes on as without telemetry; each unusable TLS setting is refused
//! before anything runs, naming its key and file.

use std::ffi::OsStr;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

use serde_json::Value;

use crate::http;
use crate::mosquitto::{Authority, Mosquitto};
use crate::telemetry::{
    dry_run_args, mosquitto_sub, overview, until_goodbye, until_subscribed,
    until_the_overview_shows, went_on_without_the_broker, whirl,
};
use crate::util;

/// A shop over TLS: its CA, a broker whose certificate it signed for 127.0.0.1, and the
/// folder of the bridge's profile, the certificates beside it in `pki/`.
struct Shop {
    dir: tempfile::TempDir,
    authority: Authority,
    broker: Mosquitto,
}

impl Shop {
    /// `None` where mosquitto is not installed (a failure under `CI`, as the fixture says).
    fn start() -> Option<Shop> {
        let dir = tempfile::tempdir().unwrap();
        let pki = dir.path().join("pki");
        std::fs::create_dir(&pki).unwrap();
        let authority = Authority::new(&pki, "shop");
        let server = authority.server("broker", &["127.0.0.1"]);
        let broker = Mosquitto::tls(&authority.ca, (&server.0, &server.1))?;
        Some(Shop {
            dir,
            authority,
            broker,
        })
    }

    /// mosquitto_sub's and mosquitto_pub's options for a client of the shop's CA named
    /// `name`.
    fn client_args(&self, name: &str) -> Vec<String> {
        let (cert, key) = self.authority.client(name);
        let path = |p: &Path| p.display().to_string();
        vec![
            "--cafile".into(),
            path(&self.authority.ca),
            "--cert".into(),
            path(&cert),
            "--key".into(),
            path(&key),
        ]
    }

    /// The profile `NAME.toml` beside `pki/`: the built-in simulator named for the shop as
    /// Lathe 3, reporting to the shop's broker by its name on the shop's network (each test
    /// gives the broker of its own with `--mqtt`), with the `[telemetry]` lines `tls`.
    fn profile(&self, name: &str, tls: &str) -> PathBuf {
        let sim = std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap();
        util::write(
            self.dir.path(),
            &format!("{name}.toml"),
            &format!(
                "{sim}\n[telemetry]\nmqtt = \"mqtts://broker.shop.lan\"\nmachine = \"Lathe 3\"\n\
                 {tls}\n"
            ),
        )
    }

    /// The profile of Lathe 3 with its certificate: relative paths, beside the profile.
    fn lathe3(&self) -> PathBuf {
        self.authority.client("lathe3");
        self.profile(
            "lathe3",
            "tls_ca = \"pki/shop-ca.pem\"\ntls_cert = \"pki/lathe3.crt\"\ntls_key = \"pki/lathe3.key\"",
        )
    }
}

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

#[test]
fn a_dry_run_over_tls_logs_in_by_its_certificate_and_mosquitto_sub_and_the_overview_read_it() {
    let Some(shop) = Shop::start() else {
        return;
    };
    let url = shop.broker.url();
    assert!(url.starts_with("mqtts://"), "{url}");
    let reader = shop.client_args("reader");
    let reader: Vec<&str> = reader.iter().map(String::as_str).collect();
    let (mut sub, lines) = mosquitto_sub(&shop.broker, &reader);
    until_subscribed(&shop.broker, &lines, &reader);
    // The shop overview follows the broker over TLS with a certificate of its own.
    let (overview_cert, overview_key) = shop.authority.client("overview");
    let mut overview = overview(shop.dir.path(), &url)
        .arg("--tls-ca")
        .arg(&shop.authority.ca)
        .arg("--tls-cert")
        .arg(&overview_cert)
        .arg("--tls-key")
        .arg(&overview_key)
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let overview_at = http::listening(&mut overview);

    let profile = shop.lathe3();
    let profile = profile.to_str().unwrap();
    let run_dir = tempfile::tempdir().unwrap();
    let (output, report) = whirl(&dry_run_args(
        run_dir.path(),
        &["--machine", profile, "--mqtt", &url],
    ));
    assert!(output.status.success(), "{}", text(&output.stderr));
    assert!(
        output.stderr.is_empty(),
        "a broker that answers is not mentioned: {}",
        text(&output.stderr)
    );
    let got = until_goodbye(&lines);
    let _ = sub.kill();
    let _ = sub.wait();
    let events: Vec<&Value> = got
        .iter()
        .filter(|m| m.0 == "whirl/lathe-3/event")
        .map(|m| &m.3)
        .filter(|e| e["kind"] != "feed_override")
        .collect();
    let kinds: Vec<&Value> = events.iter().map(|e| &e["kind"]).collect();
    assert_eq!(kinds, ["start", "end"], "{got:?}");
    assert_eq!(events[0]["run"]["lines"], report["lines"]);
    assert_eq!(events[1]["completed"], true);
    // The broker took the bridge's certificate as its login: lathe3, its common name.
    let log = shop.broker.log();
    assert!(
        log.lines()
            .any(|l| l.contains(" as whirl-") && l.contains("u'lathe3'")),
        "{log}"
    );

    // The overview has the machine and how its run ended.
    let row = until_the_overview_shows(overview_at, "lathe-3");
    assert_eq!(row["run"]["lines"], report["lines"], "{row}");
    let _ = overview.kill();
    let _ = overview.wait();
    assert!(
        shop.broker
            .log()
            .lines()
            .any(|l| l.contains(" as whirl-shop-") && l.contains("u'overview'")),
        "{}",
        shop.broker.log()
    );
}

#[test]
fn without_tls_ca_the_systems_roots_verify_the_broker() {
    let Some(shop) = Shop::start() else {
        return;
    };
    shop.authority.client("lathe3");
    let profile = shop.profile(
        "roots",
        "tls_cert = \"pki/lathe3.crt\"\ntls_key = \"pki/lathe3.key\"",
    );
    let url = shop.broker.url();
    let run = |roots: &Path| {
        let dir = tempfile::tempdir().unwrap();
        // The system's roots as rustls-native-certs reads them: SSL_CERT_FILE, where set
        // (and no SSL_CERT_DIR), in place of the system's bundle.
        Command::new(env!("CARGO_BIN_EXE_whirl"))
            .env("WHIRL_DB", util::records_db())
            .env("SSL_CERT_FILE", roots)
            .env_remove("SSL_CERT_DIR")
            .args(dry_run_args(dir.path(), &[]))
            .arg("--machine")
            .arg(&profile)
            .args(["--mqtt", &url])
            .output()
            .unwrap()
    };
    // The shop's CA among the system's roots: published, nothing said.
    let trusted = run(&shop.authority.ca);
    assert!(trusted.status.success(), "{}", text(&trusted.stderr));
    assert!(trusted.stderr.is_empty(), "{}", text(&trusted.stderr));
    assert!(
        shop.broker
            .log()
            .lines()
            .any(|l| l.contains(" as whirl-") && l.contains("u'lathe3'")),
        "{}",
        shop.broker.log()
    );
    // Roots that are another CA's: the broker's certificate does not verify.
    let other = Authority::new(shop.dir.path(), "other");
    let untrusted = run(&other.ca);
    let stderr = text(&untrusted.stderr);
    assert!(untrusted.status.success(), "{stderr}");
    assert_eq!(stderr.matches("cannot be reached").count(), 1, "{stderr}");
    assert!(stderr.contains("UnknownIssuer"), "{stderr}");
    // No roots at all: refused before anything runs, naming tls_ca.
    let empty = util::write(shop.dir.path(), "empty.pem", "");
    let rootless = run(&empty);
    let stderr = text(&rootless.stderr);
    assert_eq!(rootless.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("tls_ca") && stderr.contains("no root certificates"),
        "{stderr}"
    );
}

#[test]
fn a_broker_that_refuses_the_bridges_certificate_is_said_once_and_the_run_goes_on() {
    let Some(shop) = Shop::start() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (plain, without) = whirl(&dry_run_args(dir.path(), &[]));
    assert!(plain.status.success());
    // No certificate at all, and one from a CA the broker does not know.
    let intruders = Authority::new(&shop.dir.path().join("pki"), "intruders");
    intruders.client("intruder");
    let anonymous = shop.profile("anonymous", "tls_ca = \"pki/shop-ca.pem\"");
    let intruder = shop.profile(
        "intruder",
        "tls_ca = \"pki/shop-ca.pem\"\ntls_cert = \"pki/intruder.crt\"\ntls_key = \"pki/intruder.key\"",
    );
    let url = shop.broker.url();
    for profile in [anonymous, intruder] {
        let profile = profile.to_str().unwrap();
        let (output, report) = whirl(&dry_run_args(
            dir.path(),
            &["--machine", profile, "--mqtt", &url],
        ));
        let stderr = went_on_without_the_broker(&output, &report, &without, profile);
        // What TLS said: the broker's alert, ending the handshake.
        assert!(stderr.contains("fatal alert"), "{profile}: {stderr}");
    }
}

#[test]
fn a_broker_whose_certificate_does_not_verify_is_said_once_and_the_run_goes_on() {
    let Some(shop) = Shop::start() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let (plain, without) = whirl(&dry_run_args(dir.path(), &[]));
    assert!(plain.status.success());
    // A broker with a certificate of the shop's CA for another host name, and one with a
    // certificate for 127.0.0.1 from a CA the bridge does not know.
    let pki = shop.dir.path().join("pki");
    let misnamed = shop.authority.server("misnamed", &["broker.other.lan"]);
    let strangers = Authority::new(&pki, "strangers");
    let unknown = strangers.server("unknown", &["127.0.0.1"]);
    let profile = shop.lathe3();
    let profile = profile.to_str().unwrap();
    for (server, says) in [
        (misnamed, "not valid for name \"127.0.0.1\""),
        (unknown, "UnknownIssuer"),
    ] {
        let Some(broker) = Mosquitto::tls(&shop.authority.ca, (&server.0, &server.1)) else {
            return;
        };
        let (output, report) = whirl(&dry_run_args(
            dir.path(),
            &["--machine", profile, "--mqtt", &broker.url()],
        ));
        let stderr = went_on_without_the_broker(&output, &report, &without, says);
        assert!(
            stderr.contains("invalid peer certificate") && stderr.contains(says),
            "{stderr}"
        );
    }
}

#[test]
fn each_unusable_tls_setting_is_refused_before_anything_runs_naming_its_key_and_file() {
    // No broker is needed: nothing may get as far as connecting.
    let dir = tempfile::tempdir().unwrap();
    let pki = dir.path().join("pki");
    std::fs::create_dir(&pki).unwrap();
    let authority = Authority::new(&pki, "shop");
    authority.client("lathe3");
    authority.client("other");
    let sim = std::fs::read_to_string(util::root().join("machine-profiles/sim.toml")).unwrap();
    let cases = [
        (
            "mqtt = \"mqtt://broker.shop.lan\"\ntls_ca = \"pki/shop-ca.pem\"",
            "telemetry.tls_ca",
            "is for a broker spoken to over TLS",
        ),
        (
            "mqtt = \"mqtts://broker.shop.lan\"\ntls_ca = \"pki/missing.pem\"",
            "tls_ca",
            "pki/missing.pem (",
        ),
        (
            "mqtt = \"mqtts://broker.shop.lan\"\ntls_ca = \"pki/lathe3.key\"",
            "tls_ca",
            "pki/lathe3.key holds no certificate",
        ),
        (
            "mqtt = \"mqtts://broker.shop.lan\"\ntls_ca = \"pki/shop-ca.pem\"\n\
             tls_cert = \"pki/lathe3.crt\"\ntls_key = \"pki/lathe3.crt\"",
            "tls_key",
            "pki/lathe3.crt holds no private key",
        ),
        (
            "mqtt = \"mqtts://broker.shop.lan\"\ntls_ca = \"pki/shop-ca.pem\"\n\
             tls_cert = \"pki/lathe3.crt\"",
            "telemetry.tls_cert",
            "give `tls_key` too",
        ),
        (
            "mqtt = \"mqtts://broker.shop.lan\"\ntls_ca = \"pki/shop-ca.pem\"\n\
             tls_cert = \"pki/lathe3.crt\"\ntls_key = \"pki/other.key\"",
            "tls_key",
            "pki/other.key cannot be used with the certificate in",
        ),
    ];
    let log = dir.path().join("run.jsonl");
    for (n, (telemetry, key, says)) in cases.iter().enumerate() {
        let profile = util::write(
            dir.path(),
            &format!("lathe-{n}.toml"),
            &format!("{sim}\n[telemetry]\n{telemetry}\n"),
        );
        let o = util::whirl(&[
            OsStr::new("dry-run"),
            util::example("double-start").as_os_str(),
            OsStr::new("--machine"),
            profile.as_os_str(),
            OsStr::new("--log"),
            log.as_os_str(),
        ]);
        let stderr = text(&o.stderr);
        assert_eq!(o.status.code(), Some(1), "{telemetry}: {stderr}");
        assert!(
            stderr.contains(key) && stderr.contains(says),
            "{telemetry}: {stderr}"
        );
        assert!(!log.exists(), "{telemetry}: a log was opened");
    }
    // `--mqtt` without TLS over a profile whose TLS keys need it.
    let profile = util::write(
        dir.path(),
        "lathe3.toml",
        &format!(
            "{sim}\n[telemetry]\nmqtt = \"mqtts://broker.shop.lan\"\ntls_ca = \"pki/shop-ca.pem\"\n"
        ),
    );
    let o = util::whirl(&[
        OsStr::new("dry-run"),
        util::example("double-start").as_os_str(),
        OsStr::new("--machine"),
        profile.as_os_str(),
        OsStr::new("--log"),
        log.as_os_str(),
        OsStr::new("--mqtt"),
        OsStr::new("mqtt://127.0.0.1:1883"),
    ]);
    let stderr = text(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.contains("tls_ca") && stderr.contains("\"mqtt://127.0.0.1:1883\" is not"),
        "{stderr}"
    );
    assert!(!log.exists(), "a log was opened");
}

#[test]
fn the_overview_refuses_unusable_tls_files_naming_the_option() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing-ca.pem");
    let missing = missing.to_str().unwrap();
    let refused = |args: &[&str]| {
        let o = Command::new(env!("CARGO_BIN_EXE_whirl"))
            .arg("--db")
            .arg(dir.path().join("shop.sqlite"))
            .args(["serve", "--shop", "--listen", "127.0.0.1:0"])
            .args(args)
            .output()
            .unwrap();
        assert!(
            !text(&o.stdout).contains("http://"),
            "{args:?}: the overview listened"
        );
        (o.status.code(), text(&o.stderr))
    };
    let (code, stderr) = refused(&["--mqtt", "mqtts://127.0.0.1:8883", "--tls-ca", missing]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("--tls-ca") && stderr.contains(missing),
        "{stderr}"
    );
    let (code, stderr) = refused(&["--mqtt", "mqtt://127.0.0.1:1883", "--tls-ca", missing]);
    assert_eq!(code, Some(1), "{stderr}");
    assert!(
        stderr.contains("--tls-ca") && stderr.contains("is for a broker spoken to over TLS"),
        "{stderr}"
    );
    // A certificate without its key is a usage error, clap's.
    let (code, stderr) = refused(&["--mqtt", "mqtts://127.0.0.1:8883", "--tls-cert", missing]);
    assert_eq!(code, Some(2), "{stderr}");
    assert!(stderr.contains("--tls-key"), "{stderr}");
}
