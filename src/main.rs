//! The `whirl` command line: thin glue over the library.

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;

#[derive(Parser)]
#[command(
    name = "whirl",
    version,
    about = "Plan and post thread-whirling programs"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
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
enum Transport {
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

impl Transport {
    /// Its name on the command line, as a profile's `[connection]` names it too.
    fn name(self) -> String {
        use clap::ValueEnum;
        let value = self
            .to_possible_value()
            .expect("every transport has a name");
        value.get_name().to_owned()
    }
}

#[derive(Subcommand)]
enum LogCommand {
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
enum SweepTool {
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

/// Exit code of `whirl verify` and `whirl dry-run` for a program measured beyond Δ.
const BEYOND_DELTA: u8 = 2;

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .init();
    match run(Cli::parse()) {
        Ok(code) => code,
        Err(e) => {
            eprintln!("error: {}", whirl::error_message(e.as_ref()));
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli) -> Result<ExitCode> {
    match cli.command {
        Command::Plan {
            job,
            machine,
            output,
            report,
            verify,
        } => {
            let machine = load_machine(machine.as_deref())?;
            let job = Job::load(&job)?;
            let plan = whirl::plan::plan(&job, &machine)
                .with_context(|| format!("cannot plan {}", job_name(&job)))?;
            let mut verified = None;
            if verify {
                let v = whirl::judge::verify::verify(&job, &machine, &plan.text, false)
                    .context("cannot verify the planned program")?;
                if !v.within_delta {
                    anyhow::bail!(
                        "the planned program measures {:.5} mm overcut, {:.5} mm undercut: beyond Δ = {} mm",
                        v.max_overcut_mm,
                        v.max_undercut_mm,
                        v.delta_mm
                    );
                }
                println!(
                    "verified: max overcut {:.5} mm, max undercut {:.5} mm over {} points (Δ {} mm)",
                    v.max_overcut_mm, v.max_undercut_mm, v.points, v.delta_mm
                );
                verified = Some(v);
            }
            let json = match &verified {
                Some(verify) => {
                    serde_json::to_string_pretty(&whirl::judge::verify::VerifiedReport {
                        report: &plan.report,
                        verify,
                    })?
                }
                None => serde_json::to_string_pretty(&plan.report)?,
            };
            // Everything is computed; only now is anything written.
            write_all(&[(Some(&output), &plan.text), (report.as_deref(), &json)])?;
            let r = &plan.report;
            println!(
                "{}: {} segments ({} per period), max error {:.4} mm of Δ {:.4} mm \
                 (interpolation {:.4}, scallop {:.4}, cusp {:.4}), cycle {:.1} s",
                output.display(),
                r.segments,
                r.nodes_per_period,
                r.max_error_mm,
                r.delta_mm,
                r.interp_error_mm,
                r.scallop_mm,
                r.cusp_mm,
                r.cycle_time_s
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::Sweep {
            tool:
                SweepTool::Paraboloid {
                    a,
                    b,
                    radius,
                    pitch,
                    accuracy,
                    output,
                },
        } => {
            let csv = whirl::papers::section::run_paraboloid(a, b, radius, pitch, accuracy)?;
            write_all(&[(Some(&output), &csv)])?;
            println!(
                "{}: {} points within {accuracy} mm of the section",
                output.display(),
                csv.lines().count() - 1
            );
            Ok(ExitCode::SUCCESS)
        }
        Command::Stream {
            input,
            port,
            transport,
            baud,
            machine,
            log,
            stall_timeout,
            resume_at,
        } => {
            let machine = load_machine(machine.as_deref())?;
            let text = if input.extension().is_some_and(|e| e == "toml") {
                let job = Job::load(&input)?;
                whirl::plan::plan(&job, &machine)
                    .with_context(|| format!("cannot plan {}", job_name(&job)))?
                    .text
            } else {
                std::fs::read_to_string(&input)
                    .with_context(|| format!("cannot read {}", input.display()))?
            };
            let lines: Vec<String> = text.lines().map(str::to_owned).collect();
            let link = Link::resolve(&machine, transport, port, baud)?;
            let (port, baud) = (link.port.as_str(), link.baud);
            match link.transport {
                Transport::Serial => {}
                Transport::ModbusTcp | Transport::ModbusRtu => {
                    return stream_modbus(
                        &input,
                        &text,
                        &lines,
                        &machine,
                        port,
                        link.transport,
                        baud,
                        &log,
                    );
                }
                Transport::CanSlcan | Transport::Can => {
                    return stream_can(&input, &text, &lines, &machine, &link, &log);
                }
            }
            let mut exec_log = whirl::log::ExecLog::append(&log)?;
            let bar = progress_bar(lines.len());
            let options = whirl::transport::StreamOptions {
                program: input.display().to_string(),
                machine: Some(machine),
                no_progress_timeout: Some(std::time::Duration::from_secs_f64(stall_timeout)),
                on_progress: bar.as_ref().map(Progress::callback),
                resume_at: match resume_at {
                    Some(0) => anyhow::bail!("--resume-at counts lines from 1"),
                    line => line.map(|l| l - 1),
                },
                ..Default::default()
            };
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()?;
            let outcome = runtime.block_on(whirl::transport::stream_port(
                port,
                baud,
                lines,
                options,
                &mut exec_log,
            ));
            if let Some(bar) = bar {
                bar.finish();
            }
            let outcome = outcome?;
            println!(
                "{}: {} of {} lines acknowledged in {:.1} s{}",
                input.display(),
                outcome.lines_acked,
                outcome.lines_total,
                outcome.wall_time.as_secs_f64(),
                outcome
                    .link_utilization
                    .map_or(String::new(), |u| format!(", link {:.0} % busy", 100.0 * u))
            );
            if outcome.completed() {
                return Ok(ExitCode::SUCCESS);
            }
            let mut message = format!("the stream {}", outcome.ending);
            if let Some(r) = &outcome.resume {
                message.push_str(&format!("; resume with --resume-at {}", r.line_index + 1));
                if !r.possibly_executed.is_empty() {
                    message.push_str(&format!(
                        " (lines {} to {} may already have run: check where the machine \
                         stands before resuming)",
                        r.possibly_executed.start + 1,
                        r.possibly_executed.end
                    ));
                }
            }
            anyhow::bail!(message)
        }
        Command::DryRun {
            job: job_path,
            program,
            machine,
            log,
            report,
            time_scale,
            baud,
            rx,
            transport,
        } => {
            let machine = load_machine(machine.as_deref())?;
            let job = Job::load(&job_path)?;
            let (name, text) = match &program {
                Some(path) => (
                    path.display().to_string(),
                    std::fs::read_to_string(path)
                        .with_context(|| format!("cannot read {}", path.display()))?,
                ),
                None => (
                    job_path.display().to_string(),
                    whirl::plan::plan(&job, &machine)
                        .with_context(|| format!("cannot plan {}", job_name(&job)))?
                        .text,
                ),
            };
            let lines: Vec<String> = text.lines().map(str::to_owned).collect();
            // Settled before the log is opened: a refusal leaves nothing behind.
            let can = match transport {
                Transport::CanSlcan => Some((can_drives(&machine)?, can_bitrate(&machine)?)),
                Transport::Can => anyhow::bail!(
                    "the simulated drives are reached through an slcan adapter, not a \
                     socketcan interface: dry-run with --transport can-slcan"
                ),
                _ => None,
            };
            let mut exec_log = match &log {
                Some(path) => whirl::log::ExecLog::append(path)?,
                None => whirl::log::ExecLog::discard(),
            };
            let bar = progress_bar(lines.len());
            let on_can_progress = bar.as_ref().map(Progress::can_callback);
            let options = whirl::judge::dry_run::DryRunOptions {
                time_scale: time_scale.filter(|s| *s > 0.0),
                baud,
                rx_size: rx,
                on_progress: bar.as_ref().map(Progress::callback),
                ..Default::default()
            };
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()?;
            let r = runtime.block_on(async {
                match transport {
                    Transport::Serial => {
                        whirl::judge::dry_run::dry_run(
                            &job,
                            &machine,
                            &name,
                            lines,
                            options,
                            &mut exec_log,
                        )
                        .await
                    }
                    Transport::ModbusTcp | Transport::ModbusRtu => {
                        let program =
                            whirl::post::gcode::parse::read_program(&text, machine.x_diameter())
                                .with_context(|| format!("cannot read {name}"))?;
                        let kind = if transport == Transport::ModbusTcp {
                            whirl::judge::dry_run::ModbusKind::Tcp
                        } else {
                            whirl::judge::dry_run::ModbusKind::Rtu
                        };
                        whirl::judge::dry_run::dry_run_modbus(
                            &job,
                            &machine,
                            &name,
                            &program,
                            kind,
                            options,
                            &mut exec_log,
                        )
                        .await
                    }
                    Transport::CanSlcan | Transport::Can => {
                        let (drives, bitrate) = can.expect("settled above");
                        let can = whirl::judge::dry_run::CanDrives {
                            drives,
                            bitrate,
                            on_progress: on_can_progress,
                        };
                        let program =
                            whirl::post::gcode::parse::read_program(&text, machine.x_diameter())
                                .with_context(|| format!("cannot read {name}"))?;
                        whirl::judge::dry_run::dry_run_can(
                            &job,
                            &machine,
                            &name,
                            &program,
                            can,
                            &mut exec_log,
                        )
                        .await
                    }
                }
                .map_err(anyhow::Error::from)
            });
            if let Some(bar) = bar {
                bar.finish();
            }
            let r = r?;
            let json = serde_json::to_string_pretty(&r)?;
            write_all(&[(report.as_deref(), &json)])?;
            println!(
                "{}: {} of {} lines acknowledged; {:.1} s on the machine, dry-run in {:.1} s; \
                 link {:.1} % busy at {} baud",
                r.job,
                r.lines_acked,
                r.lines,
                r.machine_time_s,
                r.wall_time_s,
                100.0 * r.link_utilization,
                r.baud
            );
            println!(
                "profile error measured by the simulator: overcut {:.4} mm, undercut {:.4} mm \
                 over {} of {} points; Δ {} mm",
                r.max_overcut_mm, r.max_undercut_mm, r.points_measured, r.points, r.delta_mm
            );
            for a in &r.alarms {
                println!(
                    "ALARM:{} {}{}",
                    a.code,
                    a.message,
                    a.detail
                        .as_ref()
                        .map_or(String::new(), |d| format!(": {d}"))
                );
            }
            if let Some(stop) = &r.stop {
                println!("stopped: {stop}");
            }
            let beyond = r.alarms.iter().any(|a| a.code == 64) || r.max_error_mm > r.delta_mm;
            Ok(if r.within_delta {
                println!("completed within Δ");
                ExitCode::SUCCESS
            } else if beyond {
                println!("BEYOND Δ");
                ExitCode::from(BEYOND_DELTA)
            } else {
                println!("did not complete");
                ExitCode::FAILURE
            })
        }
        Command::Log { command } => {
            match command {
                LogCommand::Summary { log } => {
                    let read = whirl::log::read(&log)?;
                    let s = whirl::log::Summary::of(&read);
                    println!("{}", serde_json::to_string_pretty(&s)?);
                }
                LogCommand::Plot { log, output, job } => {
                    let read = whirl::log::read(&log)?;
                    let mut plots = whirl::judge::plots::axis_plots(&read);
                    if let Some(job) = job {
                        let job = Job::load(&job)?;
                        plots.push(
                            whirl::judge::plots::section_plot(&read, &job)
                                .with_context(|| format!("{}", log.display()))?,
                        );
                    }
                    write_all(&[(Some(&output), &whirl::judge::svg::stack(&plots))])?;
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Verify {
            program,
            job,
            machine,
            report,
            svg,
        } => {
            let machine = load_machine(machine.as_deref())?;
            let job = Job::load(&job)?;
            let text = std::fs::read_to_string(&program)
                .with_context(|| format!("cannot read {}", program.display()))?;
            let v = whirl::judge::verify::verify(&job, &machine, &text, svg.is_some())
                .with_context(|| format!("cannot verify {}", program.display()))?;
            let json = serde_json::to_string_pretty(&v)?;
            write_all(&[
                (Some(&report), &json),
                (svg.as_deref(), &v.svg.clone().unwrap_or_default()),
            ])?;
            println!(
                "{}: max overcut {:.5} mm, max undercut {:.5} mm over {} points; Δ {} mm: {}",
                program.display(),
                v.max_overcut_mm,
                v.max_undercut_mm,
                v.points,
                v.delta_mm,
                if v.within_delta { "within" } else { "BEYOND" }
            );
            Ok(if v.within_delta {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(BEYOND_DELTA)
            })
        }
    }
}

/// Where `whirl stream` goes: the command line's transport, port and baud rate, each
/// defaulting to the machine profile's `[connection]`.
struct Link {
    transport: Transport,
    port: String,
    baud: u32,
}

impl Link {
    fn resolve(
        machine: &MachineProfile,
        transport: Option<Transport>,
        port: Option<String>,
        baud: Option<u32>,
    ) -> Result<Link> {
        use whirl::config::connection::Connection;
        let profile = machine.connection.as_ref();
        let transport = transport
            .or_else(|| {
                profile.map(|c| match c {
                    Connection::Serial(_) => Transport::Serial,
                    Connection::ModbusTcp(_) => Transport::ModbusTcp,
                    Connection::ModbusRtu(_) => Transport::ModbusRtu,
                    Connection::CanSlcan(_) => Transport::CanSlcan,
                    Connection::Can(_) => Transport::Can,
                })
            })
            .unwrap_or(Transport::Serial);
        // The profile's settings count only for its own transport.
        let same = profile.filter(|c| c.transport_name() == transport.name());
        let (profile_port, profile_baud) = match same {
            Some(Connection::Serial(s)) => (Some(s.port.clone()), Some(s.baud)),
            Some(Connection::ModbusTcp(s)) => (Some(s.address.clone()), None),
            Some(Connection::ModbusRtu(s)) => (Some(s.port.clone()), Some(s.baud)),
            Some(Connection::CanSlcan(s)) => (Some(s.port.clone()), Some(s.baud)),
            Some(Connection::Can(s)) => (Some(s.interface.clone()), None),
            None => (None, None),
        };
        let port = port.or(profile_port).with_context(|| {
            format!(
                "no --port given and machine profile \"{}\" has no [connection] for {} that \
                 names one",
                machine.name,
                transport.name()
            )
        })?;
        Ok(Link {
            transport,
            port,
            baud: baud.or(profile_baud).unwrap_or(115_200),
        })
    }
}

/// `whirl stream --transport can-slcan|can`: the program checked against the machine,
/// sampled from where the drives stand, run on them cycle by cycle.
fn stream_can(
    input: &Path,
    text: &str,
    lines: &[String],
    machine: &MachineProfile,
    link: &Link,
    log: &Path,
) -> Result<ExitCode> {
    use whirl::transport::can::{stream_can, CanClock, CanLink, CanOptions};
    whirl::transport::check_program(lines, machine)?;
    let program = whirl::post::gcode::parse::read_program(text, machine.x_diameter())?;
    let drives = can_drives(machine)?;
    let can_link = match link.transport {
        Transport::Can => CanLink::SocketCan {
            interface: link.port.clone(),
        },
        _ => CanLink::Slcan {
            path: link.port.clone(),
            baud: link.baud,
            bitrate: can_bitrate(machine)?,
        },
    };
    let bar = progress_bar(0);
    let options = CanOptions {
        session: whirl::protocol::canopen::session::SessionConfig::for_drives(drives)?,
        sample: whirl::post::setpoints::SampleConfig::for_drives(machine, drives),
        clock: CanClock::Wall,
        answer_timeout: std::time::Duration::from_secs(1),
        program: input.display().to_string(),
        on_progress: bar.as_ref().map(Progress::can_callback),
    };
    let mut exec_log = whirl::log::ExecLog::append(log)?;
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let outcome = runtime.block_on(stream_can(&can_link, &program, options, &mut exec_log));
    if let Some(bar) = bar {
        bar.finish();
    }
    let outcome = outcome?;
    println!(
        "{}: {} of {} set-points over {can_link} in {:.1} s; {} late cycles",
        input.display(),
        outcome.sent,
        outcome.setpoints,
        outcome.session_time.as_secs_f64(),
        outcome.late_cycles
    );
    if outcome.completed {
        return Ok(ExitCode::SUCCESS);
    }
    match outcome.stop {
        Some(reason) => anyhow::bail!("the drives stopped the job: {reason}"),
        None => anyhow::bail!("the job ended before the drives settled"),
    }
}

/// The CAN bus's bit rate: the profile's slcan adapter's, else 1 Mbit/s (a socketcan
/// interface's is set by the system).
fn can_bitrate(machine: &MachineProfile) -> Result<whirl::protocol::canopen::slcan::Bitrate> {
    Ok(match &machine.connection {
        Some(whirl::config::connection::Connection::CanSlcan(s)) => {
            whirl::protocol::canopen::slcan::Bitrate::from_bits_per_second(s.bitrate)
                .with_context(|| format!("{} bit/s is not an slcan rate", s.bitrate))?
        }
        _ => whirl::protocol::canopen::slcan::Bitrate::M1,
    })
}

/// The CAN drives' settings of `machine`'s `[connection]`.
fn can_drives(machine: &MachineProfile) -> Result<&whirl::config::connection::DriveSettings> {
    machine
        .connection
        .as_ref()
        .and_then(|c| c.drives())
        .with_context(|| {
            format!(
                "machine profile \"{}\" has no CAN drives (a [connection] with transport \
                 can-slcan or can, which gives their nodes, cycle and scales); use one that \
                 has, such as machine-profiles/canopen-drives.toml",
                machine.name
            )
        })
}

/// `whirl stream --transport modbus-tcp|modbus-rtu`: the program checked against the
/// machine, then its segments streamed through the register map.
#[allow(clippy::too_many_arguments)]
fn stream_modbus(
    input: &Path,
    text: &str,
    lines: &[String],
    machine: &MachineProfile,
    port: &str,
    transport: Transport,
    baud: u32,
    log: &Path,
) -> Result<ExitCode> {
    use whirl::config::connection::Connection;
    use whirl::transport::modbus::{stream_modbus, ModbusLink, ModbusOptions};
    whirl::transport::check_program(lines, machine)?;
    let program = whirl::post::gcode::parse::read_program(text, machine.x_diameter())?;
    let segments = whirl::post::modbus::segments(&program)?;
    let link = match transport {
        Transport::ModbusTcp => ModbusLink::Tcp(
            port.parse()
                .with_context(|| format!("--port {port}: not a HOST:PORT address"))?,
        ),
        _ => ModbusLink::Rtu {
            path: port.to_owned(),
            baud,
        },
    };
    let mut exec_log = whirl::log::ExecLog::append(log)?;
    // The profile's unit id and answer timeout, where its [connection] is this transport.
    let defaults = ModbusOptions::default();
    let (unit, timeout) = match (&machine.connection, transport) {
        (Some(Connection::ModbusTcp(s)), Transport::ModbusTcp) => (s.unit, s.timeout()),
        (Some(Connection::ModbusRtu(s)), Transport::ModbusRtu) => (s.unit, s.timeout()),
        _ => (defaults.unit, defaults.timeout),
    };
    let options = ModbusOptions {
        program: input.display().to_string(),
        unit,
        timeout,
        ..defaults
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    let outcome = runtime.block_on(stream_modbus(&link, segments, options, &mut exec_log))?;
    println!(
        "{}: {} of {} segments published over {link} in {:.1} s ({} timeouts, {} reconnects)",
        input.display(),
        outcome.published,
        outcome.segments,
        outcome.wall_time.as_secs_f64(),
        outcome.timeouts,
        outcome.reconnects
    );
    if outcome.completed {
        return Ok(ExitCode::SUCCESS);
    }
    match (outcome.alarm, outcome.failure) {
        (Some(alarm), _) => anyhow::bail!("the controller stopped the stream: {alarm}"),
        (None, Some(failure)) => anyhow::bail!("the stream failed: {failure}"),
        (None, None) => anyhow::bail!("the stream ended before the controller read done"),
    }
}

/// A progress bar with the ETA on a terminal (stderr), fed by the streamer's progress.
struct Progress(indicatif::ProgressBar);

impl Progress {
    fn callback(&self) -> whirl::transport::ProgressFn {
        let bar = self.0.clone();
        Box::new(move |p: &whirl::transport::StreamProgress| {
            bar.set_position(p.acked as u64);
            let state = p.state.as_ref().map_or(String::new(), |s| format!("{s:?}"));
            let eta = p.eta.map_or(String::new(), |d| {
                format!(", {} left", indicatif::HumanDuration(d))
            });
            let tail = if p.all_acked {
                ", waiting for the last moves"
            } else {
                ""
            };
            bar.set_message(format!("{state}{eta}{tail}"));
        })
    }

    /// The same for a CAN run, which counts set-points.
    fn can_callback(&self) -> whirl::transport::can::CanProgressFn {
        let bar = self.0.clone();
        Box::new(move |p: &whirl::transport::can::CanProgress| {
            bar.set_length(p.total as u64);
            bar.set_position(p.sent as u64);
            bar.set_message(format!(
                "set-points, {} of machine time left",
                indicatif::HumanDuration(p.left)
            ));
        })
    }

    fn finish(self) {
        self.0.finish_and_clear();
    }
}

/// `Some` only when stderr is a terminal: logs and pipes get no bar. Its length is the
/// program's lines; a CAN run's callback sets it to the set-points.
fn progress_bar(lines: usize) -> Option<Progress> {
    use std::io::IsTerminal;
    if !std::io::stderr().is_terminal() {
        return None;
    }
    let bar = indicatif::ProgressBar::new(lines as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("{bar:40} {pos}/{len} {elapsed} {msg}")
            .expect("a valid template"),
    );
    Some(Progress(bar))
}

fn job_name(job: &Job) -> String {
    format!(
        "the {}-start groove of lead {} mm",
        job.groove.starts, job.groove.lead
    )
}

fn load_machine(path: Option<&Path>) -> Result<MachineProfile> {
    match path {
        Some(p) => Ok(MachineProfile::load(p)?),
        None => Ok(MachineProfile::builtin_sim()?),
    }
}

/// Write each file through a temporary sibling and rename, so that a failure part-way leaves
/// no half-written program behind.
fn write_all(files: &[(Option<&Path>, &String)]) -> Result<()> {
    let mut staged = Vec::new();
    for (path, text) in files {
        let Some(path) = path else { continue };
        let mut tmp = path.as_os_str().to_owned();
        tmp.push(".whirl-tmp");
        let tmp = PathBuf::from(tmp);
        if let Err(e) = std::fs::write(&tmp, text) {
            let _ = std::fs::remove_file(&tmp);
            for (t, _) in &staged {
                let _ = std::fs::remove_file(t);
            }
            return Err(e).with_context(|| format!("cannot write {}", path.display()));
        }
        staged.push((tmp, path.to_path_buf()));
    }
    for (tmp, path) in staged {
        std::fs::rename(&tmp, &path).with_context(|| format!("cannot write {}", path.display()))?;
    }
    Ok(())
}
