//! The CANopen bus served: the [`Bus`]'s slcan adapter on a byte stream (a pseudo-terminal,
//! an in-memory pipe), its clock locked to the master's SYNC.
//!
//! Only bytes and time move here; every decision is the bus's. Host bytes go to
//! [`Bus::receive`] as they arrive, and everything the adapter then has for the host goes
//! back in one write: a master in lockstep reads the acknowledgement of its SYNC and the
//! drives' TPDOs of that cycle together, and would take a reply split across writes for a
//! short one.
//!
//! Time runs two ways ([`Bus::lock_clock_to_sync`]). While the master sends SYNCs, they are
//! the clock: each lets one interpolation period pass on the bus, and wall time does not
//! count, so a master faster or slower than real time still sees cycles of one period.
//! Before the first SYNC, and once none has come for [`ServeOptions::sync_hold`] (the job
//! ended, or the master went away), the wall clock runs the bus instead, scaled by
//! [`ServeOptions::time_scale`], so boot-up, heartbeats and a master's SDO timeouts go on
//! as on real drives. When the wall clock takes over it counts from the last SYNC: the
//! hold was real time in which the drives stood.

use std::io;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::Duration;

use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::time::Instant;

use super::{Bus, BusEvent};

/// A bus shared by the server and whoever else acts on the machine while it serves (a
/// test pulling a cable or faulting a drive).
pub type SharedBus = Arc<Mutex<Bus>>;

/// How the served bus's clock runs and when serving stops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServeOptions {
    /// Simulated seconds per wall second while the wall clock runs the bus; finite and
    /// above zero.
    pub time_scale: f64,
    /// Wall time between clock steps while no bytes come; above zero.
    pub tick: Duration,
    /// Wall time after a SYNC during which the bus waits for the next one rather than
    /// running on the wall clock.
    pub sync_hold: Duration,
    /// Stop serving (Ok) after this much wall time without a byte from the host; `None`:
    /// serve until the host closes the stream.
    pub idle_exit: Option<Duration>,
}

impl Default for ServeOptions {
    /// Real time, a millisecond tick (a heartbeat or a master's timeout is late by at
    /// most that), and a hold of 100 ms: 25 cycles of 4 ms, far beyond a SYNC's jitter,
    /// well within any heartbeat consumer's patience.
    fn default() -> ServeOptions {
        ServeOptions {
            time_scale: 1.0,
            tick: Duration::from_millis(1),
            sync_hold: Duration::from_millis(100),
            idle_exit: None,
        }
    }
}

impl ServeOptions {
    fn check(&self) -> io::Result<()> {
        if !(self.time_scale.is_finite() && self.time_scale > 0.0) {
            return Err(invalid(format!(
                "time scale {} must be finite and above zero",
                self.time_scale
            )));
        }
        if self.tick.is_zero() {
            return Err(invalid("the clock tick must be above zero".to_owned()));
        }
        Ok(())
    }
}

fn invalid(message: String) -> io::Error {
    io::Error::new(io::ErrorKind::InvalidInput, message)
}

/// Serves `bus` on `port` until the host closes it or stays silent for
/// [`ServeOptions::idle_exit`] (Ok), or the port fails (a read or write error) or the
/// options are impossible (Err). Every bus event goes to `on_event`, in order.
///
/// A pseudo-terminal's master end fails its reads (EIO) once no one holds the other end
/// open; whirl-sim keeps it open so hosts can come and go, and a read error here is a real
/// one, as in [`crate::serve::serve`].
pub async fn serve_slcan<P: AsyncRead + AsyncWrite + Unpin>(
    mut port: P,
    bus: SharedBus,
    options: ServeOptions,
    mut on_event: impl FnMut(&BusEvent),
) -> io::Result<()> {
    options.check()?;
    lock(&bus).lock_clock_to_sync();
    let mut clock = Clock::new(Instant::now());
    let mut buf = vec![0u8; 4096];
    let mut last_byte = Instant::now();
    loop {
        let read = tokio::select! {
            read = port.read(&mut buf) => Some(read?),
            () = tokio::time::sleep(options.tick) => None,
        };
        let now = Instant::now();
        let bytes = match read {
            Some(0) => return Ok(()),
            Some(n) => {
                last_byte = now;
                &buf[..n]
            }
            None if options
                .idle_exit
                .is_some_and(|idle| now - last_byte >= idle) =>
            {
                return Ok(())
            }
            None => &[],
        };
        let (output, events) = {
            let mut bus = lock(&bus);
            clock.step(&mut bus, now, bytes, &options)?;
            (bus.take_output(), bus.take_events())
        };
        for event in &events {
            on_event(event);
        }
        let deadline = options.idle_exit.map(|idle| last_byte + idle);
        if !output.is_empty() && !write_before(&mut port, &output, deadline).await? {
            return Ok(());
        }
    }
}

/// Writes `bytes` whole, unless `deadline` (the idle exit) comes first: then false. The
/// drives talk unasked (heartbeats, EMCY), and a pseudo-terminal no one reads fills up and
/// holds the write; a host that neither writes nor reads has gone.
async fn write_before<P: AsyncWrite + Unpin>(
    port: &mut P,
    bytes: &[u8],
    deadline: Option<Instant>,
) -> io::Result<bool> {
    let write = async {
        port.write_all(bytes).await?;
        port.flush().await
    };
    match deadline {
        Some(deadline) => tokio::select! {
            written = write => written.map(|()| true),
            () = tokio::time::sleep_until(deadline) => Ok(false),
        },
        None => write.await.map(|()| true),
    }
}

/// The bus, even if a panicking holder poisoned the lock: its state is whole between
/// calls, and a simulator that stops answering would hide the first failure behind others.
fn lock(bus: &SharedBus) -> MutexGuard<'_, Bus> {
    bus.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Which clock runs the bus: the wall's, or the master's SYNCs (see the module docs).
#[derive(Debug)]
struct Clock {
    /// The wall time the bus has been advanced to (or that the last SYNC stood for).
    caught_up: Instant,
    /// When the last SYNC came.
    last_sync: Option<Instant>,
}

impl Clock {
    fn new(now: Instant) -> Clock {
        Clock {
            caught_up: now,
            last_sync: None,
        }
    }

    /// Wall time up to `now` passes on the bus unless SYNCs hold the clock; then `bytes`
    /// arrive, a SYNC among them taking the clock over.
    fn step(
        &mut self,
        bus: &mut Bus,
        now: Instant,
        bytes: &[u8],
        options: &ServeOptions,
    ) -> io::Result<()> {
        let holding = self
            .last_sync
            .is_some_and(|at| now - at < options.sync_hold);
        if !holding {
            let wall = (now - self.caught_up).as_secs_f64();
            let dt = Duration::try_from_secs_f64(wall * options.time_scale).map_err(|_| {
                invalid(format!(
                    "{wall} s at time scale {} is beyond the clock",
                    options.time_scale
                ))
            })?;
            bus.advance(dt);
            self.caught_up = now;
        }
        let syncs = bus.syncs();
        bus.receive(bytes);
        if bus.syncs() > syncs {
            self.last_sync = Some(now);
            self.caught_up = now;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests;
