//! `whirl-sim`: the simulated whirling-lathe controller on a pseudo-terminal or a TCP port.
//!
//! It lives in the root package because it builds the controller from whirl's machine
//! profiles; the controller itself is the `whirl-sim` library in `sim/`, which depends on
//! nothing of whirl's.

use anyhow::{Context, Result};
use clap::Parser;
use std::path::PathBuf;
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
    let options = ControllerOptions {
        rx_buffer_size: cli.rx,
        ..ControllerOptions::default()
    };
    let mut controller = Controller::new(&whirl::simulator::machine(&profile), options)?;
    let serve_options = ServeOptions {
        time_scale: (cli.time_scale > 0.0).then_some(cli.time_scale),
        baud: cli.baud,
        ..ServeOptions::default()
    };
    let log = |e: &whirl_sim::Event| tracing::debug!(?e);
    if let Some(link) = &cli.pty {
        let (master, slave) =
            tokio_serial::SerialStream::pair().context("cannot open a pseudo-terminal")?;
        let device = slave
            .name()
            .context("the pseudo-terminal has no device name")?;
        let _ = std::fs::remove_file(link);
        std::os::unix::fs::symlink(&device, link)
            .with_context(|| format!("cannot link {} to {device}", link.display()))?;
        eprintln!("whirl-sim: serving on {} -> {device}", link.display());
        // Keep the slave end open so the terminal lives while clients come and go. A board on
        // a USB serial port booted long before the host opened it: the host never sees its
        // power-up banner, so none is left waiting in the terminal (a soft reset shows one).
        let _slave = slave;
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
