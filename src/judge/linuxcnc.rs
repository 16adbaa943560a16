//! `whirl dry-run --controller linuxcnc`: the job run by a real LinuxCNC, in its own
//! simulation, and the path it executed measured against Δ.
//!
//! LinuxCNC 2.9 (Debian's `linuxcnc-uspace`) runs without a realtime kernel and without a
//! display. The dry run writes an X-Z-C configuration made from the machine profile
//! ([`config_files`]: trivkins with coordinates XZC, C an angular joint with limits far
//! beyond any program, one 1 ms servo thread, commanded positions fed straight back as the
//! joints' feedback, and a HAL `sampler` recording X, Z, C and the program line every
//! servo period), starts LinuxCNC on it (`linuxcnc -r`, `DISPLAY = linuxcncrsh` on a free
//! loopback port with passwords of the run's own), reads the samples through
//! `halsampler` as they come, runs the program through the same LinuxCNC transport a
//! machine gets ([`crate::transport::linuxcnc`]), measures the sampled path with the Δ guard
//! ([`SampledPath`]) and shuts LinuxCNC down, whatever happened.
//!
//! Running it here, as found:
//!
//! - LinuxCNC allows one instance per host (its lock file, shared memory, its port), and
//!   its start script, finding `/tmp/linuxcnc.lock`, *kills* the other instance when there
//!   is no terminal to ask on: so the dry run refuses to start while one of LinuxCNC's
//!   processes runs ([`running_instance`]). A lock with none running was left by an
//!   instance killed before its clean-up (a power cut, a `kill -9`): the dry run removes it
//!   and says so, as the start script's own clean-up would have.
//! - As root, `rtapi_app` refuses to run without `RTAPI_UID` (a user to drop to; not 0) and
//!   needs `RTAPI_FIFO_PATH`, the path of its master socket, in a folder that user can
//!   write: the dry run gives it `nobody`'s uid and a socket in its own folder.
//! - LinuxCNC runs in real time: an example takes its whole machine time. With
//!   `libfaketime` preloaded into `rtapi_app` alone, its clock (and so the servo thread)
//!   runs faster while the task and the interface keep real time; the samples are
//!   bit-identical to a real-time run's at 50× and 100× (measured; at 200× they diverge,
//!   and a test compares the two on every CI run). The preload reaches `rtapi_app` through
//!   a `halcmd` wrapper in the configuration's `bin/`, which LinuxCNC's start script puts
//!   first on the PATH: the other processes, preloaded, break LinuxCNC's own timers. A
//!   setuid `rtapi_app` takes a preload only from root, so the speed-up is root's.

use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::time::{Duration, Instant};

use crate::config::connection::LinuxcncSettings;
use crate::config::job::Job;
use crate::config::machine::{MachineProfile, XMode};
use crate::geometry::linkage::Ring;
use crate::judge::dry_run::DryRunReport;
use crate::judge::guard::DeltaGuard;
use crate::judge::sampled::{SampledPath, SampledRun};
use crate::judge::verify::CheckError;
use crate::log::ExecLog;
use crate::log::LogError;
use crate::program::Move;
use crate::transport::linuxcnc::LinuxcncError;
use crate::transport::linuxcnc::{run_linuxcnc_unended, LinuxcncOptions, LinuxcncOutcome};
use crate::transport::{control, Commands, Posted, ProgressFn};

/// LinuxCNC's servo period, s: the sampler records once a period.
pub const SERVO_PERIOD_S: f64 = 0.001;

/// The fastest clock the dry run allows LinuxCNC: 100× was bit-identical to real time
/// here, 200× was not (the servo thread no longer keeps up with its own clock).
pub const MAX_SPEED_UP: f64 = 100.0;

/// The speed-up a dry run uses unless told: where the samples were first found identical
/// to a real-time run's, with room below [`MAX_SPEED_UP`] for a busy host.
pub const DEFAULT_SPEED_UP: f64 = 50.0;

/// The speed-up a dry run uses unless told: [`DEFAULT_SPEED_UP`] as root (who can preload
/// libfaketime into the setuid `rtapi_app`), real time for anyone else.
pub fn default_speed_up() -> f64 {
    if is_root() {
        DEFAULT_SPEED_UP
    } else {
        1.0
    }
}

/// LinuxCNC's lock file: present while an instance runs on this host.
const LOCK_FILE: &str = "/tmp/linuxcnc.lock";

/// Where Debian's `faketime` package puts the preload library.
const FAKETIME_LIBS: [&str; 2] = [
    "/usr/lib/x86_64-linux-gnu/faketime/libfaketime.so.1",
    "/usr/lib/aarch64-linux-gnu/faketime/libfaketime.so.1",
];

/// How long LinuxCNC may take to come up, and to go down.
const START_TIMEOUT: Duration = Duration::from_secs(60);
const STOP_TIMEOUT: Duration = Duration::from_secs(30);

/// `nobody`: the user a root `rtapi_app` drops to.
const FALLBACK_UID: u32 = 65534;

/// Why LinuxCNC's simulation could not run the job.
#[derive(Debug, thiserror::Error)]
pub enum LinuxcncSimError {
    /// LinuxCNC is not installed.
    #[error(
        "LinuxCNC is not installed (no `linuxcnc` on the PATH): install Debian's \
         linuxcnc-uspace, or dry-run against the built-in simulator (leave out --controller)"
    )]
    Missing,
    /// Another LinuxCNC runs on this host.
    #[error(
        "another LinuxCNC runs on this host ({process}, pid {pid}): LinuxCNC allows one \
         instance per host, and starting a second would stop the first; stop it first"
    )]
    Busy {
        /// The running process's name.
        process: String,
        /// Its process id.
        pid: u32,
    },
    /// A speed-up that cannot be had.
    #[error("{0}")]
    SpeedUp(String),
    /// The configuration or the program's folder.
    #[error("cannot prepare LinuxCNC's configuration in {path}: {source}")]
    Files {
        /// Where.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// LinuxCNC did not come up.
    #[error("LinuxCNC did not start: {0}")]
    Start(String),
    /// The sampler failed.
    #[error("LinuxCNC's sampler: {0}")]
    Sampler(String),
    /// The job's groove cannot be measured.
    #[error("the Δ guard: {0}")]
    Guard(CheckError),
    /// The LinuxCNC transport.
    #[error(transparent)]
    Run(#[from] LinuxcncError),
    /// The executed-path log.
    #[error(transparent)]
    Log(#[from] LogError),
}

/// The configuration files of a LinuxCNC simulation of `machine`, as (name, text):
/// `whirl.ini`, `whirl.hal`, a tool table and an empty parameter file. `display` is the
/// `[DISPLAY] DISPLAY` line (the `linuxcncrsh` command with its options).
pub fn config_files(machine: &MachineProfile, display: &str) -> Vec<(&'static str, String)> {
    let x = &machine.axes.x;
    let z = &machine.axes.z;
    let c = &machine.axes.c;
    // C is unwrapped: a program counts its turns (17 641° is two millimetres of a fine
    // lead), so its joint limits are far beyond any program; the profile's own, if any.
    let (c_min, c_max) = (c.min.unwrap_or(-1e9), c.max.unwrap_or(1e9));
    let linear = (x.max_rate.max(z.max_rate)) / 60.0;
    let axis = |name: &str, joint: usize, kind: &str, min: f64, max: f64, rate: f64, accel: f64| {
        format!(
            "[AXIS_{name}]\nMIN_LIMIT = {min}\nMAX_LIMIT = {max}\nMAX_VELOCITY = {v}\n\
             MAX_ACCELERATION = {accel}\n\n[JOINT_{joint}]\nTYPE = {kind}\nMIN_LIMIT = {min}\n\
             MAX_LIMIT = {max}\nMAX_VELOCITY = {v}\nMAX_ACCELERATION = {accel}\n\
             HOME_SEQUENCE = 0\n\n",
            v = rate / 60.0
        )
    };
    let ini = format!(
        "# whirl's LinuxCNC simulation of \"{name}\": X (radius), Z, C; written for one dry run.\n\
         [EMC]\nVERSION = 1.1\nMACHINE = whirl-xzc\n\n\
         [DISPLAY]\nDISPLAY = {display}\n\n\
         [RS274NGC]\nPARAMETER_FILE = whirl.var\n\n\
         [EMCMOT]\nEMCMOT = motmod\nCOMM_TIMEOUT = 1.0\nSERVO_PERIOD = {servo_ns}\n\n\
         [TASK]\nTASK = milltask\nCYCLE_TIME = 0.001\n\n\
         [HAL]\nHALFILE = whirl.hal\n\n\
         [TRAJ]\nCOORDINATES = X Z C\nLINEAR_UNITS = mm\nANGULAR_UNITS = degree\n\
         MAX_LINEAR_VELOCITY = {linear}\nMAX_ANGULAR_VELOCITY = {angular}\n\
         # Positions are commanded ones fed back: there is nothing to home.\n\
         NO_FORCE_HOMING = 1\n\n\
         [EMCIO]\nEMCIO = io\nCYCLE_TIME = 0.100\nTOOL_TABLE = whirl.tbl\n\n\
         [KINS]\nKINEMATICS = trivkins coordinates=XZC\nJOINTS = 3\n\n{ax}{az}{ac}",
        name = machine.name.replace('\n', " "),
        servo_ns = (SERVO_PERIOD_S * 1e9) as u64,
        angular = c.max_rate / 60.0,
        ax = axis("X", 0, "LINEAR", x.min, x.max, x.max_rate, x.accel),
        az = axis("Z", 1, "LINEAR", z.min, z.max, z.max_rate, z.accel),
        ac = axis("C", 2, "ANGULAR", c_min, c_max, c.max_rate, c.accel),
    );
    let hal = "\
# Motion on a 1 ms servo thread, commanded positions fed back (a perfect machine), and a
# sampler recording X, Z, C (axis positions: X is the radius) and the program line each period.
loadrt [KINS]KINEMATICS
loadrt [EMCMOT]EMCMOT servo_period_nsec=[EMCMOT]SERVO_PERIOD num_joints=[KINS]JOINTS
loadrt sampler depth=200000 cfg=fffs
addf motion-command-handler servo-thread
addf motion-controller servo-thread
addf sampler.0 servo-thread
net x-pos joint.0.motor-pos-cmd => joint.0.motor-pos-fb
net z-pos joint.1.motor-pos-cmd => joint.1.motor-pos-fb
net c-pos joint.2.motor-pos-cmd => joint.2.motor-pos-fb
net x-sample axis.x.pos-cmd => sampler.0.pin.0
net z-sample axis.z.pos-cmd => sampler.0.pin.1
net c-sample axis.c.pos-cmd => sampler.0.pin.2
net line-sample motion.program-line => sampler.0.pin.3
net estop-loop iocontrol.0.user-enable-out => iocontrol.0.emc-enable-in
net tool-prep-loop iocontrol.0.tool-prepare => iocontrol.0.tool-prepared
net tool-change-loop iocontrol.0.tool-change => iocontrol.0.tool-changed
"
    .to_owned();
    vec![
        ("whirl.ini", ini),
        ("whirl.hal", hal),
        ("whirl.tbl", "T1 P1 Z0 D0 ;\n".to_owned()),
        ("whirl.var", String::new()),
    ]
}

/// The `halcmd` wrapper that preloads `libfaketime` at `speed`× into the `rtapi_app` it
/// starts (and into nothing else): see the module docs.
fn halcmd_wrapper(library: &Path, speed: f64) -> String {
    format!(
        "#!/bin/sh\n# whirl: LinuxCNC's realtime clock at {speed}x (libfaketime in rtapi_app only).\n\
         LD_PRELOAD={} FAKETIME='+0 x{speed}' FAKETIME_ONLY_CMDS=rtapi_app exec /usr/bin/halcmd \"$@\"\n",
        library.display()
    )
}

/// Random hex from the kernel, for the run's passwords: eight digits, as linuxcncrsh keeps
/// only the first 15 characters of a password it is given, and compares those.
fn random_word() -> String {
    use std::io::Read;
    let mut bytes = [0u8; 4];
    let read = std::fs::File::open("/dev/urandom").and_then(|mut f| f.read_exact(&mut bytes));
    if read.is_err() {
        // No /dev/urandom: the time and the pid, which still differ between runs.
        let now = std::time::SystemTime::now()
            .duration_since(std::time::UNIX_EPOCH)
            .unwrap_or_default();
        bytes = (now.subsec_nanos() ^ std::process::id()).to_le_bytes();
    }
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// Whether this process runs as root (the owner of `/proc/self`).
fn is_root() -> bool {
    use std::os::unix::fs::MetadataExt;
    std::fs::metadata("/proc/self").is_ok_and(|m| m.uid() == 0)
}

fn on_path(program: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|dir| dir.join(program).is_file()))
}

/// The processes of a running LinuxCNC: its start script, the task, the server and the
/// realtime application (the names its script's clean-up looks for with `pidof`).
const INSTANCE_PROCESSES: [&str; 4] = ["linuxcnc", "milltask", "linuxcncsvr", "rtapi_app"];

/// A process of a LinuxCNC running on this host, as (pid, name), found in `/proc`. A
/// zombie (exited, not yet reaped by its parent: an instance's processes linger so after a
/// shut-down where no init reaps them promptly) runs nothing and holds nothing.
pub fn running_instance() -> Option<(u32, String)> {
    std::fs::read_dir("/proc")
        .ok()?
        .flatten()
        .find_map(|entry| {
            let pid = entry.file_name().to_str()?.parse().ok()?;
            // `pid (name) state …`; the name may hold spaces and parentheses, the state follows
            // the last `)`.
            let stat = std::fs::read_to_string(entry.path().join("stat")).ok()?;
            let (head, tail) = stat.rsplit_once(')')?;
            let name = head.split_once('(')?.1;
            let zombie = tail.trim_start().starts_with('Z');
            (INSTANCE_PROCESSES.contains(&name) && !zombie).then(|| (pid, name.to_owned()))
        })
}

/// A free TCP port on the loopback interface.
fn free_port() -> std::io::Result<u16> {
    let listener = std::net::TcpListener::bind("127.0.0.1:0")?;
    Ok(listener.local_addr()?.port())
}

/// LinuxCNC's simulation of a machine, running (a controller to stream to, for tests and
/// for trying a profile); [`Simulation::shut_down`] ends it.
pub struct Simulation {
    linuxcnc: tokio::process::Child,
    dir: PathBuf,
    env: Vec<(String, String)>,
    settings: LinuxcncSettings,
}

impl Simulation {
    /// Writes the configuration for `machine` to a new folder and starts LinuxCNC on it,
    /// its clock at `speed`× (1: real time).
    pub async fn start(
        machine: &MachineProfile,
        speed: f64,
    ) -> Result<Simulation, LinuxcncSimError> {
        if !on_path("linuxcnc") {
            return Err(LinuxcncSimError::Missing);
        }
        if let Some((pid, process)) = running_instance() {
            return Err(LinuxcncSimError::Busy { process, pid });
        }
        if Path::new(LOCK_FILE).exists() {
            tracing::warn!(
                "{LOCK_FILE} was left by a LinuxCNC that no longer runs (killed before its \
                 clean-up): removed"
            );
            let _ = std::fs::remove_file(LOCK_FILE);
        }
        let root = is_root();
        let faketime = if speed == 1.0 {
            None
        } else if !root {
            return Err(LinuxcncSimError::SpeedUp(format!(
                "a {speed}x clock needs root (libfaketime preloaded into the setuid rtapi_app); \
                 run with --time-scale 1"
            )));
        } else {
            Some(
                FAKETIME_LIBS
                    .iter()
                    .map(Path::new)
                    .find(|p| p.exists())
                    .ok_or_else(|| {
                        LinuxcncSimError::SpeedUp(
                            "a faster clock needs libfaketime (Debian's faketime package); \
                             install it or run with --time-scale 1"
                                .into(),
                        )
                    })?,
            )
        };
        let dir = new_dir()?;
        let files = |e| LinuxcncSimError::Files {
            path: dir.clone(),
            source: e,
        };
        let port = free_port().map_err(files)?;
        let settings = LinuxcncSettings {
            address: format!("127.0.0.1:{port}"),
            connect_password: random_word(),
            enable_password: random_word(),
            power_on: true,
            program_dir: Some(dir.display().to_string()),
            timeout_ms: 5000,
        };
        // linuxcncrsh listens on every interface (it has no option to bind one): the
        // run's own passwords keep others out. (`--sessions 1` would too, but the probe
        // that finds the port listening uses up its one session.)
        let display = format!(
            "linuxcncrsh --port {port} --connectpw {} --enablepw {}",
            settings.connect_password, settings.enable_password
        );
        for (name, text) in config_files(machine, &display) {
            std::fs::write(dir.join(name), text).map_err(files)?;
        }
        if let Some(library) = faketime {
            use std::os::unix::fs::PermissionsExt;
            let bin = dir.join("bin");
            std::fs::create_dir(&bin).map_err(files)?;
            let wrapper = bin.join("halcmd");
            std::fs::write(&wrapper, halcmd_wrapper(library, speed)).map_err(files)?;
            std::fs::set_permissions(&wrapper, std::fs::Permissions::from_mode(0o755))
                .map_err(files)?;
        }
        let mut env = Vec::new();
        if root {
            // rtapi_app's master socket, in a folder the uid it drops to can write.
            use std::os::unix::fs::PermissionsExt;
            let fifo = dir.join("rtapi");
            std::fs::create_dir(&fifo).map_err(files)?;
            std::fs::set_permissions(&fifo, std::fs::Permissions::from_mode(0o1777))
                .map_err(files)?;
            std::fs::set_permissions(&dir, std::fs::Permissions::from_mode(0o755))
                .map_err(files)?;
            env.push(("RTAPI_UID".into(), FALLBACK_UID.to_string()));
            env.push((
                "RTAPI_FIFO_PATH".into(),
                fifo.join("fifo").display().to_string(),
            ));
        }
        let log = std::fs::File::create(dir.join("linuxcnc.out")).map_err(files)?;
        let log2 = log.try_clone().map_err(files)?;
        let mut command = tokio::process::Command::new("linuxcnc");
        command
            .arg("-r")
            .arg(dir.join("whirl.ini"))
            .current_dir(&dir)
            .envs(env.iter().cloned())
            .stdin(Stdio::null())
            .stdout(log)
            .stderr(log2)
            .process_group(0)
            .kill_on_drop(true);
        let linuxcnc = command
            .spawn()
            .map_err(|e| LinuxcncSimError::Start(format!("cannot start `linuxcnc`: {e}")))?;
        let mut instance = Simulation {
            linuxcnc,
            dir,
            env,
            settings,
        };
        if let Err(error) = instance.wait_for_port(port).await {
            instance.shut_down().await;
            return Err(error);
        }
        Ok(instance)
    }

    /// How to reach its `linuxcncrsh`: a loopback port, the run's passwords, power-on
    /// allowed, programs in its own folder.
    pub fn settings(&self) -> &LinuxcncSettings {
        &self.settings
    }

    /// Waits until `linuxcncrsh` listens, or LinuxCNC gives up.
    async fn wait_for_port(&mut self, port: u16) -> Result<(), LinuxcncSimError> {
        let started = Instant::now();
        loop {
            if let Ok(Some(status)) = self.linuxcnc.try_wait() {
                return Err(LinuxcncSimError::Start(format!(
                    "it exited ({status}): {}",
                    self.output_tail()
                )));
            }
            if tokio::net::TcpStream::connect(("127.0.0.1", port))
                .await
                .is_ok()
            {
                return Ok(());
            }
            if started.elapsed() > START_TIMEOUT {
                return Err(LinuxcncSimError::Start(format!(
                    "linuxcncrsh did not listen within {} s: {}",
                    START_TIMEOUT.as_secs(),
                    self.output_tail()
                )));
            }
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    }

    /// The last lines LinuxCNC printed.
    fn output_tail(&self) -> String {
        let text = std::fs::read_to_string(self.dir.join("linuxcnc.out")).unwrap_or_default();
        let lines: Vec<&str> = text
            .lines()
            .filter(|l| !l.starts_with("Running with fallback_uid"))
            .collect();
        lines[lines.len().saturating_sub(6)..].join(" | ")
    }

    /// `halsampler`, reading the sampler's FIFO to its stdout.
    fn sampler(&self) -> Result<std::process::Child, LinuxcncSimError> {
        std::process::Command::new("halsampler")
            .arg("-t")
            .envs(self.env.iter().cloned())
            .stdin(Stdio::null())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .map_err(|e| LinuxcncSimError::Sampler(format!("cannot start halsampler: {e}")))
    }

    /// Stops LinuxCNC as a Ctrl-C in its terminal does: SIGINT to its process group, so
    /// the interface exits and the start script runs its own clean-up (bash runs the
    /// script's trap only once its foreground program, `linuxcncrsh`, has exited); if that
    /// hangs, every process of the group is killed. Its folder goes too.
    pub async fn shut_down(mut self) {
        if let Some(pid) = self.linuxcnc.id() {
            let _ = std::process::Command::new("kill")
                .args(["-INT", "--", &format!("-{pid}")])
                .status();
            let stopped = tokio::time::timeout(STOP_TIMEOUT, self.linuxcnc.wait()).await;
            if stopped.is_err() {
                let _ = std::process::Command::new("kill")
                    .args(["-KILL", "--", &format!("-{pid}")])
                    .status();
                let _ = self.linuxcnc.wait().await;
                // The script's clean-up, which removes the lock, died with it: the lock
                // is this instance's, and left behind it would refuse every later start.
                let _ = std::fs::remove_file(LOCK_FILE);
            }
        }
        let _ = std::fs::remove_dir_all(&self.dir);
    }
}

/// A new folder of this run's own under the system's temporary folder.
fn new_dir() -> Result<PathBuf, LinuxcncSimError> {
    let base = std::env::temp_dir();
    for n in 0..10_000 {
        let dir = base.join(format!("whirl-linuxcnc-{}-{n}", std::process::id()));
        match std::fs::create_dir(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(source) => return Err(LinuxcncSimError::Files { path: dir, source }),
        }
    }
    Err(LinuxcncSimError::Files {
        path: base,
        source: std::io::ErrorKind::AlreadyExists.into(),
    })
}

/// Whether each file line (1-based index) of `posted` is a rapid.
fn rapid_lines(posted: &Posted) -> Vec<bool> {
    let mut rapid = vec![false; posted.lines.len() + 2];
    for (m, &line) in posted.program.moves.iter().zip(&posted.move_lines) {
        if let (Move::Rapid { .. }, Some(slot)) = (m, rapid.get_mut(line)) {
            *slot = true;
        }
    }
    rapid
}

/// How a LinuxCNC dry run runs.
pub struct LinuxcncDryRunOptions {
    /// LinuxCNC's clock against real time: 1, or up to [`MAX_SPEED_UP`].
    pub speed_up: f64,
    /// Give up (with a hold) after this long without progress.
    pub stall_timeout: Duration,
    /// Told how far the run is.
    pub progress: Option<ProgressFn>,
    /// The caller's hold, resume and abort.
    pub commands: Option<Commands>,
}

/// Dry-runs `posted` (written for a LinuxCNC `machine`, planned for `job` with `ring`) on
/// LinuxCNC's simulation, its Δ guard measuring with that ring; see the module docs.
pub async fn dry_run(
    job: &Job,
    ring: Ring,
    machine: &MachineProfile,
    posted: &Posted,
    options: LinuxcncDryRunOptions,
    log: &mut ExecLog,
) -> Result<DryRunReport, LinuxcncSimError> {
    let speed = options.speed_up;
    if !(1.0..=MAX_SPEED_UP).contains(&speed) {
        return Err(LinuxcncSimError::SpeedUp(format!(
            "--time-scale {speed}: LinuxCNC's clock runs at 1 (real time) to {MAX_SPEED_UP}x \
             (faster, its samples were found to differ from a real-time run's)"
        )));
    }
    // The sampler records LinuxCNC's axis positions, whose X is a radius in every X mode.
    let radius = MachineProfile {
        x_mode: XMode::Radius,
        ..machine.clone()
    };
    let guard = DeltaGuard::new(job, ring, &radius).map_err(LinuxcncSimError::Guard)?;
    let points = guard.points();
    let started = Instant::now();
    let instance = Simulation::start(machine, speed).await?;
    let result = run_on(&instance, guard, posted, options, log).await;
    instance.shut_down().await;
    let (outcome, sampled) = result?;
    let completed = outcome.completed() && sampled.lost == 0;
    let within_delta = completed
        && sampled.breach.is_none()
        && sampled.measured.points == points
        && sampled.measured.max_error_mm() <= sampled.measured.delta_mm;
    let stop = if sampled.lost > 0 {
        Some(format!(
            "{} of LinuxCNC's samples were lost (the sampler's FIFO ran over): the path is not \
             known there",
            sampled.lost
        ))
    } else {
        outcome.stop()
    };
    let alarms = sampled
        .breach
        .iter()
        .map(|detail| crate::judge::dry_run::Alarm {
            code: 64,
            message: crate::protocol::grbl::codes::alarm_message(64).to_owned(),
            detail: Some(detail.clone()),
        })
        .collect();
    Ok(DryRunReport {
        job: posted.name.clone(),
        within_delta,
        completed,
        lines: posted.lines.len(),
        lines_acked: sampled.furthest_line as usize,
        stop,
        // LinuxCNC keeps its place in the program: a stopped run resumes at its console.
        resume_at: None,
        machine_time_s: sampled.machine_time_s,
        wall_time_s: started.elapsed().as_secs_f64(),
        baud: 0,
        link_utilization: 0.0,
        max_error_mm: sampled.measured.max_error_mm(),
        max_overcut_mm: sampled.measured.max_overcut_mm,
        max_undercut_mm: sampled.measured.max_undercut_mm,
        delta_mm: sampled.measured.delta_mm,
        points_measured: sampled.measured.points,
        points,
        alarms,
    })
}

/// The program run on `instance`, its samples measured as they come.
async fn run_on(
    instance: &Simulation,
    guard: DeltaGuard,
    posted: &Posted,
    options: LinuxcncDryRunOptions,
    log: &mut ExecLog,
) -> Result<(LinuxcncOutcome, SampledRun), LinuxcncSimError> {
    let mut sampler = instance.sampler()?;
    let stdout = sampler.stdout.take().expect("piped");
    let mut path = SampledPath::new(guard, rapid_lines(posted), SERVO_PERIOD_S, log);
    // A breach stops the machine: the reader aborts the program through the same control
    // the caller has.
    let (control, commands) = control();
    let caller = options.commands;
    let forward = control.clone();
    let relay = tokio::spawn(async move {
        if let Some(mut caller) = caller {
            loop {
                let command = caller.next().await;
                if !forward.send(command) {
                    break;
                }
            }
        }
    });
    let reader = std::thread::spawn(move || -> Result<SampledPath, String> {
        use std::io::BufRead;
        let mut aborted = false;
        let mut reader = std::io::BufReader::new(stdout);
        let mut line = String::new();
        loop {
            line.clear();
            reader.read_line(&mut line).map_err(|e| e.to_string())?;
            // The sampler is stopped when the run is over: a last line it did not finish
            // is not a sample.
            if !line.ends_with('\n') {
                break;
            }
            let mut words = line.split_whitespace();
            let mut number = || words.next().and_then(|w| w.parse::<f64>().ok());
            let (Some(index), Some(x), Some(z), Some(c), Some(l)) =
                (number(), number(), number(), number(), number())
            else {
                return Err(format!("not a sample: {line:?}"));
            };
            path.push(index as u64, [x, z, c], l as u64);
            if !aborted && path.breach().is_some() {
                aborted = control.abort();
            }
        }
        Ok(path)
    });
    let run_options = LinuxcncOptions {
        program: posted.name.clone(),
        end_position: posted.program.end_position(),
        stall_timeout: Some(options.stall_timeout),
        on_progress: options.progress,
        commands: Some(commands),
        ..LinuxcncOptions::default()
    };
    let unended = run_linuxcnc_unended(&instance.settings, &posted.lines, run_options, log).await;
    relay.abort();
    // The last samples are a servo period behind the status LinuxCNC reports: let the
    // sampler's FIFO drain (it reads far faster than 1 ms a sample), then end it, and
    // only then the run, so that the log has the whole path before its End.
    tokio::time::sleep(Duration::from_millis(500)).await;
    let _ = sampler.kill();
    let _ = sampler.wait();
    let path = tokio::task::spawn_blocking(move || reader.join())
        .await
        .map_err(|e| LinuxcncSimError::Sampler(e.to_string()))
        .and_then(|joined| {
            joined.map_err(|_| LinuxcncSimError::Sampler("the reader panicked".into()))
        })
        .and_then(|read| read.map_err(LinuxcncSimError::Sampler));
    let unended = unended?;
    let sampled = path.and_then(|path| Ok(path.finish(unended.completed())?));
    let outcome = unended.end(log)?;
    let sampled = sampled?;
    Ok((outcome, sampled))
}
