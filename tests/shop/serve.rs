//! A shop's `whirl serve` processes for the shop tests and the shop benchmark: bridges
//! (one machine each, reporting to the broker) and the overview.

use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};

use serde_json::Value;

use crate::http::{self, request};
use crate::mosquitto::Mosquitto;

/// The job every bridge runs.
pub const JOB: &str = "double-start/job.toml";
/// The keep-alive of each bridge, s.
pub const KEEPALIVE: u64 = 5;

pub fn repo() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

/// A `whirl serve` of the test: a bridge, or the overview.
pub struct Serve {
    pub child: Child,
    pub addr: SocketAddr,
    key: String,
    /// Where its standard error goes.
    said: PathBuf,
}

impl Serve {
    /// `whirl serve ARGS` with the examples as its jobs, recording in `db`, its machine
    /// locks in `dir`. `home` is its data folder (`XDG_DATA_HOME`), where the spool of a
    /// PostgreSQL it cannot reach is kept: one a bridge, as on a host of its own, and never
    /// the user's; its standard error is added to `home/serve.log`, so that a bridge started
    /// again in the same `home` adds to what the one before it said.
    pub fn start(args: &[&str], db: &str, home: &Path, dir: &Path) -> Serve {
        std::fs::create_dir_all(home).unwrap();
        let said = home.join("serve.log");
        let log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&said)
            .unwrap();
        let mut child = Command::new(env!("CARGO_BIN_EXE_whirl"))
            .args(["serve", "--listen", "127.0.0.1:0", "--jobs"])
            .arg(repo().join("examples"))
            .args(args)
            .args(["--db", db])
            .env("WHIRL_LOCK_DIR", dir.join("locks"))
            .env("XDG_DATA_HOME", home)
            .stdout(Stdio::piped())
            .stderr(log)
            .spawn()
            .unwrap();
        let addr = http::listening(&mut child);
        let key = request(addr, "GET", "/api/session", &[], None).json()["page_key"]
            .as_str()
            .unwrap()
            .to_owned();
        Serve {
            child,
            addr,
            key,
            said,
        }
    }

    /// What it (and any `whirl serve` before it in its `home`) said on standard error.
    pub fn said(&self) -> String {
        std::fs::read_to_string(&self.said).unwrap_or_default()
    }

    /// An action, as the console's own page sends it.
    pub fn post(&self, path: &str, body: &str) -> http::Answer {
        request(
            self.addr,
            "POST",
            path,
            &[("X-Whirl-Page", &self.key)],
            Some(body),
        )
    }

    pub fn get(&self, path: &str) -> Value {
        request(self.addr, "GET", path, &[], None).json()
    }
}

impl Drop for Serve {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The machine profile of bridge `n`: the built-in simulator, named `Lathe NN`, reporting
/// to `broker`.
pub fn profile(dir: &Path, n: usize, broker: &Mosquitto) -> PathBuf {
    let sim = std::fs::read_to_string(repo().join("machine-profiles/sim.toml")).unwrap();
    let sim = sim.replacen(
        "name = \"whirl-sim: simulated XZC whirling lathe\"",
        &format!("name = \"Lathe {n:02}\""),
        1,
    );
    let path = dir.join(format!("lathe-{n:02}.toml"));
    std::fs::write(
        &path,
        format!(
            "{sim}\n[telemetry]\nmqtt = \"{}\"\nkeepalive_s = {KEEPALIVE}\n",
            broker.url()
        ),
    )
    .unwrap();
    path
}
