//! OPC UA's own security for the server, from checked settings
//! ([`crate::config::opcua::OpcUaSettings`], which refuse an unsecured channel or an
//! anonymous client beyond loopback before anything listens): the endpoints' security
//! policies and mode, who may log in, and where the server keeps its certificate.
//!
//! A secured server offers Basic256Sha256 (OPC 40501-1's Basic Server Profile's),
//! Aes128-Sha256-RsaOaep (its Secure one's) and Aes256-Sha256-RsaPss, all in the one mode
//! the settings say. Its certificate is made on its first start, self-signed, in its PKI
//! folder; a client's certificate is trusted once the operator moves it from the folder's
//! `rejected/` (where the server puts every unknown one) to `trusted/`.

use std::path::PathBuf;

use opcua::crypto::SecurityPolicy;
use opcua::server::{ServerBuilder, ServerEndpoint, ServerUserToken, ANONYMOUS_USER_TOKEN_ID};
use opcua::types::MessageSecurityMode;

use crate::config::opcua::{OpcUaSettings, Security};

/// The id of the one user token the server knows.
const USER_TOKEN: &str = "whirl-user";

/// The security policies a secured server offers.
const POLICIES: [SecurityPolicy; 3] = [
    SecurityPolicy::Basic256Sha256,
    SecurityPolicy::Aes128Sha256RsaOaep,
    SecurityPolicy::Aes256Sha256RsaPss,
];

/// `builder` with the endpoints, the user and the PKI folder `settings` say; `pki` is the
/// folder to use when the settings name none. The PKI folder is made when first used.
pub fn secure(builder: ServerBuilder, settings: &OpcUaSettings, pki: PathBuf) -> ServerBuilder {
    let (tokens, builder) = match &settings.login {
        Some(login) => (
            vec![USER_TOKEN.to_owned()],
            builder.add_user_token(
                USER_TOKEN,
                ServerUserToken::user_pass(login.user.as_str(), login.password.as_str()),
            ),
        ),
        None => (vec![ANONYMOUS_USER_TOKEN_ID.to_owned()], builder),
    };
    let mode = match settings.security {
        Security::None => {
            return builder
                .create_sample_keypair(false)
                .add_endpoint("none", ServerEndpoint::new_none("/", &tokens));
        }
        Security::Sign => MessageSecurityMode::Sign,
        Security::SignAndEncrypt => MessageSecurityMode::SignAndEncrypt,
    };
    let mut builder = builder
        .create_sample_keypair(true)
        .pki_dir(settings.pki.clone().unwrap_or(pki))
        .certificate_path("own/cert.der")
        .private_key_path("private/private.pem")
        .trust_client_certs(false);
    for policy in POLICIES {
        builder = builder.add_endpoint(
            format!("{policy}").as_str(),
            ServerEndpoint::new("/", policy, mode, &tokens),
        );
    }
    builder
}

/// The default PKI folder: `opcua-pki` in the user's data folder, `$XDG_DATA_HOME/whirl/`
/// (an absolute one) or `$HOME/.local/share/whirl/`, as the run records' is; `None` without
/// a home.
pub fn default_pki(
    xdg_data_home: Option<&std::ffi::OsStr>,
    home: Option<&std::ffi::OsStr>,
) -> Option<PathBuf> {
    let xdg = xdg_data_home.map(std::path::Path::new);
    let home = home.map(std::path::Path::new);
    let data = match (xdg, home) {
        (Some(xdg), _) if xdg.is_absolute() => xdg.to_owned(),
        (_, Some(home)) if home.is_absolute() => home.join(".local/share"),
        _ => return None,
    };
    Some(data.join("whirl").join("opcua-pki"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::ffi::OsStr;

    fn settings(address: &str, security: Option<Security>, login: bool) -> OpcUaSettings {
        let login = if login {
            (Some("mes"), Some("pw"))
        } else {
            (None, None)
        };
        OpcUaSettings::new(address.parse().unwrap(), "opcua", security, login, None).unwrap()
    }

    fn endpoints(builder: &ServerBuilder) -> Vec<(String, String, Vec<String>)> {
        builder
            .config()
            .endpoints
            .values()
            .map(|e| {
                (
                    e.security_policy.clone(),
                    e.security_mode.clone(),
                    e.user_token_ids.iter().cloned().collect(),
                )
            })
            .collect()
    }

    #[test]
    fn loopback_without_a_login_is_one_unsecured_anonymous_endpoint() {
        let builder = secure(
            ServerBuilder::new(),
            &settings("127.0.0.1:0", None, false),
            PathBuf::from("pki"),
        );
        assert_eq!(
            endpoints(&builder),
            [("None".into(), "None".into(), vec!["ANONYMOUS".into()])]
        );
        assert!(
            !builder.config().create_sample_keypair,
            "no certificate made"
        );
    }

    #[test]
    fn a_login_is_the_only_way_in_and_a_secured_server_keeps_its_certificate() {
        let builder = secure(
            ServerBuilder::new(),
            &settings("0.0.0.0:4840", Some(Security::Sign), true),
            PathBuf::from("/data/whirl/opcua-pki"),
        );
        let found = endpoints(&builder);
        assert_eq!(found.len(), POLICIES.len());
        for (policy, mode, tokens) in &found {
            assert_ne!(policy, "None");
            assert_eq!(mode, "Sign");
            assert_eq!(tokens, &[USER_TOKEN.to_owned()]);
        }
        let config = builder.config();
        assert_eq!(config.user_tokens[USER_TOKEN].user, "mes");
        assert!(config.create_sample_keypair);
        assert!(!config.certificate_validation.trust_client_certs);
        assert_eq!(config.pki_dir, PathBuf::from("/data/whirl/opcua-pki"));
    }

    #[test]
    fn the_default_pki_is_in_the_users_data_folder() {
        assert_eq!(
            default_pki(None, Some(OsStr::new("/home/op"))),
            Some(PathBuf::from("/home/op/.local/share/whirl/opcua-pki"))
        );
        assert_eq!(
            default_pki(Some(OsStr::new("/xdg")), Some(OsStr::new("/home/op"))),
            Some(PathBuf::from("/xdg/whirl/opcua-pki"))
        );
        assert_eq!(default_pki(Some(OsStr::new("rel")), None), None);
    }
}
