//! A shop of twenty bridges on one host, measured (`cargo bench --bench shop`): twenty
//! `whirl serve` bridges, each running the double-start example at 20× real time with a
//! hold and a resume, publishing to one mosquitto and recording in one database, and the
//! shop overview following them.
//!
//! It measures what docs/shop.md reports: the time from a bridge's state message (its
//! `time`, stamped as it is made) to the overview's page (the overview's server-sent event,
//! read here as a page reads it), at p50, p99 and the worst; the messages per second on the
//! broker; each bridge's CPU time and peak memory, and the broker's. Needs mosquitto
//! (Debian's); the figures are the host's, not a pass or a fail.

#[path = "../tests/console/http.rs"]
#[allow(dead_code)]
mod http;
#[path = "../tests/integration/mosquitto.rs"]
#[allow(dead_code)]
mod mosquitto;
#[path = "../tests/shop/serve.rs"]
mod serve;

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use mosquitto::{Mosquitto, Subscriber};
use serve::{profile, Serve, JOB};
use whirl::records::Timestamp;

const BRIDGES: usize = 20;
/// The machine time of a run is 1618 s; at 20× it takes 81 s.
const TIME_SCALE: f64 = 20.0;

/// A process's CPU time (user and system, s) and peak resident memory (KiB), from /proc.
fn usage(pid: u32) -> Option<(f64, u64)> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    let fields: Vec<&str> = stat.rsplit_once(')')?.1.split_whitespace().collect();
    // utime and stime are the 14th and 15th fields, in clock ticks (100 a second on Linux).
    let ticks: f64 = fields[11].parse::<f64>().ok()? + fields[12].parse::<f64>().ok()?;
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let peak = status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))?
        .trim()
        .trim_end_matches(" kB")
        .parse()
        .ok()?;
    Some((ticks / 100.0, peak))
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

fn main() {
    let Some(broker) = Mosquitto::start() else {
        eprintln!("the shop benchmark needs mosquitto (apt-get install mosquitto)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("shop.sqlite");
    let subscriber = Subscriber::new(&broker, "whirl/#");
    let overview = Serve::start(&["--shop", "--mqtt", &broker.url()], &db, dir.path());
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
            Serve::start(&["--machine", profile.to_str().unwrap()], &db, dir.path())
        })
        .collect();
    std::thread::sleep(Duration::from_secs(2));
    latencies.lock().unwrap().clear();
    let started = Instant::now();
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
    while bridges.iter().any(running) {
        for (u, b) in usages.iter_mut().zip(&bridges) {
            *u = usage(b.child.id()).unwrap_or(*u);
        }
        broker_usage = broker.pid().and_then(usage).unwrap_or(broker_usage);
        std::thread::sleep(Duration::from_millis(500));
    }
    let wall = started.elapsed().as_secs_f64();
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
}
