//! The Modbus front-end served: a [`Bank`] behind tokio-modbus's TCP or RTU server, its
//! clock advanced in simulated time.
//!
//! Only bytes and time move here. tokio-modbus frames the requests and answers; each request
//! goes to the bank under a lock, and a clock task advances the bank by the wall time
//! elapsed times the time scale. Events (lines answered, blocks executed, alarms) are handed
//! to the caller's `on_event` from the clock task, so the caller sees them in order.

use super::{Bank, Exception, Request, Response};
use crate::Event;
use std::future::{ready, Ready};
use std::io;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio_modbus::server::Service;
use tokio_modbus::{ExceptionCode, SlaveRequest};

/// The unit id the map serves (`docs/modbus.md`); requests to others get no answer, as on
/// a shared RTU line.
pub const UNIT_ID: u8 = 1;

/// A bank shared by the server's connection and the clock.
pub type SharedBank = Arc<Mutex<Bank>>;

/// How the served bank's clock runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClockOptions {
    /// Simulated seconds per wall second.
    pub time_scale: f64,
    /// Wall time between clock steps.
    pub tick: Duration,
    /// Stop serving (Ok) after this much wall time without a request; `None`: never.
    pub idle_exit: Option<Duration>,
    /// The most wall time one clock step counts; `None`: all of it. For a bank served in
    /// the same process as its client (a dry run): when the host does not run the process
    /// for a while, neither the client nor the controller ran, and the controller must not
    /// count that time against the client (its watchdog would trip at a high time scale
    /// because the host was busy). A bank in a process of its own counts every wall second:
    /// its client may really have stopped.
    pub max_step: Option<Duration>,
}

impl Default for ClockOptions {
    fn default() -> ClockOptions {
        ClockOptions {
            time_scale: 1.0,
            tick: Duration::from_millis(2),
            idle_exit: None,
            max_step: None,
        }
    }
}

/// tokio-modbus's view of the bank.
#[derive(Clone)]
struct Front {
    bank: SharedBank,
    /// When the last request came, for [`ClockOptions::idle_exit`].
    last_request: Arc<Mutex<tokio::time::Instant>>,
}

impl Front {
    fn new(bank: &SharedBank) -> Front {
        Front {
            bank: Arc::clone(bank),
            last_request: Arc::new(Mutex::new(tokio::time::Instant::now())),
        }
    }
}

impl Service for Front {
    type Request = SlaveRequest<'static>;
    type Response = Option<tokio_modbus::Response>;
    type Exception = ExceptionCode;
    type Future = Ready<Result<Self::Response, Self::Exception>>;

    fn call(&self, req: Self::Request) -> Self::Future {
        *self
            .last_request
            .lock()
            .unwrap_or_else(|poisoned| poisoned.into_inner()) = tokio::time::Instant::now();
        if req.slave != UNIT_ID {
            return ready(Ok(None));
        }
        let request = match req.request {
            tokio_modbus::Request::ReadHoldingRegisters(address, count) => {
                Request::ReadHolding { address, count }
            }
            tokio_modbus::Request::WriteSingleRegister(address, value) => {
                Request::WriteSingle { address, value }
            }
            tokio_modbus::Request::WriteMultipleRegisters(address, values) => {
                Request::WriteMultiple {
                    address,
                    values: values.into_owned(),
                }
            }
            other => Request::Other {
                function: function_code(&other),
            },
        };
        let answer = lock(&self.bank).request(&request);
        ready(answer.map(|r| Some(to_wire(r))).map_err(to_exception))
    }
}

/// The bank, even if a panicking holder poisoned the lock: its state is whole between
/// calls, and a simulator that stops answering would hide the first failure behind others.
fn lock(bank: &SharedBank) -> std::sync::MutexGuard<'_, Bank> {
    bank.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

fn function_code(request: &tokio_modbus::Request<'_>) -> u8 {
    request.function_code().value()
}

fn to_wire(response: Response) -> tokio_modbus::Response {
    match response {
        Response::ReadHolding(values) => tokio_modbus::Response::ReadHoldingRegisters(values),
        Response::WriteSingle { address, value } => {
            tokio_modbus::Response::WriteSingleRegister(address, value)
        }
        Response::WriteMultiple { address, count } => {
            tokio_modbus::Response::WriteMultipleRegisters(address, count)
        }
    }
}

fn to_exception(exception: Exception) -> ExceptionCode {
    match exception {
        Exception::IllegalFunction => ExceptionCode::IllegalFunction,
        Exception::IllegalDataAddress => ExceptionCode::IllegalDataAddress,
        Exception::IllegalDataValue => ExceptionCode::IllegalDataValue,
        Exception::ServerDeviceFailure => ExceptionCode::ServerDeviceFailure,
        Exception::ServerDeviceBusy => ExceptionCode::ServerDeviceBusy,
    }
}

/// Advances `bank` in simulated time, handing its events to `on_event`, until the client
/// has been silent for [`ClockOptions::idle_exit`].
async fn run_clock(
    front: Front,
    clock: ClockOptions,
    mut on_event: impl FnMut(&Event),
) -> io::Result<()> {
    let bank = front.bank;
    let mut last = tokio::time::Instant::now();
    loop {
        tokio::time::sleep(clock.tick).await;
        if let Some(idle) = clock.idle_exit {
            let since = *front
                .last_request
                .lock()
                .unwrap_or_else(|poisoned| poisoned.into_inner());
            if since.elapsed() >= idle {
                return Ok(());
            }
        }
        let now = tokio::time::Instant::now();
        let wall = clock
            .max_step
            .map_or(now - last, |most| (now - last).min(most));
        let dt = wall.as_secs_f64() * clock.time_scale;
        last = now;
        let events = {
            let mut bank = lock(&bank);
            bank.advance(dt)
                .map_err(|e| io::Error::other(e.to_string()))?;
            bank.take_events()
        };
        for e in &events {
            on_event(e);
        }
    }
}

/// Serves `bank` on Modbus TCP connections accepted from `listener` until the client has
/// been silent for [`ClockOptions::idle_exit`], the clock fails (a bad time step) or
/// accepting does; every event goes to `on_event`.
pub async fn serve_tcp(
    listener: tokio::net::TcpListener,
    bank: SharedBank,
    clock: ClockOptions,
    on_event: impl FnMut(&Event),
) -> io::Result<()> {
    let server = tokio_modbus::server::tcp::Server::new(listener);
    let front = Front::new(&bank);
    let on_connected = |stream, _addr| {
        let front = front.clone();
        async move { Ok(Some((front, stream))) }
    };
    let on_error = |error: io::Error| report_connection_end(&error);
    tokio::select! {
        served = server.serve(&on_connected, on_error) => served,
        clocked = run_clock(front.clone(), clock, on_event) => clocked,
    }
}

/// Serves `bank` as a Modbus RTU server on `serial` (a pseudo-terminal or a serial port)
/// until the line fails or the clock does.
pub async fn serve_rtu(
    serial: tokio_serial::SerialStream,
    bank: SharedBank,
    clock: ClockOptions,
    on_event: impl FnMut(&Event),
) -> io::Result<()> {
    let server = tokio_modbus::server::rtu::Server::new(serial);
    let front = Front::new(&bank);
    tokio::select! {
        served = server.serve_forever(front.clone()) => served,
        clocked = run_clock(front, clock, on_event) => clocked,
    }
}

/// A connection that failed mid-request ends that connection only; the server goes on
/// accepting. The simulator has no logger, so the failure goes to stderr.
fn report_connection_end(error: &io::Error) {
    eprintln!("whirl-sim: Modbus connection ended: {error}");
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::modbus::BankOptions;
    use crate::{Controller, ControllerOptions};

    /// The simulated seconds a bank's clock counts, at 100×, over 3 ms of running, a
    /// second in which the process is not run (the clock not polled), then 1 ms more:
    /// tokio's paused time, so the host's speed plays no part.
    async fn counted_over_a_pause(max_step: Option<Duration>) -> f64 {
        let machine = crate::machine::test_machines::sim_default();
        let controller = Controller::new(&machine, ControllerOptions::default()).unwrap();
        let bank = Arc::new(Mutex::new(
            Bank::new(controller, BankOptions::default()).unwrap(),
        ));
        let clock = ClockOptions {
            time_scale: 100.0,
            max_step,
            ..ClockOptions::default()
        };
        let clocked = run_clock(Front::new(&bank), clock, |_| {});
        tokio::pin!(clocked);
        let ms = Duration::from_millis(1);
        assert!(tokio::time::timeout(3 * ms, &mut clocked).await.is_err());
        tokio::time::advance(Duration::from_secs(1)).await;
        assert!(tokio::time::timeout(ms, &mut clocked).await.is_err());
        let now = lock(&bank).controller().now();
        now
    }

    #[tokio::test(start_paused = true)]
    async fn a_pause_of_the_process_counts_at_most_max_step_of_wall_time() {
        // Capped: 4 ms of running and one step of at most 20 ms, at 100×.
        let capped = counted_over_a_pause(Some(Duration::from_millis(20))).await;
        assert!(capped <= (0.004 + 0.020) * 100.0 + 1e-9, "{capped}");
        // Uncapped, the whole second counts: 100 simulated seconds.
        let whole = counted_over_a_pause(None).await;
        assert!(whole >= 100.0, "{whole}");
    }
}
