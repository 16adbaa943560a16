//! No byte sequence panics the controller, and the protocol's invariants hold whatever
//! arrives.

use proptest::prelude::*;

use super::*;
use crate::{ConfigError, TimeError};

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn random_bytes_and_time_never_panic(
        chunks in proptest::collection::vec(
            (proptest::collection::vec(any::<u8>(), 0..200), 0.0f64..0.3),
            0..30,
        ),
        rx in prop_oneof![Just(128usize), Just(1024usize), 2usize..64],
    ) {
        let mut sim = sim_with(ControllerOptions { rx_buffer_size: rx, ..ControllerOptions::default() });
        let mut answers = 0;
        let mut lines = 0;
        for (bytes, dt) in chunks {
            sim.receive(&bytes);
            sim.advance(dt).unwrap();
            prop_assert!(sim.rx_free() < rx);
            answers += responses(&output(&mut sim)).len();
            lines += sim.take_events().iter().filter(|e| matches!(e, Event::Line { .. })).count();
        }
        // Exactly one answer per line taken, whatever the bytes were.
        prop_assert_eq!(answers, lines);
    }

    #[test]
    fn gcode_like_lines_never_panic(
        lines in proptest::collection::vec(
            "(N[0-9]{1,8} ?)?([GMXZCFSPYTgmxzc] ?[-+]?[0-9]{0,6}(\\.[0-9]{0,4})? ?){0,6}(\\([a-z?!~ ]{0,5}\\))?",
            0..40,
        ),
        dt in 0.0f64..2.0,
    ) {
        let mut sim = new_sim();
        for line in &lines {
            sim.receive(format!("{line}\n").as_bytes());
            sim.advance(dt).unwrap();
        }
        let position = sim.position().to_array();
        prop_assert!(position.iter().all(|v| v.is_finite()));
    }
}

#[test]
fn bad_options_and_time_steps_are_errors() {
    let bad = |options: ControllerOptions| Controller::new(&profile(), options).unwrap_err();
    assert!(matches!(
        bad(ControllerOptions {
            rx_buffer_size: 1,
            ..ControllerOptions::default()
        }),
        ConfigError::Option {
            name: "rx_buffer_size",
            ..
        }
    ));
    assert!(matches!(
        bad(ControllerOptions {
            planner_blocks: 0,
            ..ControllerOptions::default()
        }),
        ConfigError::Option {
            name: "planner_blocks",
            ..
        }
    ));
    assert!(matches!(
        bad(ControllerOptions {
            junction_deviation: f64::NAN,
            ..ControllerOptions::default()
        }),
        ConfigError::Option {
            name: "junction_deviation",
            ..
        }
    ));
    assert!(matches!(
        bad(ControllerOptions {
            start: crate::Position {
                x: f64::INFINITY,
                z: 0.0,
                c: 0.0
            },
            ..ControllerOptions::default()
        }),
        ConfigError::Option { name: "start", .. }
    ));
    let mut profile = profile();
    profile.c.accel = 0.0;
    assert_eq!(
        Controller::new(&profile, ControllerOptions::default()).unwrap_err(),
        ConfigError::Profile {
            key: "axes.c.accel",
            value: 0.0
        }
    );
    let mut sim = new_sim();
    for dt in [-1.0, f64::NAN, f64::INFINITY] {
        assert!(matches!(sim.advance(dt), Err(TimeError(_))));
    }
    assert!(sim.advance(0.0).is_ok());
}
