//! `whirl-sim`: the simulated whirling-lathe controller on a pseudo-terminal or a TCP port,
//! or, with `--can-slcan`, three simulated CANopen drives behind an slcan adapter.
//!
//! It lives in the root package because it builds the controller from whirl's machine
//! profiles; the controller itself is the `whirl-sim` library in `sim/`, which depends on
//! nothing of whirl's.

use anyhow::{Context, Result};
use clap::Parser;
use std::ffi::OsStr;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::pin::Pin;
use std::process::ExitCode;
use std::task::Poll;
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, ReadBuf};
use tokio::signal::unix::{signal, Signal, SignalKind};
use tokio::time::{timeout, Instant};
use tokio_serial::{SerialPort, SerialStream};
use whirl::config::connection::{MAX_CYCLE_US, MIN_CYCLE_US};
use whirl::config::machine::MachineProfile;
use whirl::judge::guard::DeltaGuard;
use whirl_sim::serve::{serve, ServeOptions};
use whirl_sim::{Controller, ControllerOptions};

#[path = "whirl/numbers.rs"]
mod numbers;
use numbers::{baud, number, rx, time_scale, whole_in};

#[derive(Parser)]
#[command(
    name = "whirl-sim",
    version,
    about = "A simulated grblHAL whirling-lathe controller"
)]
struct Cli {
    /// Serve on a new pseudo-terminal; PATH becomes a symlink to its device, removed when
    /// whirl-sim stops. Nothing may be at PATH but such a link an earlier whirl-sim left
    /// behind (a symlink to a /dev/pts/N since closed), which is replaced.
    #[arg(long, conflicts_with = "tcp")]
    pty: Option<PathBuf>,
    /// With --pty: model a board that resets when its port is opened (the DTR line of an
    /// Arduino or a USB serial adapter): each time a client opens the terminal the
    /// controller powers up afresh, boots for --boot-time, dropping what arrives meanwhile,
    /// then prints its banner. Without it, the controller powered up when whirl-sim started
    /// and its banner waits in the terminal for the first client, as a board's waits in its
    /// port.
    #[arg(
        long,
        requires = "pty",
        conflicts_with_all = ["tcp", "modbus_tcp", "modbus_rtu", "can_slcan"]
    )]
    reset_on_open: bool,
    /// With --reset-on-open: how long the board boots, seconds of wall time, 0 to 10 (an
    /// Arduino's boot loader takes about half a second, older ones up to 2).
    #[arg(
        long,
        value_name = "SECONDS",
        default_value_t = 0.5,
        allow_hyphen_values = true,
        value_parser = boot_time,
        requires = "reset_on_open"
    )]
    boot_time: f64,
    /// Serve one connection on this TCP address (loopback unless you say otherwise).
    #[arg(long)]
    tcp: Option<String>,
    /// Serve the Modbus register map (docs/modbus.md) on this TCP address instead of G-code.
    #[arg(long, conflicts_with_all = ["pty", "tcp"])]
    modbus_tcp: Option<String>,
    /// Serve the Modbus register map as an RTU server on a new pseudo-terminal; PATH becomes
    /// a symlink to its device, as with --pty.
    #[arg(long, conflicts_with_all = ["pty", "tcp", "modbus_tcp"])]
    modbus_rtu: Option<PathBuf>,
    /// Serve three CiA 402 drives (X, Z, C on CANopen nodes 1, 2, 3) behind an slcan
    /// adapter on a new pseudo-terminal instead of a controller; PATH becomes a symlink to
    /// its device, as with --pty.
    #[arg(long, conflicts_with_all = ["pty", "tcp", "modbus_tcp", "modbus_rtu"])]
    can_slcan: Option<PathBuf>,
    /// The CAN drives' counts per mm of X and Z and per degree of C; default: the machine
    /// profile's `[connection.drives]`, else 10000,10000,10000. Each above 0, at most 1e9.
    #[arg(long, allow_hyphen_values = true, value_name = "X,Z,C", value_parser = counts)]
    can_counts: Option<[f64; 3]>,
    /// The CAN master's SYNC period, µs: each drive moves at most its axis's max rate for
    /// this long a cycle, 250 to 100000 (as a profile's); default: the profile's
    /// `cycle_us`, else 4000.
    #[arg(long, allow_hyphen_values = true, value_parser = cycle_us)]
    can_cycle_us: Option<u64>,
    /// Machine profile (TOML); default: machine-profiles/sim.toml, built in.
    #[arg(long)]
    machine: Option<PathBuf>,
    /// Simulated seconds per wall second, 0.001 to 10000; 0: as fast as the host allows.
    #[arg(long, allow_hyphen_values = true, default_value_t = 1.0, value_parser = time_scale)]
    time_scale: f64,
    /// Emulated link rate, bits per second, 300 to 10000000; default: unlimited.
    #[arg(long, allow_hyphen_values = true, value_parser = baud)]
    baud: Option<u32>,
    /// Receive buffer size in bytes (grblHAL 1024; 128 like an AVR grbl), 128 to 65536.
    #[arg(long, allow_hyphen_values = true, default_value_t = 1024, value_parser = rx)]
    rx: usize,
    /// Model a link that stops at a nearly full receive buffer: no byte, real-time ones
    /// included, is delivered while FREE bytes of it or fewer are free (grblHAL's own
    /// Simulator: 100; 0: only when full), so a status request or a feed hold waits behind
    /// the lines. Default: a receive interrupt that sees every byte at once.
    #[arg(long, value_name = "FREE")]
    rx_backpressure: Option<usize>,
    /// The job whose groove the machine cuts: the Δ guard measures the executed motion
    /// against it and raises ALARM:64 as soon as the profile error exceeds Δ.
    #[arg(long)]
    job: Option<PathBuf>,
    /// Append every simulator event (answers, executed moves, alarms) to this file as JSON
    /// lines.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Stop after this many seconds without a byte from the client, up to 604800 (a week);
    /// 0: never.
    #[arg(long, allow_hyphen_values = true, default_value_t = 600.0, value_parser = idle_exit)]
    idle_exit: f64,
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> ExitCode {
    let cli = Cli::parse();
    let mut stop = match Stop::listen() {
        Ok(stop) => stop,
        Err(e) => {
            note(format_args!("error: cannot listen for signals: {e}"));
            return ExitCode::FAILURE;
        }
    };
    // A signal drops `run` where it waits, and with it the terminal's link, which removes
    // itself (see `PtyLink`).
    tokio::select! {
        result = run(cli) => match result {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => {
                note(format_args!("error: {e:#}"));
                ExitCode::FAILURE
            }
        },
        (name, code) = stop.first() => {
            note(format_args!("whirl-sim: stopped by {name}"));
            ExitCode::from(code)
        }
    }
}

/// The signals that stop whirl-sim from outside: Ctrl-C (SIGINT), `kill` (SIGTERM), its
/// terminal closed (SIGHUP). Listened for before anything starts, so that whirl-sim stops by
/// returning, cleaning up as it goes, rather than dying where it stands.
struct Stop {
    interrupt: Signal,
    terminate: Signal,
    hangup: Signal,
}

impl Stop {
    fn listen() -> std::io::Result<Stop> {
        Ok(Stop {
            interrupt: signal(SignalKind::interrupt())?,
            terminate: signal(SignalKind::terminate())?,
            hangup: signal(SignalKind::hangup())?,
        })
    }

    /// The first of them to come: its name, and the exit code a shell gives a command that
    /// signal ended, 128 + its number.
    async fn first(&mut self) -> (&'static str, u8) {
        tokio::select! {
            _ = self.interrupt.recv() => ("SIGINT", 128 + 2),
            _ = self.terminate.recv() => ("SIGTERM", 128 + 15),
            _ = self.hangup.recv() => ("SIGHUP", 128 + 1),
        }
    }
}

/// A line on standard error; if standard error cannot take it (a closed pipe), there is
/// nowhere left to say so, and serving goes on.
fn note(line: std::fmt::Arguments) {
    let _ = writeln!(std::io::stderr(), "{line}");
}

async fn run(cli: Cli) -> Result<()> {
    // A path that cannot take the terminal's link is refused before anything starts.
    for (option, path) in [
        ("--pty", &cli.pty),
        ("--modbus-rtu", &cli.modbus_rtu),
        ("--can-slcan", &cli.can_slcan),
    ] {
        if let Some(path) = path {
            earlier_link(option, path)?;
        }
    }
    let profile = match &cli.machine {
        Some(p) => MachineProfile::load(p)?,
        None => MachineProfile::builtin_sim()?,
    };
    let guard = match &cli.job {
        Some(path) => Some(delta_guard(path, &profile)?),
        None => None,
    };
    let mut event_log = EventLog::open(cli.log.as_deref())?;
    let idle_exit = (cli.idle_exit > 0.0).then(|| Duration::from_secs_f64(cli.idle_exit));
    if let Some(link) = &cli.can_slcan {
        return serve_can(&cli, &profile, guard, link, idle_exit, &mut event_log).await;
    }
    if let Some(reserve) = cli.rx_backpressure {
        anyhow::ensure!(
            reserve + 1 < cli.rx,
            "--rx-backpressure {reserve}: must be below the receive buffer's {} bytes less one",
            cli.rx
        );
    }
    let options = ControllerOptions {
        rx_buffer_size: cli.rx,
        rx_backpressure: cli.rx_backpressure,
        ..ControllerOptions::default()
    };
    let machine = whirl::judge::simulator::machine(&profile);
    let mut controller = Controller::new(&machine, options.clone())?;
    if let Some(guard) = guard {
        controller.set_guard(Box::new(guard));
    }
    let serve_options = ServeOptions {
        time_scale: (cli.time_scale > 0.0).then_some(cli.time_scale),
        baud: cli.baud,
        idle_exit,
        ..ServeOptions::default()
    };
    let log = |e: &whirl_sim::Event| event_log.record(e);
    if cli.modbus_tcp.is_some() || cli.modbus_rtu.is_some() {
        use whirl_sim::modbus::serve::{serve_rtu, serve_tcp, ClockOptions};
        use whirl_sim::modbus::{Bank, BankOptions};
        anyhow::ensure!(
            cli.time_scale > 0.0,
            "Modbus needs a time scale above 0: the bridge feeds the watchdog in the \
             controller's time"
        );
        let bank = Bank::new(controller, BankOptions::default())?;
        let bank = std::sync::Arc::new(std::sync::Mutex::new(bank));
        let clock = ClockOptions {
            time_scale: cli.time_scale,
            idle_exit: serve_options.idle_exit,
            ..ClockOptions::default()
        };
        if let Some(addr) = &cli.modbus_tcp {
            let listener = tokio::net::TcpListener::bind(addr)
                .await
                .with_context(|| format!("cannot listen on {addr}"))?;
            note(format_args!(
                "whirl-sim: serving Modbus on {}",
                listener.local_addr()?
            ));
            serve_tcp(listener, bank, clock, log).await?;
        } else if let Some(link) = &cli.modbus_rtu {
            let (master, _slave, _link) = pty_at("--modbus-rtu", link)?;
            serve_rtu(master, bank, clock, log).await?;
        }
    } else if let Some(link) = &cli.pty {
        let (master, slave, _link) = pty_at("--pty", link)?;
        if !cli.reset_on_open {
            // Powered up when whirl-sim started: the banner waits in the terminal (`serve`
            // writes it first) for whoever opens it, as grblHAL's waits in a board's port;
            // the slave end stays open so the terminal outlives its clients.
            let _slave = slave;
            serve(master, &mut controller, serve_options, log).await?;
        } else {
            // No end of the terminal kept open here: the master then reads EIO
            // while no client has it open, which is how an opening is seen.
            drop(slave);
            let boot = Duration::from_secs_f64(cli.boot_time);
            let mut first = Some(controller);
            let power_up = || -> Result<Controller> {
                if let Some(controller) = first.take() {
                    return Ok(controller);
                }
                let mut controller = Controller::new(&machine, options.clone())?;
                if let Some(job) = &cli.job {
                    controller.set_guard(Box::new(delta_guard(job, &profile)?));
                }
                Ok(controller)
            };
            serve_resetting(master, boot, power_up, serve_options, log).await?;
        }
    } else {
        let addr = cli.tcp.as_deref().unwrap_or("127.0.0.1:0");
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .with_context(|| format!("cannot listen on {addr}"))?;
        note(format_args!(
            "whirl-sim: serving on {}",
            listener.local_addr()?
        ));
        let (socket, _) = listener.accept().await?;
        serve(socket, &mut controller, serve_options, log).await?;
    }
    Ok(())
}

/// The EIO of Linux: what reading a pseudo-terminal's master gives while no process has its
/// slave end open.
const EIO: i32 = 5;

/// How often the master is tried while no client has the terminal open.
const OPEN_POLL: Duration = Duration::from_millis(20);

/// Whether a client has the terminal open (`Some(bytes)`: it has, and sent these), or not
/// (`None`), as reading the master says within [`OPEN_POLL`]: EIO while none has, a wait for
/// bytes while one has.
async fn client(master: &mut SerialStream) -> Result<Option<Vec<u8>>> {
    let mut buf = [0u8; 4096];
    match timeout(OPEN_POLL, master.read(&mut buf)).await {
        Err(_waiting) => Ok(Some(Vec::new())),
        Ok(Ok(n)) => Ok(Some(buf[..n].to_vec())),
        Ok(Err(e)) if e.raw_os_error() == Some(EIO) => {
            tokio::time::sleep(OPEN_POLL).await;
            Ok(None)
        }
        Ok(Err(e)) => Err(e).context("cannot read the pseudo-terminal"),
    }
}

/// `--reset-on-open`: for each client that opens the terminal, the board resets: it boots
/// for `boot`, the bytes sent meanwhile lost (a boot loader listens for its own protocol,
/// not for grbl's), then a freshly powered-up controller from `power_up` prints its banner
/// and serves until the client closes the terminal. Ends when no client comes, or one
/// says nothing, for `options.idle_exit`.
async fn serve_resetting(
    mut master: SerialStream,
    boot: Duration,
    mut power_up: impl FnMut() -> Result<Controller>,
    options: ServeOptions,
    mut log: impl FnMut(&whirl_sim::Event),
) -> Result<()> {
    let mut since = Instant::now();
    loop {
        if client(&mut master).await?.is_none() {
            if options
                .idle_exit
                .is_some_and(|idle| since.elapsed() >= idle)
            {
                return Ok(());
            }
            continue;
        }
        let booted = Instant::now() + boot;
        while Instant::now() < booted {
            // Dropped: the board is not listening yet.
            client(&mut master).await?;
        }
        let mut controller = power_up()?;
        let mut port = Hangup {
            master: &mut master,
            hung_up: false,
        };
        serve(&mut port, &mut controller, options, &mut log).await?;
        if !port.hung_up {
            // The client fell silent for the idle time.
            return Ok(());
        }
        since = Instant::now();
    }
}

/// The master of a terminal as a stream that ends when the client closes the terminal:
/// the EIO that reading then gives is the end of the stream, as a closed socket's.
struct Hangup<'a> {
    master: &'a mut SerialStream,
    /// The stream ended that way.
    hung_up: bool,
}

impl AsyncRead for Hangup<'_> {
    fn poll_read(
        mut self: Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &mut ReadBuf<'_>,
    ) -> Poll<std::io::Result<()>> {
        match Pin::new(&mut *self.master).poll_read(cx, buf) {
            Poll::Ready(Err(e)) if e.raw_os_error() == Some(EIO) => {
                self.hung_up = true;
                Poll::Ready(Ok(()))
            }
            other => other,
        }
    }
}

impl AsyncWrite for Hangup<'_> {
    fn poll_write(
        mut self: Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
        buf: &[u8],
    ) -> Poll<std::io::Result<usize>> {
        Pin::new(&mut *self.master).poll_write(cx, buf)
    }

    fn poll_flush(
        mut self: Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut *self.master).poll_flush(cx)
    }

    fn poll_shutdown(
        mut self: Pin<&mut Self>,
        cx: &mut std::task::Context<'_>,
    ) -> Poll<std::io::Result<()>> {
        Pin::new(&mut *self.master).poll_shutdown(cx)
    }
}

/// The Δ guard of the job at `path`: the groove it measures the executed motion against, cut
/// by the ring `whirl plan` plans the job with.
fn delta_guard(path: &Path, profile: &MachineProfile) -> Result<DeltaGuard> {
    let job = whirl::config::job::Job::load(path)?;
    let (ring, _) = whirl::plan::angles::ring(&job)
        .with_context(|| format!("cannot plan {}", path.display()))?;
    DeltaGuard::new(&job, ring, profile)
        .with_context(|| format!("cannot measure {}", path.display()))
}

/// Serves the profile's machine as three CANopen drives on a pseudo-terminal at `link`
/// (see [`whirl_sim::canopen::serve`]), `guard` watching what they execute.
async fn serve_can(
    cli: &Cli,
    profile: &MachineProfile,
    guard: Option<DeltaGuard>,
    link: &Path,
    idle_exit: Option<Duration>,
    log: &mut EventLog,
) -> Result<()> {
    use whirl_sim::canopen::serve::{serve_slcan, ServeOptions};
    use whirl_sim::canopen::{Bus, BusConfig};
    anyhow::ensure!(
        cli.time_scale > 0.0,
        "CAN needs a time scale above 0: until the master sends SYNCs, the drives' boot-up, \
         heartbeats and the master's timeouts run in wall time"
    );
    let drives = profile.connection.as_ref().and_then(|c| c.drives());
    let cycle_us = cli
        .can_cycle_us
        .or(drives.map(|d| u64::from(d.cycle_us)))
        .unwrap_or(4000);
    let period = Duration::from_micros(cycle_us);
    let counts = cli
        .can_counts
        .or(drives.map(|d| d.counts_per_unit()))
        .unwrap_or([10_000.0; 3]);
    let machine = whirl::judge::simulator::machine(profile);
    let start = whirl_sim::Position::default();
    let config = BusConfig::for_machine(&machine, counts, period, start);
    let mut bus = Bus::new(config)?;
    if let Some(guard) = guard {
        let merged = whirl::judge::cycles::MergedGuard::new(guard, counts);
        bus.set_guard(Box::new(merged));
    }
    let options = ServeOptions {
        time_scale: cli.time_scale,
        idle_exit,
        ..ServeOptions::default()
    };
    let (master, _slave, _link) = pty_at("--can-slcan", link)?;
    let bus = std::sync::Arc::new(std::sync::Mutex::new(bus));
    serve_slcan(master, bus, options, |e| log.record(e)).await?;
    Ok(())
}

/// `--can-counts`: three numbers, X, Z, C, separated by commas, each finite, above 0 and at
/// most 10⁹. Whether they make sense as the machine's scales is the bus's to say.
fn counts(text: &str) -> Result<[f64; 3], String> {
    let values = text
        .split(',')
        .map(|v| {
            let count = v.trim().parse::<f64>().map_err(|e| format!("{v:?}: {e}"))?;
            if count.is_finite() && count > 0.0 && count <= 1e9 {
                Ok(count)
            } else {
                Err(format!("{v:?}: each count must be above 0 and at most 1e9"))
            }
        })
        .collect::<Result<Vec<f64>, String>>()?;
    <[f64; 3]>::try_from(values)
        .map_err(|values| format!("three counts, X,Z,C; got {}", values.len()))
}

// The other numbers: each checked here, so that clap refuses a wrong one naming the option,
// before anything starts.

/// `--boot-time`: the boot's seconds, 0 to 10 (a boot loader waits up to 2 s).
fn boot_time(text: &str) -> Result<f64, String> {
    let seconds = number(text)?;
    if (0.0..=10.0).contains(&seconds) {
        Ok(seconds)
    } else {
        Err("must be a number of seconds from 0 to 10".into())
    }
}

/// `--idle-exit`: seconds, up to a week; 0: never.
fn idle_exit(text: &str) -> Result<f64, String> {
    let seconds = number(text)?;
    if (0.0..=604_800.0).contains(&seconds) {
        Ok(seconds)
    } else {
        Err("must be 0 (never) or a number of seconds up to 604800 (a week)".into())
    }
}

/// `--can-cycle-us`: the SYNC period, in the range a machine profile's `cycle_us` takes.
fn cycle_us(text: &str) -> Result<u64, String> {
    whole_in(text, MIN_CYCLE_US.into(), MAX_CYCLE_US.into(), " µs")
}

/// The simulator's log (`--log`): every event of whichever front-end serves, as JSON lines.
struct EventLog {
    file: Option<std::fs::File>,
}

impl EventLog {
    /// Appends to `path`; `None`: events only go to the debug trace.
    fn open(path: Option<&Path>) -> Result<EventLog> {
        let file = match path {
            Some(path) => Some(
                std::fs::OpenOptions::new()
                    .create(true)
                    .append(true)
                    .open(path)
                    .with_context(|| format!("cannot open {}", path.display()))?,
            ),
            None => None,
        };
        Ok(EventLog { file })
    }

    /// One line per event, written whole and unbuffered: a crash loses at most the last
    /// one. Each carries the wall clock (`wall_s`, seconds since the Unix epoch) beside the
    /// simulated time, so what the machine did can be set against what happened outside it
    /// (a signal to the bridge, an operator's button).
    fn record(&mut self, e: &(impl serde::Serialize + std::fmt::Debug)) {
        /// An event with the wall clock.
        #[derive(serde::Serialize)]
        struct Stamped<'a, E> {
            wall_s: f64,
            #[serde(flatten)]
            event: &'a E,
        }
        tracing::debug!(?e);
        if let Some(file) = self.file.as_mut() {
            let wall_s = std::time::SystemTime::now()
                .duration_since(std::time::UNIX_EPOCH)
                .map_or(0.0, |d| d.as_secs_f64());
            let stamped = Stamped { wall_s, event: e };
            let mut line = serde_json::to_string(&stamped).expect("simulator events serialise");
            line.push('\n');
            if let Err(error) = file.write_all(line.as_bytes()) {
                tracing::error!(%error, "cannot write the simulator log");
            }
        }
    }
}

/// Whether `target` is a pseudo-terminal's device, `/dev/pts/N`: what whirl-sim links to.
fn is_pts(target: &Path) -> bool {
    target
        .strip_prefix("/dev/pts")
        .ok()
        .and_then(|n| n.to_str())
        .is_some_and(|n| !n.is_empty() && n.bytes().all(|b| b.is_ascii_digit()))
}

/// What is at `link`, given with `option`, if whirl-sim may put its terminal's link there:
/// `None`, nothing; `Some(target)`, a link an earlier whirl-sim left behind, to replace: a
/// symlink to a `/dev/pts/N` that no longer exists (whirl-sim removes its link when it
/// stops, but one killed outright cannot). Anything else is refused, and left alone: a file,
/// a directory, any other link, and a link to a terminal still open, which may be another
/// whirl-sim's, serving.
fn earlier_link(option: &str, link: &Path) -> Result<Option<PathBuf>> {
    let meta = match std::fs::symlink_metadata(link) {
        Ok(meta) => meta,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => {
            return Err(e).with_context(|| format!("cannot look at {} ({option})", link.display()))
        }
    };
    let what = if meta.file_type().is_symlink() {
        let target = std::fs::read_link(link)
            .with_context(|| format!("cannot read the link {} ({option})", link.display()))?;
        if !is_pts(&target) {
            format!("a symbolic link to {}", target.display())
        } else if std::fs::symlink_metadata(&target).is_err() {
            return Ok(Some(target));
        } else {
            format!(
                "a link to {}, a terminal still open (another whirl-sim serving there?)",
                target.display()
            )
        }
    } else if meta.is_dir() {
        "a directory".to_owned()
    } else if meta.is_file() {
        "a file".to_owned()
    } else {
        "a device or other special file".to_owned()
    };
    anyhow::bail!(
        "refusing {option} {}: {what} is there, and whirl-sim replaces only a link of its own \
         that an earlier run left behind, to a pseudo-terminal (/dev/pts/N) since closed; \
         move it or choose another path",
        link.display()
    )
}

/// The link to a pseudo-terminal whirl-sim made: removed when dropped, that is whenever
/// whirl-sim stops serving (idle, an error, a signal), if it still leads to
/// the terminal it was made for.
struct PtyLink {
    /// Where the link is.
    path: PathBuf,
    /// The terminal's device it leads to.
    device: PathBuf,
}

impl Drop for PtyLink {
    fn drop(&mut self) {
        if std::fs::read_link(&self.path).is_ok_and(|target| target == self.device) {
            let _ = std::fs::remove_file(&self.path);
        }
    }
}

/// A new pseudo-terminal with a symlink to its device at `link` (given with `option`;
/// refused, see [`earlier_link`], unless nothing or an earlier whirl-sim's link is there):
/// the master end to serve; the slave end, which the caller keeps open so the terminal
/// lives while clients come and go; and the link, removed when dropped.
fn pty_at(
    option: &str,
    link: &Path,
) -> Result<(
    tokio_serial::SerialStream,
    tokio_serial::SerialStream,
    PtyLink,
)> {
    let earlier = earlier_link(option, link)?;
    let (master, slave) =
        tokio_serial::SerialStream::pair().context("cannot open a pseudo-terminal")?;
    let device = slave
        .name()
        .context("the pseudo-terminal has no device name")?;
    if let Some(target) = earlier {
        std::fs::remove_file(link)
            .with_context(|| format!("cannot replace {} ({option})", link.display()))?;
        note(format_args!(
            "whirl-sim: replacing {}, a link to {} left by an earlier whirl-sim",
            link.display(),
            target.display()
        ));
    }
    std::os::unix::fs::symlink(&device, link)
        .with_context(|| format!("cannot link {} to {device}", link.display()))?;
    note(format_args!(
        "whirl-sim: serving on {} -> {device}",
        link.display()
    ));
    let link = PtyLink {
        path: link.to_owned(),
        device: PathBuf::from(OsStr::new(&device)),
    };
    Ok((master, slave, link))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn can_counts_are_three_numbers() {
        assert_eq!(
            counts("10000,10000,2912.7"),
            Ok([10_000.0, 10_000.0, 2912.7])
        );
        assert_eq!(counts(" 1, 2 ,3"), Ok([1.0, 2.0, 3.0]));
        assert_eq!(counts("1,2").unwrap_err(), "three counts, X,Z,C; got 2");
        assert_eq!(counts("1,2,3,4").unwrap_err(), "three counts, X,Z,C; got 4");
        assert_eq!(counts("1,x,3").unwrap_err(), "\"x\": invalid float literal");
        for bad in ["0,1,1", "1,-1,1", "1,1,nan", "inf,1,1", "1,1,1e10"] {
            let error = counts(bad).unwrap_err();
            assert!(
                error.ends_with("each count must be above 0 and at most 1e9"),
                "{error}"
            );
        }
    }

    #[test]
    fn numbers_are_refused_naming_the_option() {
        let cases: [(&[&str], &str); 13] = [
            (&["--time-scale", "nan"], "--time-scale"),
            (&["--time-scale", "1e308"], "--time-scale"),
            (&["--time-scale", "-1"], "--time-scale"),
            (&["--baud", "0"], "--baud"),
            (&["--rx", "0"], "--rx"),
            (&["--rx", "100000"], "--rx"),
            (&["--idle-exit", "nan"], "--idle-exit"),
            (&["--idle-exit", "-1"], "--idle-exit"),
            (&["--idle-exit", "1e30"], "--idle-exit"),
            (&["--can-cycle-us", "0"], "--can-cycle-us"),
            (&["--can-counts", "10000,0,10000"], "--can-counts"),
            (&["--reset-on-open", "--boot-time", "11"], "--boot-time"),
            (&["--reset-on-open", "--boot-time", "nan"], "--boot-time"),
        ];
        for (args, option) in cases {
            let mut argv = vec!["whirl-sim", "--pty", "link"];
            argv.extend_from_slice(args);
            let error = Cli::try_parse_from(argv).err().expect("refused");
            assert_eq!(error.kind(), clap::error::ErrorKind::ValueValidation);
            assert!(error.to_string().contains(option), "{error}");
        }
        // 0 has a meaning: as fast as the host allows; never stop.
        let cli = Cli::try_parse_from(["whirl-sim", "--time-scale", "0", "--idle-exit", "0"]);
        let cli = cli.unwrap();
        assert_eq!((cli.time_scale, cli.idle_exit), (0.0, 0.0));
    }

    #[test]
    fn reset_on_open_takes_a_boot_time_and_needs_a_pseudo_terminal() {
        use clap::error::ErrorKind;
        let parse = |args: &[&str]| {
            let mut argv = vec!["whirl-sim"];
            argv.extend_from_slice(args);
            Cli::try_parse_from(argv)
        };
        let given = parse(&["--pty", "link", "--reset-on-open", "--boot-time", "1.5"]).unwrap();
        assert_eq!((given.reset_on_open, given.boot_time), (true, 1.5));
        // By default an Arduino's boot loader, half a second.
        let bare = parse(&["--pty", "link", "--reset-on-open"]).unwrap();
        assert_eq!((bare.reset_on_open, bare.boot_time), (true, 0.5));
        assert!(!parse(&["--pty", "link"]).unwrap().reset_on_open);
        for (args, kind) in [
            (&["--reset-on-open"][..], ErrorKind::MissingRequiredArgument),
            (
                &["--pty", "link", "--boot-time", "1"],
                ErrorKind::MissingRequiredArgument,
            ),
            (
                &["--tcp", "127.0.0.1:0", "--reset-on-open"],
                ErrorKind::ArgumentConflict,
            ),
        ] {
            let error = parse(args).err().expect("refused");
            assert_eq!(error.kind(), kind, "{args:?}");
        }
    }

    #[test]
    fn only_a_link_to_a_pseudo_terminal_is_taken_for_an_earlier_whirl_sims() {
        assert!(is_pts(Path::new("/dev/pts/3")));
        for other in [
            "/dev/pts",
            "/dev/pts/",
            "/dev/pts/x",
            "/dev/null",
            "pts/3",
            "/tmp/a",
        ] {
            assert!(!is_pts(Path::new(other)), "{other}");
        }
    }

    #[test]
    fn the_can_options_conflict_with_the_other_front_ends() {
        for other in ["--pty", "--tcp", "--modbus-tcp", "--modbus-rtu"] {
            let parsed = Cli::try_parse_from(["whirl-sim", "--can-slcan", "a", other, "b"]);
            let error = parsed.err().unwrap_or_else(|| panic!("{other} was taken"));
            assert_eq!(error.kind(), clap::error::ErrorKind::ArgumentConflict);
        }
        let cli = Cli::try_parse_from(["whirl-sim", "--can-slcan", "a"]).unwrap();
        // Left to the machine profile's drives, or the defaults.
        assert_eq!((cli.can_counts, cli.can_cycle_us), (None, None));
    }

    #[tokio::test]
    async fn impossible_can_settings_are_refused_before_serving() {
        let profile = MachineProfile::builtin_sim().unwrap();
        let link = std::env::temp_dir().join(format!("whirl-sim-can-{}", std::process::id()));
        let refused = |args: &[&str]| {
            let mut argv = vec!["whirl-sim", "--can-slcan", link.to_str().unwrap()];
            argv.extend_from_slice(args);
            Cli::try_parse_from(argv).unwrap()
        };
        let mut log = EventLog::open(None).unwrap();
        // (A cycle of 0 µs and counts of 0 are refused by the command line itself:
        // `numbers_are_refused_naming_the_option`.)
        let cases = [(&["--time-scale", "0"][..], "CAN needs a time scale above 0")];
        for (args, message) in cases {
            let cli = refused(args);
            let error = serve_can(&cli, &profile, None, &link, None, &mut log)
                .await
                .unwrap_err();
            assert!(error.to_string().starts_with(message), "{error}");
        }
        assert!(!link.exists(), "no terminal was made");
    }
}
