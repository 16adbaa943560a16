//! The MQTT edge: a thread of its own that follows the run ([`Tracker`]), keeps what must
//! be delivered ([`Outbox`]) and talks to the broker (rumqttc), so that nothing the broker
//! does (down, slow, refusing the login) reaches the run. The run hands its log events and
//! progress over a bounded channel with `try_send`, which never waits: were the channel
//! ever full, the message is counted as lost and the run goes on.
//!
//! A connection lost is said once (a warning), retried every one to five seconds while
//! the outbox keeps the events, and said again when it is back. A broker over TLS whose
//! certificate does not verify, or that refuses the bridge's, is such a connection lost:
//! said once with what TLS said, and retried, the run going on. The bridge's birth and its
//! last will are retained on `status`, so a bridge that dies is shown offline by the broker
//! once one and a half keep-alives pass without a word from it.
//!
//! The tracker's messages may have a second reader, an [`Observer`] called on the same
//! thread (the OPC UA server's feed, `crate::opcua`), and the broker may be absent
//! (`[telemetry]` without `mqtt`): then the thread only follows the run for its observer.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

use rumqttc::{
    AsyncClient, ConnectionError, Event, LastWill, MqttOptions, Outgoing, Packet, QoS,
    TlsConfiguration, Transport,
};
use tokio::sync::{mpsc, oneshot};
use tokio::time::Instant;

use crate::config::telemetry::{TelemetryError, TelemetrySettings, TlsConfig};
use crate::log::{self, Record, Tap};
use crate::records::{Process, Timestamp};
use crate::telemetry::message::{self, Command, Status};
use crate::telemetry::outbox::{self, Outbox};
use crate::telemetry::tracker::{self, Out, RunContext, Tracker};
use crate::transport::{Progress, ProgressFn};

/// QoS 1 messages out before their acknowledgements.
const WINDOW: usize = 32;
/// What the run may hand over before the thread takes it (it takes it at once).
const INPUTS: usize = 4096;
/// The first wait before a reconnection, and the longest.
const FIRST_RETRY: Duration = Duration::from_secs(1);
const LAST_RETRY: Duration = Duration::from_secs(5);
/// How long a bridge that stops waits for the broker to take what is queued.
pub const CLOSE_WAIT: Duration = Duration::from_secs(3);
/// The largest message: a run's start with its provenance is a few kilobytes.
const MAX_PACKET: usize = 256 * 1024;

/// What the run hands the thread.
#[derive(Debug)]
enum Input {
    Run(RunContext),
    Record(Record),
    Progress(Progress),
}

/// How a bridge's telemetry ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Closed {
    /// Messages the broker had not acknowledged when the bridge stopped.
    pub undelivered: usize,
    /// Messages dropped from a full queue while the broker was away.
    pub dropped: u64,
    /// Log events or progress the thread could not take (its channel full).
    pub lost: u64,
}

/// Another reader of the tracker's messages, called on the telemetry thread with each one
/// as it is made, the machine's first state included. It must not wait: the thread
/// publishes to the broker too.
pub type Observer = Box<dyn Fn(&Out) + Send>;

/// Who publishes: the machine's name and topics, and this bridge.
#[derive(Debug, Clone)]
struct Identity {
    root: String,
    status: Status,
}

/// Why a bridge's telemetry did not start.
#[derive(Debug, thiserror::Error)]
pub enum StartError {
    /// A TLS file that cannot be used, its key and path named. A caller that checked the
    /// settings before its run ([`TelemetrySettings::tls`]) sees this only for a file
    /// changed since.
    #[error("[telemetry] {0}")]
    Tls(#[from] TelemetryError),
    /// The thread could not be made.
    #[error("cannot start the telemetry thread: {0}")]
    Thread(#[from] std::io::Error),
}

/// A bridge's telemetry, publishing from a thread of its own until [`Telemetry::close`].
pub struct Telemetry {
    handle: Handle,
    close: oneshot::Sender<()>,
    thread: std::thread::JoinHandle<Closed>,
}

/// What a run hands its telemetry through: clonable, never waiting.
#[derive(Clone)]
pub struct Handle {
    inputs: mpsc::Sender<Input>,
    lost: Arc<AtomicU64>,
    root: String,
    commands: Commands,
}

/// Who takes the commands that come for the bridge (see [`Handle::on_command`]).
type Commands = Arc<std::sync::Mutex<Option<Box<dyn Fn(Command) + Send>>>>;

impl std::fmt::Debug for Handle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Handle").field("root", &self.root).finish()
    }
}

impl Telemetry {
    /// Starts publishing the machine named `machine` (its profile's name) with `settings`,
    /// which must be valid ([`TelemetrySettings::validate`]: a profile's loading checks
    /// them). The machine is announced online and idle as soon as the broker answers. An
    /// `mqtts://` broker's TLS files are read here, once.
    pub fn start(settings: &TelemetrySettings, machine: &str) -> Result<Telemetry, StartError> {
        Telemetry::start_observed(settings, machine, None)
    }

    /// [`Telemetry::start`], the tracker's messages also handed to `observer`. Without a
    /// broker (`mqtt` absent) nothing is published: the thread follows the run for the
    /// observer alone.
    pub fn start_observed(
        settings: &TelemetrySettings,
        machine: &str,
        observer: Option<Observer>,
    ) -> Result<Telemetry, StartError> {
        let tls = settings.tls()?;
        let session = session_word();
        let identity = Identity {
            root: settings.topic_root(machine),
            status: Status {
                online: true,
                machine: machine.to_owned(),
                bridge: Process::current().host,
                pid: std::process::id(),
                session,
                version: env!("CARGO_PKG_VERSION").to_owned(),
                since: Timestamp::now().to_text(),
                keepalive_s: settings.keepalive_s,
                console: settings.console.clone(),
                reason: None,
            },
        };
        let (inputs, receiver) = mpsc::channel(INPUTS);
        let (close, closing) = oneshot::channel();
        let handle = Handle {
            inputs,
            lost: Arc::new(AtomicU64::new(0)),
            root: identity.root.clone(),
            commands: Commands::default(),
        };
        let settings = settings.clone();
        let lost = handle.lost.clone();
        let commands = handle.commands.clone();
        let thread = std::thread::Builder::new()
            .name("whirl-telemetry".into())
            .spawn(move || {
                let runtime = tokio::runtime::Builder::new_current_thread()
                    .enable_all()
                    .build()
                    .expect("a runtime of one thread builds");
                let mut closed = runtime.block_on(publish(
                    (&settings, tls),
                    identity,
                    receiver,
                    observer.as_ref(),
                    closing,
                    commands,
                ));
                closed.lost = lost.load(Ordering::Relaxed);
                closed
            })?;
        Ok(Telemetry {
            handle,
            close,
            thread,
        })
    }

    /// What runs hand their log events and progress through.
    pub fn handle(&self) -> &Handle {
        &self.handle
    }

    /// Says goodbye (the bridge offline, retained), waits up to [`CLOSE_WAIT`] for the
    /// broker to take what is queued, and ends the thread. It blocks: from async code, call
    /// it on a blocking thread.
    pub fn close(self) -> Closed {
        let _ = self.close.send(());
        let lost = self.handle.lost.clone();
        drop(self.handle);
        self.thread.join().unwrap_or(Closed {
            undelivered: 0,
            dropped: 0,
            lost: lost.load(Ordering::Relaxed),
        })
    }
}

impl Handle {
    /// `PREFIX/MACHINE`, the root of the bridge's topics.
    pub fn root(&self) -> &str {
        &self.root
    }

    /// What the next run's log will not say: its kind, record, job and provenance.
    pub fn prepare(&self, context: RunContext) {
        self.hand(Input::Run(context));
    }

    /// A tap for the run's log (`crate::log::ExecLog::tapped`): the events the tracker
    /// reads go to the thread; the rest (every line sent and acknowledged, every move
    /// executed) never leaves the run.
    pub fn tap(&self) -> Tap {
        let handle = self.clone();
        Tap::new(move |record: &Record| {
            if matters(&record.event) {
                handle.hand(Input::Record(record.clone()));
            }
        })
    }

    /// A progress callback that hands each snapshot to the thread, then calls `then` (the
    /// terminal's bar, the console's page).
    pub fn progress(&self, mut then: Option<ProgressFn>) -> ProgressFn {
        let handle = self.clone();
        Box::new(move |p: &Progress| {
            handle.hand(Input::Progress(p.clone()));
            if let Some(then) = then.as_mut() {
                then(p);
            }
        })
    }

    /// Who takes the commands the broker brings for this bridge (the shop overview's Hold):
    /// `take` is called on the telemetry thread with each, to check its token and act.
    /// Without one, a command is said and dropped.
    pub fn on_command(&self, take: impl Fn(Command) + Send + 'static) {
        *self.commands.lock().unwrap_or_else(|p| p.into_inner()) = Some(Box::new(take));
    }

    /// Hands `input` over without waiting; counted as lost if the channel is full.
    fn hand(&self, input: Input) {
        if self.inputs.try_send(input).is_err() {
            self.lost.fetch_add(1, Ordering::Relaxed);
        }
    }
}

/// Whether the tracker reads this event.
fn matters(event: &log::Event) -> bool {
    !matches!(
        event,
        log::Event::Sent { .. }
            | log::Event::Ack { .. }
            | log::Event::Executed { .. }
            | log::Event::Message { .. }
    )
}

/// A random word naming this start of the bridge (and its MQTT client id).
fn session_word() -> String {
    let mut bytes = [0u8; 8];
    if getrandom::fill(&mut bytes).is_err() {
        // No randomness from the OS: the time and the pid still differ between starts.
        let now = Timestamp::now().0 as u64;
        bytes = (now ^ u64::from(std::process::id()) << 40).to_le_bytes();
    }
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// A live connection: the client that publishes and the events its loop reports.
struct Connection {
    client: AsyncClient,
    events: mpsc::UnboundedReceiver<Result<Event, ConnectionError>>,
    poller: tokio::task::JoinHandle<()>,
}

impl Connection {
    /// Opens a connection (its loop polled on a task of its own, whose events come over a
    /// channel: a loop's poll must not be dropped halfway, a channel's receive may).
    fn open(options: MqttOptions) -> Connection {
        let (client, mut eventloop) = AsyncClient::new(options, WINDOW + 8);
        let (sender, events) = mpsc::unbounded_channel();
        let poller = tokio::spawn(async move {
            loop {
                let event = eventloop.poll().await;
                let failed = event.is_err();
                if sender.send(event).is_err() || failed {
                    return;
                }
            }
        });
        Connection {
            client,
            events,
            poller,
        }
    }

    /// Publishes what the outbox hands out now; one the client's queue cannot take (its loop
    /// busy, or ended: then its error comes) goes back to the outbox, to go first next time.
    fn publish(&self, root: &str, outbox: &mut Outbox) {
        while let Some(m) = outbox.to_send() {
            let qos = if m.acknowledged {
                QoS::AtLeastOnce
            } else {
                QoS::AtMostOnce
            };
            let topic = format!("{root}/{}", m.topic);
            if self
                .client
                .try_publish(topic, qos, m.retain, m.payload.clone())
                .is_err()
            {
                outbox.unsend(m);
                return;
            }
        }
    }
}

impl Drop for Connection {
    fn drop(&mut self) {
        self.poller.abort();
    }
}

/// The next event of the connection, if there is one (else never).
async fn next_event(connection: &mut Option<Connection>) -> Option<Result<Event, ConnectionError>> {
    match connection {
        Some(c) => c.events.recv().await,
        None => std::future::pending().await,
    }
}

/// Sleeps until `at`, or forever if there is no such time.
async fn until(at: Option<Instant>) {
    match at {
        Some(at) => tokio::time::sleep_until(at).await,
        None => std::future::pending().await,
    }
}

/// The thread's work: follow the run, hand its messages to the observer, keep the outbox,
/// hold a connection to the broker (if there is one), over TLS with `tls` if given.
async fn publish(
    (settings, tls): (&TelemetrySettings, Option<TlsConfig>),
    identity: Identity,
    mut inputs: mpsc::Receiver<Input>,
    observer: Option<&Observer>,
    mut closing: oneshot::Receiver<()>,
    commands: Commands,
) -> Closed {
    let broker = settings.broker().expect("telemetry settings are validated");
    let payload = |status: &Status| serde_json::to_vec(status).expect("a status serialises");
    let status = |status: &Status| outbox::Outgoing {
        topic: message::STATUS,
        payload: payload(status),
        acknowledged: true,
        retain: true,
    };
    let will = Status {
        online: false,
        reason: Some("connection lost (the broker's last will for the bridge)".into()),
        ..identity.status.clone()
    };
    let options = broker.map(|broker| {
        let mut options = MqttOptions::new(
            format!("whirl-{}", identity.status.session),
            broker.host,
            broker.port,
        );
        options
            .set_keep_alive(Duration::from_secs(settings.keepalive_s))
            .set_clean_session(true)
            .set_inflight(WINDOW as u16)
            .set_max_packet_size(MAX_PACKET, MAX_PACKET)
            .set_last_will(LastWill::new(
                format!("{}/{}", identity.root, message::STATUS),
                payload(&will),
                QoS::AtLeastOnce,
                true,
            ));
        if let Some(user) = &settings.user {
            options.set_credentials(user, settings.password.clone().unwrap_or_default());
        }
        if let Some(tls) = tls {
            options.set_transport(Transport::tls_with_config(TlsConfiguration::Rustls(tls)));
        }
        options
    });
    let observe = |out: &[Out]| {
        if let Some(observer) = observer {
            out.iter().for_each(observer);
        }
    };
    let started = Instant::now();
    let mut tracker = Tracker::new(&identity.status.session, settings.progress_interval_s);
    let mut outbox = Outbox::new(status(&identity.status), settings.queue, WINDOW);
    let mut said = Said::default();
    let first = vec![Out::State(tracker.state(&Timestamp::now().to_text()))];
    observe(&first);
    take(first, &mut outbox, &mut said);
    let mut connection: Option<Connection> = None;
    let mut retry_at: Option<Instant> = None;
    let mut retry = FIRST_RETRY;
    let mut deadline: Option<Instant> = None;
    let mut inputs_open = true;
    let mut disconnecting = false;
    let url = settings.mqtt.as_deref().unwrap_or_default();
    let command_topic = format!("{}/{}", identity.root, message::COMMAND);
    loop {
        if let Some(options) = &options {
            if connection.is_none() && retry_at.is_none_or(|at| at <= Instant::now()) {
                connection = Some(Connection::open(options.clone()));
                retry_at = None;
            }
        }
        if let Some(c) = &connection {
            c.publish(&identity.root, &mut outbox);
            if deadline.is_some() && outbox.waiting() == 0 && !disconnecting {
                // Said before the socket closes, so the broker drops the last will.
                disconnecting = c.client.try_disconnect().is_ok();
            }
        }
        tokio::select! {
            input = inputs.recv(), if inputs_open => match input {
                Some(input) => {
                    let out = follow(&mut tracker, input, started);
                    observe(&out);
                    take(out, &mut outbox, &mut said);
                }
                None => inputs_open = false,
            },
            _ = &mut closing, if deadline.is_none() => {
                // What the run handed over before it closed comes before the goodbye: the
                // run's end among it (this branch may be taken while inputs wait).
                while let Ok(input) = inputs.try_recv() {
                    let out = follow(&mut tracker, input, started);
                    observe(&out);
                    take(out, &mut outbox, &mut said);
                }
                if options.is_none() {
                    // No broker to wait for.
                    break;
                }
                deadline = Some(Instant::now() + CLOSE_WAIT);
                let goodbye = Status {
                    online: false,
                    reason: Some("the bridge stopped".into()),
                    ..identity.status.clone()
                };
                queue(status(&goodbye), &mut outbox, &mut said);
            }
            event = next_event(&mut connection) => match event {
                Some(Ok(Event::Incoming(Packet::ConnAck(_)))) => {
                    if let Some(c) = &connection {
                        // A clean session keeps no subscription: each connection asks again.
                        let _ = c.client.try_subscribe(&command_topic, QoS::AtLeastOnce);
                    }
                    outbox.connected();
                    retry = FIRST_RETRY;
                    if said.away {
                        // Said as loudly as its going was.
                        tracing::warn!(
                            "telemetry: the broker at {url} answers again; {} queued \
                             messages go now",
                            outbox.waiting()
                        );
                        said.away = false;
                    }
                }
                Some(Ok(Event::Incoming(Packet::PubAck(_)))) => outbox.acked(),
                Some(Ok(Event::Incoming(Packet::Publish(p)))) if p.topic == command_topic => {
                    if let Err(dropped) = take_command(&p.payload, &commands) {
                        tracing::warn!("telemetry: {dropped}");
                    }
                }
                Some(Ok(Event::Outgoing(Outgoing::Disconnect))) => break,
                Some(Ok(_)) => {}
                Some(Err(error)) => {
                    outbox.disconnected();
                    connection = None;
                    disconnecting = false;
                    retry_at = Some(Instant::now() + retry);
                    retry = (retry * 2).min(LAST_RETRY);
                    if !said.away {
                        tracing::warn!(
                            "telemetry: the broker at {url} cannot be reached ({error}); the \
                             run goes on, up to {} events wait for it",
                            settings.queue
                        );
                        said.away = true;
                    }
                }
                None => {
                    outbox.disconnected();
                    connection = None;
                    disconnecting = false;
                    retry_at = Some(Instant::now() + retry);
                }
            },
            _ = until(retry_at), if connection.is_none() => {}
            _ = until(deadline) => break,
        }
    }
    Closed {
        // The goodbye is the last of them; a bridge that could not say it is shown
        // offline by its will.
        undelivered: outbox.waiting(),
        dropped: outbox.dropped(),
        lost: 0,
    }
}

/// A command from the broker, to whoever takes them; why one was dropped: it does not read,
/// or it came to a bridge that takes none.
fn take_command(payload: &[u8], commands: &Commands) -> Result<(), String> {
    let command: Command = serde_json::from_slice(payload)
        .map_err(|e| format!("a command that does not read was dropped: {e}"))?;
    match commands.lock().unwrap_or_else(|p| p.into_inner()).as_ref() {
        Some(take) => {
            take(command);
            Ok(())
        }
        None => Err(format!(
            "a {} from {} was dropped: this bridge takes no remote command (only `whirl \
             serve` does)",
            command.command, command.by
        )),
    }
}

/// What the tracker makes of one input, at the time of its taking.
fn follow(tracker: &mut Tracker, input: Input, started: Instant) -> Vec<Out> {
    let ms = started.elapsed().as_millis() as i64;
    let time = Timestamp::now().to_text();
    match input {
        Input::Run(context) => {
            tracker.prepare(context);
            Vec::new()
        }
        Input::Record(record) => tracker.record(&record, &time),
        Input::Progress(p) => tracker.progress(&p, ms, &time),
    }
}

/// What the thread has said of the broker, so that it says each once.
#[derive(Debug, Default)]
struct Said {
    away: bool,
    full: bool,
}

/// The tracker's messages into the outbox.
fn take(out: Vec<Out>, outbox: &mut Outbox, said: &mut Said) {
    for message in out {
        let topic = tracker::topic(&message);
        let (payload, retain) = match &message {
            Out::State(state) => (serde_json::to_vec(state), true),
            Out::Event(event) => (serde_json::to_vec(event), false),
            Out::Progress(progress) => (serde_json::to_vec(progress), false),
        };
        let outgoing = outbox::Outgoing {
            topic,
            payload: payload.expect("telemetry messages serialise"),
            acknowledged: !matches!(message, Out::Progress(_)),
            retain,
        };
        if outgoing.acknowledged {
            queue(outgoing, outbox, said);
        } else {
            outbox.progress(outgoing);
        }
    }
}

/// One QoS 1 message into the outbox, saying once that the queue overflows.
fn queue(outgoing: outbox::Outgoing, outbox: &mut Outbox, said: &mut Said) {
    if outbox.push(outgoing) && !said.full {
        tracing::warn!(
            "telemetry: the broker has been away so long that its queue is full: the oldest \
             events are dropped (the readers see the gap in `seq`)"
        );
        said.full = true;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_command_goes_to_its_taker_and_is_dropped_unread_or_untaken() {
        let commands = Commands::default();
        let hold = br#"{"command": "hold", "token": "t", "by": "127.0.0.1:4711"}"#;
        let dropped = take_command(hold, &commands).unwrap_err();
        assert!(dropped.contains("takes no remote command"), "{dropped}");
        let taken = Arc::new(std::sync::Mutex::new(Vec::new()));
        let kept = taken.clone();
        *commands.lock().unwrap() = Some(Box::new(move |c: Command| kept.lock().unwrap().push(c)));
        take_command(hold, &commands).unwrap();
        assert_eq!(taken.lock().unwrap()[0].by, "127.0.0.1:4711");
        let dropped = take_command(b"{\"command\": 1}", &commands).unwrap_err();
        assert!(dropped.contains("does not read"), "{dropped}");
        assert_eq!(taken.lock().unwrap().len(), 1);
    }
}
