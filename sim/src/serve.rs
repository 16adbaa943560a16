//! The simulator's front-end: a controller served on a byte stream (a pseudo-terminal, a TCP
//! connection, an in-memory pipe), in simulated time.
//!
//! Only bytes and time move here; every decision is the [`Controller`]'s. Each tick the
//! simulated clock advances by the wall time elapsed times the time scale (or by a fixed step
//! when the scale is "as fast as possible"), the bytes that arrived are handed over, no faster
//! than the emulated baud rate allows in simulated time, and the controller's output is
//! written back.

use crate::{Controller, Event};
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};

/// As fast as possible, simulated time runs hundreds of times faster than wall time, so a
/// sender descheduled for a few milliseconds would look like a link idle for seconds, and
/// the machine would stop for want of lines it would have had. So while the controller is
/// about to starve the simulator waits, in wall time, for the sender's next bytes, up to
/// this long, as a real controller's clock would have waited a few microseconds.
const SENDER_WAIT: Duration = Duration::from_millis(50);

/// Waits in a row a sender may let pass before the simulator stops waiting for it: it has
/// nothing more to send (until it sends again).
const SENDER_PATIENCE: u32 = 3;

/// The controller could take a line (its planner has room) but has almost none to take:
/// less than a quarter of its receive buffer holds bytes, and none are waiting on the link.
fn starving(controller: &Controller, inbox: &[u8]) -> bool {
    let size = controller.options().rx_buffer_size;
    inbox.is_empty() && controller.blocks_free() > 0 && controller.rx_free() > size * 3 / 4
}

/// How the simulated clock and the link behave.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ServeOptions {
    /// Simulated seconds per wall second; `None`: as fast as the host allows (each tick
    /// advances `fast_step` simulated seconds, without waiting).
    pub time_scale: Option<f64>,
    /// Simulated seconds per tick when running as fast as possible.
    pub fast_step: f64,
    /// Wall time between ticks when running scaled.
    pub tick: Duration,
    /// Emulated link rate, bits per second (10 bits a byte); `None`: unlimited.
    pub baud: Option<u32>,
    /// Stop serving (Ok) after this much wall time without a byte from the client; `None`:
    /// serve until the client closes the stream.
    pub idle_exit: Option<Duration>,
}

impl Default for ServeOptions {
    fn default() -> Self {
        ServeOptions {
            time_scale: Some(1.0),
            fast_step: 0.005,
            tick: Duration::from_millis(2),
            baud: None,
            idle_exit: None,
        }
    }
}

/// Serve `controller` on `stream` until the other side closes it or stays silent for
/// [`ServeOptions::idle_exit`] (Ok), or the link fails.
/// `on_event` sees every controller event (answers, executed blocks, alarms) as it happens.
pub async fn serve<S: AsyncRead + AsyncWrite + Unpin>(
    mut stream: S,
    controller: &mut Controller,
    options: ServeOptions,
    mut on_event: impl FnMut(&Event),
) -> std::io::Result<()> {
    let mut inbox: Vec<u8> = Vec::new();
    let mut buf = [0u8; 4096];
    let mut budget = 0.0_f64; // bytes the link may still deliver
    let banner = controller.take_output();
    stream.write_all(&banner).await?;
    let mut last = tokio::time::Instant::now();
    let mut last_byte = last;
    let mut missed_waits = 0;
    loop {
        // Scaled: wait for bytes or for the next tick, whichever comes first. As fast as
        // possible: take whatever bytes are there and go on (a timer, even of zero, would
        // cost a timer tick of wall time per step), unless the controller is about to
        // starve (see `starving`).
        let read = match options.time_scale {
            Some(_) => tokio::select! {
                read = stream.read(&mut buf) => Some(read),
                () = tokio::time::sleep(options.tick) => None,
            },
            None if missed_waits < SENDER_PATIENCE && starving(controller, &inbox) => {
                let read = tokio::select! {
                    read = stream.read(&mut buf) => Some(read),
                    () = tokio::time::sleep(SENDER_WAIT) => None,
                };
                missed_waits = if read.is_some() { 0 } else { missed_waits + 1 };
                read
            }
            None => tokio::select! {
                biased;
                read = stream.read(&mut buf) => Some(read),
                () = std::future::ready(()) => None,
            },
        };
        if let Some(read) = read {
            let n = read?;
            if n == 0 {
                return Ok(());
            }
            inbox.extend_from_slice(&buf[..n]);
            last_byte = tokio::time::Instant::now();
        } else if options
            .idle_exit
            .is_some_and(|idle| last_byte.elapsed() >= idle)
        {
            return Ok(());
        }
        let now = tokio::time::Instant::now();
        let dt = match options.time_scale {
            Some(scale) => (now - last).as_secs_f64() * scale,
            None => options.fast_step,
        };
        last = now;
        match options.baud {
            Some(baud) => {
                budget += dt * f64::from(baud) / 10.0;
                let n = (budget.floor() as usize).min(inbox.len());
                controller.receive(&inbox[..n]);
                inbox.drain(..n);
                budget -= n as f64;
                if inbox.is_empty() {
                    // An idle link saves nothing up: what it could have carried while
                    // nothing waited is gone, so bytes never arrive faster than the rate.
                    budget = budget.min(1.0);
                }
            }
            None => {
                controller.receive(&inbox);
                inbox.clear();
            }
        }
        controller
            .advance(dt)
            .map_err(|e| std::io::Error::other(e.to_string()))?;
        for e in controller.take_events() {
            on_event(&e);
        }
        let out = controller.take_output();
        if !out.is_empty() {
            stream.write_all(&out).await?;
            stream.flush().await?;
        }
        if options.time_scale.is_none() {
            tokio::task::yield_now().await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tests::profile;
    use crate::ControllerOptions;
    use tokio::io::AsyncBufReadExt;

    async fn answers_to(lines: &[&str], options: ServeOptions) -> (Vec<String>, f64) {
        answers_after(Duration::ZERO, lines, options).await
    }

    /// The answers to `lines` sent after the link has been idle for `idle`, and the
    /// simulated time their exchange took.
    async fn answers_after(
        idle: Duration,
        lines: &[&str],
        options: ServeOptions,
    ) -> (Vec<String>, f64) {
        let (client, server) = tokio::io::duplex(4096);
        let mut controller = Controller::new(&profile(), ControllerOptions::default()).unwrap();
        let task = tokio::spawn(async move {
            serve(server, &mut controller, options, |_| {})
                .await
                .unwrap();
            controller.now()
        });
        let (read, mut write) = tokio::io::split(client);
        let mut reader = tokio::io::BufReader::new(read);
        // grbl opens with a blank line, then the banner.
        let mut banner = String::new();
        while banner.trim().is_empty() {
            banner.clear();
            reader.read_line(&mut banner).await.unwrap();
        }
        assert!(banner.starts_with("Grbl"), "{banner}");
        tokio::time::sleep(idle).await;
        let mut answers = Vec::new();
        for line in lines {
            write
                .write_all(format!("{line}\n").as_bytes())
                .await
                .unwrap();
            let mut answer = String::new();
            reader.read_line(&mut answer).await.unwrap();
            answers.push(answer.trim().to_owned());
        }
        drop(write);
        drop(reader);
        (answers, task.await.unwrap() - idle.as_secs_f64())
    }

    #[tokio::test(start_paused = true)]
    async fn each_line_gets_its_answer_over_the_stream() {
        let (answers, _) =
            answers_to(&["G21 G90", "G0 Z1", "G1 X1 Q2"], ServeOptions::default()).await;
        assert_eq!(answers[..2], ["ok", "ok"]);
        assert!(answers[2].starts_with("error:"), "{answers:?}");
    }

    #[tokio::test(start_paused = true)]
    async fn the_link_rate_limits_what_arrives() {
        // At 1200 baud (120 bytes/s), 8 lines of 13 bytes take at least 104/120 s of
        // simulated time to arrive, however fast they were written.
        let lines = ["G0 Z1.000001"; 8];
        let opts = ServeOptions {
            baud: Some(1200),
            ..ServeOptions::default()
        };
        let (answers, simulated) = answers_to(&lines, opts).await;
        assert!(answers.iter().all(|a| a == "ok"));
        assert!(simulated >= 104.0 / 120.0 - 0.01, "{simulated}");
    }

    #[tokio::test(start_paused = true)]
    async fn an_idle_link_saves_up_no_rate() {
        // Ten idle seconds first: the same 104 bytes at 120 bytes/s still take 104/120 s.
        let lines = ["G0 Z1.000001"; 8];
        let opts = ServeOptions {
            baud: Some(1200),
            ..ServeOptions::default()
        };
        let (answers, simulated) = answers_after(Duration::from_secs(10), &lines, opts).await;
        assert!(answers.iter().all(|a| a == "ok"));
        assert!(simulated >= 104.0 / 120.0 - 0.01, "{simulated}");
    }

    #[tokio::test(start_paused = true)]
    async fn a_silent_client_is_left_after_the_idle_time() {
        let (client, server) = tokio::io::duplex(4096);
        let mut controller = Controller::new(&profile(), ControllerOptions::default()).unwrap();
        let options = ServeOptions {
            idle_exit: Some(Duration::from_secs(60)),
            ..ServeOptions::default()
        };
        let started = tokio::time::Instant::now();
        serve(server, &mut controller, options, |_| {})
            .await
            .unwrap();
        let waited = started.elapsed();
        assert!(waited >= Duration::from_secs(60), "{waited:?}");
        assert!(waited < Duration::from_secs(61), "{waited:?}");
        drop(client);
    }

    #[tokio::test(start_paused = true)]
    async fn running_as_fast_as_possible_it_waits_for_a_sender_it_would_starve() {
        // The sender takes 20 ms (wall) to follow its first line with the second. The
        // simulator runs unscaled, hundreds of simulated seconds per wall second, but the
        // machine must not stop between the two moves: the second is sent before the first
        // is done on any real controller. A dwell, answered once the queue has run, ends it.
        let (client, server) = tokio::io::duplex(4096);
        let mut controller = Controller::new(&profile(), ControllerOptions::default()).unwrap();
        let options = ServeOptions {
            time_scale: None,
            ..ServeOptions::default()
        };
        let sender = async move {
            let (read, mut write) = tokio::io::split(client);
            let mut reader = tokio::io::BufReader::new(read);
            write.write_all(b"G1 X10 F600\n").await.unwrap();
            tokio::time::sleep(Duration::from_millis(20)).await;
            write.write_all(b"G1 X20\nG4 P0\n").await.unwrap();
            let mut oks = 0;
            while oks < 3 {
                let mut line = String::new();
                reader.read_line(&mut line).await.unwrap();
                oks += usize::from(line.trim() == "ok");
            }
        };
        let mut blocks = Vec::new();
        let served = serve(server, &mut controller, options, |e| {
            if let Event::Executed(b) = e {
                blocks.push(b.clone());
            }
        });
        tokio::join!(sender, async {
            served.await.unwrap();
        });
        assert_eq!(blocks.len(), 2);
        assert_eq!(blocks[1].start_time, blocks[0].end_time);
    }
}
