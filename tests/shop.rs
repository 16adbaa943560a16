//! A shop at scale: twenty bridges (`whirl serve` consoles, one machine each) publishing to
//! one mosquitto and recording in one PostgreSQL, and the shop overview following them and
//! reading the shop's history from that database. The broker and the database are stopped
//! for 30 s while every machine runs (its runs held and resumed while they are away): every
//! run completes; every event the broker missed arrives after it is back, each once and in
//! order; every run is in the database once, whole (its hold, its resume, its end), uploaded
//! from its bridge's spool, and no spool keeps anything. A bridge killed outright mid-run is
//! shown offline, and its run is closed as interrupted in the database by the next bridge
//! start on its host, while another bridge's run goes on there, untouched.
//!
//! The verdicts are the facts above; nothing here is timed against the host's speed but
//! the generous limits on waiting, each with its reason. The figures (latencies, message
//! rates, the bridges', the broker's and the database's CPU and memory, the database's
//! write and upload rates) are measured by `benches/shop.rs`.

#[path = "console/http.rs"]
mod http;
mod shop {
    pub mod serve;
}
// Shared with the integration tests, some of whose helpers this test does not use.
#[path = "integration/mosquitto.rs"]
#[allow(dead_code)]
mod mosquitto;
#[path = "integration/postgres.rs"]
#[allow(dead_code)]
mod postgres;

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use mosquitto::{on, Got, Mosquitto, Subscriber};
use postgres::private_postgres;
use serde_json::Value;
use shop::serve::{profile, Serve, JOB, KEEPALIVE};
use whirl::records::{Filter, Place, Store};

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

/// The data folder of bridge `n` (or of the overview): its spool is there.
fn home(dir: &Path, n: usize) -> PathBuf {
    dir.join(format!("home-{n:02}"))
}

/// The run the page of `bridge` shows, as its console sees it.
fn view(bridge: &Serve) -> Value {
    bridge.get("/api/runs")[0].clone()
}

/// How many runs the spool `file` keeps (none if it was never made), read as the records
/// database of its own it is.
fn spooled(file: &Path) -> usize {
    if !file.exists() {
        return 0;
    }
    let place = Place::parse(&format!("sqlite://{}?mode=rw", file.display())).unwrap();
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .unwrap()
        .block_on(async {
            let store = Store::open(&place).await.unwrap();
            let runs = store.list(&Filter::default()).await.unwrap().len();
            store.close_connections().await;
            runs
        })
}

#[test]
fn twenty_bridges_share_one_broker_and_one_postgresql_through_their_outage_and_a_bridge_killed_outright(
) {
    let Some(mut broker) = Mosquitto::start() else {
        return;
    };
    let Some(server) = private_postgres() else {
        return;
    };
    let db = server.database();
    let dir = tempfile::tempdir().unwrap();
    let spool = |n: usize| {
        home(dir.path(), n)
            .join("whirl")
            .join(whirl::records::spool::file_name(&db))
    };
    let subscriber = Subscriber::new(&broker, "whirl/#");
    // The overview first: it brings the new database's schema up to date before the
    // bridges start.
    let overview = Serve::start(
        &["--shop", "--mqtt", &broker.url()],
        &db,
        &dir.path().join("home-overview"),
        dir.path(),
    );
    let profiles: Vec<PathBuf> = (0..BRIDGES)
        .map(|n| profile(dir.path(), n, &broker))
        .collect();
    let bridge = |n: usize| {
        Serve::start(
            &["--machine", profiles[n].to_str().unwrap()],
            &db,
            &home(dir.path(), n),
            dir.path(),
        )
    };
    let bridges: Vec<Serve> = (0..BRIDGES).map(bridge).collect();
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
    // twenty starts, each planning the job first, take half a minute here). A start answers
    // once its run's record is open: each in the database, numbered there.
    for (n, bridge) in bridges.iter().enumerate() {
        let body = serde_json::json!({
            "machine": format!("Lathe {n:02}"), "job": JOB, "transport": "serial", "time_scale": 20.0
        });
        let answer = bridge.post("/api/runs", &body.to_string());
        assert_eq!(answer.status, 200, "bridge {n}: {}", answer.body);
    }
    let records: Vec<i64> = bridges
        .iter()
        .map(|b| {
            let view = view(b);
            view["record"]
                .as_i64()
                .unwrap_or_else(|| panic!("not numbered by the database: {view}"))
        })
        .collect();

    // The broker and the database stop together (what the broker has not passed on of the
    // starts waits in the bridges), so that every run's hold, resume and end must go
    // through its bridge's spool: the hold is the first write of its run the database
    // cannot take, which continues the run's record in the spool, and its resume and end
    // follow it there, though the database is back by then. Every run is held and resumed
    // while they are away, each bridge's at once: a hold's answer waits for its note, and a
    // note to a database that is gone waits out the store's bound (POSTGRES_TIMEOUT, 5 s)
    // before it goes to the spool, which twenty bridges in turn would make longer than
    // their runs.
    broker.stop();
    server.stop();
    let stopped = Instant::now();
    std::thread::scope(|scope| {
        for (n, bridge) in bridges.iter().enumerate() {
            scope.spawn(move || {
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
            });
        }
    });
    let away = stopped.elapsed();
    std::thread::sleep(Duration::from_secs(30).saturating_sub(away));
    // Both back while every machine still runs: the database restarted mid-run.
    broker.run();
    server.start_again();
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

    // Every run in the database once, whole, as the overview's history reads it, and no
    // spool keeping anything: each bridge uploads its spool every minute (UPLOAD_EVERY), so
    // the first upload after its run's end brings the hold, the resume and the end its
    // spool kept to the record the database holds, then removes them from the spool.
    let uploaded = |history: &Value| {
        history.as_array().is_some_and(|runs| {
            runs.len() == BRIDGES && runs.iter().all(|r| r["outcome"] != "running")
        }) && (0..BRIDGES).all(|n| spooled(&spool(n)) == 0)
    };
    let waiting = Instant::now();
    let mut history = overview.get("/api/history");
    while !uploaded(&history) {
        assert!(
            waiting.elapsed() < LONG,
            "the spools were not uploaded: {history}"
        );
        std::thread::sleep(Duration::from_secs(1));
        history = overview.get("/api/history");
    }
    let mut listed: Vec<i64> = history
        .as_array()
        .unwrap()
        .iter()
        .map(|r| r["id"].as_i64().unwrap())
        .collect();
    listed.sort_unstable();
    let mut numbered = records.clone();
    numbered.sort_unstable();
    assert_eq!(
        listed, numbered,
        "each run once, by the number it began with"
    );
    for (n, (bridge, id)) in bridges.iter().zip(&records).enumerate() {
        let run = overview.get(&format!("/api/history/{id}"));
        assert_eq!(
            (&run["machine"], &run["outcome"]),
            (
                &Value::from(format!("Lathe {n:02}")),
                &Value::from("completed")
            ),
            "{run}"
        );
        assert!(
            run["ended_at"].as_str() > run["started_at"].as_str(),
            "{run}"
        );
        // The error the bridge measured of its cut, as its page shows it.
        let page = view(bridge);
        assert!(run["measured"]["max_overcut_mm"].is_number(), "{run}");
        for figure in ["max_overcut_mm", "max_undercut_mm", "within_delta"] {
            assert_eq!(run["measured"][figure], page["measured"][figure], "{run}");
        }
        let notes: Vec<(&str, &str)> = run["notes"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|note| note["kind"] != "feed-override")
            .map(|note| {
                (
                    note["kind"].as_str().unwrap(),
                    note["text"].as_str().unwrap(),
                )
            })
            .collect();
        assert!(
            matches!(notes[..], [("hold", held), ("resume", resumed)]
                if held.starts_with("held from the console") && resumed.starts_with("resumed from the console")),
            "{run}"
        );
        // Its end went through the spool and was uploaded from it.
        assert!(
            bridge.said().contains("kept in the spool uploaded to"),
            "lathe {n}: {}",
            bridge.said()
        );
    }

    // A bridge killed outright mid-run, while another bridge's run goes on: offline by its
    // will; its run closed as interrupted in the database by the next bridge start on its
    // host, the other's left running, its process alive.
    let mut bridges = bridges;
    let victim = bridges.remove(0);
    let slow = |n: usize| {
        serde_json::json!({
            "machine": format!("Lathe {n:02}"), "job": JOB, "transport": "serial", "time_scale": 1.0
        })
        .to_string()
    };
    assert_eq!(bridges[0].post("/api/runs", &slow(1)).status, 200);
    assert_eq!(victim.post("/api/runs", &slow(0)).status, 200);
    let (killed_run, going_run) = (
        view(&victim)["record"].clone(),
        view(&bridges[0])["record"].clone(),
    );
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
    let running = overview.get(&format!("/api/history/{killed_run}"));
    assert_eq!(running["outcome"], "running", "{running}");
    let next = bridge(0);
    let history = next.get("/api/history?machine=Lathe%2000");
    let last = &history.as_array().unwrap()[0];
    assert_eq!(
        (&last["id"], &last["outcome"]),
        (&killed_run, &Value::from("interrupted")),
        "{last}"
    );
    let closed = overview.get(&format!("/api/history/{killed_run}"));
    assert!(closed["ended_at"].is_string(), "{closed}");
    assert_eq!(
        closed["notes"].as_array().unwrap().last().unwrap()["kind"],
        "stop",
        "{closed}"
    );
    let going = overview.get(&format!("/api/history/{going_run}"));
    assert_eq!(
        (&going["machine"], &going["outcome"]),
        (&Value::from("Lathe 01"), &Value::from("running")),
        "{going}"
    );
    assert!(going["ended_at"].is_null(), "{going}");
}
