//! A real PostgreSQL for the tests that record in one: Debian's server (15 or later,
//! `/usr/lib/postgresql/N/bin`), started in a temporary folder on a free loopback port,
//! shared by the tests that only need a database of their own ([`postgres`]) or private to
//! one that stops, starts again or freezes it ([`private_postgres`]). Where PostgreSQL is
//! not installed a test says it skipped, and with `CI` set fails instead. The run records'
//! tests (`records.rs`) and the shop's scale test (`tests/shop.rs`) use it.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, Weak};
use std::time::{Duration, Instant};

/// A PostgreSQL server in a temporary folder, on a free loopback port, stopped (and its
/// folder removed) when dropped.
pub struct Postgres {
    bin: PathBuf,
    port: u16,
    /// The user and group it runs as (as root: nobody's).
    user: Option<(u32, u32)>,
    child: Mutex<Child>,
    databases: AtomicUsize,
    /// Whether it flushes its writes to disk ([`Postgres::make_durable`]).
    durable: AtomicBool,
    dir: tempfile::TempDir,
}

/// Debian's PostgreSQL programs (`/usr/lib/postgresql/N/bin`), the newest from 15 on.
fn postgres_bin() -> Option<PathBuf> {
    let mut found: Vec<(u32, PathBuf)> = std::fs::read_dir("/usr/lib/postgresql")
        .ok()?
        .filter_map(|e| e.ok())
        .filter_map(|e| {
            let version: u32 = e.file_name().to_str()?.parse().ok()?;
            let bin = e.path().join("bin");
            (version >= 15 && bin.join("initdb").exists()).then_some((version, bin))
        })
        .collect();
    found.sort();
    found.pop().map(|(_, bin)| bin)
}

/// PostgreSQL's programs; `None` (the test then says it skipped) where PostgreSQL is not
/// installed, which with `CI` set fails the test instead.
fn postgres_installed() -> Option<PathBuf> {
    let bin = postgres_bin();
    if bin.is_none() {
        let missing = "PostgreSQL 15 or later is not installed (apt-get install postgresql)";
        assert!(
            std::env::var_os("CI").is_none(),
            "on CI PostgreSQL must be there: {missing}"
        );
        eprintln!("skipped: {missing}");
    }
    bin
}

/// The server the tests share, started if none runs (`None` as [`postgres_installed`]).
pub fn postgres() -> Option<Arc<Postgres>> {
    static SHARED: Mutex<Weak<Postgres>> = Mutex::new(Weak::new());
    let mut shared = SHARED.lock().unwrap_or_else(|p| p.into_inner());
    if let Some(server) = shared.upgrade() {
        return Some(server);
    }
    let server = Arc::new(Postgres::start(postgres_installed()?));
    *shared = Arc::downgrade(&server);
    Some(server)
}

/// A server of the test's own, to stop, start again or freeze (`None` as
/// [`postgres_installed`]).
pub fn private_postgres() -> Option<Postgres> {
    Some(Postgres::start(postgres_installed()?))
}

/// `user:group` ids to run the server as: postgres refuses to run as root, so as root it
/// runs as nobody.
fn server_user(dir: &Path) -> Option<(u32, u32)> {
    use std::os::unix::fs::MetadataExt;
    if std::fs::metadata(dir).unwrap().uid() != 0 {
        return None;
    }
    let passwd = std::fs::read_to_string("/etc/passwd").unwrap();
    let nobody: Vec<&str> = passwd
        .lines()
        .find(|l| l.starts_with("nobody:"))
        .expect("a nobody user")
        .split(':')
        .collect();
    Some((nobody[2].parse().unwrap(), nobody[3].parse().unwrap()))
}

/// PostgreSQL's `program` in `bin`, run as `user` if given.
fn as_server(bin: &Path, user: Option<(u32, u32)>, program: &str) -> Command {
    let mut command = match user {
        Some((uid, gid)) => {
            let mut c = Command::new("setpriv");
            c.args([
                format!("--reuid={uid}"),
                format!("--regid={gid}"),
                "--clear-groups".into(),
            ])
            .arg(bin.join(program));
            c
        }
        None => Command::new(bin.join(program)),
    };
    command.env_remove("PGDATA");
    command
}

impl Postgres {
    fn start(bin: PathBuf) -> Postgres {
        use std::os::unix::fs::PermissionsExt;
        let dir = tempfile::tempdir().unwrap();
        let data = dir.path().join("data");
        std::fs::create_dir(&data).unwrap();
        let user = server_user(dir.path());
        // As root: the folder open to nobody, the data folder nobody's.
        if let Some((uid, gid)) = user {
            std::fs::set_permissions(dir.path(), std::fs::Permissions::from_mode(0o755)).unwrap();
            std::os::unix::fs::chown(&data, Some(uid), Some(gid)).unwrap();
        }
        let o = as_server(&bin, user, "initdb")
            .args([
                "-U",
                "postgres",
                "-A",
                "trust",
                "-E",
                "UTF8",
                "--locale=C",
                "--no-sync",
            ])
            .arg("-D")
            .arg(&data)
            .output()
            .expect("initdb runs");
        assert!(
            o.status.success(),
            "initdb: {}",
            String::from_utf8_lossy(&o.stderr)
        );
        let port = std::net::TcpListener::bind("127.0.0.1:0")
            .unwrap()
            .local_addr()
            .unwrap()
            .port();
        let child = Postgres::serve(&bin, user, dir.path(), port, false);
        let server = Postgres {
            bin,
            port,
            user,
            child: Mutex::new(child),
            databases: AtomicUsize::new(0),
            durable: AtomicBool::new(false),
            dir,
        };
        server.wait_ready();
        server
    }

    /// The server process on the data in `dir`, on `port`; unless `durable`, its writes not
    /// flushed to disk (the tests' data lives as long as they do, and flushing would only
    /// slow them).
    fn serve(bin: &Path, user: Option<(u32, u32)>, dir: &Path, port: u16, durable: bool) -> Child {
        let server_log = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(dir.join("server.log"))
            .unwrap();
        as_server(bin, user, "postgres")
            .arg("-D")
            .arg(dir.join("data"))
            .args(["-p", &port.to_string()])
            .args(["-c", "listen_addresses=127.0.0.1"])
            .args(["-c", "unix_socket_directories="])
            .args(if durable {
                [].as_slice()
            } else {
                ["-c", "fsync=off", "-c", "full_page_writes=off"].as_slice()
            })
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(server_log)
            .spawn()
            .expect("postgres starts")
    }

    /// Waits until the server answers (a minute: a loaded host starts it slowly, and a
    /// server that has not answered by then will not).
    fn wait_ready(&self) {
        let deadline = Instant::now() + Duration::from_secs(60);
        while !self.psql("postgres", "SELECT 1").status.success() {
            assert!(
                Instant::now() < deadline,
                "PostgreSQL did not start: {}",
                std::fs::read_to_string(self.dir.path().join("server.log")).unwrap_or_default()
            );
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Stops the server as `pg_ctl stop -m fast` does (SIGINT: its clients cut off, its
    /// data kept), and waits for it to end.
    pub fn stop(&self) {
        let mut child = self.child.lock().unwrap_or_else(|p| p.into_inner());
        stop(&mut child);
    }

    /// Starts the stopped server again, on its port, with its data.
    pub fn start_again(&self) {
        *self.child.lock().unwrap_or_else(|p| p.into_inner()) = Postgres::serve(
            &self.bin,
            self.user,
            self.dir.path(),
            self.port,
            self.durable.load(Ordering::Relaxed),
        );
        self.wait_ready();
    }

    /// Restarts the server flushing its writes to disk as a production server does, and so
    /// on every later start: for the shop benchmark's figures of what the database takes.
    #[allow(dead_code)]
    pub fn make_durable(&self) {
        self.stop();
        self.durable.store(true, Ordering::Relaxed);
        self.start_again();
    }

    /// The server's processes, by their ids: the postmaster first, then its children, which
    /// serve its connections and do its background work.
    pub fn processes(&self) -> Vec<u32> {
        let postmaster = self.child.lock().unwrap_or_else(|p| p.into_inner()).id();
        let mut pids = vec![postmaster];
        for entry in std::fs::read_dir("/proc").unwrap().flatten() {
            let Ok(pid) = entry.file_name().to_string_lossy().parse::<u32>() else {
                continue;
            };
            let stat = std::fs::read_to_string(entry.path().join("stat")).unwrap_or_default();
            let parent = stat
                .rfind(')')
                .and_then(|end| stat[end + 1..].split_whitespace().nth(1))
                .and_then(|p| p.parse::<u32>().ok());
            if parent == Some(postmaster) {
                pids.push(pid);
            }
        }
        pids
    }

    /// Sends `signal` to the server and every process of its: SIGSTOP freezes it as a
    /// server that no longer answers, SIGCONT lets it go on.
    pub fn signal_all(&self, signal: &str) {
        for pid in self.processes() {
            let _ = Command::new("kill")
                .args([&format!("-{signal}"), &pid.to_string()])
                .status();
        }
    }

    fn psql(&self, database: &str, sql: &str) -> Output {
        Command::new(self.bin.join("psql"))
            .args([
                "-h",
                "127.0.0.1",
                "-p",
                &self.port.to_string(),
                "-U",
                "postgres",
            ])
            .args(["-d", database, "-v", "ON_ERROR_STOP=1", "-c", sql])
            .output()
            .expect("psql runs")
    }

    /// A new, empty database on the server: its URL.
    pub fn database(&self) -> String {
        let name = format!("runs{}", self.databases.fetch_add(1, Ordering::Relaxed));
        let o = self.psql("postgres", &format!("CREATE DATABASE {name}"));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        format!("postgres://postgres@127.0.0.1:{}/{name}", self.port)
    }
}

/// A fast shutdown (SIGINT), then, if the server lingers past 20 s, a kill; nothing for a
/// server that has ended.
fn stop(child: &mut Child) {
    if child.try_wait().ok().flatten().is_some() {
        return;
    }
    let _ = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status();
    let deadline = Instant::now() + Duration::from_secs(20);
    while child.try_wait().ok().flatten().is_none() && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    let _ = child.kill();
    let _ = child.wait();
}

impl Drop for Postgres {
    fn drop(&mut self) {
        // A frozen server hears no SIGINT.
        let running = self
            .child
            .lock()
            .unwrap_or_else(|p| p.into_inner())
            .try_wait()
            .ok()
            .flatten()
            .is_none();
        if running {
            self.signal_all("CONT");
        }
        self.stop();
    }
}

/// A port on loopback that nothing listens on: a PostgreSQL that is down.
pub fn dead_postgres_url() -> String {
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    format!("postgres://postgres@127.0.0.1:{port}/runs")
}
