//! Every machine of the shop as its bridge last said it on the broker: plain values in
//! (a topic and its payload), the overview's rows out. No socket, no clock.
//!
//! A bridge's messages may come twice (QoS 1 is at least once) and a retained state may
//! be older than what came live: within a bridge's session, a state numbered at or below
//! the last one taken is a redelivery and is skipped. A new session (the bridge started
//! again) starts its numbering afresh.

use std::collections::BTreeMap;

use serde::Serialize;

use crate::telemetry::message::{self, Alarm, Ending, Machine, Progress, Run, State, Status};

/// One machine, as the overview shows it.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct MachineRow {
    /// Its name in topics (`lathe-3`).
    pub topic: String,
    /// Its profile's name, once its bridge said it.
    pub name: Option<String>,
    /// Whether its bridge is connected to the broker.
    pub online: bool,
    /// Why it is offline, as the bridge or its last will says.
    pub offline: Option<String>,
    /// The host its bridge runs on.
    pub bridge: Option<String>,
    /// The bridge's console, to link to.
    pub console: Option<String>,
    /// What the machine does.
    pub state: Option<Machine>,
    /// The run under way, or the last one.
    pub run: Option<Run>,
    /// The active alarm.
    pub alarm: Option<Alarm>,
    /// The feed override, percent.
    pub feed_override: Option<u16>,
    /// How the last run ended.
    pub last: Option<Ending>,
    /// Where the run is, while it runs.
    pub progress: Option<Progress>,
    /// When the state last changed (the bridge's time, UTC).
    pub since: Option<String>,
    #[serde(skip)]
    session: Option<String>,
    #[serde(skip)]
    seq: u64,
}

/// What a message could not be read as.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{topic}: {problem}")]
pub struct Unreadable {
    /// The topic.
    pub topic: String,
    /// What is wrong.
    pub problem: String,
}

/// The shop's machines, by their topic names.
#[derive(Debug, Default)]
pub struct ShopView {
    prefix: String,
    machines: BTreeMap<String, MachineRow>,
}

impl ShopView {
    /// A view of the machines under `prefix` (`whirl`).
    pub fn new(prefix: &str) -> ShopView {
        ShopView {
            prefix: prefix.to_owned(),
            machines: BTreeMap::new(),
        }
    }

    /// The subscriptions that feed it: status, state and progress of every machine.
    pub fn filters(&self) -> [String; 3] {
        [message::STATUS, message::STATE, message::PROGRESS]
            .map(|l| format!("{}/+/{l}", self.prefix))
    }

    /// Takes one message; whether a row changed. A topic outside the view's, or another
    /// level, changes nothing; a payload that does not read is refused, naming the topic.
    pub fn apply(&mut self, topic: &str, payload: &[u8]) -> Result<bool, Unreadable> {
        let Some((machine, level)) = topic
            .strip_prefix(&self.prefix)
            .and_then(|rest| rest.strip_prefix('/'))
            .and_then(|rest| rest.split_once('/'))
        else {
            return Ok(false);
        };
        if machine.is_empty() || level.contains('/') {
            return Ok(false);
        }
        let unreadable = |e: serde_json::Error| Unreadable {
            topic: topic.to_owned(),
            problem: format!("not a whirl {level} message: {e}"),
        };
        let row = || MachineRow {
            topic: machine.to_owned(),
            ..MachineRow::default()
        };
        match level {
            message::STATUS => {
                let status: Status = serde_json::from_slice(payload).map_err(unreadable)?;
                let row = self.machines.entry(machine.to_owned()).or_insert_with(row);
                if row.session.as_ref() != Some(&status.session) && status.online {
                    row.seq = 0;
                    row.session = Some(status.session.clone());
                }
                row.name = Some(status.machine);
                row.online = status.online;
                row.offline =
                    (!status.online).then(|| status.reason.unwrap_or_else(|| "offline".to_owned()));
                row.bridge = Some(status.bridge);
                row.console = status.console;
                Ok(true)
            }
            message::STATE => {
                let state: State = serde_json::from_slice(payload).map_err(unreadable)?;
                let row = self.machines.entry(machine.to_owned()).or_insert_with(row);
                if row.session.as_ref() == Some(&state.session) && state.seq <= row.seq {
                    return Ok(false);
                }
                row.session = Some(state.session);
                row.seq = state.seq;
                row.state = Some(state.state);
                if !matches!(state.state, Machine::Running | Machine::Held) {
                    row.progress = None;
                }
                row.run = state.run;
                row.alarm = state.alarm;
                row.feed_override = state.feed_override;
                row.last = state.last;
                row.since = Some(state.time);
                Ok(true)
            }
            message::PROGRESS => {
                let progress: Progress = serde_json::from_slice(payload).map_err(unreadable)?;
                let row = self.machines.entry(machine.to_owned()).or_insert_with(row);
                if matches!(row.state, Some(Machine::Running | Machine::Held)) {
                    row.progress = Some(progress);
                    Ok(true)
                } else {
                    Ok(false)
                }
            }
            _ => Ok(false),
        }
    }

    /// Every machine, by name.
    pub fn rows(&self) -> Vec<MachineRow> {
        self.machines.values().cloned().collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn status(online: bool, session: &str) -> Vec<u8> {
        serde_json::to_vec(&Status {
            online,
            machine: "Lathe 3".into(),
            bridge: "cell-2".into(),
            pid: 7,
            session: session.into(),
            version: "0.1.0".into(),
            since: "2026-11-28T08:00:00.000Z".into(),
            keepalive_s: 10,
            console: Some("http://cell-2:8480".into()),
            reason: (!online).then(|| "connection lost".to_owned()),
        })
        .unwrap()
    }

    fn state(session: &str, seq: u64, machine: Machine) -> Vec<u8> {
        serde_json::to_vec(&State {
            session: session.into(),
            seq,
            time: format!("2026-11-28T08:00:{seq:02}.000Z"),
            state: machine,
            run: None,
            alarm: None,
            feed_override: None,
            last: None,
        })
        .unwrap()
    }

    fn progress() -> Vec<u8> {
        serde_json::to_vec(&Progress {
            time: "t".into(),
            unit: "lines".into(),
            done: 5,
            total: 10,
            percent: 50.0,
            line: Some(5),
            elapsed_s: 1.0,
            left_s: Some(1.0),
            position: None,
            controller: None,
        })
        .unwrap()
    }

    #[test]
    fn a_machine_comes_online_runs_and_goes_offline() {
        let mut view = ShopView::new("whirl");
        assert!(view
            .apply("whirl/lathe-3/status", &status(true, "a"))
            .unwrap());
        assert!(view
            .apply("whirl/lathe-3/state", &state("a", 1, Machine::Running))
            .unwrap());
        assert!(view.apply("whirl/lathe-3/progress", &progress()).unwrap());
        let row = &view.rows()[0];
        assert_eq!(
            (row.online, row.state, row.console.as_deref()),
            (true, Some(Machine::Running), Some("http://cell-2:8480"))
        );
        assert_eq!(row.progress.as_ref().map(|p| p.percent), Some(50.0));
        assert!(view
            .apply("whirl/lathe-3/status", &status(false, "a"))
            .unwrap());
        let row = &view.rows()[0];
        assert_eq!(
            (row.online, row.offline.as_deref()),
            (false, Some("connection lost"))
        );
    }

    #[test]
    fn a_redelivered_or_older_state_is_skipped_and_a_new_session_counts_afresh() {
        let mut view = ShopView::new("whirl");
        view.apply("whirl/m/state", &state("a", 5, Machine::Held))
            .unwrap();
        assert!(!view
            .apply("whirl/m/state", &state("a", 5, Machine::Held))
            .unwrap());
        assert!(!view
            .apply("whirl/m/state", &state("a", 4, Machine::Running))
            .unwrap());
        assert_eq!(view.rows()[0].state, Some(Machine::Held));
        // The bridge started again: its numbering starts again.
        view.apply("whirl/m/status", &status(true, "b")).unwrap();
        assert!(view
            .apply("whirl/m/state", &state("b", 1, Machine::Idle))
            .unwrap());
        assert_eq!(view.rows()[0].state, Some(Machine::Idle));
    }

    #[test]
    fn progress_shows_only_while_a_run_goes() {
        let mut view = ShopView::new("whirl");
        view.apply("whirl/m/state", &state("a", 1, Machine::Idle))
            .unwrap();
        assert!(!view.apply("whirl/m/progress", &progress()).unwrap());
        view.apply("whirl/m/state", &state("a", 2, Machine::Running))
            .unwrap();
        view.apply("whirl/m/progress", &progress()).unwrap();
        view.apply("whirl/m/state", &state("a", 3, Machine::Idle))
            .unwrap();
        assert_eq!(view.rows()[0].progress, None);
    }

    #[test]
    fn other_topics_change_nothing_and_a_bad_payload_is_refused_by_topic() {
        let mut view = ShopView::new("plant2/whirling");
        assert_eq!(view.filters()[1], "plant2/whirling/+/state");
        for topic in [
            "whirl/m/state",
            "plant2/whirling/m",
            "plant2/whirling/m/event",
            "plant2/whirling//state",
        ] {
            assert!(
                !view.apply(topic, &state("a", 1, Machine::Idle)).unwrap(),
                "{topic}"
            );
        }
        let error = view
            .apply("plant2/whirling/m/state", b"{\"seq\": \"one\"}")
            .unwrap_err();
        assert_eq!(error.topic, "plant2/whirling/m/state");
        assert!(
            error.problem.contains("not a whirl state message"),
            "{error}"
        );
        assert!(view.rows().is_empty());
    }
}
