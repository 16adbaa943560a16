//! `whirl serve`: the operator's console ([`whirl::console`]) on an address, until a
//! signal ends it. Refused before anything is read or opened if it would listen beyond
//! loopback without an access token. Its runs are recorded in the run records (`--db`,
//! `WHIRL_DB`, else the default): a database it cannot open refuses the start unless
//! `--allow-unrecorded`, and the records a killed console left running are closed when it
//! starts again. A shop's PostgreSQL that cannot be reached keeps the console's runs in
//! its spool on the host, uploaded when each run starts and every [`UPLOAD_EVERY`] while
//! the console serves, once the server answers. Each machine whose profile's `[telemetry]`
//! names `opcua` (or every machine, with `--opcua`) is served as OPC UA for Machine Tools
//! (docs/opcua.md): one server for the machines that name one address, refused before
//! anything listens if its security breaks the rules.

use anyhow::{Context, Result};
use std::future::IntoFuture;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;
use tokio::signal::unix::{signal, SignalKind};
use whirl::config::machine::MachineProfile;
use whirl::config::opcua::{parse_address, OpcUaSettings};
use whirl::config::telemetry::TelemetrySettings;
use whirl::console::gate::Gate;
use whirl::console::http::{self, Edge};
use whirl::console::paths::JobDir;
use whirl::console::record::Records;
use whirl::console::registry::Phase;
use whirl::console::shop::{feed, Shop};
use whirl::console::token::{check_listen, Token};
use whirl::console::{machines, Console};
use whirl::opcua::{Identity, OpcUa};
use whirl::records::{FileSnapshot, Place, Process, Store};
use whirl::telemetry::{Observer, Telemetry};
use whirl::transport::Command;

use crate::terminal::say;

/// How often a console whose records have a spool uploads what it keeps: a console that
/// serves for weeks sends the runs it kept while the shop's database was down soon after
/// it is back, not only when a run starts.
const UPLOAD_EVERY: Duration = Duration::from_secs(60);

/// How long a signal waits for the runs it stops to stand.
const STOP_WAIT: Duration = Duration::from_secs(60);

/// The built-in simulator's profile, as a record keeps it.
const BUILTIN_SIM: (&str, &str) = (
    "machine-profiles/sim.toml (built in)",
    include_str!("../../../machine-profiles/sim.toml"),
);

/// Where and to whom the console listens: `--listen`, `--token`, `--allow-host`.
pub(crate) struct Listen<'a> {
    pub(crate) address: SocketAddr,
    pub(crate) token: Option<&'a str>,
    pub(crate) hosts: &'a [String],
}

/// The console of `profiles` (the built-in simulator's if none) and the jobs under
/// `jobs`, on `listen`, recording its runs in `db` (`--db`; else `WHIRL_DB` or the
/// default), publishing to `--mqtt` and serving OPC UA at `--opcua` if given.
pub(crate) fn run(
    profiles: &[PathBuf],
    jobs: &std::path::Path,
    listen: Listen<'_>,
    (db, allow_unrecorded): (Option<&str>, bool),
    (mqtt, opcua): (Option<&str>, Option<&str>),
) -> Result<ExitCode> {
    let token = listen.token.map(Token::new).transpose()?;
    check_listen(listen.address, token.as_ref())?;
    let mut files = Vec::new();
    let profiles = if profiles.is_empty() {
        let sim = MachineProfile::builtin_sim()?;
        files.push(FileSnapshot::of(BUILTIN_SIM.0, BUILTIN_SIM.1.as_bytes()));
        vec![sim]
    } else {
        let mut loaded = Vec::new();
        for path in profiles {
            loaded.push(MachineProfile::load(path)?);
            let bytes = std::fs::read(path)
                .with_context(|| format!("the machine profile {}", path.display()))?;
            files.push(FileSnapshot::of(path.display().to_string(), &bytes));
        }
        loaded
    };
    let machine_files = profiles.iter().map(|p| p.name.clone()).zip(files).collect();
    let servers = opcua_servers(&profiles, opcua)?;
    let mut telemetry = Vec::new();
    for profile in &profiles {
        let broker = crate::telemetry::settings(profile, mqtt)?;
        let feeds: Vec<_> = servers
            .iter()
            .filter_map(|server| server.feed(&profile.name))
            .collect();
        if broker.is_none() && feeds.is_empty() {
            continue;
        }
        let observer: Option<Observer> = (!feeds.is_empty()).then(|| {
            Box::new(move |out: &_| feeds.iter().for_each(|feed| feed.apply(out))) as Observer
        });
        let settings = broker
            .or_else(|| profile.telemetry.clone())
            .unwrap_or_else(TelemetrySettings::nowhere);
        let started = Telemetry::start_observed(&settings, &profile.name, observer)
            .with_context(|| format!("the machine profile {}", profile.name))?;
        telemetry.push((profile.name.clone(), started));
    }
    let machines = machines(profiles).map_err(anyhow::Error::msg)?;
    let jobs = JobDir::open(jobs)
        .with_context(|| format!("the jobs folder (--jobs) {}", jobs.display()))?;
    let mut console = Console::new(machines, jobs);
    console.machine_files = machine_files;
    console.telemetry = telemetry
        .iter()
        .map(|(name, t)| (name.clone(), t.handle().clone()))
        .collect();
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async move {
        console.records = records(db, allow_unrecorded).await?;
        if let Some(store) = console.records.as_ref().map(|r| r.store.clone()) {
            if store.spool().is_some() {
                tokio::spawn(upload_every(store));
            }
        }
        let console = Arc::new(console);
        whirl::console::remote::take_commands(
            &console,
            token.clone(),
            tokio::runtime::Handle::current(),
        );
        let (listener, address, edge) = bind(&listen, token).await?;
        say!("whirl serve: the console is at http://{address}/ (Ctrl-C ends it)")?;
        for server in &servers {
            say!(
                "whirl serve: OPC UA for Machine Tools at opc.tcp://{}/",
                server.address()
            )?;
        }
        let mut signals = Signals::install()?;
        let (stopped, serving_ends) = tokio::sync::oneshot::channel::<()>();
        let app = http::router(Arc::clone(&console), Arc::clone(&edge));
        let server = tokio::spawn(
            axum::serve(
                listener,
                app.into_make_service_with_connect_info::<SocketAddr>(),
            )
            .with_graceful_shutdown(async move {
                let _ = serving_ends.await;
            })
            .into_future(),
        );
        // The first signal stops every run while the pages still see them stop; only then
        // are the pages told the console is gone, and the server ends.
        let signal = signals.next().await;
        // On standard error: standard output may be a pipe nobody reads any more, and
        // nothing may keep the runs from being stopped.
        eprintln!("whirl serve: {signal}: stopping every run, then ending");
        edge.end_actions();
        stop_runs(&console, &mut signals).await;
        edge.close();
        let _ = stopped.send(());
        server
            .await
            .context("the console's server")?
            .context("the console's server")?;
        // Each machine said offline, after its runs have stopped.
        for (_, telemetry) in telemetry {
            let _ = tokio::task::spawn_blocking(move || telemetry.close()).await;
        }
        for server in servers {
            let _ = tokio::task::spawn_blocking(move || server.close()).await;
        }
        Ok(ExitCode::SUCCESS)
    })
}

/// Listens on `listen`'s address behind a gate of its own (the hosts it answers to, a
/// page key of this start's own) and the token; the address it listens on.
async fn bind(
    listen: &Listen<'_>,
    token: Option<Token>,
) -> Result<(tokio::net::TcpListener, SocketAddr, Arc<Edge>)> {
    let listener = tokio::net::TcpListener::bind(listen.address)
        .await
        .with_context(|| format!("cannot listen on {} (--listen)", listen.address))?;
    let address = listener.local_addr()?;
    let gate = Gate::with_random_key(address, listen.hosts)
        .context("no randomness for the console's page key")?;
    Ok((
        listener,
        address,
        Arc::new(Edge::new(gate, token, address.port())),
    ))
}

/// The overview's broker: `--mqtt`, its login `--mqtt-user` with `$WHIRL_MQTT_PASSWORD`,
/// and over TLS the files `--tls-ca`, `--tls-cert` and `--tls-key` (relative to the working
/// directory).
pub(crate) struct ShopBroker<'a> {
    pub(crate) mqtt: &'a str,
    pub(crate) prefix: &'a str,
    pub(crate) login: (Option<String>, Option<String>),
    pub(crate) tls: [Option<PathBuf>; 3],
}

/// `whirl serve --shop`: the shop overview of the machines publishing under the prefix on
/// the broker, and the history in the run records, until a signal ends it. The broker's
/// address, the prefix, the login and the TLS files are refused before anything listens,
/// naming the option.
pub(crate) fn shop(
    jobs: &std::path::Path,
    listen: Listen<'_>,
    (db, allow_unrecorded): (Option<&str>, bool),
    broker: ShopBroker<'_>,
) -> Result<ExitCode> {
    let token = listen.token.map(Token::new).transpose()?;
    check_listen(listen.address, token.as_ref())?;
    let [tls_ca, tls_cert, tls_key] = broker.tls;
    let (user, password) = broker.login;
    let prefix = broker.prefix;
    let settings = TelemetrySettings {
        prefix: prefix.to_owned(),
        user,
        password,
        tls_ca,
        tls_cert,
        tls_key,
        ..TelemetrySettings::for_broker(broker.mqtt)
    };
    // Each refusal names the option it came from (`tls_ca` is `--tls-ca`).
    let option = |key: &str| match key {
        "mqtt" => "--mqtt".to_owned(),
        "user" => "--mqtt-user".to_owned(),
        "password" => "WHIRL_MQTT_PASSWORD".to_owned(),
        key => format!("--{}", key.replace('_', "-")),
    };
    let refused = |e: whirl::config::telemetry::TelemetryError| {
        anyhow::anyhow!("{}: {}", option(&e.key), e.problem)
    };
    settings.validate().map_err(refused)?;
    let broker = settings
        .broker()
        .map_err(refused)?
        .expect("for_broker names a broker");
    let tls = settings.tls().map_err(refused)?;
    let jobs = JobDir::open(jobs)
        .with_context(|| format!("the jobs folder (--jobs) {}", jobs.display()))?;
    let mut console = Console::new(Default::default(), jobs);
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async move {
        console.records = records(db, allow_unrecorded).await?;
        let shop = Arc::new(Shop::new(prefix, listen.token.map(str::to_owned)));
        let login = settings
            .user
            .clone()
            .map(|user| (user, settings.password.clone().unwrap_or_default()));
        let following = tokio::spawn(feed::follow(Arc::clone(&shop), (broker, tls), login));
        let (listener, address, edge) = bind(&listen, token).await?;
        say!("whirl serve --shop: the shop overview is at http://{address}/ (Ctrl-C ends it)")?;
        let app = whirl::console::shop::page::router(shop, Arc::new(console), Arc::clone(&edge));
        let mut signals = Signals::install()?;
        let serving = axum::serve(
            listener,
            app.into_make_service_with_connect_info::<SocketAddr>(),
        )
        .with_graceful_shutdown(async move {
            let signal = signals.next().await;
            eprintln!("whirl serve --shop: {signal}: ending");
            edge.close();
        });
        serving.await.context("the overview's server")?;
        following.abort();
        Ok(ExitCode::SUCCESS)
    })
}

/// Uploads what the spool keeps every [`UPLOAD_EVERY`], saying on standard error what
/// went, and why nothing could when that changes (not once a minute while the database is
/// down).
async fn upload_every(store: Store) {
    let mut ticks = tokio::time::interval(UPLOAD_EVERY);
    ticks.tick().await;
    let mut said = None;
    loop {
        ticks.tick().await;
        match store.upload().await {
            Ok(uploaded) => {
                said = None;
                for (spooled, id) in uploaded.runs {
                    eprintln!(
                        "whirl serve: run {spooled} kept in the spool uploaded to {} as run {id}",
                        store.place()
                    );
                }
            }
            Err(e) => {
                let now = e.to_string();
                if said.as_ref() != Some(&now) {
                    eprintln!(
                        "warning: {now}: the runs kept in the spool stay there until it answers"
                    );
                    said = Some(now);
                }
            }
        }
    }
}

/// The OPC UA servers for `profiles`: each profile's `[telemetry] opcua`, or `--opcua`
/// (`flag`) for every profile over it, the profiles' other `opcua_*` keys kept. Machines
/// that name one address share its server, and must secure it alike. Each listens before
/// this returns.
fn opcua_servers(profiles: &[MachineProfile], flag: Option<&str>) -> Result<Vec<OpcUa>> {
    let flag = flag
        .map(|text| parse_address(text, "--opcua"))
        .transpose()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut wanted: Vec<(OpcUaSettings, &'static str, Vec<Identity>)> = Vec::new();
    for profile in profiles {
        let telemetry = profile
            .telemetry
            .clone()
            .unwrap_or_else(TelemetrySettings::nowhere);
        let (settings, key) = match flag {
            Some(address) => (telemetry.opcua_at(address, "--opcua"), "--opcua"),
            None => match telemetry.opcua().transpose() {
                Some(settings) => (settings, "opcua"),
                None => continue,
            },
        };
        let settings = settings.map_err(|e| {
            anyhow::anyhow!("the machine profile {}: [telemetry] {e}", profile.name)
        })?;
        let identity = Identity::new(&profile.name, &telemetry.nameplate());
        match wanted
            .iter_mut()
            .find(|(s, ..)| s.address == settings.address)
        {
            Some((same, _, identities)) if *same == settings => identities.push(identity),
            Some((_, _, identities)) => anyhow::bail!(
                "the machine profile {} serves OPC UA at {} as {} does, with other \
                 `opcua_*` keys: machines on one server are secured alike",
                profile.name,
                settings.address,
                identities[0].name
            ),
            None => wanted.push((settings, key, vec![identity])),
        }
    }
    wanted
        .iter()
        .map(|(settings, key, identities)| {
            OpcUa::start(settings, key, identities).context("cannot serve OPC UA")
        })
        .collect()
}

/// SIGINT and SIGTERM, as `whirl serve` hears them.
struct Signals {
    interrupt: tokio::signal::unix::Signal,
    terminate: tokio::signal::unix::Signal,
}

impl Signals {
    fn install() -> Result<Signals> {
        Ok(Signals {
            interrupt: signal(SignalKind::interrupt())?,
            terminate: signal(SignalKind::terminate())?,
        })
    }

    /// The next signal's name.
    async fn next(&mut self) -> &'static str {
        tokio::select! {
            _ = self.interrupt.recv() => "SIGINT",
            _ = self.terminate.recv() => "SIGTERM",
        }
    }
}

/// Stops every run still going, as `whirl stream` does on a signal (held along the path,
/// then ended where it stands, its resume point logged and recorded), and waits for them to
/// end before the process does; a second signal aborts them, as a second Ctrl-C does
/// `whirl stream`'s.
async fn stop_runs(console: &Console, signals: &mut Signals) {
    let running = |console: &Console| {
        console
            .registry
            .views()
            .into_iter()
            .filter(|v| v.phase == Phase::Running)
            .map(|v| v.machine)
            .collect::<Vec<_>>()
    };
    let press = |command: Command| {
        for machine in running(console) {
            let _ = console.registry.press(&machine, command);
        }
    };
    press(Command::Stop {
        reason: "whirl serve ended",
    });
    let ended = async {
        while !running(console).is_empty() {
            tokio::time::sleep(Duration::from_millis(50)).await;
        }
    };
    tokio::pin!(ended);
    let waited = tokio::time::timeout(STOP_WAIT, async {
        tokio::select! {
            () = &mut ended => {}
            signal = signals.next() => {
                eprintln!("whirl serve: {signal} again: aborting every run");
                press(Command::Abort);
                ended.await;
            }
        }
    })
    .await;
    if waited.is_err() {
        eprintln!(
            "whirl serve: runs still going after {STOP_WAIT:?}: {:?}",
            running(console)
        );
    }
}

/// The run records the console keeps, opened (and the runs a console or command killed
/// before left running closed from their logs, said on standard error); `None` if they
/// cannot be opened and `allow_unrecorded` lets the console serve without them.
async fn records(db: Option<&str>, allow_unrecorded: bool) -> Result<Option<Records>> {
    let opened = async {
        let place = Place::resolve(db)?;
        let store = Store::open(&place).await?;
        Ok::<_, anyhow::Error>(Records { place, store })
    }
    .await;
    let records = match opened {
        Ok(records) => records,
        Err(e) if allow_unrecorded => {
            eprintln!("warning: {e:#}: the console's runs are not recorded (--allow-unrecorded)");
            return Ok(None);
        }
        Err(e) => {
            return Err(e.context(
                "whirl serve records every run it starts and could not open the run records; \
                 --allow-unrecorded serves without them",
            ))
        }
    };
    match records.store.uploaded() {
        Some(Ok(uploaded)) => {
            for (spooled, id) in &uploaded.runs {
                eprintln!(
                    "whirl serve: run {spooled} kept in the spool uploaded to {} as run {id}",
                    records.store.place()
                );
            }
        }
        Some(Err(e)) => {
            eprintln!("warning: {e}: the runs kept in the spool stay there until it answers")
        }
        None => {}
    }
    if let Some(why) = records.store.down() {
        eprintln!(
            "warning: {why}: the console's runs are kept in the spool {} until the run \
             records answer",
            records
                .store
                .spool()
                .map_or(String::new(), |f| f.display().to_string())
        );
    }
    match records.store.close_orphans(&Process::current()).await {
        Ok(closed) => {
            for (id, outcome) in closed {
                eprintln!(
                    "warning: run {id} in {} was left running by a process that is gone: \
                     closed as {outcome} (whirl runs show {id})",
                    records.store.place()
                );
            }
        }
        Err(e) => eprintln!("warning: {e}"),
    }
    Ok(Some(records))
}
