//! Tests of the bus served on a byte stream, kept apart from the server for length: a host
//! on the other end, clocked by its SYNCs or the wall, idle hosts and failing ports.

use super::*;
use crate::canopen::{BusConfig, DriveEvent, PowerState};
use crate::machine::Machine;
use crate::record::Position;

const MS: Duration = Duration::from_millis(1);
/// The SYNC period the tests' master runs.
const PERIOD: Duration = Duration::from_millis(4);

fn machine() -> Machine {
    crate::machine::test_machines::sim_default()
}

fn bus() -> SharedBus {
    let config = BusConfig::for_machine(
        &machine(),
        [10_000.0, 10_000.0, 1000.0],
        PERIOD,
        Position::default(),
    );
    Arc::new(Mutex::new(Bus::new(config).unwrap()))
}

/// An slcan transmit command.
fn t(id: u16, data: &[u8]) -> String {
    let mut text = format!("t{id:03X}{}", data.len());
    for byte in data {
        text.push_str(&format!("{byte:02X}"));
    }
    text.push('\r');
    text
}

/// The host's end of the port.
struct Host {
    port: tokio::io::DuplexStream,
}

impl Host {
    /// Writes `text` and returns what one read gives back.
    async fn send(&mut self, text: &str) -> String {
        self.port.write_all(text.as_bytes()).await.unwrap();
        self.read().await
    }

    async fn read(&mut self) -> String {
        let mut buf = [0u8; 4096];
        let n = self.port.read(&mut buf).await.unwrap();
        String::from_utf8(buf[..n].to_vec()).unwrap()
    }

    /// Reads until `done` holds for all that came, which it returns.
    async fn read_until(&mut self, done: impl Fn(&str) -> bool) -> String {
        let mut heard = String::new();
        while !done(&heard) {
            heard += &self.read().await;
        }
        heard
    }

    /// An SDO download of `data` (1–4 bytes) to `index`/`sub` of `node`, answered.
    async fn sdo_write(&mut self, node: u16, index: u16, sub: u8, data: &[u8]) {
        let [lo, hi] = index.to_le_bytes();
        let command = 0x23 | ((4 - data.len() as u8) << 2);
        let mut request = [command, lo, hi, sub, 0, 0, 0, 0];
        request[4..4 + data.len()].copy_from_slice(data);
        let answer = self.send(&t(0x600 + node, &request)).await;
        let ok = t(0x580 + node, &[0x60, lo, hi, sub, 0, 0, 0, 0]);
        assert_eq!(answer, format!("z\r{ok}"));
    }

    /// Channel open at 1 Mbit/s, all nodes started, their SYNC period 4 ms (60C2h).
    async fn start(&mut self) {
        assert_eq!(self.send("S8\rO\r").await, "\r\r");
        assert_eq!(self.send(&t(0x000, &[0x01, 0x00])).await, "z\r");
        for node in 1..=3 {
            self.sdo_write(node, 0x60C2, 1, &[4]).await;
            self.sdo_write(node, 0x60C2, 2, &[-3i8 as u8]).await;
        }
    }
}

/// Serves `bus` to the returned host; the server's task returns the events it saw.
fn serving(
    bus: &SharedBus,
    options: ServeOptions,
) -> (Host, tokio::task::JoinHandle<io::Result<Vec<BusEvent>>>) {
    let (host, port) = tokio::io::duplex(64 * 1024);
    let bus = Arc::clone(bus);
    let server = tokio::spawn(async move {
        let mut events = Vec::new();
        serve_slcan(port, bus, options, |e| events.push(e.clone())).await?;
        Ok(events)
    });
    (Host { port: host }, server)
}

fn heartbeats(text: &str, node: u16) -> usize {
    text.matches(&format!("t70{node}1")).count()
}

#[tokio::test(start_paused = true)]
async fn each_sync_is_answered_whole_and_is_one_period() {
    let bus = bus();
    let (mut host, server) = serving(&bus, ServeOptions::default());
    host.start().await;
    host.send(&t(0x080, &[])).await;
    let after_first = lock(&bus).now();
    for _ in 0..20 {
        // 10 ms of wall time between SYNCs, within the hold: only the SYNCs count.
        tokio::time::sleep(10 * MS).await;
        let answer = host.send(&t(0x080, &[])).await;
        // The acknowledgement and each drive's TPDO1 (statusword 0250h: Switch on
        // disabled, remote, voltage enabled; position 0) in one read.
        let tpdo = |node: u16| t(0x180 + node, &[0x50, 0x02, 0, 0, 0, 0]);
        assert_eq!(answer, format!("z\r{}{}{}", tpdo(1), tpdo(2), tpdo(3)));
    }
    assert_eq!(lock(&bus).now(), after_first + 20 * PERIOD);
    drop(host);
    let events = server.await.unwrap().unwrap();
    let blocks: Vec<_> = events
        .iter()
        .filter_map(|e| match e {
            BusEvent::Executed(block) => Some(block),
            _ => None,
        })
        .collect();
    assert_eq!(blocks.len(), 21);
    for pair in blocks.windows(2) {
        assert_eq!(pair[1].start_time, pair[0].end_time);
        let span = Duration::from_secs_f64(pair[1].end_time - pair[1].start_time);
        assert!(span.abs_diff(PERIOD) < Duration::from_nanos(1), "{span:?}");
    }
}

#[tokio::test(start_paused = true)]
async fn heartbeats_run_on_wall_time_without_sync() {
    let bus = bus();
    let (mut host, server) = serving(
        &bus,
        ServeOptions {
            time_scale: 2.0,
            ..ServeOptions::default()
        },
    );
    assert_eq!(host.send("S8\rO\r").await, "\r\r");
    for node in 1..=3 {
        // 1017h = 50 ms.
        host.sdo_write(node, 0x1017, 0, &[50, 0]).await;
    }
    let start = Instant::now();
    let heard = host
        .read_until(|heard| (1..=3).all(|node| heartbeats(heard, node) >= 2))
        .await;
    // Due at 50 and 100 ms of simulated time: 50 ms of wall time at twice real time,
    // give or take a tick. Pre-operational: 7Fh.
    let waited = start.elapsed();
    assert!(waited >= 50 * MS && waited <= 52 * MS, "{waited:?}");
    assert!(heard.contains(&t(0x701, &[0x7F])), "{heard}");
    drop(host);
    server.await.unwrap().unwrap();
}

#[tokio::test(start_paused = true)]
async fn the_wall_clock_takes_over_once_syncs_stop() {
    let bus = bus();
    let (mut host, server) = serving(&bus, ServeOptions::default());
    host.start().await;
    for node in 1..=3 {
        host.sdo_write(node, 0x1017, 0, &[50, 0]).await;
    }
    host.send(&t(0x080, &[])).await;
    let (sync_at, bus_at) = (Instant::now(), lock(&bus).now());
    // Within the hold the bus waits for the next SYNC: no time, no heartbeat.
    tokio::time::sleep(90 * MS).await;
    assert_eq!(lock(&bus).now(), bus_at);
    // Past it, the wall clock runs from the SYNC on: the hold was real time, in which
    // the drives stood. 1017h was written one period before the SYNC's end, so 104 ms
    // have passed on the bus: the heartbeats of 50 and 100 ms come at once.
    let heard = host.read_until(|heard| heartbeats(heard, 3) > 0).await;
    assert!(sync_at.elapsed() >= 100 * MS, "{:?}", sync_at.elapsed());
    assert!((1..=3).all(|node| heartbeats(&heard, node) == 2), "{heard}");
    tokio::time::sleep(10 * MS).await;
    let ran = lock(&bus).now() - bus_at;
    let wall = sync_at.elapsed();
    assert!(ran.abs_diff(wall) <= MS, "{ran:?} in {wall:?}");
    drop(host);
    server.await.unwrap().unwrap();
}

#[tokio::test(start_paused = true)]
async fn a_fault_from_outside_reaches_the_host_at_the_next_tick() {
    let bus = bus();
    let (mut host, server) = serving(&bus, ServeOptions::default());
    host.start().await;
    assert!(lock(&bus).external_fault(1, 0x3210));
    // EMCY 3210h (DC link over-voltage) with the generic error bit, unasked for.
    let heard = host.read().await;
    assert_eq!(heard, t(0x081, &[0x10, 0x32, 0x01, 0, 0, 0, 0, 0]));
    drop(host);
    let events = server.await.unwrap().unwrap();
    assert!(events.iter().any(|e| matches!(
        e,
        BusEvent::Drive {
            node: 1,
            event: DriveEvent::Power {
                state: PowerState::Fault,
                ..
            }
        }
    )));
}

#[tokio::test(start_paused = true)]
async fn a_silent_host_is_left_after_the_idle_time() {
    let bus = bus();
    let options = ServeOptions {
        idle_exit: Some(Duration::from_secs(60)),
        ..ServeOptions::default()
    };
    let (mut host, server) = serving(&bus, options);
    tokio::time::sleep(Duration::from_secs(30)).await;
    assert_eq!(host.send("S8\r").await, "\r");
    let spoke = Instant::now();
    server.await.unwrap().unwrap();
    let waited = spoke.elapsed();
    assert!(waited >= Duration::from_secs(60), "{waited:?}");
    assert!(waited <= Duration::from_secs(60) + 2 * MS, "{waited:?}");
}

#[tokio::test(start_paused = true)]
async fn a_host_that_neither_writes_nor_reads_is_left_after_the_idle_time() {
    let options = ServeOptions {
        idle_exit: Some(Duration::from_secs(1)),
        ..ServeOptions::default()
    };
    // Room for 64 bytes towards the host; heartbeats every millisecond fill it.
    let (mut host, port) = tokio::io::duplex(64);
    let server = tokio::spawn(serve_slcan(port, bus(), options, |_| {}));
    host.write_all(b"S8\rO\r").await.unwrap();
    for node in 1..=3 {
        let heartbeat = t(0x600 + node, &[0x2B, 0x17, 0x10, 0, 1, 0, 0, 0]);
        host.write_all(heartbeat.as_bytes()).await.unwrap();
    }
    let spoke = Instant::now();
    server.await.unwrap().unwrap();
    let waited = spoke.elapsed();
    assert!(waited >= Duration::from_secs(1), "{waited:?}");
    assert!(waited <= Duration::from_secs(1) + 2 * MS, "{waited:?}");
    drop(host);
}

/// A port whose reads fail and whose writes go nowhere.
struct Broken;

impl AsyncRead for Broken {
    fn poll_read(
        self: std::pin::Pin<&mut Self>,
        _: &mut std::task::Context<'_>,
        _: &mut tokio::io::ReadBuf<'_>,
    ) -> std::task::Poll<io::Result<()>> {
        std::task::Poll::Ready(Err(io::ErrorKind::ConnectionReset.into()))
    }
}

impl AsyncWrite for Broken {
    fn poll_write(
        self: std::pin::Pin<&mut Self>,
        _: &mut std::task::Context<'_>,
        buf: &[u8],
    ) -> std::task::Poll<io::Result<usize>> {
        std::task::Poll::Ready(Ok(buf.len()))
    }

    fn poll_flush(
        self: std::pin::Pin<&mut Self>,
        _: &mut std::task::Context<'_>,
    ) -> std::task::Poll<io::Result<()>> {
        std::task::Poll::Ready(Ok(()))
    }

    fn poll_shutdown(
        self: std::pin::Pin<&mut Self>,
        _: &mut std::task::Context<'_>,
    ) -> std::task::Poll<io::Result<()>> {
        std::task::Poll::Ready(Ok(()))
    }
}

#[tokio::test(start_paused = true)]
async fn a_failing_port_ends_serving_with_its_error() {
    let served = serve_slcan(Broken, bus(), ServeOptions::default(), |_| {}).await;
    assert_eq!(served.unwrap_err().kind(), io::ErrorKind::ConnectionReset);
    // A host gone before its answer was written: the write fails.
    let (mut host, port) = tokio::io::duplex(64);
    host.write_all(b"S8\r").await.unwrap();
    drop(host);
    let served = serve_slcan(port, bus(), ServeOptions::default(), |_| {}).await;
    assert_eq!(served.unwrap_err().kind(), io::ErrorKind::BrokenPipe);
}

#[tokio::test(start_paused = true)]
async fn impossible_options_are_refused() {
    let refused = |options: ServeOptions| async move {
        let (_host, port) = tokio::io::duplex(64);
        serve_slcan(port, bus(), options, |_| {}).await.unwrap_err()
    };
    for time_scale in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        let options = ServeOptions {
            time_scale,
            ..ServeOptions::default()
        };
        let error = refused(options).await;
        assert_eq!(error.kind(), io::ErrorKind::InvalidInput);
        assert!(error.to_string().starts_with("time scale"), "{error}");
    }
    let no_tick = ServeOptions {
        tick: Duration::ZERO,
        ..ServeOptions::default()
    };
    assert_eq!(
        refused(no_tick).await.to_string(),
        "the clock tick must be above zero"
    );
    // Finite, but a millisecond of it is more time than a clock holds.
    let too_fast = ServeOptions {
        time_scale: f64::MAX,
        ..ServeOptions::default()
    };
    let error = refused(too_fast).await;
    assert_eq!(error.kind(), io::ErrorKind::InvalidInput);
    assert!(error.to_string().contains("beyond the clock"), "{error}");
}
