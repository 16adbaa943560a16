//! `docs/modbus.md` over real sockets: whirl's Modbus transport
//! (`whirl::transport::modbus`, tokio-modbus TCP) against the simulator's server
//! (`whirl_sim::modbus::serve`), with a proxy between them that does to the traffic what a
//! flaky network or gateway does: loses an answer, holds a request past the bridge's
//! timeout and delivers it late, corrupts a slot on the way, garbles a write's echo. Also
//! the map's exceptions as they come back on the wire, and a third-party client (pymodbus)
//! reading the simulator.
//!
//! Everything is checked from the side that did not do it: what executed from the
//! simulator's own events (each motion block's N word is its segment's sequence number),
//! what was asked and answered from the bytes the proxy relayed.

use std::future::Future;
use std::net::SocketAddr;
use std::process::Command;
use std::sync::{Arc, Mutex, OnceLock};
use std::time::Duration;

use crate::util;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio_modbus::client::{tcp, Reader, Writer};
use tokio_modbus::{ExceptionCode, Slave};
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::judge::dry_run::MODBUS_TIME_SCALE;
use whirl::log::ExecLog;
use whirl::post::modbus::Segment;
use whirl::program::{Move, Position, Program};
use whirl::protocol::modbus::map::{AlarmCode, WordOrder};
use whirl::protocol::modbus::{Exception, WriterError, WriterOptions};
use whirl::transport::modbus::{stream_modbus, ModbusLink, ModbusOptions, ModbusOutcome};
use whirl_sim::modbus::serve::{serve_rtu, serve_tcp, ClockOptions, SharedBank};
use whirl_sim::modbus::{Bank, BankOptions};
use whirl_sim::{Controller, ControllerOptions, Event};

// Registers, as docs/modbus.md's address map numbers them on the wire (written here from
// the document, not taken from either side's constants).
const MAGIC: [u16; 2] = [0x5748, 0x524C];
const STATUS: u16 = 16;
/// One read of 16–34 gets the status and control blocks, as the bridge polls them.
const STATUS_LEN: u16 = 19;
const CONTROL: u16 = 32;
const HEAD: u16 = 33;
const RING: u16 = 256;
/// `TAIL` (21) and `HEAD` (33) within a read of 16–34.
const TAIL_IN_STATUS: usize = 21 - 16;
const HEAD_IN_STATUS: usize = 33 - 16;
/// The control word's `ABORT` bit (4): stop and flush, `HEAD` = `TAIL` = 0.
const ABORT: u16 = 1 << 4;
/// `STATE` values.
const IDLE: u16 = 0;
const ALARM: u16 = 3;

/// The simulated watchdog, ms of the controller's time: the longest the map holds, as in
/// a dry run. At a dry run's time scale (100×) the default second is 10 ms of wall time,
/// less than one lost answer costs; this is 0.65 s, past a timeout and reconnect and a busy
/// host's pauses, and still stops a bridge that is gone.
const WATCHDOG_MS: u16 = u16::MAX;

/// How long the bridge waits for an answer, wall time. On loopback an answer takes well
/// under a millisecond, so a lost one is noticed soon; a spurious timeout on a busy host
/// is one more re-send, which these tests show to be harmless.
const TIMEOUT: Duration = Duration::from_millis(40);

/// Re-sends of one request before the bridge gives up: more than a machine would want, so
/// that a busy host's pauses past [`TIMEOUT`], a few in a row, cannot end a stream in
/// which the proxy faults a request at most twice.
const RETRIES: u32 = 8;

/// Longest a test's exchange with the simulator may take before it counts as hung.
const LIMIT: Duration = Duration::from_secs(60);

/// What the proxy does to one request.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Fault {
    /// Passed on both ways.
    None,
    /// Passed on; the answer is dropped, so the bridge times out on a request the
    /// controller carried out.
    LoseAnswer,
    /// Held back past the bridge's timeout, and delivered on its old connection once the
    /// bridge's re-sent copy has been published (the next `HEAD` write answered): a
    /// gateway that carries out a request after the bridge gave up on it.
    Hold,
    /// The lowest bit of a slot write's X flipped (0.1 µm): damage on the way that Modbus
    /// TCP, with no frame check of its own, lets through and only the slot's CRC catches.
    Corrupt,
    /// Passed on; the lowest bit of the value its FC06 answer echoes flipped, as when an
    /// answer meant for another write is read (a late answer on a serial line).
    BadEcho,
}

/// A Modbus TCP frame: the MBAP header and the PDU (function code first).
struct Frame {
    header: [u8; 7],
    pdu: Vec<u8>,
}

async fn read_frame(stream: &mut TcpStream) -> std::io::Result<Frame> {
    let mut header = [0; 7];
    stream.read_exact(&mut header).await?;
    // The length field counts the unit id and the PDU.
    let length = usize::from(u16::from_be_bytes([header[4], header[5]]));
    if length < 2 {
        return Err(std::io::Error::other(format!("MBAP length {length}")));
    }
    let mut pdu = vec![0; length - 1];
    stream.read_exact(&mut pdu).await?;
    Ok(Frame { header, pdu })
}

async fn write_frame(stream: &mut TcpStream, frame: &Frame) -> std::io::Result<()> {
    let mut bytes = frame.header.to_vec();
    bytes.extend_from_slice(&frame.pdu);
    stream.write_all(&bytes).await
}

/// A request the proxy passed on and the controller's answer, whether or not the bridge
/// got it.
#[derive(Debug)]
struct Exchange {
    request: Vec<u8>,
    answer: Vec<u8>,
    fault: Fault,
}

/// A request held back ([`Fault::Hold`]) with the connection it came for.
struct Held {
    frame: Frame,
    upstream: TcpStream,
    /// The bridge's re-sent copy has gone through.
    resent: bool,
}

/// Relays the Modbus TCP connections accepted on `listener` to `server`, one at a time
/// (the bridge opens a new one only after dropping the old), doing to the n-th request
/// (from 1, over all connections) what `plan` says, and recording every exchange in
/// `wire`. Ends only on a failure of the server's side.
async fn proxy(
    listener: TcpListener,
    server: SocketAddr,
    mut plan: impl FnMut(usize, &[u8]) -> Fault,
    wire: &mut Vec<Exchange>,
) -> std::io::Result<()> {
    let mut count = 0;
    let mut held: Option<Held> = None;
    loop {
        let (mut client, _) = listener.accept().await?;
        let mut upstream = TcpStream::connect(server).await?;
        // Until the bridge drops the connection (after a timeout, or at the end).
        while let Ok(mut request) = read_frame(&mut client).await {
            count += 1;
            let fault = plan(count, &request.pdu);
            if fault == Fault::Hold {
                // Kept with its upstream connection; the bridge times out and reconnects.
                while read_frame(&mut client).await.is_ok() {}
                held = Some(Held {
                    frame: request,
                    upstream,
                    resent: false,
                });
                break;
            }
            if fault == Fault::Corrupt {
                // FC16's PDU: function, address, quantity, byte count, then the registers;
                // X is the slot's registers 4–5, its low byte last.
                request.pdu[6 + 2 * 5 + 1] ^= 1;
            }
            write_frame(&mut upstream, &request).await?;
            let mut answer = read_frame(&mut upstream).await?;
            if fault == Fault::BadEcho && answer.pdu[0] == 0x06 {
                // FC06's answer: function, address, value, its low byte last.
                answer.pdu[4] ^= 1;
            }
            let connected =
                fault == Fault::LoseAnswer || write_frame(&mut client, &answer).await.is_ok();
            let published = head_write(&request.pdu).is_some() && exception(&answer.pdu).is_none();
            wire.push(Exchange {
                request: request.pdu,
                answer: answer.pdu,
                fault,
            });
            if let Some(h) = &mut held {
                if h.frame.pdu == wire.last().expect("just pushed").request {
                    h.resent = true;
                } else if h.resent && published {
                    let mut h = held.take().expect("checked");
                    write_frame(&mut h.upstream, &h.frame).await?;
                    let answer = read_frame(&mut h.upstream).await?;
                    wire.push(Exchange {
                        request: h.frame.pdu,
                        answer: answer.pdu,
                        fault: Fault::Hold,
                    });
                }
            }
            if !connected {
                break;
            }
        }
    }
}

/// The big-endian word at byte `at`.
fn word(bytes: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([bytes[at], bytes[at + 1]])
}

/// The value of an FC06 write to `HEAD`.
fn head_write(pdu: &[u8]) -> Option<u16> {
    (pdu[0] == 0x06 && word(pdu, 1) == HEAD).then(|| word(pdu, 3))
}

/// An FC16 write into the ring.
fn is_slot_write(pdu: &[u8]) -> bool {
    pdu[0] == 0x10 && word(pdu, 1) >= RING
}

/// The exception code of an exception answer (its function code has the high bit set).
fn exception(pdu: &[u8]) -> Option<u8> {
    (pdu[0] & 0x80 != 0).then(|| pdu[1])
}

/// The registers of an answered status read (FC03 of 16–34).
fn status_read(e: &Exchange) -> Option<Vec<u16>> {
    let asked = e.request[0] == 0x03 && word(&e.request, 1) == STATUS;
    (asked && word(&e.request, 3) == STATUS_LEN && e.answer[0] == 0x03)
        .then(|| e.answer[2..].chunks(2).map(|w| word(w, 0)).collect())
}

/// The simulated controller with a register bank of `slots` slots in front, its watchdog
/// at [`WATCHDOG_MS`].
fn bank(slots: u16) -> SharedBank {
    let options = BankOptions {
        slots,
        watchdog_timeout_ms: WATCHDOG_MS,
        ..BankOptions::default()
    };
    let profile = MachineProfile::builtin_sim().unwrap();
    let controller = Controller::new(
        &whirl::judge::simulator::machine(&profile),
        ControllerOptions::default(),
    )
    .unwrap();
    Arc::new(Mutex::new(Bank::new(controller, options).unwrap()))
}

/// What running alongside the simulator left behind.
struct Served<T> {
    /// What the body returned.
    result: T,
    /// The simulator's events, all of them.
    events: Vec<Event>,
    /// What passed through the proxy.
    wire: Vec<Exchange>,
}

/// Serves `bank` on loopback TCP at a dry run's time scale, with the proxy in front of it
/// faulting as `plan` says, and runs `body` (given the proxy's address, then the server's
/// own) until it is done.
async fn served<T, F: Future<Output = T>>(
    bank: &SharedBank,
    plan: impl FnMut(usize, &[u8]) -> Fault,
    body: impl FnOnce(SocketAddr, SocketAddr) -> F,
) -> Served<T> {
    let server = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let direct = server.local_addr().unwrap();
    let front = TcpListener::bind("127.0.0.1:0").await.unwrap();
    let proxied = front.local_addr().unwrap();
    let clock = ClockOptions {
        time_scale: MODBUS_TIME_SCALE,
        max_step: Some(whirl::judge::dry_run::SIM_MAX_STEP),
        ..ClockOptions::default()
    };
    let (mut events, mut wire) = (Vec::new(), Vec::new());
    let result = {
        let serving = serve_tcp(server, Arc::clone(bank), clock, |e| events.push(e.clone()));
        let proxying = proxy(front, direct, plan, &mut wire);
        let body = tokio::time::timeout(LIMIT, body(proxied, direct));
        tokio::select! {
            result = body => result.unwrap_or_else(|_| panic!("not done in {LIMIT:?}")),
            ended = serving => panic!("the simulator's server ended: {ended:?}"),
            ended = proxying => panic!("the proxy ended: {ended:?}"),
        }
    };
    // What the clock had not handed over yet.
    events.extend(bank.lock().unwrap().take_events());
    Served {
        result,
        events,
        wire,
    }
}

/// The bridge's options in these tests: [`TIMEOUT`], [`RETRIES`], a short backoff, the
/// simulator's clock.
fn options() -> ModbusOptions {
    ModbusOptions {
        writer: WriterOptions {
            max_retries: RETRIES,
            ..WriterOptions::default()
        },
        timeout: TIMEOUT,
        backoff: Duration::from_millis(5),
        clock_scale: MODBUS_TIME_SCALE,
        ..ModbusOptions::default()
    }
}

/// Streams `segments` to `addr` with whirl's Modbus transport, at the simulator's clock.
async fn stream_to(addr: SocketAddr, segments: Vec<Segment>) -> ModbusOutcome {
    let options = options();
    stream_modbus(
        &ModbusLink::Tcp(addr),
        segments,
        options,
        &mut ExecLog::discard(),
    )
    .await
    .expect("the stream runs")
}

/// The double-start example's planned program (short linked moves, so the ring turns over
/// fast), planned once for every test here.
fn planned() -> &'static Program {
    static PLANNED: OnceLock<Program> = OnceLock::new();
    PLANNED.get_or_init(|| {
        let profile = MachineProfile::builtin_sim().unwrap();
        let job = Job::load(&util::example("double-start")).unwrap();
        whirl::plan::plan(&job, &profile).unwrap().program
    })
}

/// The planned program's first `blocks` blocks (the lead-in: rapids, spindle on, the
/// plunge, then linked moves) and its lead-out (everything after the last linked move),
/// as segments, with the sequence numbers of those that move the machine.
fn program(blocks: usize) -> (Vec<Segment>, Vec<u32>) {
    let all = &planned().moves;
    let last_linked = all
        .iter()
        .rposition(|b| matches!(b, Move::Linked { .. }))
        .unwrap();
    let program = Program {
        moves: all[..blocks]
            .iter()
            .chain(&all[last_linked + 1..])
            .cloned()
            .collect(),
    };
    let segments = whirl::post::modbus::segments(&program).unwrap();
    // Sequence numbers are 1, 2, … in program order past the comments, which are no
    // segments; a segment moves the machine unless it ends where the machine already is
    // (grbl plans no block for that).
    let start = ControllerOptions::default().start.to_array();
    let moving = program
        .steps(Position::known(start[0], start[1], start[2]))
        .filter(|s| !matches!(s.action, Move::Comment(_)))
        .zip(1..)
        .filter(|(s, _)| s.action.target().is_some() && s.from != s.to)
        .map(|(_, sequence)| sequence)
        .collect();
    (segments, moving)
}

/// The stream completed and the controller ran each segment once, in order: every slot
/// became one line answered `ok` with its sequence number as N, and every motion segment
/// executed once, to completion; no alarm.
fn assert_each_segment_once(outcome: &ModbusOutcome, events: &[Event], moving: &[u32]) {
    assert!(outcome.completed, "{outcome:?}");
    assert_eq!((outcome.failure.as_ref(), outcome.alarm), (None, None));
    assert_eq!(outcome.published, outcome.segments);
    let count = outcome.segments as u32;
    let answered: Vec<Option<u32>> = events
        .iter()
        .filter_map(|e| match e {
            Event::Line { n, error, text, .. } => {
                assert_eq!(*error, None, "{text}");
                Some(*n)
            }
            _ => None,
        })
        .collect();
    assert_eq!(answered, (1..=count).map(Some).collect::<Vec<_>>());
    let executed: Vec<u32> = events
        .iter()
        .filter_map(|e| match e {
            Event::Executed(block) => {
                assert!(block.completed, "{block:?}");
                block.n
            }
            _ => None,
        })
        .collect();
    assert_eq!(executed, moving);
    let alarms: Vec<&Event> = events
        .iter()
        .filter(|e| matches!(e, Event::Alarm { .. }))
        .collect();
    assert!(alarms.is_empty(), "{alarms:?}");
}

/// docs/modbus.md, "Re-sending is idempotent": every seventh answer is lost and one slot
/// write arrives late, after the bridge re-sent it and published it; the bridge times out,
/// drops the connection, reconnects and re-sends, and the controller still runs each
/// segment exactly once.
#[tokio::test]
async fn a_modbus_timeout_and_reconnect_loses_no_segment_and_repeats_none() {
    let (segments, moving) = program(300);
    let bank = bank(BankOptions::default().slots);
    let mut held = false;
    let plan = move |n: usize, pdu: &[u8]| {
        if n.is_multiple_of(7) {
            Fault::LoseAnswer
        } else if !held && n > 100 && is_slot_write(pdu) {
            held = true;
            Fault::Hold
        } else {
            Fault::None
        }
    };
    let run = served(&bank, plan, |proxied, _| stream_to(proxied, segments)).await;
    let outcome = run.result;
    assert_each_segment_once(&outcome, &run.events, &moving);
    // Each fault cost the bridge a timeout and a new connection (a busy host may add some).
    let faults = run.wire.iter().filter(|e| e.fault != Fault::None).count() as u32;
    assert!(outcome.timeouts >= faults && faults > 0, "{outcome:?}");
    assert!(outcome.reconnects >= faults, "{outcome:?}");
    // Lost answers hit both halves of a publication: slot writes and HEAD writes.
    let lost = |is: fn(&[u8]) -> bool| {
        run.wire
            .iter()
            .any(|e| e.fault == Fault::LoseAnswer && is(&e.request))
    };
    assert!(lost(is_slot_write));
    assert!(lost(|pdu| head_write(pdu).is_some()));
    // The late copy left the published slot as it was, so it was accepted (FC16 echoed).
    let late: Vec<&Exchange> = run.wire.iter().filter(|e| e.fault == Fault::Hold).collect();
    assert_eq!(late.len(), 1, "the held request was delivered");
    assert!(is_slot_write(&late[0].request));
    assert_eq!(late[0].answer[0], 0x10, "{:?}", late[0].answer);
}

/// docs/modbus.md, "The ring": with four slots and the machine setting the pace, the bridge
/// writes a slot only while the ring has room by the last `TAIL` it read, so no `HEAD`
/// write is refused, though the ring is full again and again; every segment still runs
/// once.
#[tokio::test]
async fn a_full_ring_applies_back_pressure() {
    let slots = 4;
    let (segments, moving) = program(150);
    let bank = bank(slots);
    let run = served(
        &bank,
        |_, _| Fault::None,
        |proxied, _| stream_to(proxied, segments),
    )
    .await;
    assert_each_segment_once(&run.result, &run.events, &moving);
    let refused: Vec<&Exchange> = run
        .wire
        .iter()
        .filter(|e| exception(&e.answer).is_some())
        .collect();
    assert!(refused.is_empty(), "{refused:?}");
    // Publishing slot h moves HEAD to (h + 1) mod N; the ring is full when that is TAIL.
    // The flush (ABORT) leaves TAIL at 0; later, TAIL is what the last status read said.
    let (mut tail, mut full, mut heads) = (None, 0, 0);
    for e in &run.wire {
        if e.request[0] == 0x06 && word(&e.request, 1) == CONTROL {
            if word(&e.request, 3) & ABORT != 0 {
                tail = Some(0);
            }
        } else if let Some(head) = head_write(&e.request) {
            assert_ne!(Some(head), tail, "HEAD written into a full ring");
            heads += 1;
        } else if let Some(status) = status_read(e) {
            let (t, h) = (status[TAIL_IN_STATUS], status[HEAD_IN_STATUS]);
            full += usize::from((h + 1) % slots == t);
            tail = Some(t);
        }
    }
    assert_eq!(heads, run.result.segments, "one HEAD write per segment");
    assert!(full > 0, "the ring never read full");
}

/// docs/modbus.md, "Exception codes": each code the map uses, provoked with a raw
/// tokio-modbus client (not whirl's transport) and read off the wire; and the bridge's
/// name for each, which is how a stream reports it.
#[tokio::test]
async fn every_exception_response_comes_back_on_the_wire_and_reads_clearly() {
    let bank = bank(4);
    let run = served(
        &bank,
        |_, _| Fault::None,
        |_, direct| async move {
            let mut ctx = tcp::connect_slave(direct, Slave(1)).await.unwrap();
            let mut codes = Vec::new();
            // 01: FC04 (read input registers) is not one of 03, 06, 16.
            codes.push(ctx.read_input_registers(0, 1).await.unwrap());
            // 02: register 8 is in the gap after the identification block; an FC16 may
            // not touch the control registers, each written alone with FC06.
            codes.push(ctx.read_holding_registers(8, 1).await.unwrap());
            let control = ctx.write_multiple_registers(CONTROL, &[0, 0]).await;
            codes.push(control.unwrap().map(|()| Vec::new()));
            // 03: control word bits 6–15 must be 0.
            let bit15 = ctx.write_single_register(CONTROL, 1 << 15).await;
            codes.push(bit15.unwrap().map(|()| Vec::new()));
            // 06: a published slot (RUN clear, so the controller leaves it) cannot change;
            // the same registers again are a re-sent copy and accepted.
            let slot = Segment::SpindleOff.encode(1, WordOrder::HighFirst);
            ctx.write_multiple_registers(RING, &slot)
                .await
                .unwrap()
                .unwrap();
            ctx.write_single_register(HEAD, 1).await.unwrap().unwrap();
            let mut changed = slot;
            changed[2] = Segment::ProgramEnd.encode(1, WordOrder::HighFirst)[2];
            let busy = ctx.write_multiple_registers(RING, &changed).await;
            codes.push(busy.unwrap().map(|()| Vec::new()));
            let again = ctx.write_multiple_registers(RING, &slot).await;
            assert_eq!(again.unwrap(), Ok(()), "a copy that changes nothing");
            // 04: slot 1 was never written, and an all-zero slot fails its CRC; the HEAD
            // write publishing it is refused and raises alarm 101.
            let failed = ctx.write_single_register(HEAD, 2).await;
            codes.push(failed.unwrap().map(|()| Vec::new()));
            let status = ctx.read_holding_registers(STATUS, STATUS_LEN).await;
            (codes, status.unwrap().unwrap())
        },
    )
    .await;
    let (codes, status) = run.result;
    use ExceptionCode::*;
    let expected = [
        IllegalFunction,
        IllegalDataAddress,
        IllegalDataAddress,
        IllegalDataValue,
        ServerDeviceBusy,
        ServerDeviceFailure,
    ];
    assert_eq!(codes, expected.map(Err));
    // Alarm 101 (slot CRC) at the segment expected there, the one after sequence 1; HEAD
    // did not move past the refused slot.
    assert_eq!(status[0], ALARM);
    assert_eq!(status[1], 101);
    assert_eq!(&status[2..4], &[0, 2]);
    assert_eq!(status[HEAD_IN_STATUS], 1);
    // The bridge names each code and its meaning as the Modbus application protocol does.
    let names = [
        (
            IllegalFunction,
            Exception::IllegalFunction,
            "illegal function",
        ),
        (
            IllegalDataAddress,
            Exception::IllegalDataAddress,
            "illegal data address",
        ),
        (
            IllegalDataValue,
            Exception::IllegalDataValue,
            "illegal data value",
        ),
        (
            ServerDeviceFailure,
            Exception::ServerDeviceFailure,
            "server device failure",
        ),
        (
            ServerDeviceBusy,
            Exception::ServerDeviceBusy,
            "server device busy",
        ),
    ];
    for (code, exception, meaning) in names {
        let number = u8::from(code);
        assert_eq!(
            exception.to_string(),
            format!("exception {number:02} ({meaning})")
        );
    }
}

/// docs/modbus.md, "Checks when HEAD moves": a slot damaged on the way fails its CRC, the
/// HEAD write publishing it is answered 04, and the stream ends with alarm 101 at that
/// segment; the controller, left in alarm, refuses the next stream before it starts, and
/// both reports name the alarm.
#[tokio::test]
async fn a_stream_refused_by_the_controller_says_why() {
    let (segments, _) = program(20);
    let damaged = 3;
    let bank = bank(BankOptions::default().slots);
    let mut slot_writes = 0;
    let plan = move |_, pdu: &[u8]| {
        slot_writes += u32::from(is_slot_write(pdu));
        if is_slot_write(pdu) && slot_writes == damaged {
            Fault::Corrupt
        } else {
            Fault::None
        }
    };
    let run = served(&bank, plan, |proxied, direct| async move {
        let refused = stream_to(proxied, segments.clone()).await;
        let after = stream_to(direct, segments).await;
        (refused, after)
    })
    .await;
    let (refused, after) = run.result;
    // On the wire: the HEAD write after the damaged slot was answered 04.
    let corrupted = run
        .wire
        .iter()
        .position(|e| e.fault == Fault::Corrupt)
        .unwrap();
    let next = &run.wire[corrupted + 1];
    assert_eq!(head_write(&next.request), Some(damaged as u16));
    assert_eq!(exception(&next.answer), Some(0x04));
    // The stream: alarm 101 at the damaged segment, the ones before it published.
    assert!(!refused.completed);
    let alarm = refused.alarm.expect("an alarm ended the stream");
    assert_eq!((alarm.code, alarm.sequence), (AlarmCode::SlotCrc, damaged));
    assert_eq!(refused.published, damaged as usize - 1);
    assert!(
        alarm.to_string().starts_with("alarm 101 (slot CRC)"),
        "{alarm}"
    );
    // Left in alarm, the controller is not ready for another stream, and says which alarm.
    assert!(!after.completed);
    let failure = after.failure.expect("refused before streaming");
    assert!(matches!(failure, WriterError::NotReady(_)), "{failure:?}");
    assert!(failure.to_string().contains("alarm 101"), "{failure}");
}

/// docs/modbus.md: an FC06 write is answered by its echo. One that echoes another value
/// was not this write's answer, and the stream fails naming both rather than taking it
/// for one.
#[tokio::test]
async fn an_answer_that_does_not_echo_the_write_fails_the_stream() {
    let (segments, _) = program(20);
    let bank = bank(BankOptions::default().slots);
    // The first FC06 is the control word cleared before the flush.
    let mut first = true;
    let plan = move |_, pdu: &[u8]| {
        if pdu[0] == 0x06 && std::mem::take(&mut first) {
            Fault::BadEcho
        } else {
            Fault::None
        }
    };
    let run = served(&bank, plan, |proxied, _| stream_to(proxied, segments)).await;
    let bad = run.wire.iter().find(|e| e.fault == Fault::BadEcho).unwrap();
    assert_eq!(word(&bad.request, 1), CONTROL);
    let outcome = run.result;
    assert!(!outcome.completed);
    assert_eq!(outcome.published, 0);
    let failure = outcome.failure.expect("the stream failed");
    assert!(
        matches!(failure, WriterError::BadResponse { .. }),
        "{failure:?}"
    );
    assert_eq!(
        failure.to_string(),
        "FC06 write 0x0000 to register 32: answered WriteSingle { address: 32, value: 1 }"
    );
}

/// The length of the Modbus RTU answer frame at the start of `bytes`, once its length can be
/// told: unit and function code, then an FC03's byte count and registers, an FC06's or
/// FC16's four bytes, or an exception's code; and the CRC (Modbus over serial line, 2.5.1).
fn rtu_answer_len(bytes: &[u8]) -> Option<usize> {
    let function = *bytes.get(1)?;
    Some(match function {
        0x03 => 3 + usize::from(*bytes.get(2)?) + 2,
        0x06 | 0x10 => 8,
        f if f & 0x80 != 0 => 5,
        other => panic!("an answer of function {other:#04x}"),
    })
}

/// Relays bytes between whirl's end of a serial line (`bridge`, a pty master) and the
/// simulator's (`controller`), answer frame by answer frame, and delivers one FC06 answer
/// twice: the copy once the bridge has sent its next request, when that is an FC06 too
/// (the first such pair). A late answer, as a controller that answered a request twice or a
/// line that echoes gives one; a copy that arrived before the next request was sent,
/// tokio-modbus would drop itself with whatever else waits in its buffer. Says whether it
/// did.
async fn duplicating_relay(
    mut bridge: tokio_serial::SerialStream,
    mut controller: tokio_serial::SerialStream,
    duplicated: &mut bool,
) -> std::io::Result<()> {
    let (mut asked, mut chunk) = ([0u8; 512], [0u8; 512]);
    let (mut answers, mut last_fc06): (Vec<u8>, Option<Vec<u8>>) = (Vec::new(), None);
    loop {
        tokio::select! {
            n = bridge.read(&mut asked) => {
                let n = n?;
                let copy = last_fc06.take();
                if let (Some(frame), false, Some(0x06)) = (copy, *duplicated, asked[..n].get(1)) {
                    bridge.write_all(&frame).await?;
                    *duplicated = true;
                }
                controller.write_all(&asked[..n]).await?;
            }
            n = controller.read(&mut chunk) => {
                answers.extend_from_slice(&chunk[..n?]);
                while let Some(len) = rtu_answer_len(&answers).filter(|&len| answers.len() >= len) {
                    let frame: Vec<u8> = answers.drain(..len).collect();
                    bridge.write_all(&frame).await?;
                    if frame[1] == 0x06 {
                        last_fc06 = Some(frame);
                    }
                }
            }
        }
    }
}

/// Modbus over serial line has no transaction number: an FC06 answer delivered twice is
/// read as the answer to the bridge's next request. That copy answers the request before,
/// not this one, so the bridge takes it for a lost answer, opens the line again (clearing
/// what waits on it) and re-sends; the controller still runs each segment once. (It once
/// ended the stream: "FC06 write to register 34: answered WriteSingle { address: 33, … }".)
#[tokio::test]
async fn an_answer_delivered_twice_on_a_serial_line_is_skipped_and_no_segment_is_lost() {
    let (segments, moving) = program(120);
    let bank = bank(BankOptions::default().slots);
    let clock = ClockOptions {
        time_scale: MODBUS_TIME_SCALE,
        max_step: Some(whirl::judge::dry_run::SIM_MAX_STEP),
        ..ClockOptions::default()
    };
    let (server_end, relay_controller) = tokio_serial::SerialStream::pair().unwrap();
    let (relay_bridge, bridge_end) = tokio_serial::SerialStream::pair().unwrap();
    let path = tokio_serial::SerialPort::name(&bridge_end).unwrap();
    let options = options();
    let link = ModbusLink::Rtu {
        path,
        baud: 115_200,
    };
    let (mut events, mut duplicated) = (Vec::new(), false);
    let mut log = ExecLog::discard();
    let outcome = {
        let serving = serve_rtu(server_end, Arc::clone(&bank), clock, |e| {
            events.push(e.clone())
        });
        let relaying = duplicating_relay(relay_bridge, relay_controller, &mut duplicated);
        let streaming =
            tokio::time::timeout(LIMIT, stream_modbus(&link, segments, options, &mut log));
        tokio::select! {
            streamed = streaming => streamed.expect("done in time").expect("the stream runs"),
            ended = serving => panic!("the simulator's server ended: {ended:?}"),
            ended = relaying => panic!("the relay ended: {ended:?}"),
        }
    };
    drop(bridge_end);
    events.extend(bank.lock().unwrap().take_events());
    assert!(duplicated, "the relay delivered an answer twice");
    assert_each_segment_once(&outcome, &events, &moving);
    assert!(outcome.reconnects >= 1, "{outcome:?}");
}

/// A third-party Modbus client (pymodbus, `tests/clients/modbus_status.py`), sharing no
/// code with whirl or tokio-modbus, reads the simulator's identification and status blocks
/// as docs/modbus.md lays them out.
#[tokio::test]
async fn pymodbus_reads_the_simulators_identification_and_status() {
    if !util::python_with("pymodbus", "pymodbus") {
        return;
    }
    let slots = 8;
    let bank = bank(slots);
    let script = util::root().join("tests/clients/modbus_status.py");
    let run = served(
        &bank,
        |_, _| Fault::None,
        |_, direct| {
            tokio::task::spawn_blocking(move || {
                Command::new("python3")
                    .arg(script)
                    .args([direct.ip().to_string(), direct.port().to_string()])
                    .output()
                    .expect("python3 runs the client")
            })
        },
    )
    .await;
    let output = run.result.expect("the client's thread");
    let stdout = String::from_utf8_lossy(&output.stdout);
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{}: {stderr}", output.status);
    let read: serde_json::Value = serde_json::from_str(stdout.trim()).unwrap();
    let registers = |block: &str| -> Vec<u16> {
        serde_json::from_value(read[block].clone()).unwrap_or_else(|e| panic!("{block}: {e}"))
    };
    let (ident, status) = (registers("identification"), registers("status"));
    assert_eq!(ident.len(), 8);
    assert_eq!(status.len(), usize::from(STATUS_LEN));
    // "WH" "RL", map version 1, N slots of 16 registers.
    assert_eq!(&ident[0..2], &MAGIC);
    assert_eq!(ident[2], 1);
    assert_eq!(ident[3], slots);
    assert_eq!(ident[4], 16);
    // A controller nothing has been sent to: idle, no alarm, an empty ring.
    assert_eq!(status[0], IDLE);
    assert_eq!(status[1], 0);
    assert_eq!((status[TAIL_IN_STATUS], status[HEAD_IN_STATUS]), (0, 0));
}
