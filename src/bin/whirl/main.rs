//! The `whirl` command line: thin glue over the library. Each subcommand reads its files,
//! calls the library, prints what came back and writes its outputs; the words it takes are
//! in [`args`], what it may write and how in [`files`], its printing and the terminal's
//! progress bar in [`terminal`].

mod angles;
mod args;
mod fastest;
mod files;
mod interrupt;
mod keys;
mod measure;
mod numbers;
mod profile;
mod provenance;
mod runs;
mod serve;
mod telemetry;
mod terminal;

use anyhow::{bail, Context, Result};
use args::{Cli, Command, Controller, LogCommand, SweepTool};
use clap::Parser;
use files::Files;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use terminal::say;
use whirl::config::job::Job;
use whirl::config::machine::{Dialect, MachineProfile};
use whirl::config::telemetry::TelemetrySettings;
use whirl::geometry::linkage::Ring;
use whirl::judge::dry_run::{self, DryRunOptions};
use whirl::judge::linuxcnc::LinuxcncDryRunOptions;
use whirl::log::ExecLog;
use whirl::transport::{self, Link, Posted, Resume, RunOptions, TransportKind};

/// Exit code of `whirl verify` and `whirl dry-run` for a program measured beyond Δ.
const BEYOND_DELTA: u8 = 2;

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(
            tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "warn".into()),
        )
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
    let cli = Cli::parse();
    let mut record = runs::Recorder::new(&cli);
    let result = run(cli, &mut record);
    match record.finish(result) {
        Ok(code) => code,
        Err(e) => {
            terminal::error(&e);
            ExitCode::FAILURE
        }
    }
}

fn run(cli: Cli, record: &mut runs::Recorder) -> Result<ExitCode> {
    match cli.command {
        Command::Plan {
            job,
            machine,
            output,
            report,
            verify,
            fastest,
        } => plan(
            &job,
            machine.as_deref(),
            &output,
            report.as_deref(),
            verify,
            fastest,
            record,
        ),
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
            Files::new().output("-o", Some(&output)).check()?;
            let csv = whirl::papers::section::run_paraboloid(a, b, radius, pitch, accuracy)?;
            files::write_all(&[(Some(&output), &csv)])?;
            say!(
                "{}: {} points within {accuracy} mm of the section",
                output.display(),
                csv.lines().count() - 1
            )?;
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
            unlock,
            feed_override,
            no_provenance_check,
            mqtt,
        } => {
            let files = if input.extension().is_some_and(|e| e == "toml") {
                Files::new().job(&input)
            } else {
                Files::new().input("the program", Some(&input))
            };
            files
                .input("the machine profile (--machine)", machine.as_deref())
                .log("the log (--log)", Some(&log))
                .database(record.database())
                .check()?;
            let machine_path = machine;
            let machine = load_machine(machine_path.as_deref())?;
            let telemetry = telemetry::settings(&machine, mqtt.as_deref())?;
            let link = Link::resolve(&machine, transport.map(TransportKind::from), port, baud)?;
            // Counted from 1 on the command line (clap refuses 0), from 0 below.
            let resume_at = resume_at.map(|line| line - 1);
            let options = RunOptions {
                stall_timeout: Some(std::time::Duration::from_secs_f64(stall_timeout)),
                resume_at,
                unlock,
                progress: None,
            };
            let file = provenance::MachineFile::read(machine_path.as_deref(), runs::BUILTIN_SIM)?;
            stream(
                &input,
                (&machine, &file),
                &link,
                options,
                (&log, telemetry.as_ref()),
                record,
                (feed_override, no_provenance_check),
            )
        }
        Command::DryRun {
            job,
            program,
            machine,
            log,
            report,
            time_scale,
            baud,
            rx,
            transport,
            controller,
            feed_override,
            mqtt,
        } => {
            Files::new()
                .output("--report", report.as_deref())
                .job(&job)
                .input("the program (--program)", program.as_deref())
                .input("the machine profile (--machine)", machine.as_deref())
                .log("the log (--log)", log.as_deref())
                .database(record.database())
                .check()?;
            let options = DryRunOptions {
                transport: transport.into(),
                time_scale: time_scale.filter(|s| *s > 0.0),
                baud,
                rx_size: rx,
                ..DryRunOptions::default()
            };
            let paths = DryRunPaths {
                job,
                program,
                machine,
                log,
                report,
            };
            dry_run(paths, options, controller, record, (feed_override, mqtt))
        }
        Command::Serve {
            machines,
            jobs,
            listen,
            token,
            allow_hosts,
            shop,
            prefix,
            mqtt,
            mqtt_user,
            tls_ca,
            tls_cert,
            tls_key,
            opcua,
        } => {
            let listen = serve::Listen {
                address: listen,
                token: token.as_deref(),
                hosts: &allow_hosts,
            };
            let records = (cli.db.as_deref(), cli.allow_unrecorded);
            match (shop, mqtt.as_deref()) {
                (true, Some(mqtt)) => {
                    let broker = serve::ShopBroker {
                        mqtt,
                        prefix: &prefix,
                        login: (mqtt_user, std::env::var("WHIRL_MQTT_PASSWORD").ok()),
                        tls: [tls_ca, tls_cert, tls_key],
                    };
                    serve::shop(&jobs, listen, records, broker)
                }
                _ => serve::run(
                    &machines,
                    &jobs,
                    listen,
                    records,
                    (mqtt.as_deref(), opcua.as_deref()),
                ),
            }
        }
        Command::Runs { command } => runs::runs(command, record),
        Command::Log { command } => {
            match command {
                LogCommand::Summary { log } => {
                    let read = whirl::log::read(&log)?;
                    let s = whirl::log::Summary::of(&read);
                    say!("{}", serde_json::to_string_pretty(&s)?)?;
                }
                LogCommand::Plot { log, output, job } => {
                    let files = match &job {
                        Some(job) => Files::new().job(job),
                        None => Files::new(),
                    };
                    files
                        .output("-o", Some(&output))
                        .input("the log", Some(&log))
                        .check()?;
                    let read = whirl::log::read(&log)?;
                    let mut plots = whirl::judge::plots::axis_plots(&read);
                    if let Some(job) = job {
                        let job = Job::load(&job)?;
                        plots.push(
                            whirl::judge::plots::section_plot(&read, &job, planned_ring(&job)?)
                                .with_context(|| format!("{}", log.display()))?,
                        );
                    }
                    files::write_all(&[(Some(&output), &whirl::judge::svg::stack(&plots))])?;
                }
            }
            Ok(ExitCode::SUCCESS)
        }
        Command::Measure(args) => measure::run(args),
        Command::Angles(args) => angles::run(args),
        Command::Profile(args) => profile::run(args),
        Command::Verify {
            program,
            job,
            machine,
            report,
            svg,
        } => {
            Files::new()
                .output("--report", Some(&report))
                .output("--svg", svg.as_deref())
                .input("the program", Some(&program))
                .job(&job)
                .input("the machine profile (--machine)", machine.as_deref())
                .check()?;
            let file = provenance::MachineFile::read(machine.as_deref(), runs::BUILTIN_SIM)?;
            let machine = load_machine(machine.as_deref())?;
            let job_path = job;
            let job = fastest::resolve(Job::load(&job_path)?, &machine, Some(&program))?;
            let text = std::fs::read_to_string(&program)
                .with_context(|| format!("cannot read {}", program.display()))?;
            provenance::report(&provenance::check(
                &program,
                &text,
                Some(&job_path),
                &machine,
                &file,
            ));
            let ring = planned_ring(&job)?;
            let v = whirl::judge::verify::verify(&job, ring, &machine, &text, svg.is_some())
                .with_context(|| format!("cannot verify {}", program.display()))?;
            let json = serde_json::to_string_pretty(&v)?;
            files::write_all(&[
                (Some(&report), &json),
                (svg.as_deref(), &v.svg.clone().unwrap_or_default()),
            ])?;
            say!(
                "{}: max overcut {:.5} mm, max undercut {:.5} mm over {} points; Δ {} mm: {}",
                program.display(),
                v.max_overcut_mm,
                v.max_undercut_mm,
                v.points,
                v.delta_mm,
                if v.within_delta { "within" } else { "BEYOND" }
            )?;
            Ok(if v.within_delta {
                ExitCode::SUCCESS
            } else {
                ExitCode::from(BEYOND_DELTA)
            })
        }
    }
}

/// `whirl plan`: the program and its report, written only once everything is computed (and
/// refused before anything is if they cannot be).
fn plan(
    job: &Path,
    machine: Option<&Path>,
    output: &Path,
    report: Option<&Path>,
    verify: bool,
    fastest: bool,
    record: &mut runs::Recorder,
) -> Result<ExitCode> {
    Files::new()
        .output("-o", Some(output))
        .output("--report", report)
        .job(job)
        .input("the machine profile (--machine)", machine)
        .database(record.database())
        .check()?;
    let file = provenance::MachineFile::read(machine, runs::BUILTIN_SIM)?;
    let machine = load_machine(machine)?;
    let job_path = job;
    let mut job = Job::load(job_path)?;
    job.cut.auto_feed |= fastest;
    record.begin(&machine, None, None)?;
    let mut plan = fastest::planned(&mut job, &machine)?;
    let header = provenance::of_plan(
        job_path,
        &machine,
        &file,
        &provenance::real_folder(output)?,
        &plan,
        fastest,
    )?;
    provenance::stamp(&mut plan, &machine, &header)?;
    record.provenance(whirl::records::RunProvenance::planned(header));
    record.planned(&plan);
    let mut verified = None;
    if verify {
        let v = whirl::judge::verify::verify(&job, plan.ring, &machine, &plan.text, false)
            .context("cannot verify the planned program")?;
        if !v.within_delta {
            anyhow::bail!(
                "the planned program measures {:.5} mm overcut, {:.5} mm undercut: beyond Δ = {} mm",
                v.max_overcut_mm,
                v.max_undercut_mm,
                v.delta_mm
            );
        }
        say!(
            "verified: max overcut {:.5} mm, max undercut {:.5} mm over {} points (Δ {} mm)",
            v.max_overcut_mm,
            v.max_undercut_mm,
            v.points,
            v.delta_mm
        )?;
        verified = Some(v);
    }
    let json = match &verified {
        Some(verify) => serde_json::to_string_pretty(&whirl::judge::verify::VerifiedReport {
            report: &plan.report,
            verify,
        })?,
        None => serde_json::to_string_pretty(&plan.report)?,
    };
    files::write_all(&[(Some(output), &plan.text), (report, &json)])?;
    let r = &plan.report;
    say!(
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
    )?;
    if let Some(line) = r.blending_summary() {
        say!("{line}")?;
    }
    if let Some(line) = r.fastest_summary() {
        say!("{line}")?;
    }
    Ok(ExitCode::SUCCESS)
}

/// `whirl stream`: the program (or the job, planned for the machine first) to the machine
/// at `link`, checked against its limits before the log is opened.
fn stream(
    input: &Path,
    (machine, file): (&MachineProfile, &provenance::MachineFile),
    link: &Link,
    mut options: RunOptions,
    (log, telemetry): (&Path, Option<&TelemetrySettings>),
    record: &mut runs::Recorder,
    (feed_override, unchecked): (Option<u16>, bool),
) -> Result<ExitCode> {
    let name = input.display().to_string();
    let is_job = input.extension().is_some_and(|e| e == "toml");
    let (text, cap) = if is_job {
        let plan = fastest::planned(&mut Job::load(input)?, machine)?;
        let here = provenance::here()?;
        let header = provenance::of_plan(input, machine, file, &here, &plan, false)?;
        record.provenance(whirl::records::RunProvenance::planned(header));
        record.planned(&plan);
        let cap = transport::control::feed_cap(&plan.report, link.kind());
        (plan.text, Some(cap))
    } else {
        let text = std::fs::read_to_string(input).with_context(|| format!("cannot read {name}"))?;
        (text, None)
    };
    let cap = keys::start_cap(cap, feed_override, input)?;
    let posted = Posted::read(name.as_str(), &text, machine)
        .with_context(|| format!("cannot read {name}"))?;
    posted.check(machine)?;
    if !is_job {
        // Before anything is opened: a stale program, one for another machine or one
        // without provenance goes no further unless the operator says so.
        let checked = provenance::check(input, &text, None, machine, file);
        provenance::refuse_or_warn(&checked, input, unchecked)?;
        record.provenance(checked.record(whirl::records::ProvenanceCheck::Overridden));
    }
    // One run per machine: refused, naming the holder, while another process (a console,
    // another terminal) runs this port.
    let _lock = whirl::console::lock::MachineLock::acquire(
        &whirl::console::lock::lock_dir(),
        &whirl::console::link_key(link),
        &whirl::console::lock::this_process(),
    )?;
    record.begin(machine, Some(&posted), Some(link))?;
    let mut log = ExecLog::append(log)?;
    let bar = terminal::progress_bar();
    options.progress = bar.as_ref().map(terminal::Bar::callback);
    let live = telemetry
        .map(|settings| {
            telemetry::Live::start(settings, machine, record.telemetry_context("stream"))
        })
        .transpose()?;
    if let Some(live) = &live {
        log = live.tap(log);
        options.progress = live.progress(options.progress.take());
    }
    let (control, commands) = transport::control();
    let _keys = keys::arm(&control, cap, feed_override);
    let runtime = runtime()?;
    // The handlers go in before the first byte goes out.
    let interrupts = {
        let _inside = runtime.enter();
        interrupt::Interrupts::install().context("cannot install the signal handlers")?
    };
    let outcome = runtime.block_on(async {
        let watching = tokio::spawn(interrupts.watch(control));
        let outcome = transport::stream(link, &posted, machine, options, commands, &mut log).await;
        watching.abort();
        outcome
    });
    if let Some(bar) = bar {
        bar.finish();
    }
    if let Some(live) = live {
        live.close();
    }
    record.streamed(&outcome);
    let outcome = match outcome {
        Ok(outcome) => outcome,
        Err(error) => anyhow::bail!("{error}{}", resume_hint(error.resume())),
    };
    say!("{}", outcome.summary(&name, link))?;
    match outcome.stop() {
        None => Ok(ExitCode::SUCCESS),
        Some(stop) => anyhow::bail!("{stop}{}", resume_hint(outcome.resume())),
    }
}

/// Where a run that did not complete resumes, in the command line's words.
fn resume_hint(resume: Option<Resume>) -> String {
    let Some(resume) = resume else {
        return String::new();
    };
    let mut hint = format!("; resume with --resume-at {}", resume.line + 1);
    if !resume.possibly_executed.is_empty() {
        hint.push_str(&format!(
            " (lines {} to {} may already have run: the resume cuts them again along the \
             groove, which removes nothing more)",
            resume.possibly_executed.start + 1,
            resume.possibly_executed.end
        ));
    }
    hint
}

/// The files `whirl dry-run` reads and writes.
struct DryRunPaths {
    job: PathBuf,
    program: Option<PathBuf>,
    machine: Option<PathBuf>,
    log: Option<PathBuf>,
    report: Option<PathBuf>,
}

/// `whirl dry-run`: the job's program (or one given for it) on the simulator, refused
/// before the log is opened if it cannot run; the exit code says whether it was within Δ.
fn dry_run(
    paths: DryRunPaths,
    mut options: DryRunOptions,
    controller: Controller,
    record: &mut runs::Recorder,
    (feed_override, mqtt): (Option<u16>, Option<String>),
) -> Result<ExitCode> {
    let machine = match (controller, paths.machine.as_deref()) {
        (Controller::Linuxcnc, None) => MachineProfile::builtin_linuxcnc()?,
        (_, path) => load_machine(path)?,
    };
    let telemetry = telemetry::settings(&machine, mqtt.as_deref())?;
    if controller == Controller::Linuxcnc && machine.dialect != Dialect::LinuxCnc {
        bail!(
            "--controller linuxcnc runs LinuxCNC's G-code, and machine profile \"{}\" is \
             written for {:?}: give a LinuxCNC profile (machine-profiles/linuxcnc-lathe.toml)",
            machine.name,
            machine.dialect
        );
    }
    let builtin = match controller {
        Controller::WhirlSim => runs::BUILTIN_SIM,
        Controller::Linuxcnc => runs::BUILTIN_LINUXCNC,
    };
    let file = provenance::MachineFile::read(paths.machine.as_deref(), builtin)?;
    let mut job = Job::load(&paths.job)?;
    let (name, text, cap, ring) = match &paths.program {
        Some(path) => {
            job = fastest::resolve(job, &machine, Some(path))?;
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("cannot read {}", path.display()))?;
            let checked = provenance::check(path, &text, Some(&paths.job), &machine, &file);
            provenance::report(&checked);
            record.provenance(checked.record(whirl::records::ProvenanceCheck::Reported));
            (path.display().to_string(), text, None, planned_ring(&job)?)
        }
        None => {
            let plan = fastest::planned(&mut job, &machine)?;
            let here = provenance::here()?;
            let header = provenance::of_plan(&paths.job, &machine, &file, &here, &plan, false)?;
            record.provenance(whirl::records::RunProvenance::planned(header));
            record.planned(&plan);
            let kind = match controller {
                Controller::WhirlSim => options.transport,
                Controller::Linuxcnc => TransportKind::Linuxcnc,
            };
            let cap = transport::control::feed_cap(&plan.report, kind);
            (
                paths.job.display().to_string(),
                plan.text,
                Some(cap),
                plan.ring,
            )
        }
    };
    let cap = keys::start_cap(
        cap,
        feed_override,
        paths.program.as_deref().unwrap_or(&paths.job),
    )?;
    let posted = Posted::read(name.as_str(), &text, &machine)
        .with_context(|| format!("cannot read {name}"))?;
    match controller {
        Controller::WhirlSim => {
            dry_run::preflight(&machine, &posted, options.transport)?;
        }
        Controller::Linuxcnc => posted.check(&machine)?,
    }
    record.begin(&machine, Some(&posted), None)?;
    let mut log = match &paths.log {
        Some(path) => ExecLog::append(path)?,
        None => ExecLog::discard(),
    };
    let bar = terminal::progress_bar();
    options.progress = bar.as_ref().map(terminal::Bar::callback);
    let live = telemetry
        .as_ref()
        .map(|settings| {
            telemetry::Live::start(settings, &machine, record.telemetry_context("dry-run"))
        })
        .transpose()?;
    if let Some(live) = &live {
        log = live.tap(log);
        options.progress = live.progress(options.progress.take());
    }
    let (control, commands) = transport::control();
    let _keys = keys::arm(&control, cap, feed_override);
    if control.feed_cap().is_some() {
        options.commands = Some(commands);
    }
    let r = match controller {
        Controller::WhirlSim => runtime()?
            .block_on(dry_run::dry_run(
                &job, ring, &machine, &posted, options, &mut log,
            ))
            .map_err(anyhow::Error::from),
        Controller::Linuxcnc => {
            let options = LinuxcncDryRunOptions {
                speed_up: options
                    .time_scale
                    .unwrap_or_else(whirl::judge::linuxcnc::default_speed_up),
                stall_timeout: options.stall_timeout,
                progress: options.progress,
                commands: options.commands,
            };
            runtime()?
                .block_on(whirl::judge::linuxcnc::dry_run(
                    &job, ring, &machine, &posted, options, &mut log,
                ))
                .map_err(anyhow::Error::from)
        }
    };
    if let Some(bar) = bar {
        bar.finish();
    }
    if let Some(live) = live {
        live.close();
    }
    let r = r?;
    record.dry_ran(&r);
    let json = serde_json::to_string_pretty(&r)?;
    files::write_all(&[(paths.report.as_deref(), &json)])?;
    say!(
        "{}: {} of {} lines acknowledged; {:.1} s on the machine, dry-run in {:.1} s; \
         link {:.1} % busy at {} baud",
        r.job,
        r.lines_acked,
        r.lines,
        r.machine_time_s,
        r.wall_time_s,
        100.0 * r.link_utilization,
        r.baud
    )?;
    say!(
        "profile error measured by the simulator: overcut {:.4} mm, undercut {:.4} mm \
         over {} of {} points; Δ {} mm",
        r.max_overcut_mm,
        r.max_undercut_mm,
        r.points_measured,
        r.points,
        r.delta_mm
    )?;
    for a in &r.alarms {
        say!(
            "ALARM:{} {}{}",
            a.code,
            a.message,
            a.detail
                .as_ref()
                .map_or(String::new(), |d| format!(": {d}"))
        )?;
    }
    if let Some(stop) = &r.stop {
        say!("stopped: {stop}")?;
    }
    let beyond = r.alarms.iter().any(|a| a.code == 64) || r.max_error_mm > r.delta_mm;
    Ok(if r.within_delta {
        say!("completed within Δ")?;
        ExitCode::SUCCESS
    } else if beyond {
        say!("BEYOND Δ")?;
        ExitCode::from(BEYOND_DELTA)
    } else {
        say!("did not complete")?;
        ExitCode::FAILURE
    })
}

/// The async runtime of a stream or a dry run: one thread, time and I/O.
fn runtime() -> Result<tokio::runtime::Runtime> {
    Ok(tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?)
}

/// The ring `whirl plan` plans `job` with: tilted by its installation angle, or where it gives
/// none, by the window's angle of largest margin. What a program of the job planned before is
/// measured with.
fn planned_ring(job: &Job) -> Result<Ring> {
    let (ring, _) = whirl::plan::angles::ring(job)
        .map_err(whirl::plan::PlanError::NoAngle)
        .with_context(|| format!("cannot plan {}", job_name(job)))?;
    Ok(ring)
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
