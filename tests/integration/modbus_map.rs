//! The two sides of `docs/modbus.md` meet: whirl's bridge (`whirl::protocol::modbus`, the ring
//! writer) streams a planned program into the simulator's register bank
//! (`whirl_sim::modbus`), written apart from it, in front of the simulated controller.
//! Only the Modbus requests and answers pass between them, translated field by field.
//!
//! Checked from the controller's own execution record: every segment is taken once and
//! answered `ok`, every motion segment executes exactly once and in order (its block's N
//! word is its sequence number), and the machine ends where the program says. Once with a
//! clean link and a roomy ring, once with a ring of four slots (back-pressure, HEAD and
//! TAIL wrapping dozens of times) and every fifth answer lost, so the writer re-sends
//! requests the bank has already carried out.

use std::time::Duration;

use crate::util;
use whirl::config::job::Job;
use whirl::config::machine::MachineProfile;
use whirl::judge::simulator::machine;
use whirl::post::modbus::Segment;
use whirl::program::{Position, Program};
use whirl::protocol::modbus::map::State;
use whirl::protocol::modbus::{
    Exception, Request, Response, RingWriter, WriterEvent, WriterOptions,
};
use whirl_sim::modbus::{self as bank, Bank, BankOptions};
use whirl_sim::{Controller, ControllerOptions, Event};

/// A writer's request as the simulator's bank takes it (shared with the override tests).
pub(crate) fn to_bank(request: &Request) -> bank::Request {
    match request {
        Request::ReadHolding { address, count } => bank::Request::ReadHolding {
            address: *address,
            count: *count,
        },
        Request::WriteSingle { address, value } => bank::Request::WriteSingle {
            address: *address,
            value: *value,
        },
        Request::WriteMultiple { address, values } => bank::Request::WriteMultiple {
            address: *address,
            values: values.clone(),
        },
    }
}

/// The bank's answer as the writer reads it.
pub(crate) fn from_bank(
    answer: Result<bank::Response, bank::Exception>,
) -> Result<Response, Exception> {
    match answer {
        Ok(bank::Response::ReadHolding(values)) => Ok(Response::ReadHolding(values)),
        Ok(bank::Response::WriteSingle { address, value }) => {
            Ok(Response::WriteSingle { address, value })
        }
        Ok(bank::Response::WriteMultiple { address, count }) => {
            Ok(Response::WriteMultiple { address, count })
        }
        Err(e) => Err(match e.code() {
            0x01 => Exception::IllegalFunction,
            0x02 => Exception::IllegalDataAddress,
            0x03 => Exception::IllegalDataValue,
            0x04 => Exception::ServerDeviceFailure,
            0x06 => Exception::ServerDeviceBusy,
            other => panic!("exception {other:#04x} is not in the map"),
        }),
    }
}

/// What one stream left behind.
struct Outcome {
    writer: Vec<WriterEvent>,
    controller: Vec<Event>,
    position: [f64; 3],
}

/// Streams `segments` through a bank of `slots` slots, losing the answer to every
/// `lose_every`-th request (the bank carried it out; the writer hears nothing).
fn stream(
    profile: &MachineProfile,
    segments: Vec<Segment>,
    slots: u16,
    lose_every: Option<usize>,
) -> Outcome {
    let controller = Controller::new(&machine(profile), ControllerOptions::default()).unwrap();
    let options = BankOptions {
        slots,
        ..BankOptions::default()
    };
    let mut bank = Bank::new(controller, options).unwrap();
    let mut writer = RingWriter::new(segments, WriterOptions::default()).unwrap();
    let dt = 0.005;
    let (mut now, mut sent) = (Duration::ZERO, 0usize);
    let (mut writer_events, mut controller_events) = (Vec::new(), Vec::new());
    while !writer.is_finished() {
        while let Some(request) = writer.poll(now) {
            let answer = from_bank(bank.request(&to_bank(&request)));
            sent += 1;
            if lose_every.is_some_and(|k| sent % k == 0) {
                writer.timeout();
            } else {
                writer.response(answer);
            }
        }
        writer_events.extend(std::iter::from_fn(|| writer.next_event()));
        bank.advance(dt).unwrap();
        controller_events.extend(bank.take_events());
        now += Duration::from_secs_f64(dt);
        assert!(now < Duration::from_secs(3600), "the stream stalled");
    }
    writer_events.extend(std::iter::from_fn(|| writer.next_event()));
    Outcome {
        writer: writer_events,
        controller: controller_events,
        position: bank.controller().position().to_array(),
    }
}

#[test]
fn a_planned_program_streams_through_the_register_map_each_segment_once() {
    let profile = MachineProfile::builtin_sim().unwrap();
    let job = Job::load(&util::example("trapezoidal")).unwrap();
    let plan = whirl::plan::plan(&job, &profile).unwrap();
    // The lead-in (rapids, spindle on, plunge) and a few hundred linked moves.
    let program = Program {
        moves: plan.program.moves[..300].to_vec(),
    };
    let segments = whirl::post::modbus::segments(&program).unwrap();
    let count = segments.len() as u32;
    assert!(
        segments
            .iter()
            .filter(|s| matches!(s, Segment::Linked { .. }))
            .count()
            > 250
    );
    // Sequence numbers are 1, 2, …; the motion segments are the ones with blocks, less any
    // that ends where the machine already is (grbl plans no block for it). Comments are
    // not segments, so the program's blocks are walked past them.
    let start = ControllerOptions::default().start.to_array();
    let steps: Vec<_> = program
        .steps(Position::known(start[0], start[1], start[2]))
        .filter(|s| !matches!(s.action, whirl::program::Move::Comment(_)))
        .collect();
    assert_eq!(steps.len() + 1, segments.len(), "M2 is added at the end");
    let moving: Vec<u32> = steps
        .iter()
        .zip(1..)
        .filter(|(s, _)| s.action.target().is_some() && s.from != s.to)
        .map(|(_, sequence)| sequence)
        .collect();
    let end = steps.last().unwrap().to;

    for (slots, lose_every) in [(32, None), (4, Some(5))] {
        let outcome = stream(&profile, segments.clone(), slots, lose_every);
        let case = format!("{slots} slots, lose every {lose_every:?}");
        assert_eq!(outcome.writer.last(), Some(&WriterEvent::Done), "{case}");
        // Published once each, in order.
        let published: Vec<u32> = outcome
            .writer
            .iter()
            .filter_map(|e| match e {
                WriterEvent::Published { sequence, .. } => Some(*sequence),
                _ => None,
            })
            .collect();
        assert_eq!(published, (1..=count).collect::<Vec<_>>(), "{case}");
        // Every slot became one line, answered ok, N = its sequence number.
        let answered: Vec<Option<u32>> = outcome
            .controller
            .iter()
            .filter_map(|e| match e {
                Event::Line { n, error, text, .. } => {
                    assert_eq!(*error, None, "{case}: {text}");
                    Some(*n)
                }
                _ => None,
            })
            .collect();
        assert_eq!(
            answered,
            (1..=count).map(Some).collect::<Vec<_>>(),
            "{case}"
        );
        // Every motion segment executed exactly once, in order, to completion.
        let executed: Vec<u32> = outcome
            .controller
            .iter()
            .filter_map(|e| match e {
                Event::Executed(block) => {
                    assert!(block.completed, "{case}");
                    block.n
                }
                _ => None,
            })
            .collect();
        assert_eq!(executed, moving, "{case}");
        // No alarm, and the last status says done with everything executed.
        assert!(
            !outcome
                .controller
                .iter()
                .any(|e| matches!(e, Event::Alarm { .. })),
            "{case}"
        );
        let last = outcome
            .writer
            .iter()
            .rev()
            .find_map(|e| match e {
                WriterEvent::Status(s) => Some(*s),
                _ => None,
            })
            .unwrap();
        assert_eq!(
            (last.state, last.executed, last.alarm),
            (State::Done, count, None)
        );
        // Where the program ends: the map rounds to 0.1 µm and 10⁻⁴ °, and the controller
        // holds the target in its own numbers (grbl's 32-bit floats: at C ≈ 4000° they are
        // 2.4·10⁻⁴ ° apart), rounding it again by up to half their spacing.
        let [x, z, c] = outcome.position;
        let held = |v: f64| 0.5e-4 + profile.number.spacing_at(v) / 2.0 + 1e-9;
        let [ex, ez, ec] = [end.x, end.z, end.c].map(Option::unwrap);
        assert!((x - ex).abs() <= held(ex), "{case}: X {x}");
        assert!((z - ez).abs() <= held(ez), "{case}: Z {z}");
        assert!((c - ec).abs() <= held(ec), "{case}: C {c}");
        assert_eq!(
            [last.x, last.z].map(f64::from),
            [x, z].map(|v| (v * 1e4).round()),
            "{case}"
        );
    }
}
