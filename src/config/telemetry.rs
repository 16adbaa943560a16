//! Where a bridge reports its machine's live state: the `[telemetry]` table of a machine
//! profile (or the command line's `--mqtt` and `whirl serve --opcua`).
//!
//! A shop's machines report to one MQTT broker, under one topic prefix, each under its own
//! name: `whirl/lathe-3/state`; a shop's MES may instead (or as well) read each machine as
//! OPC UA for Machine Tools from the bridge's own OPC UA server. The table says where the
//! broker is, how to log in and how the bridge keeps its messages while the broker is
//! away (`crate::telemetry` publishes), how it checks the broker and shows itself over
//! TLS (`mqtts://`, [`TelemetrySettings::tls`]), and where the OPC UA server listens, how
//! it secures its messages and who may log in (`crate::opcua` serves,
//! [`crate::config::opcua`] checks). A table names `mqtt`, `opcua` or both.
//!
//! ```
//! use whirl::config::telemetry::TelemetrySettings;
//!
//! let settings: TelemetrySettings = toml::from_str(
//!     r#"
//!     mqtt = "mqtt://broker.shop.lan"
//!     machine = "Lathe 3"
//!     user = "lathe3"
//!     password = "secret"
//!     opcua = "127.0.0.1:4840"
//!     "#,
//! )
//! .unwrap();
//! settings.validate().unwrap();
//! let broker = settings.broker().unwrap().unwrap();
//! assert_eq!((broker.host.as_str(), broker.port), ("broker.shop.lan", 1883));
//! assert_eq!(settings.topic_root("ignored"), "whirl/lathe-3");
//! assert_eq!(settings.opcua().unwrap().unwrap().url(), "opc.tcp://127.0.0.1:4840/");
//! ```

use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde::{Deserialize, Serialize};

use crate::config::opcua::{self, Nameplate, OpcUaSettings, Security};

mod tls;

/// MQTT's registered port for unencrypted connections (IANA).
pub const MQTT_PORT: u16 = 1883;
/// MQTT's registered port for connections over TLS (IANA).
pub const MQTTS_PORT: u16 = 8883;

/// A machine profile's `[telemetry]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TelemetrySettings {
    /// The broker, `mqtt://HOST[:PORT]` (port 1883 unless given), or `mqtts://HOST[:PORT]`
    /// over TLS (port 8883 unless given); absent: no MQTT.
    #[serde(default)]
    pub mqtt: Option<String>,
    /// The shop's topic prefix, one or more levels (`whirl`, `plant2/whirling`).
    #[serde(default = "default_prefix")]
    pub prefix: String,
    /// The machine's name in topics; absent: the profile's name. Made topic-safe
    /// ([`topic_name`]).
    #[serde(default)]
    pub machine: Option<String>,
    /// The broker's user name, if it asks for one.
    #[serde(default)]
    pub user: Option<String>,
    /// Its password (with `user`).
    #[serde(default)]
    pub password: Option<String>,
    /// The shop's CA, a PEM file of one or more certificates, that an `mqtts://` broker's
    /// certificate must be signed by; absent: the system's root certificates. A relative
    /// path is relative to the profile's folder, as the profile's other files are.
    #[serde(default)]
    pub tls_ca: Option<PathBuf>,
    /// The bridge's own certificate (PEM, any intermediate after it), which a broker that
    /// asks for one takes as the bridge's login (mosquitto's `use_identity_as_username`);
    /// with `tls_key`.
    #[serde(default)]
    pub tls_cert: Option<PathBuf>,
    /// Its private key (PEM: PKCS #8, PKCS #1 or SEC 1, not encrypted: the bridge starts
    /// unattended); with `tls_cert`.
    #[serde(default)]
    pub tls_key: Option<PathBuf>,
    /// MQTT keep-alive, s: the broker publishes the bridge's last will (offline) when it
    /// has heard nothing for one and a half times this.
    #[serde(default = "default_keepalive")]
    pub keepalive_s: u64,
    /// The events kept while the broker is away (oldest dropped past it, and said).
    #[serde(default = "default_queue")]
    pub queue: usize,
    /// The shortest time between two progress messages, s.
    #[serde(default = "default_progress_interval")]
    pub progress_interval_s: f64,
    /// The console's address the shop overview links to (`http://lathe3.shop.lan:8080`);
    /// absent: none.
    #[serde(default)]
    pub console: Option<String>,
    /// Where the OPC UA server listens, `HOST:PORT` (an IP address of this host, or
    /// localhost; port 4840 unless given); absent: no OPC UA server.
    #[serde(default)]
    pub opcua: Option<String>,
    /// How the OPC UA server secures messages: `none` (loopback only, its default),
    /// `sign` or `sign-and-encrypt` (the default beyond loopback).
    #[serde(default)]
    pub opcua_security: Option<Security>,
    /// The user OPC UA clients log in as (required beyond loopback; absent on loopback:
    /// anonymous clients).
    #[serde(default)]
    pub opcua_user: Option<String>,
    /// Its password.
    #[serde(default)]
    pub opcua_password: Option<String>,
    /// The folder of the server's certificate and the clients' it trusts; absent: the
    /// user's data folder.
    #[serde(default)]
    pub opcua_pki: Option<PathBuf>,
    /// The machine's maker in its OPC UA `Identification`; absent: "whirl".
    #[serde(default)]
    pub opcua_manufacturer: Option<String>,
    /// Its model; absent: the profile's name.
    #[serde(default)]
    pub opcua_model: Option<String>,
    /// Its serial number.
    #[serde(default)]
    pub opcua_serial_number: Option<String>,
    /// A URI naming this one machine (`urn:shop.example:lathe-3`); absent: made from the
    /// host's name and the machine's.
    #[serde(default)]
    pub opcua_product_instance_uri: Option<String>,
}

fn default_prefix() -> String {
    "whirl".into()
}
fn default_keepalive() -> u64 {
    10
}
fn default_queue() -> usize {
    1000
}
fn default_progress_interval() -> f64 {
    0.5
}

/// A broker's address.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Broker {
    /// Host name or address.
    pub host: String,
    /// TCP port.
    pub port: u16,
    /// Spoken to over TLS (`mqtts://`): its certificate checked, and the bridge's shown
    /// if it has one ([`TelemetrySettings::tls`]).
    pub tls: bool,
}

/// How a bridge speaks TLS to its broker: the roots the broker's certificate must chain
/// to and the bridge's certificate, as rustls takes them (rumqttc's
/// `TlsConfiguration::Rustls`).
pub type TlsConfig = Arc<rustls::ClientConfig>;

/// The keys that say how TLS is spoken, in the order they are checked.
const TLS_KEYS: [&str; 3] = ["tls_ca", "tls_cert", "tls_key"];

/// A `[telemetry]` value that cannot be used: the key and what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{key}: {problem}")]
pub struct TelemetryError {
    /// The key, as in the profile (`mqtt`, `prefix`).
    pub key: String,
    /// What is wrong and what it must be.
    pub problem: String,
}

/// An OPC UA setting's refusal, as a `[telemetry]` one.
fn from_opcua(e: opcua::OpcUaSettingsError) -> TelemetryError {
    TelemetryError {
        key: e.key,
        problem: e.problem,
    }
}

fn invalid(key: &str, problem: impl Into<String>) -> TelemetryError {
    TelemetryError {
        key: key.into(),
        problem: problem.into(),
    }
}

impl TelemetrySettings {
    /// Settings for the broker at `url` and nothing else said (the command line's `--mqtt`).
    pub fn for_broker(url: &str) -> TelemetrySettings {
        TelemetrySettings {
            mqtt: Some(url.into()),
            ..TelemetrySettings::nowhere()
        }
    }

    /// Settings that say nothing: no broker, no OPC UA server, every default.
    pub fn nowhere() -> TelemetrySettings {
        TelemetrySettings {
            mqtt: None,
            prefix: default_prefix(),
            machine: None,
            user: None,
            password: None,
            tls_ca: None,
            tls_cert: None,
            tls_key: None,
            keepalive_s: default_keepalive(),
            queue: default_queue(),
            progress_interval_s: default_progress_interval(),
            console: None,
            opcua: None,
            opcua_security: None,
            opcua_user: None,
            opcua_password: None,
            opcua_pki: None,
            opcua_manufacturer: None,
            opcua_model: None,
            opcua_serial_number: None,
            opcua_product_instance_uri: None,
        }
    }

    /// These settings with the broker at `url` (`--mqtt` over a profile's `mqtt`).
    pub fn with_broker(mut self, url: &str) -> TelemetrySettings {
        self.mqtt = Some(url.into());
        self
    }

    /// These settings with their files' relative paths made relative to `folder` (the
    /// profile's), as a profile's other files are: a bridge started from any working
    /// directory finds the certificates that ship beside its profile.
    pub fn in_folder(mut self, folder: &Path) -> TelemetrySettings {
        for path in [&mut self.tls_ca, &mut self.tls_cert, &mut self.tls_key]
            .into_iter()
            .flatten()
        {
            *path = folder.join(&*path);
        }
        self
    }

    /// The broker's host and port from `mqtt`, and whether it is spoken to over TLS; `None`
    /// without one.
    pub fn broker(&self) -> Result<Option<Broker>, TelemetryError> {
        let Some(mqtt) = &self.mqtt else {
            return Ok(None);
        };
        let url = url::Url::parse(mqtt).map_err(|e| {
            invalid(
                "mqtt",
                format!(
                    "\"{mqtt}\" is not a URL ({e}): give mqtt://HOST[:PORT] or \
                     mqtts://HOST[:PORT]"
                ),
            )
        })?;
        let (tls, default_port) = match url.scheme() {
            "mqtt" => (false, MQTT_PORT),
            "mqtts" => (true, MQTTS_PORT),
            scheme => {
                return Err(invalid(
                    "mqtt",
                    format!(
                        "\"{mqtt}\": the scheme must be mqtt:// (a broker's unencrypted port) \
                         or mqtts:// (over TLS); {scheme}:// is not spoken"
                    ),
                ))
            }
        };
        let extra = !url.username().is_empty()
            || url.password().is_some()
            || !matches!(url.path(), "" | "/")
            || url.query().is_some()
            || url.fragment().is_some();
        if extra {
            return Err(invalid(
                "mqtt",
                format!(
                    "\"{mqtt}\" says more than {}://HOST[:PORT]: a user and a password go \
                     in `user` and `password`, the topic prefix in `prefix`",
                    url.scheme()
                ),
            ));
        }
        let host = match url.host() {
            Some(url::Host::Ipv6(address)) => address.to_string(),
            Some(host) => host.to_string(),
            None => return Err(invalid("mqtt", format!("\"{mqtt}\" names no host"))),
        };
        Ok(Some(Broker {
            host,
            port: url.port().unwrap_or(default_port),
            tls,
        }))
    }

    /// How the broker is spoken to over TLS: `None` for an `mqtt://` broker (or none); for
    /// `mqtts://`, the roots its certificate must chain to (`tls_ca`'s, else the system's)
    /// and the bridge's certificate (`tls_cert` and `tls_key`), their files read now. Every
    /// refusal names the key and the file: a `tls_*` key with an `mqtt://` broker, a file
    /// that cannot be read or holds no certificate or key, a key that is not the
    /// certificate's, a system without root certificates when `tls_ca` is absent.
    pub fn tls(&self) -> Result<Option<TlsConfig>, TelemetryError> {
        let broker = self.broker()?;
        self.check_tls_keys(broker.as_ref())?;
        if !broker.is_some_and(|b| b.tls) {
            return Ok(None);
        }
        let client = self.tls_cert.as_deref().zip(self.tls_key.as_deref());
        tls::client_config(self.tls_ca.as_deref(), client).map(Some)
    }

    /// The `tls_*` keys together and with the broker's scheme, no file read: a profile's
    /// loading checks them so, [`TelemetrySettings::tls`] again with `--mqtt`'s broker.
    fn check_tls_keys(&self, broker: Option<&Broker>) -> Result<(), TelemetryError> {
        let paths = [&self.tls_ca, &self.tls_cert, &self.tls_key];
        for (key, path) in TLS_KEYS.into_iter().zip(paths) {
            let Some(path) = path else { continue };
            if path.as_os_str().is_empty() {
                return Err(invalid(key, "names no file"));
            }
            match broker {
                None => {
                    return Err(invalid(
                        key,
                        "is how the MQTT broker is spoken to over TLS: give `mqtt` too, \
                         mqtts://HOST[:PORT]",
                    ))
                }
                Some(broker) if !broker.tls => {
                    return Err(invalid(
                        key,
                        format!(
                            "is for a broker spoken to over TLS, and \"{}\" is not: give \
                             mqtts://HOST[:PORT], the broker's TLS listener",
                            self.mqtt.as_deref().unwrap_or_default(),
                        ),
                    ))
                }
                Some(_) => {}
            }
        }
        match (&self.tls_cert, &self.tls_key) {
            (Some(_), None) => Err(invalid(
                "tls_cert",
                "a certificate shows who the bridge is only with its private key: give \
                 `tls_key` too",
            )),
            (None, Some(_)) => Err(invalid(
                "tls_key",
                "a private key is shown to the broker with its certificate: give `tls_cert` \
                 too",
            )),
            _ => Ok(()),
        }
    }

    /// The OPC UA server's settings from `opcua` and the `opcua_*` keys, checked; `None`
    /// without `opcua`.
    pub fn opcua(&self) -> Result<Option<OpcUaSettings>, TelemetryError> {
        let Some(address) = &self.opcua else {
            return Ok(None);
        };
        let address = opcua::parse_address(address, "opcua").map_err(from_opcua)?;
        self.opcua_at(address, "opcua").map(Some)
    }

    /// The OPC UA server's settings with the address `address` (from `key`: the profile's
    /// `opcua`, or `--opcua` over it), checked.
    pub fn opcua_at(
        &self,
        address: std::net::SocketAddr,
        key: &str,
    ) -> Result<OpcUaSettings, TelemetryError> {
        OpcUaSettings::new(
            address,
            key,
            self.opcua_security,
            (self.opcua_user.as_deref(), self.opcua_password.as_deref()),
            self.opcua_pki.clone(),
        )
        .map_err(from_opcua)
    }

    /// What the machine's OPC UA `Identification` says beyond its defaults.
    pub fn nameplate(&self) -> Nameplate {
        Nameplate {
            manufacturer: self.opcua_manufacturer.clone(),
            model: self.opcua_model.clone(),
            serial_number: self.opcua_serial_number.clone(),
            product_instance_uri: self.opcua_product_instance_uri.clone(),
        }
    }

    /// Every value checked, naming the key.
    pub fn validate(&self) -> Result<(), TelemetryError> {
        if self.mqtt.is_none() && self.opcua.is_none() {
            return Err(invalid(
                "mqtt",
                "a [telemetry] says where the machine's state goes: `mqtt` (a broker), \
                 `opcua` (an OPC UA server of the bridge's own) or both",
            ));
        }
        let broker = self.broker()?;
        self.check_tls_keys(broker.as_ref())?;
        self.opcua()?;
        if self.mqtt.is_none() {
            for (key, given) in [
                ("user", self.user.is_some()),
                ("password", self.password.is_some()),
            ] {
                if given {
                    return Err(invalid(key, "is the MQTT broker's login: give `mqtt` too"));
                }
            }
        }
        let prefix = &self.prefix;
        if prefix.is_empty()
            || prefix.starts_with('/')
            || prefix.ends_with('/')
            || prefix.split('/').any(|level| level.is_empty())
        {
            return Err(invalid(
                "prefix",
                format!(
                    "\"{prefix}\" must be one or more topic levels without empty ones \
                     (whirl, plant2/whirling)"
                ),
            ));
        }
        if let Some(c) = prefix.chars().find(|c| matches!(c, '+' | '#' | '\0')) {
            return Err(invalid(
                "prefix",
                format!("\"{prefix}\" holds '{c}', which MQTT keeps for subscriptions"),
            ));
        }
        if let Some(machine) = &self.machine {
            if topic_name(machine).is_empty() {
                return Err(invalid(
                    "machine",
                    format!("\"{machine}\" has no letter or digit to name a topic by"),
                ));
            }
        }
        if self.password.is_some() && self.user.is_none() {
            return Err(invalid("password", "a password needs a `user`"));
        }
        // MQTT's keep-alive is two bytes of seconds; 0 would turn the last will off.
        if !(1..=u64::from(u16::MAX)).contains(&self.keepalive_s) {
            return Err(invalid(
                "keepalive_s",
                format!("{} must be 1 to 65535 s", self.keepalive_s),
            ));
        }
        if self.queue == 0 {
            return Err(invalid("queue", "must keep at least one event"));
        }
        if !(self.progress_interval_s.is_finite() && self.progress_interval_s > 0.0) {
            return Err(invalid(
                "progress_interval_s",
                format!("{} must be above zero", self.progress_interval_s),
            ));
        }
        Ok(())
    }

    /// `PREFIX/MACHINE`: the topics' root for a machine whose profile is named
    /// `profile_name` (unless `machine` names it).
    pub fn topic_root(&self, profile_name: &str) -> String {
        let name = self.machine.as_deref().unwrap_or(profile_name);
        format!("{}/{}", self.prefix, topic_name(name))
    }
}

/// A name made one topic level: lower case, every run of characters other than letters,
/// digits, `-` and `_` one `-`, none at either end (`"Lathe 3 (whirl)"` → `lathe-3-whirl`):
/// no `/`, `+`, `#` or space, which a subscriber would have to quote or could not match.
pub fn topic_name(name: &str) -> String {
    let mut out = String::with_capacity(name.len());
    for c in name.chars().flat_map(char::to_lowercase) {
        if c.is_alphanumeric() || c == '_' || c == '-' {
            out.push(c);
        } else if !out.is_empty() && !out.ends_with('-') {
            out.push('-');
        }
    }
    out.trim_end_matches('-').to_owned()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings(text: &str) -> TelemetrySettings {
        toml::from_str(text).unwrap()
    }

    #[test]
    fn a_broker_without_a_port_is_on_mqtts_registered_1883() {
        let s = TelemetrySettings::for_broker("mqtt://10.0.0.5");
        assert_eq!(
            s.broker().unwrap(),
            Some(Broker {
                host: "10.0.0.5".into(),
                port: 1883,
                tls: false,
            })
        );
        let s = TelemetrySettings::for_broker("mqtt://[::1]:18830");
        let broker = s.broker().unwrap().unwrap();
        assert_eq!((broker.host.as_str(), broker.port), ("::1", 18830));
    }

    #[test]
    fn a_tls_broker_without_a_port_is_on_mqtts_registered_8883() {
        let s = TelemetrySettings::for_broker("mqtts://broker.shop.lan");
        assert_eq!(
            s.broker().unwrap(),
            Some(Broker {
                host: "broker.shop.lan".into(),
                port: 8883,
                tls: true,
            })
        );
        let broker = TelemetrySettings::for_broker("mqtts://[::1]:18883")
            .broker()
            .unwrap()
            .unwrap();
        assert_eq!(
            (broker.host.as_str(), broker.port, broker.tls),
            ("::1", 18883, true)
        );
        // A plain broker speaks no TLS, whatever the files.
        assert!(TelemetrySettings::for_broker("mqtt://b")
            .tls()
            .unwrap()
            .is_none());
    }

    #[test]
    fn tls_files_are_relative_to_the_profiles_folder() {
        let s = settings(
            "mqtt = \"mqtts://b\"\ntls_ca = \"ca.pem\"\ntls_cert = \"/etc/whirl/l.crt\"\n\
             tls_key = \"keys/l.key\"",
        )
        .in_folder(Path::new("/srv/profiles"));
        assert_eq!(s.tls_ca, Some(PathBuf::from("/srv/profiles/ca.pem")));
        assert_eq!(s.tls_cert, Some(PathBuf::from("/etc/whirl/l.crt")));
        assert_eq!(s.tls_key, Some(PathBuf::from("/srv/profiles/keys/l.key")));
    }

    #[test]
    fn a_table_names_a_broker_an_opcua_server_or_both() {
        let opcua = settings("opcua = \"127.0.0.1:4841\"");
        opcua.validate().unwrap();
        assert_eq!(opcua.broker().unwrap(), None);
        let served = opcua.opcua().unwrap().unwrap();
        assert_eq!(served.address, "127.0.0.1:4841".parse().unwrap());
        assert_eq!(served.security, Security::None);
        let both = settings("mqtt = \"mqtt://b\"\nopcua = \"localhost\"");
        both.validate().unwrap();
        assert!(both.broker().unwrap().is_some() && both.opcua().unwrap().is_some());
        let secured = settings(
            "opcua = \"0.0.0.0:4840\"\nopcua_security = \"sign\"\nopcua_user = \"mes\"\n\
             opcua_password = \"pw\"\nopcua_pki = \"/var/lib/whirl/pki\"\n\
             opcua_manufacturer = \"Acme\"\nopcua_serial_number = \"W-17\"",
        );
        secured.validate().unwrap();
        let served = secured.opcua().unwrap().unwrap();
        assert_eq!(served.security, Security::Sign);
        assert_eq!(served.pki, Some(PathBuf::from("/var/lib/whirl/pki")));
        let nameplate = secured.nameplate();
        assert_eq!(nameplate.manufacturer.as_deref(), Some("Acme"));
        assert_eq!(nameplate.serial_number.as_deref(), Some("W-17"));
        // `--opcua` over a profile without `opcua` uses its other keys, and names itself.
        let at = "0.0.0.0:4840".parse().unwrap();
        let error = TelemetrySettings::nowhere()
            .opcua_at(at, "--opcua")
            .unwrap_err();
        assert_eq!(error.key, "opcua_user");
        assert!(error.problem.contains("--opcua"), "{error}");
    }

    #[test]
    fn names_become_one_topic_level() {
        assert_eq!(topic_name("Lathe 3 (whirl)"), "lathe-3-whirl");
        assert_eq!(topic_name("a/b+c#d"), "a-b-c-d");
        assert_eq!(topic_name("  cell_2--x "), "cell_2--x");
        assert_eq!(topic_name("///"), "");
        let s = settings("mqtt = \"mqtt://b\"\nprefix = \"plant2/whirling\"");
        assert_eq!(
            s.topic_root("whirl-sim (grblHAL)"),
            "plant2/whirling/whirl-sim-grblhal"
        );
    }

    #[test]
    fn bad_values_are_refused_naming_the_key() {
        let cases = [
            ("mqtt = \"broker:1883\"", "mqtt"),
            ("mqtt = \"http://broker\"", "mqtt"),
            ("mqtt = \"mqtt://u:p@broker\"", "mqtt"),
            ("mqtt = \"mqtt://broker/whirl\"", "mqtt"),
            ("mqtt = \"mqtt://b\"\nprefix = \"whirl/\"", "prefix"),
            ("mqtt = \"mqtt://b\"\nprefix = \"a//b\"", "prefix"),
            ("mqtt = \"mqtt://b\"\nprefix = \"shop/#\"", "prefix"),
            ("mqtt = \"mqtt://b\"\nmachine = \"***\"", "machine"),
            ("mqtt = \"mqtt://b\"\npassword = \"p\"", "password"),
            ("mqtt = \"mqtt://b\"\ntls_ca = \"ca.pem\"", "tls_ca"),
            (
                "mqtt = \"mqtt://b\"\ntls_cert = \"l.crt\"\ntls_key = \"l.key\"",
                "tls_cert",
            ),
            ("mqtt = \"mqtts://b\"\ntls_cert = \"l.crt\"", "tls_cert"),
            ("mqtt = \"mqtts://b\"\ntls_key = \"l.key\"", "tls_key"),
            ("mqtt = \"mqtts://b\"\ntls_ca = \"\"", "tls_ca"),
            ("opcua = \"127.0.0.1\"\ntls_ca = \"ca.pem\"", "tls_ca"),
            ("mqtt = \"mqtt://b\"\nkeepalive_s = 0", "keepalive_s"),
            ("mqtt = \"mqtt://b\"\nkeepalive_s = 70000", "keepalive_s"),
            ("mqtt = \"mqtt://b\"\nqueue = 0", "queue"),
            (
                "mqtt = \"mqtt://b\"\nprogress_interval_s = 0.0",
                "progress_interval_s",
            ),
            ("prefix = \"whirl\"", "mqtt"),
            (
                "opcua = \"127.0.0.1\"\nuser = \"u\"\npassword = \"p\"",
                "user",
            ),
            ("opcua = \"lathe3.shop.lan:4840\"", "opcua"),
            ("opcua = \"0.0.0.0:4840\"", "opcua_user"),
            (
                "opcua = \"0.0.0.0:4840\"\nopcua_security = \"none\"\nopcua_user = \"u\"\n\
                 opcua_password = \"p\"",
                "opcua_security",
            ),
            (
                "opcua = \"127.0.0.1\"\nopcua_user = \"u\"",
                "opcua_password",
            ),
        ];
        for (text, key) in cases {
            let error = settings(text).validate().expect_err(text);
            assert_eq!(error.key, key, "{text}: {error}");
        }
        let unknown = toml::from_str::<TelemetrySettings>("mqtt = \"mqtt://b\"\ntopic = \"x\"");
        assert!(unknown.unwrap_err().to_string().contains("topic"));
        let mode =
            toml::from_str::<TelemetrySettings>("opcua = \"::1\"\nopcua_security = \"open\"");
        assert!(mode.unwrap_err().to_string().contains("sign-and-encrypt"));
    }
}
