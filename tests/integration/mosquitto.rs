//! A real MQTT broker for the telemetry tests: Debian's mosquitto, started on a free
//! loopback port with a configuration of the test's own, stopped and started again on the
//! same port (its retained messages and persistent sessions kept on disk), and a
//! subscriber that keeps its session across the broker's restarts. A broker may listen
//! over TLS, taking each client's certificate as its login, with certificates a test makes
//! ([`Authority`]).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// How long a broker may take to listen: it starts in milliseconds; the margin is a busy
/// CI host's.
const START_TIMEOUT: Duration = Duration::from_secs(20);

/// A mosquitto of a test's own.
pub struct Mosquitto {
    child: Option<Child>,
    pub port: u16,
    conf: PathBuf,
    pub dir: tempfile::TempDir,
    /// Its listener speaks TLS.
    tls: bool,
}

impl Mosquitto {
    /// A broker allowing anonymous clients; `None` (the test then says it skipped) where
    /// mosquitto is not installed, which with `CI` set fails the test instead.
    pub fn start() -> Option<Mosquitto> {
        Mosquitto::with("allow_anonymous true\n")
    }

    /// A broker over TLS, as a shop that logs its machines in by their certificates runs
    /// one: its own certificate and key `server`, a client's certificate required and
    /// signed by the CA in the PEM file `ca`, its common name the client's user name.
    pub fn tls(ca: &Path, server: (&Path, &Path)) -> Option<Mosquitto> {
        let mut broker = Mosquitto::with(&format!(
            "cafile {}\ncertfile {}\nkeyfile {}\nrequire_certificate true\n\
             use_identity_as_username true\nallow_anonymous false\n",
            ca.display(),
            server.0.display(),
            server.1.display()
        ))?;
        broker.tls = true;
        Some(broker)
    }

    /// A broker with `settings` (mosquitto.conf lines) beside its listener and its
    /// persistence.
    pub fn with(settings: &str) -> Option<Mosquitto> {
        if Command::new("mosquitto").arg("-h").output().is_err() {
            let missing =
                "mosquitto is not installed (apt-get install mosquitto mosquitto-clients)";
            assert!(
                std::env::var_os("CI").is_none(),
                "on CI the broker must be there: {missing}"
            );
            eprintln!("skipped: {missing}");
            return None;
        }
        let dir = tempfile::tempdir().unwrap();
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let conf = dir.path().join("mosquitto.conf");
        // `user root`: as root, mosquitto would otherwise drop to its own user, who cannot
        // write the test's folder; run by anyone else, it is ignored.
        std::fs::write(
            &conf,
            format!(
                "listener {port} 127.0.0.1\npersistence true\npersistence_location {}/\n\
                 user root\n{settings}",
                dir.path().display()
            ),
        )
        .unwrap();
        let mut broker = Mosquitto {
            child: None,
            port,
            conf,
            dir,
            tls: false,
        };
        broker.run();
        Some(broker)
    }

    /// Its process id, while it runs (for the shop benchmark's CPU and memory figures).
    #[allow(dead_code)]
    pub fn pid(&self) -> Option<u32> {
        self.child.as_ref().map(Child::id)
    }

    /// `mqtt://127.0.0.1:PORT`, or `mqtts://…` over TLS.
    pub fn url(&self) -> String {
        let scheme = if self.tls { "mqtts" } else { "mqtt" };
        format!("{scheme}://127.0.0.1:{}", self.port)
    }

    /// Starts it (again), and waits until it listens.
    pub fn run(&mut self) {
        assert!(self.child.is_none(), "the broker runs already");
        let log = std::fs::File::create(self.dir.path().join("mosquitto.log")).unwrap();
        self.child = Some(
            Command::new("mosquitto")
                .arg("-c")
                .arg(&self.conf)
                .stdout(log.try_clone().unwrap())
                .stderr(log)
                .spawn()
                .expect("mosquitto starts"),
        );
        let started = Instant::now();
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            assert!(
                started.elapsed() < START_TIMEOUT,
                "mosquitto does not listen: {}",
                self.log()
            );
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    /// Stops it as a service stop does (SIGTERM: it saves its sessions and retained
    /// messages, then ends).
    pub fn stop(&mut self) {
        let mut child = self.child.take().expect("the broker runs");
        let _ = Command::new("kill")
            .args(["-TERM", &child.id().to_string()])
            .status();
        child.wait().unwrap();
    }

    /// What it logged.
    pub fn log(&self) -> String {
        std::fs::read_to_string(self.dir.path().join("mosquitto.log")).unwrap_or_default()
    }

    /// A password file with each user's password, for `password_file`.
    pub fn password_file(dir: &Path, logins: &[(&str, &str)]) -> PathBuf {
        let file = dir.join("passwords");
        for (k, (user, password)) in logins.iter().enumerate() {
            // -c makes the file, with the first user; -b takes the password from the line.
            let create: &[&str] = if k == 0 { &["-c", "-b"] } else { &["-b"] };
            let made = Command::new("mosquitto_passwd")
                .args(create)
                .arg(&file)
                .args([user, password])
                .stdout(Stdio::null())
                .status()
                .expect("mosquitto_passwd runs");
            assert!(made.success());
        }
        file
    }
}

/// A shop's certificate authority, made for a test: its certificate in a PEM file (a
/// broker's `cafile`, a bridge's `tls_ca`) and the certificates it signs, for a broker or a
/// client, each with its key beside it.
pub struct Authority {
    issuer: rcgen::CertifiedIssuer<'static, rcgen::KeyPair>,
    dir: PathBuf,
    /// Its certificate, PEM.
    pub ca: PathBuf,
}

impl Authority {
    /// A CA named `name`, its certificate written to `dir/NAME-ca.pem`.
    pub fn new(dir: &Path, name: &str) -> Authority {
        let mut params = rcgen::CertificateParams::new(Vec::<String>::new()).unwrap();
        params.distinguished_name = rcgen::DistinguishedName::new();
        params
            .distinguished_name
            .push(rcgen::DnType::CommonName, format!("{name} CA"));
        params.is_ca = rcgen::IsCa::Ca(rcgen::BasicConstraints::Unconstrained);
        params.key_usages = vec![
            rcgen::KeyUsagePurpose::KeyCertSign,
            rcgen::KeyUsagePurpose::CrlSign,
        ];
        let issuer =
            rcgen::CertifiedIssuer::self_signed(params, rcgen::KeyPair::generate().unwrap())
                .unwrap();
        let ca = dir.join(format!("{name}-ca.pem"));
        std::fs::write(&ca, issuer.pem()).unwrap();
        Authority {
            issuer,
            dir: dir.to_owned(),
            ca,
        }
    }

    /// A broker's certificate for `names` (host names and IP addresses it is reached at),
    /// `dir/FILE.crt`, and its key, `dir/FILE.key`.
    pub fn server(&self, file: &str, names: &[&str]) -> (PathBuf, PathBuf) {
        self.issue(
            file,
            names[0],
            names,
            rcgen::ExtendedKeyUsagePurpose::ServerAuth,
        )
    }

    /// A client's certificate whose common name is `name` (its user name on a broker that
    /// takes the certificate as the login), `dir/NAME.crt`, and its key, `dir/NAME.key`.
    pub fn client(&self, name: &str) -> (PathBuf, PathBuf) {
        self.issue(name, name, &[], rcgen::ExtendedKeyUsagePurpose::ClientAuth)
    }

    fn issue(
        &self,
        file: &str,
        common_name: &str,
        names: &[&str],
        usage: rcgen::ExtendedKeyUsagePurpose,
    ) -> (PathBuf, PathBuf) {
        let names: Vec<String> = names.iter().map(|n| n.to_string()).collect();
        let mut params = rcgen::CertificateParams::new(names).unwrap();
        params.distinguished_name = rcgen::DistinguishedName::new();
        params
            .distinguished_name
            .push(rcgen::DnType::CommonName, common_name);
        params.extended_key_usages = vec![usage];
        let key = rcgen::KeyPair::generate().unwrap();
        let certificate = params.signed_by(&key, &self.issuer).unwrap();
        let (cert, key_file) = (
            self.dir.join(format!("{file}.crt")),
            self.dir.join(format!("{file}.key")),
        );
        std::fs::write(&cert, certificate.pem()).unwrap();
        std::fs::write(&key_file, key.serialize_pem()).unwrap();
        (cert, key_file)
    }
}

impl Drop for Mosquitto {
    fn drop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }
}

/// A message as a subscriber got it.
#[derive(Debug, Clone)]
pub struct Got {
    /// Its topic.
    pub topic: String,
    /// Its payload, as JSON.
    pub json: serde_json::Value,
    /// Delivered as a retained message (to a subscription made after it was published).
    pub retained: bool,
    /// When it came.
    pub at: Instant,
}

/// A subscriber to `whirl/#` at QoS 1 whose session the broker keeps (clean session off,
/// a fixed client id): what is published while it is away, broker restarts included, comes
/// when it is back.
pub struct Subscriber {
    got: Arc<Mutex<Vec<Got>>>,
    client: rumqttc::Client,
    stop: Arc<std::sync::atomic::AtomicBool>,
}

impl Subscriber {
    /// Subscribes to `filter` on `broker`, and waits until the subscription is acknowledged.
    pub fn new(broker: &Mosquitto, filter: &str) -> Subscriber {
        Subscriber::with_login(broker, filter, None)
    }

    /// The same, logged in as `(user, password)`.
    pub fn with_login(broker: &Mosquitto, filter: &str, login: Option<(&str, &str)>) -> Subscriber {
        // Each subscriber its own client id, kept across reconnections.
        static SUBSCRIBERS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);
        let n = SUBSCRIBERS.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let id = format!("test-{}-{}-{n}", std::process::id(), broker.port);
        let mut options = rumqttc::MqttOptions::new(id, "127.0.0.1", broker.port);
        options
            .set_clean_session(false)
            .set_keep_alive(Duration::from_secs(5))
            .set_max_packet_size(1 << 20, 1 << 20);
        if let Some((user, password)) = login {
            options.set_credentials(user, password);
        }
        let (client, mut connection) = rumqttc::Client::new(options, 64);
        client.subscribe(filter, rumqttc::QoS::AtLeastOnce).unwrap();
        let got = Arc::new(Mutex::new(Vec::new()));
        let (subscribed, acknowledged) = std::sync::mpsc::channel();
        let kept = got.clone();
        let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let stopped = stop.clone();
        std::thread::spawn(move || {
            for event in connection.iter() {
                if stopped.load(std::sync::atomic::Ordering::Relaxed) {
                    return;
                }
                match event {
                    Ok(rumqttc::Event::Incoming(rumqttc::Packet::Publish(p))) => {
                        let json = serde_json::from_slice(&p.payload)
                            .unwrap_or_else(|e| panic!("{}: not JSON: {e}", p.topic));
                        kept.lock().unwrap().push(Got {
                            topic: p.topic.clone(),
                            json,
                            retained: p.retain,
                            at: Instant::now(),
                        });
                    }
                    Ok(rumqttc::Event::Incoming(rumqttc::Packet::SubAck(_))) => {
                        let _ = subscribed.send(());
                    }
                    Ok(_) => {}
                    // The broker is away: the next poll connects again.
                    Err(_) => std::thread::sleep(Duration::from_millis(100)),
                }
            }
        });
        acknowledged
            .recv_timeout(START_TIMEOUT)
            .expect("the subscription is acknowledged");
        Subscriber { got, client, stop }
    }

    /// Everything so far.
    pub fn got(&self) -> Vec<Got> {
        self.got.lock().unwrap().clone()
    }

    /// Waits up to `timeout` until `done` holds of what came; what came.
    pub fn wait(&self, timeout: Duration, done: impl Fn(&[Got]) -> bool) -> Vec<Got> {
        let started = Instant::now();
        loop {
            let got = self.got();
            if done(&got) || started.elapsed() > timeout {
                return got;
            }
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

impl Drop for Subscriber {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        let _ = self.client.try_disconnect();
    }
}

/// The messages of `topic`'s last level (`event`, `state`…), in order.
pub fn on<'a>(got: &'a [Got], level: &str) -> Vec<&'a Got> {
    got.iter()
        .filter(|g| g.topic.rsplit('/').next() == Some(level))
        .collect()
}
