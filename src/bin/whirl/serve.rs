//! `whirl serve`: the operator's console ([`whirl::console`]) on an address, until a
//! signal ends it. Refused before anything is read or opened if it would listen beyond
//! loopback without an access token.

use anyhow::{Context, Result};
use std::net::SocketAddr;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Duration;
use tokio::signal::unix::{signal, SignalKind};
use whirl::config::machine::MachineProfile;
use whirl::console::paths::JobDir;
use whirl::console::registry::Phase;
use whirl::console::token::{check_listen, Token};
use whirl::console::{http, machines, Console};
use whirl::transport::Command;

use crate::terminal::say;

/// How long a signal waits for the runs it stops to stand.
const STOP_WAIT: Duration = Duration::from_secs(60);

/// The console of `profiles` (the built-in simulator's if none) and the jobs under
/// `jobs`, on `listen`.
pub(crate) fn run(
    profiles: &[PathBuf],
    jobs: &std::path::Path,
    listen: SocketAddr,
    token: Option<&str>,
) -> Result<ExitCode> {
    let token = token.map(Token::new).transpose()?;
    check_listen(listen, token.as_ref())?;
    let profiles = if profiles.is_empty() {
        vec![MachineProfile::builtin_sim()?]
    } else {
        profiles
            .iter()
            .map(|p| MachineProfile::load(p))
            .collect::<Result<_, _>>()?
    };
    let machines = machines(profiles).map_err(anyhow::Error::msg)?;
    let jobs = JobDir::open(jobs)
        .with_context(|| format!("the jobs folder (--jobs) {}", jobs.display()))?;
    let console = Arc::new(Console::new(machines, jobs, token));
    let runtime = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()?;
    runtime.block_on(async {
        let listener = tokio::net::TcpListener::bind(listen)
            .await
            .with_context(|| format!("cannot listen on {listen} (--listen)"))?;
        let address = listener.local_addr()?;
        say!("whirl serve: the console is at http://{address}/ (Ctrl-C ends it)")?;
        let mut interrupt = signal(SignalKind::interrupt())?;
        let mut terminate = signal(SignalKind::terminate())?;
        let shutdown = async move {
            tokio::select! {
                _ = interrupt.recv() => {},
                _ = terminate.recv() => {},
            }
        };
        axum::serve(listener, http::router(Arc::clone(&console)))
            .with_graceful_shutdown(shutdown)
            .await
            .context("the console's server")?;
        stop_runs(&console).await;
        Ok(ExitCode::SUCCESS)
    })
}

/// Stops every run still going, as `whirl stream` does on a signal, and waits for them to
/// stand (the machine held, where to resume said) before the process ends.
async fn stop_runs(console: &Console) {
    let running = |console: &Console| {
        console
            .registry
            .views()
            .into_iter()
            .filter(|v| v.phase == Phase::Running)
            .map(|v| v.machine)
            .collect::<Vec<_>>()
    };
    for machine in running(console) {
        let _ = console.registry.press(
            &machine,
            Command::Stop {
                reason: "whirl serve ended",
            },
        );
    }
    let waited = tokio::time::timeout(STOP_WAIT, async {
        while !running(console).is_empty() {
            tokio::time::sleep(Duration::from_millis(50)).await;
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
