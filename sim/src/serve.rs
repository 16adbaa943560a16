//! The simulator's front-end: a controller served on a byte stream (a pseudo-terminal, a TCP
//! connection, an in-memory pipe), in simulated time.
//!
//! Only bytes and time move here; every decision is the [`Controller`]'s. Each tick the
//! simulated clock advances by the wall time elapsed times the time scale (or by a fixed step
//! when the scale is "as fast as possible"), the bytes that have arrived over the emulated
//! link are handed over, and the controller's output goes back over the link's other
//! direction (see [`ServeOptions::baud`] for the link and its clock).

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

/// The grain of tokio's timers: a shorter sleep lasts this long anyway, and one that
/// rounds to nothing would not let a paused clock (the tests') move on.
const TIMER_GRAIN: Duration = Duration::from_millis(1);

/// Wall time for `simulated` seconds to pass at `scale` (a day when it is out of range).
fn wall_until(simulated: f64, scale: f64) -> Duration {
    Duration::try_from_secs_f64(simulated.max(0.0) / scale).unwrap_or(Duration::from_secs(86_400))
}

/// The controller could take a line (its planner has room) but has almost none to take:
/// less than a quarter of its receive buffer holds bytes, none are on their way to it, and
/// every answer it gave has reached the sender (a sender still waiting for one cannot send:
/// only the simulated clock, which carries the answer, can end that wait).
fn starving(controller: &Controller, up: &Wire, down: &Wire) -> bool {
    let size = controller.options().rx_buffer_size;
    up.is_empty()
        && down.is_empty()
        && controller.blocks_free() > 0
        && controller.rx_free() > size * 3 / 4
}

/// One direction of the emulated serial line, 8N1: ten bits a byte (a start bit, eight data
/// bits, a stop bit), one byte after another, so the k-th byte sent onto an idle line
/// arrives k·10/baud seconds after it was sent, and never earlier. A line left idle saves
/// nothing up: what it could have carried while nothing waited is gone. Times are the
/// link's clock, the simulated one (see [`ServeOptions::baud`]). Unlimited, every byte
/// arrives as it is sent.
#[derive(Debug)]
struct Wire {
    /// Bytes per second; `None`: unlimited.
    rate: Option<f64>,
    /// Bytes sent and not yet arrived, in order.
    bytes: Vec<u8>,
    /// When the line last started on a byte while idle.
    busy_since: f64,
    /// Bytes arrived since `busy_since`.
    arrived: u64,
}

impl Wire {
    fn new(baud: Option<u32>) -> Wire {
        Wire {
            rate: baud.map(|baud| f64::from(baud) / 10.0),
            bytes: Vec::new(),
            busy_since: 0.0,
            arrived: 0,
        }
    }

    fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// `bytes` go onto the line at `now`, behind those still on it.
    fn send(&mut self, bytes: &[u8], now: f64) {
        if bytes.is_empty() {
            return;
        }
        if self.bytes.is_empty() {
            // Idle (everything sent before has arrived, by `now`): the first of these
            // bytes starts now.
            self.busy_since = now;
            self.arrived = 0;
        }
        self.bytes.extend_from_slice(bytes);
    }

    /// The bytes whose last bit has arrived by `now`, in order.
    fn take(&mut self, now: f64) -> Vec<u8> {
        let n = match self.rate {
            Some(rate) => {
                // Every byte whose arrival is at `now` or before, by the very sum
                // `next_arrival` gives (the product's rounding may be a byte off).
                let mut due = ((now - self.busy_since) * rate).floor().max(0.0) as u64;
                while due > 0 && self.arrival(rate, due) > now {
                    due -= 1;
                }
                while self.arrival(rate, due + 1) <= now {
                    due += 1;
                }
                let n = due
                    .saturating_sub(self.arrived)
                    .min(self.bytes.len() as u64);
                self.arrived += n;
                n as usize
            }
            None => self.bytes.len(),
        };
        let rest = self.bytes.split_off(n);
        std::mem::replace(&mut self.bytes, rest)
    }

    /// When the `k`-th byte since the line last went busy arrives.
    fn arrival(&self, rate: f64, k: u64) -> f64 {
        self.busy_since + k as f64 / rate
    }

    /// When the next byte on the line arrives, if one is on it (and the rate is limited):
    /// after the last [`Wire::take`]'s `now`.
    fn next_arrival(&self) -> Option<f64> {
        let rate = self.rate?;
        (!self.bytes.is_empty()).then(|| self.arrival(rate, self.arrived + 1))
    }
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
    /// Emulated link rate, bits per second, 8N1 (10 bits a byte); `None`: unlimited.
    ///
    /// Both directions are paced, each on its own (a serial line is full duplex): the
    /// sender's bytes reach the controller no faster than the rate, and the controller's
    /// answers and reports reach the sender no faster either, so an `ok` queued behind a
    /// status report waits for it, as on a real line.
    ///
    /// The rate holds in the simulated clock, the machine's: a byte takes 10/baud simulated
    /// seconds, at every time scale. A link's byte rate is physical, part of the machine
    /// being simulated, as its feeds and accelerations are; keeping it in the same clock
    /// keeps the ratio of link time to motion time the real one, so the machine starves
    /// for lines exactly when the real one would, and bytes × 10 / baud over *simulated*
    /// time (what `whirl dry-run` reports) is the real link's use, even as fast as possible.
    /// At time scale 1 the simulated clock is the wall clock, so the link is the real line
    /// from both ends: a sender sees bytes go no faster than the baud rate in wall time,
    /// which is what a measurement of a sender's link use needs. At any other scale the
    /// sender sees a line `scale` times as fast in wall time (as fast as possible, no
    /// relation to wall time at all), and a figure it takes in wall time says nothing of a
    /// real line. Pacing in wall time at every scale was rejected: at 100× the machine
    /// would see a link 100 times slower than the real one and starve where the real one
    /// never does, and a dry run could go no faster than the real link.
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
    // The link: `up` from the sender to the controller, `down` back.
    let mut up = Wire::new(options.baud);
    let mut down = Wire::new(options.baud);
    let mut buf = [0u8; 4096];
    let banner = controller.take_output();
    stream.write_all(&banner).await?;
    let started = tokio::time::Instant::now();
    // The simulated clock since serving began, the link's clock.
    let mut t = 0.0_f64;
    let mut last_byte = started;
    let mut missed_waits = 0;
    loop {
        // Scaled: wait for bytes, for the next byte due on the link, or for the next tick,
        // whichever comes first. As fast as possible: take whatever bytes are there and go
        // on (a timer, even of zero, would cost a timer tick of wall time per step), unless
        // the controller is about to starve (see `starving`).
        let read = match options.time_scale {
            Some(scale) => {
                let wait = [up.next_arrival(), down.next_arrival()]
                    .into_iter()
                    .flatten()
                    .map(|due| wall_until(due - t, scale).max(TIMER_GRAIN))
                    .fold(options.tick, Duration::min);
                tokio::select! {
                    read = stream.read(&mut buf) => Some(read),
                    () = tokio::time::sleep(wait) => None,
                }
            }
            None if missed_waits < SENDER_PATIENCE && starving(controller, &up, &down) => {
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
        let now = tokio::time::Instant::now();
        let next = match options.time_scale {
            Some(scale) => (now - started).as_secs_f64() * scale,
            None => t + options.fast_step,
        };
        let dt = (next - t).max(0.0);
        t = next;
        if let Some(read) = read {
            let n = read?;
            if n == 0 {
                return Ok(());
            }
            // Read now, so sent now: the link starts on them no earlier.
            up.send(&buf[..n], t);
            last_byte = now;
        } else if options
            .idle_exit
            .is_some_and(|idle| last_byte.elapsed() >= idle)
        {
            return Ok(());
        }
        // The controller runs up to now, then gets what has arrived by now, so it never acts
        // on a byte before its last bit is in, and its answers go out from now.
        controller
            .advance(dt)
            .map_err(|e| std::io::Error::other(e.to_string()))?;
        controller.receive(&up.take(t));
        for e in controller.take_events() {
            on_event(&e);
        }
        down.send(&controller.take_output(), t);
        let out = down.take(t);
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

    /// What a sender saw of one burst: its text written at once, the answers read.
    struct Burst {
        /// Bytes written.
        sent: usize,
        /// Bytes read, answers and everything else (the banner not counted).
        read: usize,
        /// Bytes of the last answer, its line end included.
        last_answer: usize,
        /// Wall time from the write to the last answer read.
        wall: Duration,
        /// Simulated time from serving to the sender closing the link.
        simulated: f64,
    }

    /// `text` written at once to a simulator served with `options`, after the link has been
    /// idle for `idle`, then read until `answers` lines were answered (`ok` or `error:`).
    async fn burst(idle: Duration, text: &str, answers: usize, options: ServeOptions) -> Burst {
        let (client, server) = tokio::io::duplex(65536);
        let mut controller = Controller::new(&profile(), ControllerOptions::default()).unwrap();
        let task = tokio::spawn(async move {
            serve(server, &mut controller, options, |_| {})
                .await
                .unwrap();
            controller.now()
        });
        let (read, mut write) = tokio::io::split(client);
        let mut reader = tokio::io::BufReader::new(read);
        let mut banner = String::new();
        while !banner.starts_with("Grbl") {
            banner.clear();
            reader.read_line(&mut banner).await.unwrap();
        }
        tokio::time::sleep(idle).await;
        let started = tokio::time::Instant::now();
        write.write_all(text.as_bytes()).await.unwrap();
        let (mut read, mut last_answer, mut answered) = (0, 0, 0);
        while answered < answers {
            let mut line = String::new();
            reader.read_line(&mut line).await.unwrap();
            assert!(!line.is_empty(), "the simulator closed the link");
            read += line.len();
            if line.trim() == "ok" || line.starts_with("error:") {
                answered += 1;
                last_answer = line.len();
            }
        }
        let wall = started.elapsed();
        drop(write);
        drop(reader);
        Burst {
            sent: text.len(),
            read,
            last_answer,
            wall,
            simulated: task.await.unwrap(),
        }
    }

    /// A rate slow enough for a few hundred bytes to take most of a second.
    const SLOW: u32 = 9600;

    /// What `bytes` take on a line at `baud`, 8N1: 10 bits a byte.
    fn link_time(bytes: usize, baud: u32) -> Duration {
        Duration::from_secs_f64(bytes as f64 * 10.0 / f64::from(baud))
    }

    fn at(time_scale: Option<f64>, baud: u32) -> ServeOptions {
        ServeOptions {
            time_scale,
            baud: Some(baud),
            ..ServeOptions::default()
        }
    }

    /// The most a burst may take beyond its link time: the serving loop wakes for the next
    /// byte due on either direction (at the timer's 1 ms grain) and at least every tick, so
    /// the last line and its answer are each handed over at most a tick late.
    fn slack() -> Duration {
        2 * ServeOptions::default().tick
    }

    #[tokio::test(start_paused = true)]
    async fn at_real_time_lines_take_their_link_time_in_wall_time() {
        // 40 lines of 13 bytes written at once: the last one is in after 520 byte times,
        // and its `ok` back after 4 more, however fast the sender wrote.
        let text = "G0 Z1.000001\n".repeat(40);
        let b = burst(Duration::ZERO, &text, 40, at(Some(1.0), SLOW)).await;
        let floor = link_time(b.sent + b.last_answer, SLOW);
        assert!(b.wall >= floor, "{:?} < {floor:?}", b.wall);
        assert!(b.wall <= floor + slack(), "{:?} > {floor:?}", b.wall);
    }

    #[tokio::test(start_paused = true)]
    async fn at_real_time_answers_take_their_link_time_too() {
        // `$$` is 3 bytes up, and the listing of every setting and its `ok` come down.
        let b = burst(Duration::ZERO, "$$\n", 1, at(Some(1.0), SLOW)).await;
        assert!(b.read > 10 * b.sent, "{} bytes of settings", b.read);
        let floor = link_time(b.sent + b.read, SLOW);
        assert!(b.wall >= floor, "{:?} < {floor:?}", b.wall);
        assert!(b.wall <= floor + slack(), "{:?} > {floor:?}", b.wall);
    }

    #[tokio::test(start_paused = true)]
    async fn the_two_directions_of_the_link_run_at_once() {
        // Full duplex: the settings listing comes down while the 40 lines behind `$$` go
        // up, so the whole exchange takes less than both directions' bytes one after the
        // other, and no less than either direction's own.
        let text = "$$\n".to_owned() + &"G0 Z1.000001\n".repeat(40);
        let b = burst(Duration::ZERO, &text, 41, at(Some(1.0), SLOW)).await;
        assert!(
            b.wall >= link_time(b.sent.max(b.read), SLOW),
            "{:?}",
            b.wall
        );
        assert!(b.wall < link_time(b.sent + b.read, SLOW), "{:?}", b.wall);
    }

    #[tokio::test(start_paused = true)]
    async fn an_idle_link_saves_up_no_rate() {
        // Ten idle seconds first: the same burst still takes its link time.
        let text = "G0 Z1.000001\n".repeat(40);
        let b = burst(Duration::from_secs(10), &text, 40, at(Some(1.0), SLOW)).await;
        assert!(
            b.wall >= link_time(b.sent + b.last_answer, SLOW),
            "{:?}",
            b.wall
        );
    }

    #[tokio::test(start_paused = true)]
    async fn at_any_time_scale_the_link_keeps_the_simulated_clock() {
        // The link's rate is the machine's: the burst takes its link time in simulated
        // time at every scale, as fast as possible too, and that over the scale in wall time.
        let text = "G0 Z1.000001\n".repeat(40);
        for scale in [Some(10.0), Some(0.5), None] {
            let b = burst(Duration::ZERO, &text, 40, at(scale, SLOW)).await;
            let floor = link_time(b.sent + b.last_answer, SLOW);
            assert!(
                b.simulated >= floor.as_secs_f64(),
                "{scale:?}: {}",
                b.simulated
            );
            if let Some(scale) = scale {
                let wall = floor.div_f64(scale);
                assert!(b.wall >= wall, "{scale}: {:?} < {wall:?}", b.wall);
                assert!(b.wall <= wall + slack(), "{scale}: {:?} > {wall:?}", b.wall);
            }
        }
    }

    #[tokio::test(start_paused = true)]
    async fn one_line_at_a_time_pays_the_link_both_ways() {
        // A sender that waits for each `ok` before its next line: every line's 13 bytes go
        // up and its 4 come down before the next line starts, 8 × 17 bytes in a row.
        let lines = ["G0 Z1.000001"; 8];
        let (answers, simulated) = answers_to(&lines, at(Some(1.0), 1200)).await;
        assert!(answers.iter().all(|a| a == "ok"));
        assert!(
            simulated >= link_time(8 * 17, 1200).as_secs_f64(),
            "{simulated}"
        );
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
