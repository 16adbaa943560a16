//! A shop of twenty bridges on one host, measured (`cargo bench --bench shop`): twenty
//! `whirl serve` bridges, each running the double-start example at 20× real time with a
//! hold and a resume, publishing to one mosquitto and recording in one PostgreSQL, and the
//! shop overview following them.
//!
//! It measures what docs/shop.md reports: the time from a bridge's state message (its
//! `time`, stamped as it is made) to the overview's page (the overview's server-sent event,
//! read here as a page reads it), at p50, p99 and the worst; the messages per second on the
//! broker; each bridge's CPU time and peak memory, the broker's, and the database server's
//! (all its processes, with its connections' and their peak number). Then what the one
//! database takes beyond the shop's needs: twenty writers at once recording runs as fast as
//! it answers (each run opened, held, resumed and closed, as a bridge records one), and a
//! bridge's spool of a thousand runs kept while the server was stopped, uploaded as the next
//! opening of the records does. The server flushes every commit to disk, as a shop's does.
//! Needs mosquitto and PostgreSQL (Debian's); the figures are the host's, not a pass or a
//! fail.

#[path = "../tests/console/http.rs"]
#[allow(dead_code)]
mod http;
#[path = "../tests/integration/mosquitto.rs"]
#[allow(dead_code)]
mod mosquitto;
#[path = "../tests/integration/postgres.rs"]
#[allow(dead_code)]
mod postgres;
#[path = "../tests/shop/serve.rs"]
#[allow(dead_code)]
mod serve;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mosquitto::{Mosquitto, Subscriber};
use postgres::{private_postgres, Postgres};
use serve::{profile, Serve, JOB};
use whirl::records::{Ending, Kind, NewRun, Note, NoteKind, Outcome, Place, Store, Timestamp};

const BRIDGES: usize = 20;
/// The machine time of a run is 1618 s; at 20× it takes 81 s.
const TIME_SCALE: f64 = 20.0;
/// The runs each writer records in the database's write measurement.
const RUNS_EACH: usize = 50;
/// The runs a bridge's spool keeps in the upload measurement: a bridge that cuts a part
/// every few minutes keeps some hundreds in a day the database is away.
const SPOOLED: usize = 1000;

/// A process's CPU time (user and system, s): its own, and that of its children it has
/// waited for (`/proc/PID/stat`'s 14th to 17th fields, in clock ticks, 100 a second on
/// Linux).
fn cpu(pid: u32) -> Option<(f64, f64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    let tick = |i: usize| fields[i].parse::<f64>().ok().map(|t| t / 100.0);
    Some((tick(11)? + tick(12)?, tick(13)? + tick(14)?))
}

/// A field of `/proc/PID/FILE` in KiB (`VmHWM` of `status`, `Pss` of `smaps_rollup`).
fn kib(pid: u32, file: &str, field: &str) -> Option<u64> {
    std::fs::read_to_string(format!("/proc/{pid}/{file}"))
        .ok()?
        .lines()
        .find_map(|l| l.strip_prefix(field)?.strip_prefix(':'))?
        .trim()
        .trim_end_matches(" kB")
        .parse()
        .ok()
}

/// A process's CPU time (s) and peak resident memory (KiB).
fn usage(pid: u32) -> Option<(f64, u64)> {
    Some((cpu(pid)?.0, kib(pid, "status", "VmHWM")?))
}

/// What the database server has taken: its CPU time so far (s: its processes', and that of
/// the connections' processes that have ended, which the postmaster has waited for), the
/// memory its processes hold now (KiB, proportional set sizes, so that the shared buffers
/// all of them map are counted once), and the client connections it serves now.
fn server_usage(server: &Postgres) -> (f64, u64, usize) {
    let processes = server.processes();
    let (mut seconds, mut memory, mut connections) = (0.0, 0, 0);
    for (n, &pid) in processes.iter().enumerate() {
        if let Some((own, children)) = cpu(pid) {
            // The postmaster (first) waits for every process of the server's.
            seconds += own + if n == 0 { children } else { 0.0 };
        }
        memory += kib(pid, "smaps_rollup", "Pss").unwrap_or(0);
        // A connection's process is titled `postgres: USER DATABASE HOST(PORT) STATE`.
        let title = std::fs::read(format!("/proc/{pid}/cmdline")).unwrap_or_default();
        connections += usize::from(String::from_utf8_lossy(&title).contains("127.0.0.1("));
    }
    (seconds, memory, connections)
}

/// Runs `future` on a runtime of the calling thread's: a store's connections live on the
/// runtime that opened them.
fn block_on<F: std::future::Future>(future: F) -> F::Output {
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(future)
}

/// One run as a bridge records it: opened, held, resumed and closed (four writes).
async fn record_run(store: &Store, machine: &str) {
    let mut run = NewRun::new(Kind::Serve);
    run.machine_name = Some(machine.to_owned());
    run.transport = Some("serial".into());
    let recorded = store.begin(&run).await.unwrap();
    for kind in [NoteKind::Hold, NoteKind::Resume] {
        let note = Note {
            line: Some(1200),
            ..Note::new(kind, "from the console")
        };
        store.note(&recorded, &note).await.unwrap();
    }
    store
        .finish(&recorded, &Ending::new(Outcome::Completed))
        .await
        .unwrap();
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    let Some(broker) = Mosquitto::start() else {
        eprintln!("the shop benchmark needs mosquitto (apt-get install mosquitto)");
        return;
    };
    let Some(server) = private_postgres() else {
        eprintln!("the shop benchmark needs PostgreSQL (apt-get install postgresql)");
        return;
    };
    // The database as a shop runs it: every commit flushed to disk (the tests' server is
    // not, for speed).
    server.make_durable();
    let db = server.database();
    let dir = tempfile::tempdir().unwrap();
    // Each whirl serve a data folder of its own, as on a host of its own.
    let home = |name: &str| dir.path().join(name);
    let subscriber = Subscriber::new(&broker, "whirl/#");
    let overview = Serve::start(
        &["--shop", "--mqtt", &broker.url()],
        &db,
        &home("overview"),
        dir.path(),
    );
    // The page: the overview's events, each machine's state time against the arrival.
    let latencies = Arc::new(Mutex::new(Vec::<f64>::new()));
    {
        let latencies = latencies.clone();
        let url = format!("http://{}/api/shop/events", overview.addr);
        std::thread::spawn(move || {
            let response = reqwest::blocking::Client::builder()
                .timeout(None)
                .build()
                .unwrap()
                .get(url)
                .send()
                .unwrap();
            let mut seen: BTreeMap<String, String> = BTreeMap::new();
            for line in BufReader::new(response).lines().map_while(Result::ok) {
                let Some(data) = line.strip_prefix("data:") else {
                    continue;
                };
                let now = Timestamp::now().0;
                let rows: serde_json::Value = serde_json::from_str(data.trim()).unwrap();
                for row in rows.as_array().unwrap() {
                    let (Some(topic), Some(since)) = (row["topic"].as_str(), row["since"].as_str())
                    else {
                        continue;
                    };
                    if seen.get(topic).map(String::as_str) != Some(since) {
                        seen.insert(topic.to_owned(), since.to_owned());
                        let at = Timestamp::parse(since).unwrap().0;
                        latencies.lock().unwrap().push((now - at) as f64 / 1000.0);
                    }
                }
            }
        });
    }
    let bridges: Vec<Serve> = (0..BRIDGES)
        .map(|n| {
            let profile = profile(dir.path(), n, &broker);
            Serve::start(
                &["--machine", profile.to_str().unwrap()],
                &db,
                &home(&format!("lathe-{n:02}")),
                dir.path(),
            )
        })
        .collect();
    std::thread::sleep(Duration::from_secs(2));
    latencies.lock().unwrap().clear();
    let started = Instant::now();
    let server_before = server_usage(&server);
    let before = subscriber.got().len();
    for (n, bridge) in bridges.iter().enumerate() {
        let body = serde_json::json!({
            "machine": format!("Lathe {n:02}"), "job": JOB, "transport": "serial",
            "time_scale": TIME_SCALE
        });
        assert_eq!(bridge.post("/api/runs", &body.to_string()).status, 200);
    }
    // A hold and a resume on each, a while into its run.
    std::thread::sleep(Duration::from_secs(10));
    for (n, bridge) in bridges.iter().enumerate() {
        let path = format!("/api/runs/Lathe%20{n:02}");
        bridge.post(&format!("{path}/hold"), "");
        std::thread::sleep(Duration::from_millis(200));
        bridge.post(&format!("{path}/resume"), "");
    }
    let running = |b: &Serve| {
        b.get("/api/runs")
            .as_array()
            .unwrap()
            .iter()
            .any(|v| v["phase"] == "running")
    };
    let mut usages = vec![(0.0, 0); BRIDGES];
    let mut broker_usage = (0.0, 0);
    let (mut server_memory, mut connections) = (0, 0);
    while bridges.iter().any(running) {
        for (u, b) in usages.iter_mut().zip(&bridges) {
            *u = usage(b.child.id()).unwrap_or(*u);
        }
        broker_usage = broker.pid().and_then(usage).unwrap_or(broker_usage);
        let (_, memory, serving) = server_usage(&server);
        server_memory = server_memory.max(memory);
        connections = connections.max(serving);
        std::thread::sleep(Duration::from_millis(500));
    }
    let wall = started.elapsed().as_secs_f64();
    let server_cpu = server_usage(&server).0 - server_before.0;
    std::thread::sleep(Duration::from_secs(1));
    let messages = subscriber.got().len() - before;
    let mut per_second: BTreeMap<u64, usize> = BTreeMap::new();
    for g in &subscriber.got()[before..] {
        *per_second
            .entry(g.at.duration_since(started).as_secs())
            .or_default() += 1;
    }
    let mut lat = latencies.lock().unwrap().clone();
    lat.sort_by(f64::total_cmp);
    let cpu: Vec<f64> = usages.iter().map(|u| u.0).collect();
    let peak_rss = usages.iter().map(|u| u.1).max().unwrap();
    println!("shop: {BRIDGES} bridges, each the double-start example at {TIME_SCALE}x with a hold and a resume; {wall:.1} s");
    println!(
        "state change -> overview page: {} changes, p50 {:.3} s, p99 {:.3} s, worst {:.3} s",
        lat.len(),
        percentile(&lat, 0.5),
        percentile(&lat, 0.99),
        lat.last().unwrap()
    );
    println!(
        "broker: {messages} messages, {:.1}/s on average, {} in the busiest second; mosquitto {:.2} s CPU, {} KiB peak",
        messages as f64 / wall,
        per_second.values().max().unwrap(),
        broker_usage.0,
        broker_usage.1
    );
    println!(
        "bridges: CPU {:.2} s each on average ({:.1} % of a core), {:.2} s at most; peak memory {} KiB at most",
        cpu.iter().sum::<f64>() / BRIDGES as f64,
        100.0 * cpu.iter().sum::<f64>() / BRIDGES as f64 / wall,
        cpu.iter().cloned().fold(0.0, f64::max),
        peak_rss
    );
    println!(
        "database: PostgreSQL {server_cpu:.2} s CPU ({:.2} % of a core), {} KiB at most (its processes' proportional set sizes), {connections} client connections at most",
        100.0 * server_cpu / wall,
        server_memory
    );

    // How fast the one database records: twenty writers at once, each a store (a bridge's
    // connections) of its own on a thread of its own, all let go together.
    let place = Place::parse(&db).unwrap();
    let gate = Arc::new(std::sync::Barrier::new(BRIDGES + 1));
    let writers: Vec<_> = (0..BRIDGES)
        .map(|n| {
            let (place, gate) = (place.clone(), Arc::clone(&gate));
            std::thread::spawn(move || {
                block_on(async move {
                    let store = Store::open(&place).await.unwrap();
                    gate.wait();
                    for _ in 0..RUNS_EACH {
                        record_run(&store, &format!("Writer {n:02}")).await;
                    }
                    store.close_connections().await;
                })
            })
        })
        .collect();
    gate.wait();
    let (writing, cpu_before) = (Instant::now(), server_usage(&server).0);
    for writer in writers {
        writer.join().unwrap();
    }
    let (written, cpu_writing) = (
        writing.elapsed().as_secs_f64(),
        server_usage(&server).0 - cpu_before,
    );
    let runs = BRIDGES * RUNS_EACH;
    println!(
        "database writes: {BRIDGES} writers at once, {runs} runs (each opened, held, resumed, closed: {} writes) in {written:.2} s: {:.0} runs/s, {:.0} writes/s; PostgreSQL {cpu_writing:.2} s CPU",
        4 * runs,
        runs as f64 / written,
        4.0 * runs as f64 / written
    );

    // A bridge's spool after the database was away: its runs recorded while the server was
    // stopped, uploaded by the first opening of the records once it answers again.
    let spooling = place.with_spool_in(&home("spooling"));
    server.stop();
    let kept = Instant::now();
    block_on(async {
        let store = Store::open(&spooling).await.unwrap();
        assert!(store.down().is_some(), "the server is stopped");
        for _ in 0..SPOOLED {
            record_run(&store, "Lathe spooled").await;
        }
        store.close_connections().await;
    });
    let kept = kept.elapsed().as_secs_f64();
    server.start_again();
    let (uploading, cpu_before) = (Instant::now(), server_usage(&server).0);
    let uploaded = block_on(async {
        let store = Store::open(&spooling).await.unwrap();
        let uploaded = store.uploaded().unwrap().as_ref().unwrap().runs.len();
        store.close_connections().await;
        uploaded
    });
    let (upload, cpu_upload) = (
        uploading.elapsed().as_secs_f64(),
        server_usage(&server).0 - cpu_before,
    );
    assert_eq!(uploaded, SPOOLED);
    println!(
        "spool: {SPOOLED} runs kept in the spool in {kept:.2} s ({:.0} runs/s); uploaded by the next opening in {upload:.2} s ({:.0} runs/s); PostgreSQL {cpu_upload:.2} s CPU",
        SPOOLED as f64 / kept,
        SPOOLED as f64 / upload
    );
}
