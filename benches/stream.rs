//! Link utilisation: how busy whirl's streamer keeps a 115 200 baud serial link.
//!
//! whirl-sim is served on a real pseudo-terminal, in real time, with the link's byte rate
//! emulated at 115 200 baud; `whirl::transport::stream` streams a long program of short
//! lines to it over the terminal's other end, opened by path as `whirl stream --port` opens
//! it. Each run is one sample and prints the streamer's own
//! [`StreamOutcome::streaming_utilization`]: bytes written × 10 bits over what the link
//! could carry from the first byte to the last acknowledgement. The requirement is 90 %.
//!
//! Run with `cargo bench --bench stream`; the README quotes the figures.

use std::sync::mpsc;
use std::thread::JoinHandle;
use std::time::Duration;

use divan::Bencher;
use tokio::sync::oneshot;
use tokio_serial::{SerialPort, SerialPortBuilderExt};
use whirl::config::machine::MachineProfile;
use whirl::log::ExecLog;
use whirl::transport::check_program;
use whirl::transport::serial::{stream, StreamOptions, StreamOutcome};
use whirl_sim::serve::{serve, ServeOptions};
use whirl_sim::{Controller, ControllerOptions, Event};

fn main() {
    divan::main();
}

/// The link rate, bits per second, on both sides.
const BAUD: u32 = 115_200;

/// Program moves: at about 10 bytes a line (`\n` counted), 5000 lines are 4.3 s of link
/// time, long enough that the start (the `$I` round trip) and the timer's grain do not
/// count.
const MOVES: usize = 5000;

/// Each move's length, mm.
///
/// The link must be the bottleneck, or the controller's planner fills, it stops reading and
/// the link idles through no fault of the streamer. The moves are collinear, so no junction
/// slows them: the speed is bounded only by stopping within the queued blocks,
/// v = √(2·a·n·L). Lines arrive at R ≈ 1150 per second, so the motion keeps up with
/// n = R²·L / 2a ≈ 13 of the 35 planner blocks at 500 mm/s² (11.5 mm/s, under the 50 mm/s
/// feed).
const STEP_MM: f64 = 0.01;

/// Units, absolute distances, the feed, a start at the origin (where the simulator powers
/// up, so it does not move; the machine check wants every axis placed), then [`MOVES`] short
/// G1 lines along Z from 0 to 50 mm, inside the sim machine's travel.
fn program() -> Vec<String> {
    let mut lines = vec![
        "G21 G90 G94".to_owned(),
        "F3000".to_owned(),
        "G0 X0 Z0 C0".to_owned(),
    ];
    lines.extend((1..=MOVES).map(|k| format!("G1 Z{:.2}", k as f64 * STEP_MM)));
    lines
}

/// What the simulator saw: the run must have been clean for its figure to count.
#[derive(Debug, Default)]
struct SimReport {
    executed: usize,
    overflows: usize,
    alarms: usize,
}

impl SimReport {
    fn note(&mut self, event: &Event) {
        match event {
            Event::Executed(_) => self.executed += 1,
            Event::RxOverflow { .. } => self.overflows += 1,
            Event::Alarm { .. } => self.alarms += 1,
            _ => {}
        }
    }
}

/// whirl-sim with an `rx`-byte receive buffer on a new pseudo-terminal, on its own thread (as
/// the `whirl-sim` binary runs in its own process, so neither side's work delays the other's
/// reads).
struct Sim {
    /// The terminal's device, for the streamer to open.
    path: String,
    /// Stops serving (the simulator keeps the terminal open, so it never sees it close).
    stop: oneshot::Sender<()>,
    thread: JoinHandle<SimReport>,
}

impl Sim {
    /// Starts the thread, which opens the terminal and waits for the returned switch to
    /// start serving: the emulated link credits the time it sat idle to later bytes, so it
    /// starts when the streamer is about to write, not while the streamer opens the port.
    fn start(rx: usize) -> (Sim, oneshot::Sender<()>) {
        let (path_tx, path_rx) = mpsc::channel();
        let (go, go_rx) = oneshot::channel();
        let (stop, stop_rx) = oneshot::channel();
        let thread = std::thread::spawn(move || {
            let runtime = tokio::runtime::Builder::new_current_thread()
                .enable_all()
                .build()
                .expect("a runtime");
            runtime.block_on(async move {
                let (master, slave) =
                    tokio_serial::SerialStream::pair().expect("a pseudo-terminal");
                path_tx
                    .send(slave.name().expect("the terminal's device"))
                    .expect("the bench waits for the path");
                let profile = MachineProfile::builtin_sim().expect("the built-in profile");
                let options = ControllerOptions {
                    rx_buffer_size: rx,
                    ..ControllerOptions::default()
                };
                let mut controller =
                    Controller::new(&whirl::judge::simulator::machine(&profile), options)
                        .expect("a controller");
                // As whirl-sim does: the board booted before the host opened the port.
                controller.take_output();
                let serve_options = ServeOptions {
                    time_scale: Some(1.0),
                    baud: Some(BAUD),
                    ..ServeOptions::default()
                };
                let mut report = SimReport::default();
                go_rx.await.expect("the bench starts the simulator");
                tokio::select! {
                    served = serve(master, &mut controller, serve_options, |e| report.note(e)) => {
                        served.expect("the simulator serves");
                    }
                    _ = stop_rx => {}
                }
                // The slave end stays open until here so the terminal outlives the streamer.
                drop(slave);
                report
            })
        });
        let path = path_rx.recv().expect("the simulator's terminal");
        (Sim { path, stop, thread }, go)
    }

    /// Stops the simulator and says what it saw.
    fn finish(self) -> SimReport {
        // The simulator may already have finished if something closed the link.
        let _ = self.stop.send(());
        self.thread.join().expect("the simulator thread")
    }
}

/// One whole stream of [`program`] to a simulator with an `rx`-byte receive buffer; the
/// streamer learns the size from `$I`, as it does from a real controller.
fn stream_once(rx: usize) -> StreamOutcome {
    let (sim, go) = Sim::start(rx);
    let dir = tempfile::tempdir().expect("a temporary directory");
    let mut log = ExecLog::append(&dir.path().join("exec.jsonl")).expect("the log");
    let lines = program();
    // The machine check `whirl stream` makes, done here so it runs before the link starts.
    let profile = MachineProfile::builtin_sim().expect("the built-in profile");
    check_program(&lines, &profile).expect("the program fits the sim machine");
    let options = StreamOptions {
        port_name: sim.path.clone(),
        program: "short lines".to_owned(),
        baud: Some(BAUD),
        no_progress_timeout: Some(Duration::from_secs(10)),
        ..StreamOptions::default()
    };
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .expect("a runtime");
    let outcome = runtime
        .block_on(async {
            // Opened as `stream_port` opens it.
            let port = tokio_serial::new(&sim.path, BAUD)
                .open_native_async()
                .expect("the terminal opens");
            go.send(()).expect("the simulator waits");
            stream(port, lines, options, &mut log).await
        })
        .expect("the stream runs");
    let report = sim.finish();
    assert!(outcome.completed(), "{outcome:?}");
    assert_eq!(
        (report.executed, report.overflows, report.alarms),
        (MOVES, 0, 0)
    );
    outcome
}

/// The whole program streamed at 115 200 baud, with grblHAL's 1024-byte receive buffer and
/// an AVR grbl's 128. Prints what the streamer measured.
#[divan::bench(args = [1024, 128], sample_count = 3, sample_size = 1)]
fn stream_115200(bencher: Bencher, rx: usize) {
    bencher.bench_local(|| {
        let outcome = stream_once(rx);
        let acked = outcome.all_acked_at.expect("every line acknowledged");
        let busy = outcome
            .streaming_utilization
            .expect("the baud rate is known");
        eprintln!(
            "rx {rx}: {} lines, {} bytes written, last ack at {:.2} s, link {:.1} % busy \
             while streaming; motion done {:.2} s later",
            outcome.lines_total,
            outcome.bytes_written,
            acked.as_secs_f64(),
            100.0 * busy,
            (outcome.wall_time - acked).as_secs_f64(),
        );
        outcome
    });
}
