//! Tests of the G-code writers, kept apart from them for length: both dialects' formats, line
//! lengths and numbers, inverse-time feed, comments, settings, and round trips through the
//! reader.

use super::*;
use crate::post::gcode::parse::{parse, read_program, GCode, WordKind};
use proptest::prelude::*;

fn grbl() -> PostSettings {
    PostSettings {
        dialect: Dialect::GrblHal,
        linear_decimals: 3,
        angular_decimals: 4,
        x_diameter: false,
        blend_tolerance_mm: None,
        max_line_length: 256,
    }
}

fn linuxcnc() -> PostSettings {
    PostSettings {
        dialect: Dialect::LinuxCnc,
        linear_decimals: 3,
        angular_decimals: 4,
        x_diameter: true,
        blend_tolerance_mm: Some(0.001),
        max_line_length: 255,
    }
}

fn sample() -> Program {
    Program {
        moves: vec![
            Move::Comment("whirl test".into()),
            Move::SpindleOn { rpm: 3000.0 },
            Move::Rapid {
                x: Some(12.0),
                z: Some(-1.0),
                c: Some(0.0),
            },
            Move::Feed {
                x: Some(10.5),
                z: None,
                c: None,
                feed: 200.0,
            },
            Move::Linked {
                x: 10.5,
                z: -0.5,
                c: 90.0,
                minutes: 0.01,
            },
            Move::Linked {
                x: 10.25,
                z: 0.0,
                c: 180.0,
                minutes: 0.02,
            },
            Move::Linked {
                x: 10.25,
                z: 0.5,
                c: 270.0,
                minutes: 0.01,
            },
            Move::Feed {
                x: Some(15.0),
                z: None,
                c: None,
                feed: 500.0,
            },
            Move::Rapid {
                x: None,
                z: Some(10.0),
                c: None,
            },
            Move::SpindleOff,
        ],
    }
}

/// `text` without the line numbers grblHAL programs carry (lines without one kept).
fn unnumbered(text: &str) -> String {
    text.lines()
        .map(|l| {
            let rest = l.strip_prefix('N').and_then(|r| {
                let digits = r.len() - r.trim_start_matches(|c: char| c.is_ascii_digit()).len();
                (digits > 0)
                    .then(|| r[digits..].strip_prefix(' '))
                    .flatten()
            });
            format!("{}\n", rest.unwrap_or(l))
        })
        .collect()
}

#[test]
fn grblhal_lines_carry_their_file_line_numbers_and_linuxcnc_lines_none() {
    let text = write(&sample(), &grbl()).unwrap();
    for (i, line) in text.lines().enumerate() {
        assert!(line.starts_with(&format!("N{} ", i + 1)), "{line}");
    }
    let text = write(&sample(), &linuxcnc()).unwrap();
    assert!(text.lines().all(|l| !l.starts_with('N')), "{text}");
}

#[test]
fn a_line_that_fits_only_without_its_number_is_refused() {
    // `G0 X1234.568 Z-1234.568 C123456.789` is 35 characters; with "N3 " in front
    // (after the preamble and the comment) it is 38, over a 37-character limit.
    let program = one(Move::Rapid {
        x: Some(1234.5678),
        z: Some(-1234.5678),
        c: Some(123_456.789),
    });
    let settings = PostSettings {
        max_line_length: 37,
        ..grbl()
    };
    let error = write(&program, &settings).unwrap_err();
    assert!(
        matches!(
            error,
            PostError::LineTooLong {
                length: 38,
                max: 37,
                ..
            }
        ),
        "{error}"
    );
}

#[test]
fn grblhal_format() {
    // Unchanged words are left out (X on the first linked move and on the third),
    // G93/G94 appear only at mode changes, F is on every G1 (1/0.01 min = 100).
    let expected = "\
N1 G21 G90 G94
N2 (whirl test)
N3 M3 S3000
N4 G0 X12 Z-1 C0
N5 G1 X10.5 F200
N6 G93 G1 Z-0.5 C90 F100
N7 G1 X10.25 Z0 C180 F50
N8 G1 Z0.5 C270 F100
N9 G94 G1 X15 F500
N10 G0 Z10
N11 M5
N12 M2
";
    assert_eq!(write(&sample(), &grbl()).unwrap(), expected);
}

#[test]
fn linuxcnc_format() {
    // Diameter mode doubles X; blending with the given tolerance and Q0; % around.
    let expected = "\
%
G21 G90 G94 G7
G64 P0.001 Q0
(whirl test)
M3 S3000
G0 X24 Z-1 C0
G1 X21 F200
G93 G1 Z-0.5 C90 F100
G1 X20.5 Z0 C180 F50
G1 Z0.5 C270 F100
G94 G1 X30 F500
G0 Z10
M5
M2
%
";
    assert_eq!(write(&sample(), &linuxcnc()).unwrap(), expected);
}

#[test]
fn c_is_written_as_it_is_however_many_turns() {
    // Three turns and a quarter: C1170, no G92 anywhere.
    let program = Program {
        moves: vec![
            Move::Rapid {
                x: Some(12.0),
                z: Some(0.0),
                c: Some(0.0),
            },
            Move::Linked {
                x: 12.0,
                z: 6.5,
                c: 1170.0,
                minutes: 0.1,
            },
        ],
    };
    for settings in [grbl(), linuxcnc()] {
        let text = write(&program, &settings).unwrap();
        assert!(text.contains(" C1170 "), "{text}");
        assert!(!text.contains("G92"), "{text}");
    }
}

#[test]
fn linuxcnc_without_blending_uses_exact_path_and_radius_mode() {
    let settings = PostSettings {
        blend_tolerance_mm: None,
        x_diameter: false,
        ..linuxcnc()
    };
    let text = write(&Program::default(), &settings).unwrap();
    assert_eq!(text, "%\nG21 G90 G94 G8\nG61\nM2\n%\n");
}

#[test]
fn spindle_left_on_is_stopped_and_inverse_time_is_left() {
    let program = Program {
        moves: vec![
            Move::SpindleOn { rpm: 2500.5 },
            Move::Linked {
                x: 1.0,
                z: 2.0,
                c: 3.0,
                minutes: 0.5,
            },
        ],
    };
    let text = unnumbered(&write(&program, &grbl()).unwrap());
    assert_eq!(
        text,
        "G21 G90 G94\nM3 S2500.5\nG93 G1 X1 Z2 C3 F2\nM5\nG94\nM2\n"
    );
}

#[test]
fn blend_tolerance_is_never_written_larger() {
    for tolerance in [0.0015, 0.002_000_9, 1e-6, 0.123_456_789] {
        let settings = PostSettings {
            blend_tolerance_mm: Some(tolerance),
            ..linuxcnc()
        };
        let text = write(&Program::default(), &settings).unwrap();
        let line = text.lines().find(|l| l.starts_with("G64")).unwrap();
        let p: f64 = line["G64 P".len()..line.len() - " Q0".len()]
            .parse()
            .unwrap();
        assert!(p <= tolerance && tolerance - p < 1e-6, "{line}");
    }
}

#[test]
fn settings_are_checked() {
    let program = Program::default();
    let cases = [
        (
            PostSettings {
                blend_tolerance_mm: Some(0.01),
                ..grbl()
            },
            PostError::BlendingUnsupported,
        ),
        (
            PostSettings {
                blend_tolerance_mm: Some(0.0),
                ..linuxcnc()
            },
            PostError::BadBlendTolerance(0.0),
        ),
        (
            PostSettings {
                blend_tolerance_mm: Some(5.0),
                ..linuxcnc()
            },
            PostError::BadBlendTolerance(5.0),
        ),
        (
            PostSettings {
                max_line_length: 31,
                ..grbl()
            },
            PostError::LineLengthTooSmall(31),
        ),
        (
            PostSettings {
                linear_decimals: 7,
                ..grbl()
            },
            PostError::TooManyDecimals {
                which: "linear_decimals",
                decimals: 7,
            },
        ),
        (
            PostSettings {
                angular_decimals: 9,
                ..grbl()
            },
            PostError::TooManyDecimals {
                which: "angular_decimals",
                decimals: 9,
            },
        ),
    ];
    for (settings, error) in cases {
        assert_eq!(write(&program, &settings), Err(error));
    }
    let nan = PostSettings {
        blend_tolerance_mm: Some(f64::NAN),
        ..linuxcnc()
    };
    assert!(matches!(
        write(&program, &nan),
        Err(PostError::BadBlendTolerance(_))
    ));
}

fn one(block: Move) -> Program {
    Program {
        moves: vec![Move::Comment("first".into()), block],
    }
}

#[test]
fn unwritable_moves_are_errors_naming_the_move() {
    let bad = [
        Move::Linked {
            x: 1.0,
            z: 1.0,
            c: 1.0,
            minutes: 0.0,
        },
        Move::Linked {
            x: 1.0,
            z: 1.0,
            c: 1.0,
            minutes: -1.0,
        },
        // 1/minutes overflows to infinity.
        Move::Linked {
            x: 1.0,
            z: 1.0,
            c: 1.0,
            minutes: 1e-310,
        },
        Move::Linked {
            x: 1.0,
            z: 1.0,
            c: 1.0,
            minutes: f64::INFINITY,
        },
        Move::Linked {
            x: f64::NAN,
            z: 1.0,
            c: 1.0,
            minutes: 1.0,
        },
        Move::Feed {
            x: Some(1.0),
            z: None,
            c: None,
            feed: 0.0,
        },
        Move::Feed {
            x: Some(1.0),
            z: None,
            c: None,
            feed: f64::NAN,
        },
        Move::Rapid {
            x: None,
            z: Some(f64::INFINITY),
            c: None,
        },
        Move::SpindleOn { rpm: 0.0 },
        Move::SpindleOn { rpm: -5.0 },
    ];
    for case in bad {
        let error = write(&one(case.clone()), &grbl()).unwrap_err();
        assert!(
            matches!(error, PostError::InvalidMove { index: 1, .. }),
            "{case:?}: {error}"
        );
        assert!(error.to_string().starts_with("move 1 (not a file line): "));
    }
}

#[test]
fn a_motion_line_that_cannot_fit_is_an_error_naming_the_move() {
    let settings = PostSettings {
        dialect: Dialect::LinuxCnc,
        max_line_length: 32,
        linear_decimals: 6,
        angular_decimals: 6,
        ..linuxcnc()
    };
    let block = Move::Linked {
        x: 123.456789,
        z: -234.567891,
        c: 3456.789123,
        minutes: 0.012345,
    };
    let error = write(&one(block), &settings).unwrap_err();
    assert!(
        matches!(
            error,
            PostError::LineTooLong {
                index: 1,
                max: 32,
                ..
            }
        ),
        "{error}"
    );
}

#[test]
fn grblhal_rejects_numbers_it_would_truncate() {
    let settings = PostSettings {
        linear_decimals: 6,
        ..grbl()
    };
    let block = Move::Rapid {
        x: None,
        z: Some(-1234.567891),
        c: None,
    };
    let error = write(&one(block.clone()), &settings).unwrap_err();
    assert_eq!(
        error,
        PostError::TooManyDigits {
            index: 1,
            word: "Z-1234.567891".into(),
            digits: 10,
            max: 9,
        }
    );
    // LinuxCNC reads doubles: the same number is fine there.
    let linuxcnc_settings = PostSettings {
        linear_decimals: 6,
        ..linuxcnc()
    };
    assert!(write(&one(block), &linuxcnc_settings).is_ok());
}

#[test]
fn comments_are_sanitized_for_grbl() {
    let program = one(Move::Comment("a (nested) ?!~ ünï\tcode\u{18}".into()));
    let text = unnumbered(&write(&program, &grbl()).unwrap());
    let line = text.lines().nth(2).unwrap();
    assert_eq!(line, "(a [nested] ___ _n_ code )");
}

#[test]
fn linuxcnc_active_comments_are_disarmed() {
    for active in ["MSG, hello", " debug,#<x>", "PY,print(1)", "print ,x"] {
        let text = write(&one(Move::Comment(active.into())), &linuxcnc()).unwrap();
        let line = text.lines().nth(4).unwrap();
        assert!(line.starts_with("(note: "), "{line}");
    }
    // Question marks are fine for LinuxCNC, and plain comments stay as they are.
    let text = write(&one(Move::Comment("pass 2, finish?".into())), &linuxcnc()).unwrap();
    assert_eq!(text.lines().nth(4), Some("(pass 2, finish?)"));
}

#[test]
fn long_comments_are_split_and_keep_their_text() {
    let long: String = (0..700)
        .map(|i| char::from(b'a' + (i % 26) as u8))
        .collect();
    let numbered = write(&one(Move::Comment(long.clone())), &grbl()).unwrap();
    assert!(numbered.lines().all(|l| l.len() <= 256));
    let text = unnumbered(&numbered);
    let comments: Vec<&str> = text
        .lines()
        .filter(|l| l.starts_with('('))
        .skip(1)
        .collect();
    assert_eq!(comments.len(), 3);
    let joined: String = comments.iter().map(|l| &l[1..l.len() - 1]).collect();
    assert_eq!(joined, long);
}

/// What a G-code program does, read line by line: the feed mode each G1 runs in and
/// whether it carries F, and the X written.
struct Modal {
    g1_lines: Vec<(bool, bool)>,
    x_words: Vec<f64>,
}

fn modal_facts(text: &str) -> Modal {
    let mut inverse_time = false;
    let mut facts = Modal {
        g1_lines: Vec::new(),
        x_words: Vec::new(),
    };
    for line in parse(text).unwrap() {
        let mut g1 = false;
        let mut f = false;
        for word in &line.words {
            match word.kind {
                WordKind::G(GCode::InverseTime) => inverse_time = true,
                WordKind::G(GCode::UnitsPerMinute) => inverse_time = false,
                WordKind::G(GCode::Linear) => g1 = true,
                WordKind::F(_) => f = true,
                WordKind::X(x) => facts.x_words.push(x),
                _ => {}
            }
        }
        if g1 {
            facts.g1_lines.push((inverse_time, f));
        }
    }
    facts
}

#[test]
fn every_linked_line_is_in_g93_and_carries_f() {
    let mut moves = vec![Move::Rapid {
        x: Some(5.0),
        z: Some(0.0),
        c: Some(0.0),
    }];
    for i in 1..=20 {
        moves.push(Move::Linked {
            x: 5.0 + (i % 3) as f64 * 0.01,
            z: i as f64 * 0.1,
            c: i as f64 * 18.0,
            minutes: 0.001 * i as f64,
        });
        if i % 7 == 0 {
            moves.push(Move::Feed {
                x: Some(8.0),
                z: None,
                c: None,
                feed: 300.0,
            });
        }
    }
    let program = Program { moves };
    for settings in [grbl(), linuxcnc()] {
        let facts = modal_facts(&write(&program, &settings).unwrap());
        let linked: Vec<_> = facts.g1_lines.iter().filter(|(inv, _)| *inv).collect();
        assert_eq!(linked.len(), 20);
        assert!(facts.g1_lines.iter().all(|(_, f)| *f));
        assert_eq!(facts.g1_lines.len(), 22);
    }
}

#[test]
fn x_doubles_in_diameter_mode() {
    let program = Program {
        moves: vec![
            Move::Rapid {
                x: Some(7.25),
                z: Some(0.0),
                c: None,
            },
            Move::Feed {
                x: Some(3.125),
                z: None,
                c: None,
                feed: 100.0,
            },
        ],
    };
    for (dialect, factor) in [(Dialect::GrblHal, 2.0), (Dialect::LinuxCnc, 2.0)] {
        let settings = PostSettings {
            dialect,
            x_diameter: true,
            blend_tolerance_mm: None,
            ..grbl()
        };
        let facts = modal_facts(&write(&program, &settings).unwrap());
        assert_eq!(facts.x_words, vec![7.25 * factor, 3.125 * factor]);
    }
    let facts = modal_facts(&write(&program, &grbl()).unwrap());
    assert_eq!(facts.x_words, vec![7.25, 3.125]);
}

#[test]
fn inverse_time_feed_gives_the_move_time_to_1e4() {
    for i in 1..3000 {
        let minutes = 1e-4 * 1.0037f64.powi(i);
        let program = one(Move::Linked {
            x: 1.0,
            z: 1.0,
            c: 1.0,
            minutes,
        });
        let text = write(&program, &linuxcnc()).unwrap();
        let line = text.lines().find(|l| l.contains("G1")).unwrap();
        let f: f64 = line.rsplit_once('F').unwrap().1.parse().unwrap();
        let read_minutes = 1.0 / f;
        // Never faster than planned, and right to 1e-4 relative.
        assert!(
            read_minutes >= minutes * (1.0 - 1e-15),
            "{minutes} → {line}"
        );
        assert!(
            (read_minutes - minutes) / minutes < 1e-4,
            "{minutes} → {line}"
        );
    }
}

fn arb_move() -> impl Strategy<Value = Move> {
    let coord = || -300.0..300.0f64;
    let maybe = || proptest::option::of(-300.0..300.0f64);
    prop_oneof![
        "[ -~]{0,400}".prop_map(Move::Comment),
        (maybe(), maybe(), maybe()).prop_map(|(x, z, c)| Move::Rapid { x, z, c }),
        (maybe(), maybe(), maybe(), 1.0..5000.0f64).prop_map(|(x, z, c, feed)| Move::Feed {
            x,
            z,
            c,
            feed
        }),
        (coord(), coord(), -5000.0..5000.0f64, 1e-4..10.0f64)
            .prop_map(|(x, z, c, minutes)| Move::Linked { x, z, c, minutes }),
        (100.0..9000.0f64).prop_map(|rpm| Move::SpindleOn { rpm }),
        Just(Move::SpindleOff),
    ]
}

fn arb_settings() -> impl Strategy<Value = PostSettings> {
    (
        any::<bool>(),
        0..=4u32,
        0..=4u32,
        any::<bool>(),
        32..300usize,
    )
        .prop_map(
            |(linuxcnc, linear_decimals, angular_decimals, x_diameter, max_line_length)| {
                PostSettings {
                    dialect: if linuxcnc {
                        Dialect::LinuxCnc
                    } else {
                        Dialect::GrblHal
                    },
                    linear_decimals,
                    angular_decimals,
                    x_diameter,
                    blend_tolerance_mm: linuxcnc.then_some(0.002),
                    max_line_length,
                }
            },
        )
}

proptest! {
    #[test]
    fn lines_never_exceed_the_limit(
        moves in proptest::collection::vec(arb_move(), 0..40),
        settings in arb_settings(),
    ) {
        let program = Program { moves };
        // Either the text fits, or the writer refused a line that could not fit.
        match write(&program, &settings) {
            Ok(text) => {
                for line in text.lines() {
                    prop_assert!(line.chars().count() <= settings.max_line_length, "{line}");
                    prop_assert!(line.is_ascii());
                }
                prop_assert!(!text.contains('\r'));
            }
            Err(error) => {
                let is_line_too_long = matches!(error, PostError::LineTooLong { .. });
                prop_assert!(is_line_too_long, "{}", error);
            }
        }
    }

    #[test]
    fn values_round_trip_through_the_parser(
        moves in proptest::collection::vec(arb_move(), 0..40),
        settings in arb_settings(),
    ) {
        let settings = PostSettings { max_line_length: 256, ..settings };
        let program = Program { moves };
        let text = write(&program, &settings).unwrap();
        let read = read_program(&text, settings.x_diameter).unwrap();

        // What the controller should hold after each move: every axis rounded to
        // its written decimals (X through the diameter when the controller's X is
        // one).
        let round = |axis: Axis, v: f64| -> f64 {
            match axis {
                Axis::X if settings.x_diameter => {
                    format_number(2.0 * v, settings.linear_decimals).parse::<f64>().unwrap() / 2.0
                }
                Axis::X | Axis::Z => format_number(v, settings.linear_decimals).parse().unwrap(),
                Axis::C => format_number(v, settings.angular_decimals).parse().unwrap(),
            }
        };
        let half = |axis: Axis| -> f64 {
            let d = if axis == Axis::C { settings.angular_decimals } else { settings.linear_decimals };
            let unit = 0.5 * 10f64.powi(-(d as i32));
            if axis == Axis::X && settings.x_diameter { unit / 2.0 } else { unit }
        };
        let mut expected: Vec<[Option<f64>; 3]> = Vec::new();
        let mut expected_times: Vec<f64> = Vec::new();
        let mut rounded = [None; 3];
        for action in &program.moves {
            let Some(t) = action.target() else { continue };
            let targets = [t.x, t.z, t.c];
            for (slot, axis) in Axis::ALL.into_iter().enumerate() {
                if let Some(v) = targets[slot] {
                    rounded[slot] = Some(round(axis, v));
                    prop_assert!((round(axis, v) - v).abs() <= half(axis) * (1.0 + 1e-9));
                }
            }
            if expected.last().unwrap_or(&[None; 3]) != &rounded {
                expected.push(rounded);
                if let Move::Linked { minutes, .. } = action {
                    expected_times.push(*minutes);
                }
            }
        }
        let mut actual: Vec<[Option<f64>; 3]> = Vec::new();
        let mut actual_times: Vec<f64> = Vec::new();
        let mut position = [None; 3];
        for action in &read.moves {
            let Some(t) = action.target() else { continue };
            let targets = [t.x, t.z, t.c];
            for slot in 0..3 {
                if targets[slot].is_some() {
                    position[slot] = targets[slot];
                }
            }
            if actual.last().unwrap_or(&[None; 3]) != &position {
                actual.push(position);
                if let Move::Linked { minutes, .. } = action {
                    actual_times.push(*minutes);
                }
            }
        }
        prop_assert_eq!(&actual, &expected);
        prop_assert_eq!(actual_times.len(), expected_times.len());
        for (read_minutes, planned) in actual_times.iter().zip(&expected_times) {
            prop_assert!(*read_minutes >= *planned * (1.0 - 1e-12));
            prop_assert!((read_minutes - planned) / planned < 1e-4);
        }
        // Comments and spindle blocks survive in order.
        let others = |p: &Program| -> Vec<Move> {
            p.moves.iter().filter(|b| matches!(b, Move::SpindleOn { .. } | Move::SpindleOff)).cloned().collect()
        };
        let spindle_read = others(&read);
        let mut spindle_planned = others(&program);
        // The writer stops a ring left running at the end.
        if let Some(Move::SpindleOn { .. }) = spindle_planned.last() {
            spindle_planned.push(Move::SpindleOff);
        }
        prop_assert_eq!(spindle_read.len(), spindle_planned.len());
        for (r, p) in spindle_read.iter().zip(&spindle_planned) {
            match (r, p) {
                (Move::SpindleOn { rpm: a }, Move::SpindleOn { rpm: b }) => prop_assert!((a - b).abs() <= 0.05 + 1e-9),
                (Move::SpindleOff, Move::SpindleOff) => {}
                _ => prop_assert!(false, "{r:?} vs {p:?}"),
            }
        }
    }
}
