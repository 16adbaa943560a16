//! `whirl-sim`: the simulated whirling-lathe controller on a pseudo-terminal or a TCP port.
//!
//! It lives in the root package because it builds the controller from whirl's machine
//! profiles; the controller itself is the `whirl-sim` library in `sim/`, which depends on
//! nothing of whirl's.

use anyhow::{Context, Result};
use clap::Parser;
use std::io::Write;
use std::path::PathBuf;
use std::time::Duration;
use tokio_serial::SerialPort;
use whirl::machine::MachineProfile;
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
            eprintln!("error: {}", whirl::error_message(e.as_ref()));
            std::process::ExitCode::FAILURE
        }
    }
}

async fn run(cli: Cli) -> Result<()> {
    let profile = match &cli.machine {
        Some(p) => MachineProfile::load(p)?,
        None => MachineProfile::builtin_sim()?,
    };
    let options = ControllerOptions {
        rx_buffer_size: cli.rx,
        ..ControllerOptions::default()
    };
    let mut controller = Controller::new(&whirl::simulator::machine(&profile), options)?;
    if let Some(path) = &cli.job {
        let job = whirl::job::Job::load(path)?;
        let guard = whirl::simulator::guard::DeltaGuard::new(&job, &profile)
            .with_context(|| format!("cannot measure {}", path.display()))?;
        controller.set_guard(Box::new(guard));
    }
    let mut log_file = match &cli.log {
        Some(path) => Some(
            std::fs::OpenOptions::new()
                .create(true)
                .append(true)
                .open(path)
                .with_context(|| format!("cannot open {}", path.display()))?,
        ),
        None => None,
    };
    let serve_options = ServeOptions {
        time_scale: (cli.time_scale > 0.0).then_some(cli.time_scale),
        baud: cli.baud,
        idle_exit: (cli.idle_exit > 0.0).then(|| Duration::from_secs_f64(cli.idle_exit)),
        ..ServeOptions::default()
    };
    // One line per event, written whole and flushed: a crash loses at most the last one.
    let log = |e: &whirl_sim::Event| {
        tracing::debug!(?e);
        if let Some(file) = log_file.as_mut() {
            let mut line = serde_json::to_string(e).expect("simulator events serialise");
            line.push('\n');
            if let Err(error) = file.write_all(line.as_bytes()) {
                tracing::error!(%error, "cannot write the simulator log");
            }
        }
    };
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
