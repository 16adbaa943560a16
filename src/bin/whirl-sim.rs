//! `whirl-sim`: the simulated whirling-lathe controller on a pseudo-terminal or a TCP port,
//! or, with `--can-slcan`, three simulated CANopen drives behind an slcan adapter.
//!
//! It lives in the root package because it builds the controller from whirl's machine
//! profiles; the controller itself is the `whirl-sim` library in `sim/`, which depends on
//! nothing of whirl's.

use anyhow::{Context, Result};
use clap::Parser;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio_serial::SerialPort;
use whirl::config::machine::MachineProfile;
use whirl::judge::guard::DeltaGuard;
use whirl_sim::serve::{serve, ServeOptions};
use whirl_sim::{Controller, ControllerOptions};

#[derive(Parser)]
#[command(
    name = "whirl-sim",
    version,
    about = "A simulated grblHAL whirling-lathe controller"
)]
struct Cli {
    /// Serve on a new pseudo-terminal; PATH becomes a symlink to its device.
    #[arg(long, conflicts_with = "tcp")]
    pty: Option<PathBuf>,
    /// Serve one connection on this TCP address (loopback unless you say otherwise).
    #[arg(long)]
    tcp: Option<String>,
    /// Serve the Modbus register map (docs/modbus.md) on this TCP address instead of G-code.
    #[arg(long, conflicts_with_all = ["pty", "tcp"])]
    modbus_tcp: Option<String>,
    /// Serve the Modbus register map as an RTU server on a new pseudo-terminal; PATH becomes
    /// a symlink to its device.
    #[arg(long, conflicts_with_all = ["pty", "tcp", "modbus_tcp"])]
    modbus_rtu: Option<PathBuf>,
    /// Serve three CiA 402 drives (X, Z, C on CANopen nodes 1, 2, 3) behind an slcan
    /// adapter on a new pseudo-terminal instead of a controller; PATH becomes a symlink to
    /// its device.
    #[arg(long, conflicts_with_all = ["pty", "tcp", "modbus_tcp", "modbus_rtu"])]
    can_slcan: Option<PathBuf>,
    /// The CAN drives' counts per mm of X and Z and per degree of C; default: the machine
    /// profile's `[connection.drives]`, else 10000,10000,10000.
    #[arg(long, value_name = "X,Z,C", value_parser = counts)]
    can_counts: Option<[f64; 3]>,
    /// The CAN master's SYNC period, µs: each drive moves at most its axis's max rate for
    /// this long a cycle; default: the profile's `cycle_us`, else 4000.
    #[arg(long)]
    can_cycle_us: Option<u64>,
    /// Machine profile (TOML); default: machine-profiles/sim.toml, built in.
    #[arg(long)]
    machine: Option<PathBuf>,
    /// Simulated seconds per wall second; 0: as fast as the host allows.
    #[arg(long, default_value_t = 1.0)]
    time_scale: f64,
    /// Emulated link rate, bits per second.
    #[arg(long)]
    baud: Option<u32>,
    /// Receive buffer size in bytes (grblHAL 1024; 128 like an AVR grbl).
    #[arg(long, default_value_t = 1024)]
    rx: usize,
    /// The job whose groove the machine cuts: the Δ guard measures the executed motion
    /// against it and raises ALARM:64 as soon as the profile error exceeds Δ.
    #[arg(long)]
    job: Option<PathBuf>,
    /// Append every simulator event (answers, executed moves, alarms) to this file as JSON
    /// lines.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Stop after this many seconds without a byte from the client (0: never).
    #[arg(long, default_value_t = 600.0)]
    idle_exit: f64,
}

#[tokio::main(flavor = "current_thread")]
async fn main() -> std::process::ExitCode {
    match run(Cli::parse()).await {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

async fn run(cli: Cli) -> Result<()> {
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
    let options = ControllerOptions {
        rx_buffer_size: cli.rx,
        ..ControllerOptions::default()
    };
    let mut controller = Controller::new(&whirl::judge::simulator::machine(&profile), options)?;
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
            eprintln!("whirl-sim: serving Modbus on {}", listener.local_addr()?);
            serve_tcp(listener, bank, clock, log).await?;
        } else if let Some(link) = &cli.modbus_rtu {
            let (master, _slave) = pty_at(link)?;
            serve_rtu(master, bank, clock, log).await?;
        }
    } else if let Some(link) = &cli.pty {
        // A board on a USB serial port booted long before the host opened it: the host
        // never sees its power-up banner, so none is left waiting in the terminal (a soft
        // reset shows one).
        let (master, _slave) = pty_at(link)?;
        controller.take_output();
        serve(master, &mut controller, serve_options, log).await?;
    } else {
        let addr = cli.tcp.as_deref().unwrap_or("127.0.0.1:0");
        let listener = tokio::net::TcpListener::bind(addr)
            .await
            .with_context(|| format!("cannot listen on {addr}"))?;
        eprintln!("whirl-sim: serving on {}", listener.local_addr()?);
        let (socket, _) = listener.accept().await?;
        serve(socket, &mut controller, serve_options, log).await?;
    }
    Ok(())
}

/// The Δ guard of the job at `path`: the groove it measures the executed motion against.
fn delta_guard(path: &Path, profile: &MachineProfile) -> Result<DeltaGuard> {
    let job = whirl::config::job::Job::load(path)?;
    DeltaGuard::new(&job, profile).with_context(|| format!("cannot measure {}", path.display()))
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
    anyhow::ensure!(cycle_us > 0, "--can-cycle-us must be above 0");
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
    let (master, _slave) = pty_at(link)?;
    let bus = std::sync::Arc::new(std::sync::Mutex::new(bus));
    serve_slcan(master, bus, options, |e| log.record(e)).await?;
    Ok(())
}

/// `--can-counts`: three numbers, X, Z, C, separated by commas. Whether they make sense
/// as scales is the bus's to say.
fn counts(text: &str) -> Result<[f64; 3], String> {
    let values = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|e| format!("{v:?}: {e}")))
        .collect::<Result<Vec<f64>, String>>()?;
    <[f64; 3]>::try_from(values)
        .map_err(|values| format!("three counts, X,Z,C; got {}", values.len()))
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
    /// one.
    fn record(&mut self, e: &(impl serde::Serialize + std::fmt::Debug)) {
        tracing::debug!(?e);
        if let Some(file) = self.file.as_mut() {
            let mut line = serde_json::to_string(e).expect("simulator events serialise");
            line.push('\n');
            if let Err(error) = file.write_all(line.as_bytes()) {
                tracing::error!(%error, "cannot write the simulator log");
            }
        }
    }
}

/// A new pseudo-terminal with a symlink to its device at `link`: the master end to serve,
/// and the slave end, which the caller keeps open so the terminal lives while clients come
/// and go.
fn pty_at(
    link: &std::path::Path,
) -> Result<(tokio_serial::SerialStream, tokio_serial::SerialStream)> {
    let (master, slave) =
        tokio_serial::SerialStream::pair().context("cannot open a pseudo-terminal")?;
    let device = slave
        .name()
        .context("the pseudo-terminal has no device name")?;
    let _ = std::fs::remove_file(link);
    std::os::unix::fs::symlink(&device, link)
        .with_context(|| format!("cannot link {} to {device}", link.display()))?;
    eprintln!("whirl-sim: serving on {} -> {device}", link.display());
    Ok((master, slave))
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
        let cases = [
            (&["--time-scale", "0"][..], "CAN needs a time scale above 0"),
            (&["--can-cycle-us", "0"], "--can-cycle-us must be above 0"),
            (
                &["--can-counts", "10000,0,10000"],
                "counts per unit of axis Z: 0 must be finite and above zero",
            ),
        ];
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
