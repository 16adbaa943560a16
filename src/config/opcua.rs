//! Where and to whom a bridge serves OPC UA for Machine Tools (`docs/opcua.md`): the
//! `opcua*` keys of a profile's `[telemetry]`, or `whirl serve --opcua`, checked into one
//! [`OpcUaSettings`].
//!
//! The rule is OPC UA's own security, decided before anything listens: on loopback the
//! server may take anonymous clients over an unsecured channel (the MES on the same host);
//! on any other address every message is signed (or signed and encrypted) with a
//! certificate the server keeps, and every client logs in with the profile's user name and
//! password. A key that breaks the rule is refused by name.

use std::net::{IpAddr, Ipv4Addr, SocketAddr};
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

/// OPC UA's registered port (IANA), when an address gives none.
pub const OPCUA_PORT: u16 = 4840;

/// How the server secures each message (OPC UA's MessageSecurityMode).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Security {
    /// Neither signed nor encrypted: loopback only.
    None,
    /// Signed with the server's certificate and the client's.
    Sign,
    /// Signed and encrypted.
    SignAndEncrypt,
}

/// Who may log in: a user name and its password.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Login {
    /// The user name.
    pub user: String,
    /// Its password.
    pub password: String,
}

/// What the machine says of itself in its `Identification` (OPC 40001-1's nameplate).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Nameplate {
    /// The machine's maker; absent: "whirl".
    pub manufacturer: Option<String>,
    /// Its model; absent: the profile's name.
    pub model: Option<String>,
    /// Its serial number, if the shop gives it.
    pub serial_number: Option<String>,
    /// A URI naming this one machine worldwide; absent: made from the host and the
    /// machine's name.
    pub product_instance_uri: Option<String>,
}

/// An OPC UA server's settings, checked.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct OpcUaSettings {
    /// Where it listens.
    pub address: SocketAddr,
    /// How messages are secured.
    pub security: Security,
    /// The one user allowed in; `None`: anonymous clients (loopback only).
    pub login: Option<Login>,
    /// Where the server keeps its certificate, its private key and the clients'
    /// certificates it trusts (`trusted/`) or rejected (`rejected/`); `None`: the user's
    /// data folder. Used only when messages are secured.
    pub pki: Option<PathBuf>,
}

/// A setting that breaks a rule: the key (or flag) and what is wrong.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{key}: {problem}")]
pub struct OpcUaSettingsError {
    /// The key as the profile spells it (`opcua`, `opcua_security`), or the flag.
    pub key: String,
    /// What is wrong and what it must be.
    pub problem: String,
}

fn refuse(key: &str, problem: impl Into<String>) -> OpcUaSettingsError {
    OpcUaSettingsError {
        key: key.into(),
        problem: problem.into(),
    }
}

/// `HOST:PORT` (or `HOST` alone, on port 4840) as an address to listen on: an IP address,
/// or `localhost` for 127.0.0.1. `key` names it in a refusal.
pub fn parse_address(text: &str, key: &str) -> Result<SocketAddr, OpcUaSettingsError> {
    if let Ok(address) = text.parse::<SocketAddr>() {
        return Ok(address);
    }
    let (host, port) = match text.rsplit_once(':') {
        Some((host, _)) if !host.ends_with(']') && host.contains(':') => (text, None),
        Some((host, port)) => (host, Some(port)),
        None => (text, None),
    };
    let port = match port {
        Some(port) => port.parse::<u16>().map_err(|_| {
            refuse(
                key,
                format!("\"{text}\": the port must be a number from 0 to 65535"),
            )
        })?,
        None => OPCUA_PORT,
    };
    let host = host.trim_start_matches('[').trim_end_matches(']');
    let ip = if host.eq_ignore_ascii_case("localhost") {
        IpAddr::V4(Ipv4Addr::LOCALHOST)
    } else {
        host.parse::<IpAddr>().map_err(|_| {
            refuse(
                key,
                format!(
                    "\"{text}\" is not HOST:PORT with HOST an IP address (127.0.0.1, \
                     0.0.0.0, ::1) or localhost: the server listens on an address of this \
                     host, not a name"
                ),
            )
        })?
    };
    Ok(SocketAddr::new(ip, port))
}

impl OpcUaSettings {
    /// Settings from their parts, checked: `address_key` names where the address came from
    /// (`opcua`, or `--opcua`), the other keys are the profile's.
    pub fn new(
        address: SocketAddr,
        address_key: &str,
        security: Option<Security>,
        login: (Option<&str>, Option<&str>),
        pki: Option<PathBuf>,
    ) -> Result<OpcUaSettings, OpcUaSettingsError> {
        let login = match login {
            (Some(user), Some(password)) => {
                if user.trim().is_empty() {
                    return Err(refuse("opcua_user", "the user name is empty"));
                }
                if password.is_empty() {
                    return Err(refuse("opcua_password", "the password is empty"));
                }
                Some(Login {
                    user: user.to_owned(),
                    password: password.to_owned(),
                })
            }
            (Some(_), None) => {
                return Err(refuse(
                    "opcua_password",
                    "an `opcua_user` needs its password",
                ))
            }
            (None, Some(_)) => {
                return Err(refuse("opcua_password", "a password needs an `opcua_user`"))
            }
            (None, None) => None,
        };
        let loopback = address.ip().is_loopback();
        let security = security.unwrap_or(if loopback {
            Security::None
        } else {
            Security::SignAndEncrypt
        });
        if !loopback {
            if security == Security::None {
                return Err(refuse(
                    "opcua_security",
                    format!(
                        "\"none\" is refused for {address} ({address_key}), which is not \
                         loopback: beyond this host every message is signed (\"sign\") or \
                         signed and encrypted (\"sign-and-encrypt\")"
                    ),
                ));
            }
            if login.is_none() {
                return Err(refuse(
                    "opcua_user",
                    format!(
                        "{address} ({address_key}) is not loopback: clients beyond this host \
                         log in, so give `opcua_user` and `opcua_password` (anonymous \
                         clients are let in on loopback only)"
                    ),
                ));
            }
        }
        if pki.as_ref().is_some_and(|p| p.as_os_str().is_empty()) {
            return Err(refuse("opcua_pki", "the folder is empty"));
        }
        Ok(OpcUaSettings {
            address,
            security,
            login,
            pki,
        })
    }

    /// The URL clients connect to: `opc.tcp://HOST:PORT/`.
    pub fn url(&self) -> String {
        format!("opc.tcp://{}/", self.address)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn address(text: &str) -> SocketAddr {
        parse_address(text, "opcua").unwrap()
    }

    #[test]
    fn addresses_are_ip_and_port_or_localhost_on_4840_by_default() {
        assert_eq!(address("127.0.0.1:4841"), "127.0.0.1:4841".parse().unwrap());
        assert_eq!(address("localhost:0"), "127.0.0.1:0".parse().unwrap());
        assert_eq!(address("0.0.0.0"), "0.0.0.0:4840".parse().unwrap());
        assert_eq!(address("[::1]:4842"), "[::1]:4842".parse().unwrap());
        assert_eq!(address("::1"), "[::1]:4840".parse().unwrap());
        for bad in [
            "lathe3.shop.lan:4840",
            "127.0.0.1:port",
            "127.0.0.1:70000",
            "",
        ] {
            let error = parse_address(bad, "--opcua").expect_err(bad);
            assert_eq!(error.key, "--opcua", "{bad}");
        }
    }

    #[test]
    fn loopback_is_open_and_unsecured_by_default() {
        let s =
            OpcUaSettings::new(address("127.0.0.1:0"), "opcua", None, (None, None), None).unwrap();
        assert_eq!((s.security, &s.login), (Security::None, &None));
        assert_eq!(s.url(), "opc.tcp://127.0.0.1:0/");
    }

    #[test]
    fn beyond_loopback_messages_are_secured_and_clients_log_in() {
        let open = address("0.0.0.0:4840");
        let login = (Some("mes"), Some("s3cret"));
        let error =
            OpcUaSettings::new(open, "--opcua", Some(Security::None), login, None).unwrap_err();
        assert_eq!(error.key, "opcua_security");
        assert!(error.problem.contains("--opcua"), "{error}");
        let error = OpcUaSettings::new(open, "opcua", Some(Security::Sign), (None, None), None)
            .unwrap_err();
        assert_eq!(error.key, "opcua_user");
        let s = OpcUaSettings::new(open, "opcua", None, login, None).unwrap();
        assert_eq!(
            s.security,
            Security::SignAndEncrypt,
            "the default beyond loopback"
        );
        let s = OpcUaSettings::new(open, "opcua", Some(Security::Sign), login, None).unwrap();
        assert_eq!(s.login.unwrap().user, "mes");
    }

    #[test]
    fn a_login_is_a_user_and_its_password() {
        let at = address("127.0.0.1:0");
        for (login, key) in [
            ((Some("mes"), None), "opcua_password"),
            ((None, Some("pw")), "opcua_password"),
            ((Some(" "), Some("pw")), "opcua_user"),
            ((Some("mes"), Some("")), "opcua_password"),
        ] {
            let error = OpcUaSettings::new(at, "opcua", None, login, None).unwrap_err();
            assert_eq!(error.key, key, "{login:?}");
        }
        let error =
            OpcUaSettings::new(at, "opcua", None, (None, None), Some(PathBuf::new())).unwrap_err();
        assert_eq!(error.key, "opcua_pki");
    }
}
