//! `--mqtt` and a profile's `[telemetry]`: the live telemetry of a command's run, started
//! before the run and closed after it (docs/shop.md).

use anyhow::Result;
use whirl::config::machine::MachineProfile;
use whirl::config::telemetry::TelemetrySettings;
use whirl::log::ExecLog;
use whirl::telemetry::{RunContext, Telemetry};
use whirl::transport::ProgressFn;

use crate::terminal::warn;

/// The settings a run publishes with: the profile's `[telemetry]` with `--mqtt` over its
/// broker (its `tls_*` keys kept for an `mqtts://` one), or `--mqtt` alone; `None` for no
/// broker. A bad `--mqtt` is refused here, before anything is opened, and so are TLS files
/// that cannot be used (read here for that, and again when the telemetry starts).
pub(crate) fn settings(
    machine: &MachineProfile,
    mqtt: Option<&str>,
) -> Result<Option<TelemetrySettings>> {
    let settings = match (&machine.telemetry, mqtt) {
        (Some(profile), Some(url)) => profile.clone().with_broker(url),
        (None, Some(url)) => TelemetrySettings::for_broker(url),
        (Some(profile), None) if profile.mqtt.is_some() => profile.clone(),
        // A `[telemetry]` with `opcua` alone: only `whirl serve` serves it.
        (_, None) => return Ok(None),
    };
    if let (Some(_), Err(e)) = (mqtt, settings.broker()) {
        anyhow::bail!("--mqtt: {}", e.problem);
    }
    if let Err(e) = settings.tls() {
        anyhow::bail!("the machine profile {}: [telemetry] {e}", machine.name);
    }
    Ok(Some(settings))
}

/// A run's telemetry, while it runs.
pub(crate) struct Live(Telemetry);

impl Live {
    /// Starts publishing `machine` with `settings`, for a run of `context`.
    pub(crate) fn start(
        settings: &TelemetrySettings,
        machine: &MachineProfile,
        context: RunContext,
    ) -> Result<Live> {
        let telemetry = Telemetry::start(settings, &machine.name)?;
        telemetry.handle().prepare(context);
        Ok(Live(telemetry))
    }

    /// The run's log, its events seen by the telemetry too.
    pub(crate) fn tap(&self, log: ExecLog) -> ExecLog {
        log.tapped(self.0.handle().tap())
    }

    /// The run's progress callback, `then` called after the telemetry has it.
    pub(crate) fn progress(&self, then: Option<ProgressFn>) -> Option<ProgressFn> {
        Some(self.0.handle().progress(then))
    }

    /// Says goodbye and waits a moment for the broker; says what it could not deliver.
    pub(crate) fn close(self) {
        let root = self.0.handle().root().to_owned();
        let closed = self.0.close();
        if closed.undelivered > 0 || closed.dropped > 0 || closed.lost > 0 {
            warn(&format!(
                "telemetry under {root}: {} messages not taken by the broker, {} dropped from \
                 a full queue, {} lost; the run's record and log keep everything",
                closed.undelivered, closed.dropped, closed.lost
            ));
        }
    }
}
