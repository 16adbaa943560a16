//! A shop at scale: twenty bridges (`whirl serve` consoles, one machine each) publishing to
//! one mosquitto and recording in one database, and the shop overview following them. The
//! broker is stopped for 30 s while every machine runs (its runs held and resumed while it
//! is away): every run completes, and every event the broker missed arrives after it is
//! back, each once and in order. A bridge killed outright mid-run is
//! shown offline, and its run is closed as interrupted by the next bridge start.
//!
//! The verdicts are the facts above; nothing here is timed against the host's speed but
//! the generous limits on waiting, each with its reason. The figures (latencies, message
//! rates, the bridges' CPU and memory) are measured by `benches/shop.rs`.

#[path = "console/http.rs"]
mod http;
mod shop {
    pub mod serve;
}
// Shared with the integration tests, some of whose helpers this test does not use.
#[path = "integration/mosquitto.rs"]
#[allow(dead_code)]
mod mosquitto;

use std::time::{Duration, Instant};

use mosquitto::{on, Got, Mosquitto, Subscriber};
use serde_json::Value;
use shop::serve::{profile, Serve, JOB, KEEPALIVE};

const BRIDGES: usize = 20;
/// A limit on waiting for what takes seconds: twenty bridges planning at once on a
/// two-core host take a minute; the rest is margin for a busy CI host.
const LONG: Duration = Duration::from_secs(300);

fn topic(n: usize) -> String {
    format!("whirl/lathe-{n:02}")
}

/// The messages of machine `n` at `level`.
fn of<'a>(got: &'a [Got], n: usize, level: &str) -> Vec<&'a Got> {
    let prefix = format!("{}/", topic(n));
    on(got, level)
        .into_iter()
        .filter(|g| g.topic.starts_with(&prefix))
        .collect()
}

fn kinds(got: &[Got], n: usize) -> Vec<String> {
    of(got, n, "event")
        .iter()
        .map(|g| g.json["kind"].as_str().unwrap().to_owned())
        .filter(|k| k != "feed_override")
        .collect()
}

fn press(bridge: &Serve, machine: &str, button: &str) {
    let path = format!("/api/runs/{}/{button}", machine.replace(' ', "%20"));
    let answer = bridge.post(&path, "");
    assert_eq!(answer.status, 200, "{machine} {button}: {}", answer.body);
}

#[test]
fn twenty_bridges_share_one_broker_through_its_outage_and_a_bridge_killed_outright() {
    let Some(mut broker) = Mosquitto::start() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let db = dir.path().join("shop.sqlite");
    let subscriber = Subscriber::new(&broker, "whirl/#");
    let overview = Serve::start(&["--shop", "--mqtt", &broker.url()], &db, dir.path());
    let bridges: Vec<Serve> = (0..BRIDGES)
        .map(|n| {
            let profile = profile(dir.path(), n, &broker);
            Serve::start(&["--machine", profile.to_str().unwrap()], &db, dir.path())
        })
        .collect();
    let online = subscriber.wait(LONG, |got| {
        (0..BRIDGES).all(|n| {
            of(got, n, "status")
                .iter()
                .any(|g| g.json["online"] == true)
        })
    });
    assert!(
        (0..BRIDGES).all(|n| !of(&online, n, "status").is_empty()),
        "every bridge online"
    );

    // Every machine runs the example at 20 times real time (81 s of wall time each: the
    // twenty starts, each planning the job first, take half a minute here).
    for (n, bridge) in bridges.iter().enumerate() {
        let body = serde_json::json!({
            "machine": format!("Lathe {n:02}"), "job": JOB, "transport": "serial", "time_scale": 20.0
        });
        let answer = bridge.post("/api/runs", &body.to_string());
        assert_eq!(answer.status, 200, "bridge {n}: {}", answer.body);
    }

    // The broker stops (what it has not passed on of the starts waits in the bridges);
    // every run is held and resumed while it is away.
    broker.stop();
    let stopped = Instant::now();
    for (n, bridge) in bridges.iter().enumerate() {
        let machine = format!("Lathe {n:02}");
        press(bridge, &machine, "hold");
        let held = Instant::now();
        // grbl's `Hold:0`: the hold complete, the machine at rest.
        while bridge
            .get("/api/runs")
            .as_array()
            .unwrap()
            .iter()
            .all(|v| v["state"] != "Hold:0")
        {
            assert!(held.elapsed() < LONG, "{machine} never held");
            std::thread::sleep(Duration::from_millis(50));
        }
        press(bridge, &machine, "resume");
    }
    let away = stopped.elapsed();
    std::thread::sleep(Duration::from_secs(30).saturating_sub(away));
    broker.run();
    let ended = |bridge: &Serve| {
        bridge
            .get("/api/runs")
            .as_array()
            .unwrap()
            .iter()
            .all(|v| v["phase"] != "running")
    };
    let waiting = Instant::now();
    while !bridges.iter().all(ended) {
        assert!(waiting.elapsed() < LONG, "the runs did not end");
        std::thread::sleep(Duration::from_millis(200));
    }

    // Every event arrives, each once and in order.
    let got = subscriber.wait(LONG, |got| {
        (0..BRIDGES).all(|n| kinds(got, n).last().map(String::as_str) == Some("end"))
    });
    for n in 0..BRIDGES {
        let mut events = kinds(&got, n);
        events.dedup();
        assert_eq!(events, ["start", "hold", "resume", "end"], "lathe {n}");
        let mut seqs: Vec<u64> = of(&got, n, "event")
            .iter()
            .chain(&of(&got, n, "state"))
            .map(|g| g.json["seq"].as_u64().unwrap())
            .collect();
        seqs.sort_unstable();
        seqs.dedup();
        assert_eq!(
            seqs,
            (1..=seqs.len() as u64).collect::<Vec<_>>(),
            "lathe {n}: none missed"
        );
        let end = of(&got, n, "event")
            .into_iter()
            .rev()
            .find(|g| g.json["kind"] == "end")
            .unwrap();
        assert_eq!(end.json["completed"], true, "lathe {n}");
    }
    // The overview has every machine, idle, its last run completed.
    let rows = overview.get("/api/shop");
    let rows = rows.as_array().unwrap();
    assert_eq!(rows.len(), BRIDGES, "{rows:?}");
    for row in rows {
        assert_eq!(
            (&row["online"], &row["state"]),
            (&Value::from(true), &Value::from("idle")),
            "{row}"
        );
        assert_eq!(row["last"]["completed"], true, "{row}");
    }

    // A bridge killed outright mid-run: offline by its will, its run closed as interrupted
    // by the next bridge's start.
    let mut bridges = bridges;
    let victim = bridges.remove(0);
    let body = serde_json::json!({"machine": "Lathe 00", "job": JOB, "transport": "serial", "time_scale": 1.0});
    assert_eq!(victim.post("/api/runs", &body.to_string()).status, 200);
    let runs_before = subscriber.got().len();
    subscriber.wait(LONG, |got| {
        got[runs_before..]
            .iter()
            .any(|g| g.topic == "whirl/lathe-00/event" && g.json["kind"] == "start")
    });
    let mut victim = victim;
    victim.child.kill().unwrap();
    let killed = Instant::now();
    victim.child.wait().unwrap();
    let got = subscriber.wait(LONG, |got| {
        of(got, 0, "status")
            .last()
            .is_some_and(|g| g.json["online"] == false)
    });
    let will = of(&got, 0, "status").last().copied().unwrap().clone();
    assert!(
        will.json["reason"].as_str().unwrap().contains("last will"),
        "{will:?}"
    );
    // MQTT 3.1.1 §3.1.2.10: at the latest 1.5 keep-alives; mosquitto looks once a second.
    assert!(
        will.at.duration_since(killed) <= Duration::from_secs_f64(1.5 * KEEPALIVE as f64 + 1.0)
    );
    let next = Serve::start(
        &[
            "--machine",
            profile(dir.path(), 0, &broker).to_str().unwrap(),
        ],
        &db,
        dir.path(),
    );
    let history = next.get("/api/history?machine=Lathe%2000");
    let last = &history.as_array().unwrap()[0];
    assert_eq!(last["outcome"], "interrupted", "{last}");
}
