//! The command line's words: every subcommand, option and its help, as clap reads them.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use whirl::transport::TransportKind;

#[derive(Parser)]
#[command(
    name = "whirl",
    version,
    about = "Plan and post thread-whirling programs"
)]
pub(crate) struct Cli {
    #[command(subcommand)]
    pub(crate) command: Command,
}

#[derive(Subcommand)]
pub(crate) enum Command {
    /// Plan a job: write the machine program and, optionally, a JSON report.
    Plan {
        /// The job file (TOML).
        job: PathBuf,
        /// Machine profile (TOML); default: the built-in simulator's, machine-profiles/sim.toml.
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Where to write the program.
        #[arg(short, long)]
        output: PathBuf,
        /// Where to write the report (JSON).
        #[arg(long)]
        report: Option<PathBuf>,
        /// Also measure the planned program with the swept-volume engine; refuse it (and write
        /// nothing) if the measured error exceeds Δ.
        #[arg(long)]
        verify: bool,
    },
    /// Machined sections of tools swept along helices (the swept-volume engine).
    Sweep {
        #[command(subcommand)]
        tool: SweepTool,
    },
    /// Stream a program (or a job, planned first) to a grbl/grblHAL controller on a serial
    /// port, logging everything to an append-only JSON-lines file. The program is checked
    /// against the machine's travel and speed limits before the first byte goes out.
    Stream {
        /// A program (G-code) or a job (`.toml`, planned for the machine first).
        input: PathBuf,
        /// The serial port (a device or a pseudo-terminal link such as whirl-sim's), for
        /// `--transport modbus-tcp` the controller's address (HOST:PORT), for `can` the
        /// interface; default: the machine profile's `[connection]`.
        #[arg(long)]
        port: Option<String>,
        /// G-code over a serial line, segments through the Modbus register map
        /// (docs/modbus.md) over TCP or RTU, or set-points to CiA 402 drives over CAN;
        /// default: the machine profile's `[connection]`, else serial.
        #[arg(long, value_enum)]
        transport: Option<Transport>,
        /// Baud rate of the serial line; default: the profile's, else 115200.
        #[arg(long)]
        baud: Option<u32>,
        /// Machine profile; default: the built-in simulator's.
        #[arg(long)]
        machine: Option<PathBuf>,
        /// The executed-path log (appended to).
        #[arg(long)]
        log: PathBuf,
        /// Give up (with a feed hold) after this many seconds without any progress.
        #[arg(long, default_value_t = 30.0)]
        stall_timeout: f64,
        /// Resume a stopped run at this program line (1-based, as a stop reports it), behind
        /// a preamble that restores units, distance and feed modes, the G92 offset and the
        /// spindle as the program had them there.
        #[arg(long)]
        resume_at: Option<usize>,
    },
    /// Dry-run a job: plan it, start the simulated controller in this process on a
    /// pseudo-terminal, stream the program to it through the same serial code a machine gets,
    /// and report what the simulator measured against Δ. Exits 0 only if the job completed
    /// within Δ; 2 if the simulator measured it beyond Δ; 1 on any other stop or error.
    DryRun {
        /// The job file (TOML).
        job: PathBuf,
        /// Stream this program instead of the job's planned one (a hand-edited program, say);
        /// it is still measured against the job's groove.
        #[arg(long)]
        program: Option<PathBuf>,
        /// Machine profile; default: the built-in simulator's.
        #[arg(long)]
        machine: Option<PathBuf>,
        /// The executed-path log (appended to); none kept if left out.
        #[arg(long)]
        log: Option<PathBuf>,
        /// Where to write the report (JSON).
        #[arg(long)]
        report: Option<PathBuf>,
        /// Simulated seconds per wall second; default: as fast as the host allows.
        #[arg(long)]
        time_scale: Option<f64>,
        /// The link's baud rate, emulated by the simulator.
        #[arg(long, default_value_t = 115_200)]
        baud: u32,
        /// The simulated controller's receive buffer, bytes (grblHAL 1024, grbl on an AVR 128).
        #[arg(long, default_value_t = 1024)]
        rx: usize,
        /// How the program goes to the simulated controller: G-code over a serial line, or
        /// segments through the Modbus register map (docs/modbus.md) over TCP or RTU.
        #[arg(long, value_enum, default_value_t = Transport::Serial)]
        transport: Transport,
    },
    /// Read executed-path logs.
    Log {
        #[command(subcommand)]
        command: LogCommand,
    },
    /// Measure a program's profile error against a job's groove with the swept-volume engine.
    /// Exits 0 within Δ, 2 beyond it (the report is written either way), 1 on errors.
    Verify {
        /// The program (G-code).
        program: PathBuf,
        /// The job whose groove the program should cut.
        #[arg(long)]
        job: PathBuf,
        /// Machine profile the program was written for; default: the built-in simulator's.
        #[arg(long)]
        machine: Option<PathBuf>,
        /// Where to write the report (JSON).
        #[arg(long)]
        report: PathBuf,
        /// Where to draw the axial section, target against machined (SVG).
        #[arg(long)]
        svg: Option<PathBuf>,
    },
}

/// How the program goes to the controller.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Transport {
    /// G-code, grbl's character counting, over a pseudo-terminal.
    Serial,
    /// The Modbus register map over Modbus TCP on a loopback port.
    ModbusTcp,
    /// The Modbus register map over Modbus RTU on a pseudo-terminal.
    ModbusRtu,
    /// CiA 402 drives through an slcan (Lawicel) CAN adapter on a serial line.
    CanSlcan,
    /// CiA 402 drives on a socketcan interface.
    Can,
}

impl From<Transport> for TransportKind {
    fn from(transport: Transport) -> TransportKind {
        match transport {
            Transport::Serial => TransportKind::Serial,
            Transport::ModbusTcp => TransportKind::ModbusTcp,
            Transport::ModbusRtu => TransportKind::ModbusRtu,
            Transport::CanSlcan => TransportKind::CanSlcan,
            Transport::Can => TransportKind::Can,
        }
    }
}

#[derive(Subcommand)]
pub(crate) enum LogCommand {
    /// Count what a run sent, acknowledged, refused and executed, and how it ended.
    Summary {
        /// The executed-path log (JSON lines).
        log: PathBuf,
    },
    /// Draw X, Z and C over time from the status reports and, with `--job`, the axial
    /// section the logged executed moves cut against the job's target (SVG).
    Plot {
        /// The executed-path log (JSON lines).
        log: PathBuf,
        /// Where to write the SVG.
        #[arg(short, long)]
        output: PathBuf,
        /// The job whose groove the run cut (for the measured section; needs the executed
        /// moves a simulator logs).
        #[arg(long)]
        job: Option<PathBuf>,
    },
}

#[derive(Subcommand)]
pub(crate) enum SweepTool {
    /// Seed 000: a circular paraboloid end mill (y − y0 = a·r² + b, upper half) on a helix of
    /// radius R and pitch p; writes the upper boundary of the section in the plane through the
    /// helix axis, around x = −R, as CSV `x,y`.
    Paraboloid {
        /// a, 1/mm (negative).
        #[arg(long, allow_hyphen_values = true)]
        a: f64,
        /// b, mm (positive).
        #[arg(long)]
        b: f64,
        /// Helix radius R, mm.
        #[arg(long)]
        radius: f64,
        /// Helix pitch p, mm (0: a circular path).
        #[arg(long)]
        pitch: f64,
        /// Largest distance of the written polyline from the true boundary, mm.
        #[arg(long, default_value_t = 1e-4)]
        accuracy: f64,
        /// Where to write the CSV.
        #[arg(short, long)]
        output: PathBuf,
    },
}
