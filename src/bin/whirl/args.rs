//! The command line's words: every subcommand, option and its help, as clap reads them.

use clap::{Parser, Subcommand};
use std::path::PathBuf;
use whirl::papers::section::MIN_ACCURACY;
use whirl::transport::TransportKind;

use crate::numbers::{baud, number, rx, time_scale, whole_in};

#[derive(Parser)]
#[command(
    name = "whirl",
    version,
    about = "Plan and post thread-whirling programs"
)]
pub(crate) struct Cli {
    /// The run records' database (docs/records.md): a SQLite file, a sqlite: URL or a
    /// postgres:// URL; default: $WHIRL_DB, else runs.sqlite in the user's data folder
    /// ($XDG_DATA_HOME/whirl or ~/.local/share/whirl), made on first use.
    #[arg(long, global = true, value_name = "URL")]
    pub(crate) db: Option<String>,
    /// Run even if the run cannot be recorded in the database (said on stderr; its log,
    /// if it has one, keeps it). Without it such a run does not start.
    #[arg(long, global = true)]
    pub(crate) allow_unrecorded: bool,
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
        /// Plan at the fastest feed instead of the job's (as `axial_feed = "auto"` does): the
        /// largest the engine measures within Δ and the machine sustains.
        #[arg(long)]
        fastest: bool,
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
        /// (docs/modbus.md) over TCP or RTU, set-points to CiA 402 drives over CAN, or a
        /// program LinuxCNC runs (linuxcncrsh, HOST:PORT as --port, default
        /// 127.0.0.1:5007); default: the machine profile's `[connection]`, else serial.
        #[arg(long, value_enum)]
        transport: Option<Transport>,
        /// Baud rate of the serial line, 300 to 10000000; default: the profile's, else
        /// 115200.
        #[arg(long, allow_hyphen_values = true, value_parser = baud)]
        baud: Option<u32>,
        /// Machine profile; default: the built-in simulator's.
        #[arg(long)]
        machine: Option<PathBuf>,
        /// The executed-path log (appended to).
        #[arg(long)]
        log: PathBuf,
        /// Give up (with a feed hold) after this many seconds without any progress, 1 to
        /// 604800 (a week).
        #[arg(long, allow_hyphen_values = true, default_value_t = 30.0, value_parser = stall_timeout)]
        stall_timeout: f64,
        /// Resume a stopped run at this program line (1-based, as a stop reports it). Inside
        /// the cut the ring re-enters along the groove first: X clear, C and Z to the line's
        /// start on the helix, the spindle on, a plunge in X; on a serial line a preamble
        /// restores units, distance and feed modes and the G92 offset as the program had them.
        #[arg(long, allow_hyphen_values = true, value_parser = resume_at)]
        resume_at: Option<usize>,
        /// A grbl-family controller found in alarm before the first line (after a reset
        /// mid-motion, a limit, a guard) is unlocked with $X instead of refused: say so only
        /// once the machine has been checked.
        #[arg(long)]
        unlock: bool,
        /// Run at this percent of the programmed feed from the start (a job only: refused
        /// above the cap that keeps the insert cusp within its share of Δ, naming it, before
        /// anything is sent). On a terminal, + and - change it by 10 % and 0 goes back to
        /// 100 % while the program runs (docs/streaming.md).
        #[arg(long, value_name = "PERCENT")]
        feed_override: Option<u16>,
        /// Stream a program even if its provenance header says its job or machine profile
        /// has changed since it was planned, that it was planned for another machine, or
        /// it has none (said on stderr and kept in the run's record). Without it such a
        /// program is refused before anything is opened (docs/streaming.md#provenance).
        #[arg(long)]
        no_provenance_check: bool,
        /// Publish the machine's live state to this MQTT broker, mqtt://HOST[:PORT] or
        /// mqtts://HOST[:PORT] (TLS, with the profile's `tls_*` files if it names them), in
        /// place of the machine profile's `[telemetry] mqtt` (docs/shop.md). A broker that
        /// cannot be reached never slows or stops the run.
        #[arg(long, value_name = "URL")]
        mqtt: Option<String>,
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
        /// Simulated seconds per wall second, 0.001 to 10000; 0 or left out: as fast as the
        /// host allows (over Modbus, 100).
        #[arg(long, allow_hyphen_values = true, value_parser = time_scale)]
        time_scale: Option<f64>,
        /// The link's baud rate, emulated by the simulator, 300 to 10000000.
        #[arg(long, allow_hyphen_values = true, default_value_t = 115_200, value_parser = baud)]
        baud: u32,
        /// The simulated controller's receive buffer, bytes (grblHAL 1024, grbl on an AVR
        /// 128), 128 to 65536.
        #[arg(long, allow_hyphen_values = true, default_value_t = 1024, value_parser = rx)]
        rx: usize,
        /// How the program goes to the simulated controller: G-code over a serial line, or
        /// segments through the Modbus register map (docs/modbus.md) over TCP or RTU.
        #[arg(long, value_enum, default_value_t = Transport::Serial)]
        transport: Transport,
        /// The controller that runs the program: the built-in simulator, or LinuxCNC's own
        /// simulation (Debian's linuxcnc-uspace, started headless for the run; machine
        /// profile default machine-profiles/linuxcnc-lathe.toml). For LinuxCNC,
        /// --time-scale is its clock's speed-up, 1 to 100 (default 50 as root, with
        /// libfaketime; otherwise 1, real time).
        #[arg(long, value_enum, default_value_t = Controller::WhirlSim)]
        controller: Controller,
        /// Run at this percent of the programmed feed from the start, as `whirl stream
        /// --feed-override` (refused above the cusp's cap); on a terminal, + - 0 change it.
        #[arg(long, value_name = "PERCENT")]
        feed_override: Option<u16>,
        /// Publish the machine's live state to this MQTT broker, mqtt://HOST[:PORT] or
        /// mqtts://HOST[:PORT] (TLS, with the profile's `tls_*` files if it names them), in
        /// place of the machine profile's `[telemetry] mqtt` (docs/shop.md). A broker that
        /// cannot be reached never slows or stops the run.
        #[arg(long, value_name = "URL")]
        mqtt: Option<String>,
    },
    /// The record of every plan, dry run and stream: list them, or show one.
    Runs {
        #[command(subcommand)]
        command: crate::runs::RunsCommand,
    },
    /// Serve the operator's web console: the jobs under --jobs with their plans and
    /// verification, dry runs on the simulator and streams to the machine with live
    /// position, progress, alarms, the groove as it is cut, Hold, Resume, Stop, and the
    /// history of every recorded run (docs/console.md). Listens on loopback unless told
    /// otherwise; elsewhere only with an access token.
    Serve {
        /// A machine the console runs (a profile; repeat for more); default: the built-in
        /// simulator's.
        #[arg(long = "machine")]
        machines: Vec<PathBuf>,
        /// The folder of the job files the console may read (nothing outside it).
        #[arg(long, default_value = ".")]
        jobs: PathBuf,
        /// The address to listen on (IP:PORT; port 0: any free one, printed at start).
        #[arg(long, default_value = "127.0.0.1:8480")]
        listen: std::net::SocketAddr,
        /// The access token every action then needs (at least 16 characters); required
        /// for an address other hosts reach.
        #[arg(long)]
        token: Option<String>,
        /// Another host name the console answers to (repeat for more), such as the
        /// machine's name on the shop's network; it always answers to its listening
        /// address, localhost, 127.0.0.1 and [::1], and to no other name (DNS rebinding).
        #[arg(long = "allow-host", value_name = "NAME")]
        allow_hosts: Vec<String>,
        /// Serve the shop overview instead of a machine's console: every machine whose
        /// bridge publishes to the --mqtt broker, and the shop's history from the run
        /// records (docs/shop.md). Read-only: it starts nothing.
        #[arg(long, requires = "mqtt", conflicts_with_all = ["machines", "opcua"])]
        shop: bool,
        /// The topic prefix the shop's bridges publish under (with --shop).
        #[arg(long, default_value = "whirl", requires = "shop")]
        prefix: String,
        /// Publish the live state of every machine the console runs to this MQTT broker,
        /// mqtt://HOST[:PORT] or mqtts://HOST[:PORT] (TLS, with each profile's `tls_*`
        /// files), in place of each profile's `[telemetry] mqtt` (docs/shop.md). A broker
        /// that cannot be reached never slows or stops a run. With --shop, the broker the
        /// overview reads.
        #[arg(long, value_name = "URL")]
        mqtt: Option<String>,
        /// With --shop: the overview's login on a broker that takes user names and
        /// passwords (mosquitto's `password_file`); the password comes from the environment,
        /// $WHIRL_MQTT_PASSWORD, not the command line, which any user of the host may read.
        #[arg(long, value_name = "NAME", requires = "shop")]
        mqtt_user: Option<String>,
        /// With --shop and an mqtts:// broker: the shop's CA (PEM) the broker's certificate
        /// must be signed by; default: the system's root certificates.
        #[arg(long, value_name = "FILE", requires = "shop")]
        tls_ca: Option<PathBuf>,
        /// With --shop and an mqtts:// broker: the overview's certificate (PEM), its login
        /// on a broker that takes certificates as logins; with --tls-key.
        #[arg(long, value_name = "FILE", requires_all = ["shop", "tls_key"])]
        tls_cert: Option<PathBuf>,
        /// The private key (PEM, not encrypted) of --tls-cert.
        #[arg(long, value_name = "FILE", requires_all = ["shop", "tls_cert"])]
        tls_key: Option<PathBuf>,
        /// Serve every machine the console runs as OPC UA for Machine Tools at
        /// opc.tcp://HOST:PORT (HOST an address of this host; port 0: any free one,
        /// printed at start), in place of the profiles' `[telemetry] opcua` (docs/opcua.md).
        /// Beyond loopback the profiles' `opcua_security` and `opcua_user` must secure it.
        #[arg(long, value_name = "HOST:PORT")]
        opcua: Option<String>,
    },
    /// Read executed-path logs.
    Log {
        #[command(subcommand)]
        command: LogCommand,
    },
    /// Measure a cut part: a measured axial or transverse section (a profile projector's or
    /// CMM's points, the frame stated in the file's header or with --frame) against the
    /// job's groove, each point's deviation along the normal; with --fit the ring radius,
    /// nose radius and installation angle it was really cut with, with --correct the job
    /// that cuts the target with that tool. Exits 0 within Δ, 2 beyond it, 1 on errors.
    Measure(crate::measure::MeasureArgs),
    /// The installation angles at which a job plans without interference: the max error
    /// and the segments across that window, and the angle with the largest margin (the one
    /// `plan` takes when the job gives none), as a table and, with --svg, a plot.
    Angles(crate::angles::AnglesArgs),
    /// What whirl understood of a job's groove, to see before cutting: a standard form's
    /// dimensions and source, or what the curve through the points is (its depth, its
    /// tightest concave stretch, the fit); lead, starts, hand and axial pitch; with -o the
    /// axial section over one pitch as a points file, with --svg its plot.
    Profile(crate::profile::ProfileArgs),
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
    /// A LinuxCNC machine through linuxcncrsh: it opens and runs the program.
    Linuxcnc,
}

/// The controller a dry run runs the program on.
#[derive(Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum Controller {
    /// whirl-sim, the built-in grblHAL simulator.
    WhirlSim,
    /// LinuxCNC's simulation, through linuxcncrsh.
    Linuxcnc,
}

impl From<Transport> for TransportKind {
    fn from(transport: Transport) -> TransportKind {
        match transport {
            Transport::Serial => TransportKind::Serial,
            Transport::ModbusTcp => TransportKind::ModbusTcp,
            Transport::ModbusRtu => TransportKind::ModbusRtu,
            Transport::CanSlcan => TransportKind::CanSlcan,
            Transport::Can => TransportKind::Can,
            Transport::Linuxcnc => TransportKind::Linuxcnc,
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
        #[arg(long, allow_hyphen_values = true, value_parser = negative)]
        a: f64,
        /// b, mm (positive).
        #[arg(long, allow_hyphen_values = true, value_parser = positive)]
        b: f64,
        /// Helix radius R, mm (positive).
        #[arg(long, allow_hyphen_values = true, value_parser = positive)]
        radius: f64,
        /// Helix pitch p, mm (0: a circular path).
        #[arg(long, allow_hyphen_values = true, value_parser = not_negative)]
        pitch: f64,
        /// Largest distance of the written polyline from the true boundary, mm, 1e-9 to 1.
        #[arg(long, allow_hyphen_values = true, default_value_t = 1e-4, value_parser = accuracy)]
        accuracy: f64,
        /// Where to write the CSV.
        #[arg(short, long)]
        output: PathBuf,
    },
}

// The numbers the command line takes: each checked here, so that clap refuses a wrong one
// naming the option, before anything is read or run.

/// The largest magnitude a length or a coefficient of the command line may have: far
/// beyond any machine, small enough that nothing computed from it overflows.
const LARGEST: f64 = 1e6;

/// A number (finite, then) from `low` to `high`, `what` (" seconds") saying what it counts.
fn number_in(text: &str, low: f64, high: f64, what: &str) -> Result<f64, String> {
    let value = number(text)?;
    if (low..=high).contains(&value) {
        Ok(value)
    } else {
        Err(format!("must be a number from {low} to {high}{what}"))
    }
}

/// `--stall-timeout`: seconds, from one to a week.
fn stall_timeout(text: &str) -> Result<f64, String> {
    number_in(text, 1.0, 604_800.0, " seconds (a week)")
}

/// `--resume-at`: a program line, counted from 1.
fn resume_at(text: &str) -> Result<usize, String> {
    whole_in(text, 1, usize::MAX, "").map_err(|_| "counts program lines from 1".into())
}

/// A finite number below 0 (and above −10⁶).
fn negative(text: &str) -> Result<f64, String> {
    match number(text)? {
        v if (-LARGEST..0.0).contains(&v) => Ok(v),
        _ => Err(format!(
            "must be negative: a number below 0, down to -{LARGEST}"
        )),
    }
}

/// A finite number above 0 (and at most 10⁶).
fn positive(text: &str) -> Result<f64, String> {
    match number(text)? {
        v if v > 0.0 && v <= LARGEST => Ok(v),
        _ => Err(format!(
            "must be positive: a number above 0, up to {LARGEST}"
        )),
    }
}

/// A number from 0 to 10⁶.
fn not_negative(text: &str) -> Result<f64, String> {
    number_in(text, 0.0, LARGEST, "")
}

/// `--accuracy`: mm, from the finest the engine can reach to 1.
fn accuracy(text: &str) -> Result<f64, String> {
    number_in(text, MIN_ACCURACY, 1.0, " mm")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_are_finite_and_in_range() {
        for bad in [
            "nan", "NaN", "inf", "-inf", "1e30", "0", "-1", "0.5", "x", "",
        ] {
            assert!(stall_timeout(bad).is_err(), "{bad}");
        }
        assert_eq!(stall_timeout("30"), Ok(30.0));
        for bad in ["nan", "inf", "1e308", "-1", "1e-4", "10001"] {
            assert!(time_scale(bad).is_err(), "{bad}");
        }
        assert_eq!(time_scale("0"), Ok(0.0));
        assert_eq!(time_scale("200"), Ok(200.0));
        for bad in ["0", "-1", "299", "1e6", "10000001", "nan"] {
            assert!(baud(bad).is_err(), "{bad}");
        }
        assert_eq!(baud("115200"), Ok(115_200));
        assert!(rx("0").is_err() && rx("127").is_err() && rx("65537").is_err());
        assert_eq!((rx("128"), rx("1024")), (Ok(128), Ok(1024)));
        assert_eq!(resume_at("0").unwrap_err(), "counts program lines from 1");
        assert_eq!(resume_at("20"), Ok(20));
        assert!(negative("0.05").unwrap_err().contains("must be negative"));
        assert!(negative("nan").is_err() && positive("inf").is_err());
        assert!(positive("0").is_err() && not_negative("-1").is_err());
        assert_eq!(not_negative("0"), Ok(0.0));
        for bad in ["0", "1e-10", "nan", "2"] {
            assert!(accuracy(bad).is_err(), "{bad}");
        }
        assert_eq!(accuracy("1e-9"), Ok(1e-9));
    }
}
