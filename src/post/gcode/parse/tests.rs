//! Tests of the G-code reader, kept apart from it for length: words, comments and numbers,
//! modes, G92 undone in one frame, errors naming line, column and word, and input that must
//! never panic.

use super::*;

fn err(text: &str) -> ParseError {
    match read_program(text, false) {
        Ok(program) => panic!("{text:?} parsed as {program:?}"),
        Err(error) => error,
    }
}

fn kind_at(text: &str) -> (usize, usize, ParseErrorKind) {
    let e = err(text);
    (e.line, e.column, e.kind)
}

#[test]
fn words_comments_and_numbers() {
    let line = parse_line("n10 g01 X-.5 z 3. c+2 F100 (feed (in) ; rest", 7);
    assert!(matches!(
        line,
        Err(ParseError {
            column: 34,
            kind: ParseErrorKind::NestedComment,
            ..
        })
    ));
    let line = parse_line("N10 g01 X-.5 z 3. c+2 F100 (a; b) ; rest ", 7).unwrap();
    assert_eq!(line.number, 7);
    let kinds: Vec<WordKind> = line.words.iter().map(|w| w.kind).collect();
    assert_eq!(
        kinds,
        vec![
            WordKind::LineNumber(10),
            WordKind::G(GCode::Linear),
            WordKind::X(-0.5),
            WordKind::Z(3.0),
            WordKind::C(2.0),
            WordKind::F(100.0),
        ]
    );
    assert_eq!(line.words[3].column, 14);
    assert_eq!(line.comments, vec!["a; b".to_owned(), "rest".to_owned()]);
    assert!(parse_line(" % ", 1).unwrap().percent);
    assert!(parse_line("G64 P0.001 Q0", 1).is_ok());
    // G92.1 is supported, in either case and with a trailing zero.
    for text in ["G92.1", "g92.1", "G92.10"] {
        let line = parse_line(text, 1).unwrap();
        assert_eq!(
            line.words[0].kind,
            WordKind::G(GCode::ClearOffset),
            "{text}"
        );
    }
    assert_eq!(GCode::ClearOffset.to_string(), "G92.1");
    assert_eq!(GCode::SetPosition.to_string(), "G92");
    assert_eq!(
        parse_line("G00", 1).unwrap().words[0].kind,
        WordKind::G(GCode::Rapid)
    );
}

#[test]
fn to_program_follows_modes() {
    let text = "\
%
G21 G90 G94 G7
G64 P0.001 Q0
(start)
M3 S3000
G0 X24 Z-1 C0
G1 X21 F200
G93 G1 Z-0.5 C90 F100
G91 G1 C90 F50 ; relative
G90 G92 C0
G94 G1 X30 F500
G20 G1 Z1 F10
G8 G0 X1
S2000
M5
M2
G0 X99
%
";
    let program = read_program(text, false).unwrap();
    let expected = vec![
        Move::Comment("start".into()),
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
        Move::Comment("relative".into()),
        Move::Linked {
            x: 10.5,
            z: -0.5,
            c: 180.0,
            minutes: 0.02,
        },
        Move::Feed {
            x: Some(15.0),
            z: None,
            c: None,
            feed: 500.0,
        },
        Move::Feed {
            x: None,
            z: Some(25.4),
            c: None,
            feed: 254.0,
        },
        Move::Rapid {
            x: Some(25.4),
            z: None,
            c: None,
        },
        Move::SpindleOn { rpm: 2000.0 },
        Move::SpindleOff,
    ];
    assert_eq!(program.moves, expected);
}

#[test]
fn g92_is_undone_and_c_counts_on_in_one_frame() {
    // C10 renamed as 0 (an offset of 10), a relative move to 5 (15 in the program's
    // frame), G92.1: the controller reads 15, so the relative C5 goes to 20, and a G93
    // move without C stays at 20. G92.1 with axis words clears, then moves them in
    // the current motion mode.
    let text = "\
G0 X1 Z0 C10
G92 C0
G91 G0 C5
G92.1
G0 C5
G90 G93 G1 Z1 F10
G92.1 G0 C0
";
    let (program, lines) = read_program_with_lines(text, false).unwrap();
    let c = |c: f64| Move::Rapid {
        x: None,
        z: None,
        c: Some(c),
    };
    let expected = vec![
        Move::Rapid {
            x: Some(1.0),
            z: Some(0.0),
            c: Some(10.0),
        },
        c(15.0),
        c(20.0),
        Move::Linked {
            x: 1.0,
            z: 1.0,
            c: 20.0,
            minutes: 0.1,
        },
        c(0.0),
    ];
    assert_eq!(program.moves, expected);
    assert_eq!(lines, [1, 3, 5, 6, 7]);
}

#[test]
fn two_turns_renamed_to_zero_are_still_two_turns() {
    // 720° renamed as 0°: the move to 60° in the renamed frame is a turn of 60° to
    // 780°, whole turns kept, and so is one after a second renaming.
    let text = "G0 X10 Z0 C0\nG93 G1 Z1 C720 F90\nG92 C0\nG1 Z1.1 C60 F1000\n\
                G92 C30\nG1 Z1.2 C40 F1000\n";
    let program = read_program(text, false).unwrap();
    let c: Vec<Option<f64>> = program
        .steps(crate::program::Position::UNKNOWN)
        .map(|s| s.to.c)
        .collect();
    assert_eq!(c, [0.0, 720.0, 780.0, 790.0].map(Some));
}

#[test]
fn renaming_an_unknown_c_anchors_the_frame_and_clearing_it_is_refused() {
    // C never positioned: G92 C30 anchors the frame there, so C40 is 10° on.
    let program = read_program("G92 C30\nG0 C40\nG92 C0\nG0 C5\n", false).unwrap();
    let c: Vec<Option<f64>> = program
        .moves
        .iter()
        .map(|m| m.target().unwrap().c)
        .collect();
    assert_eq!(c, [Some(40.0), Some(45.0)]);
    // Clearing that renaming leaves C where nobody knows.
    let e = err("G92 C30\nG0 C40\nG92.1\nG0 C500\n");
    assert_eq!((e.line, e.column, &e.kind), (3, 1, &ParseErrorKind::LostC));
    assert!(
        e.to_string().contains("position C before renaming it"),
        "{e}"
    );
    // A known C renamed and cleared is fine.
    assert!(read_program("G0 C5\nG92 C0\nG92.1\nG0 C500\n", false).is_ok());
}

#[test]
fn modal_motion_and_incremental_moves() {
    let program = read_program("G0 X1 Z2 C3\nX4\nG91 Z1\nC-1\n", false).unwrap();
    let targets: Vec<_> = program.moves.iter().map(|b| b.target().unwrap()).collect();
    assert_eq!(targets[1].x, Some(4.0));
    assert_eq!(targets[2].z, Some(3.0));
    assert_eq!(targets[3].c, Some(2.0));
}

#[test]
fn syntax_errors_name_line_and_column() {
    use ParseErrorKind::*;
    assert_eq!(kind_at("G0 X1\nG0 A1"), (2, 4, UnknownWord('A')));
    assert_eq!(kind_at("G0 X"), (1, 4, MissingNumber('X')));
    assert_eq!(kind_at("G0 X-"), (1, 4, MissingNumber('X')));
    assert_eq!(kind_at("G0 X."), (1, 4, MissingNumber('X')));
    assert_eq!(kind_at("G0 X1 (open"), (1, 7, UnclosedComment));
    assert_eq!(kind_at("(a (b))"), (1, 4, NestedComment));
    assert_eq!(kind_at("G0 X1 %"), (1, 7, PercentNotAlone));
    assert_eq!(kind_at("G0 #1"), (1, 4, UnexpectedCharacter('#')));
    assert_eq!(kind_at("/G0 X1"), (1, 1, UnexpectedCharacter('/')));
    assert_eq!(kind_at("G0 X1\r"), (1, 6, UnexpectedCharacter('\r')));
    assert_eq!(kind_at("G2 X1"), (1, 1, UnsupportedCode("G2".into())));
    assert_eq!(kind_at("G92.2"), (1, 1, UnsupportedCode("G92.2".into())));
    assert_eq!(
        kind_at("G0 X0 G92.3"),
        (1, 7, UnsupportedCode("G92.3".into()))
    );
    // G92 and G92.1 share the non-modal group.
    assert_eq!(
        kind_at("G92 G92.1 C0"),
        (1, 5, ModalConflict("G92".into(), "G92.1".into()))
    );
    assert_eq!(kind_at("G-1"), (1, 1, UnsupportedCode("G-1".into())));
    assert_eq!(kind_at("M4 S100"), (1, 1, UnsupportedCode("M4".into())));
    assert_eq!(kind_at("N1.5 G0 X1"), (1, 1, BadLineNumber("N1.5".into())));
    assert_eq!(kind_at("N-1 G0 X1"), (1, 1, BadLineNumber("N-1".into())));
    assert_eq!(
        kind_at("N99999999999 G0 X1"),
        (1, 1, BadLineNumber("N99999999999".into()))
    );
    assert_eq!(kind_at("G0 N1 X1"), (1, 4, LineNumberNotFirst));
    assert_eq!(kind_at("G0 X1 X2"), (1, 7, RepeatedWord('X')));
    assert_eq!(
        kind_at("G0 G1 X2"),
        (1, 4, TwoMotionCodes(GCode::Rapid, GCode::Linear))
    );
    assert_eq!(
        kind_at("G90 G91"),
        (1, 5, ModalConflict("G90".into(), "G91".into()))
    );
    assert_eq!(
        kind_at("M3 M5 S10"),
        (1, 4, ModalConflict("M3".into(), "M5".into()))
    );
    assert_eq!(
        kind_at("G92 G1 C0 F1"),
        (1, 5, AxisWordConflict(GCode::Linear))
    );
    assert_eq!(kind_at("G61 P0.1"), (1, 5, UnusedWord('P')));
    assert_eq!(kind_at("Q1"), (1, 1, UnusedWord('Q')));
    assert_eq!(kind_at("G1 X1 F-5"), (1, 7, Negative('F')));
    assert_eq!(kind_at("S-5"), (1, 1, Negative('S')));
}

#[test]
fn program_errors_name_line_and_word() {
    use ParseErrorKind::*;
    assert_eq!(kind_at("G21\nX1"), (2, 1, NoMotionMode));
    assert_eq!(kind_at("G92"), (1, 1, G92WithoutAxis));
    assert_eq!(kind_at("G92 X0"), (1, 5, G92OnLinearAxis('X')));
    // G92.1 takes no axis words: they are a move, which needs a motion mode.
    assert_eq!(kind_at("G92.1 C0"), (1, 7, NoMotionMode));
    // After renaming an unknown C, G92.1 leaves C where nobody knows.
    assert_eq!(kind_at("G92 C30\nG92.1\nG91 G0 C1"), (2, 1, LostC));
    assert_eq!(kind_at("G0 Y1"), (1, 4, YAxis));
    assert_eq!(
        kind_at("G0 X1 Z1 C1\nG93 G1 X2"),
        (2, 5, InverseTimeWithoutFeed)
    );
    assert_eq!(kind_at("G0 X1 Z1 C1\nG93 G1 X2 F0"), (2, 11, ZeroFeed));
    assert_eq!(kind_at("G1 X1"), (1, 1, FeedUndefined));
    assert_eq!(kind_at("G1 X1 F0"), (1, 7, ZeroFeed));
    // A feed-mode change forgets the units-per-minute feed.
    assert_eq!(
        kind_at("G0 X0 Z0 C0\nG1 X1 F100\nG93 G1 X2 F10\nG94 G1 X3"),
        (4, 5, FeedUndefined)
    );
    assert_eq!(kind_at("G91 G0 X1"), (1, 8, UnknownPosition(Axis::X)));
    assert_eq!(
        kind_at("G0 X1 Z1\nG93 G1 X2 F10"),
        (2, 5, UnknownPosition(Axis::C))
    );
    assert_eq!(kind_at("M3"), (1, 1, SpindleSpeedMissing));
    assert_eq!(kind_at("M3 S0"), (1, 1, SpindleSpeedMissing));
    assert_eq!(kind_at("M3 S100\nS0"), (2, 1, SpindleSpeedMissing));
}

#[test]
fn line_numbers_span_u32() {
    let line = parse_line("N4294967295 G0 X1", 1).unwrap();
    assert_eq!(line.words[0].kind, WordKind::LineNumber(u32::MAX));
    assert_eq!(
        kind_at("N4294967296"),
        (1, 1, ParseErrorKind::BadLineNumber("N4294967296".into()))
    );
}

proptest::proptest! {
    #[test]
    fn arbitrary_text_never_panics(text in "[ -~\t\r\n\u{80}-\u{3ff}]{0,200}") {
        let _ = read_program(&text, false);
    }

    #[test]
    fn gcode_like_text_never_panics(
        lines in proptest::collection::vec(
            "(N[0-9]{1,3} )?([GMXYZCFSPQ] ?[-+]?[0-9]{0,4}(\\.[0-9]{0,3})? ?){0,6}(\\([a-z ]{0,5}\\))?",
            0..30,
        ),
        diameter in proptest::bool::ANY,
    ) {
        let _ = read_program(&lines.join("\n"), diameter);
    }
}

#[test]
fn error_messages_say_where_and_what() {
    let e = err("G0 X1\nG93 G1 X2");
    assert_eq!(
        e.to_string(),
        "line 2, column 5: G1 in inverse-time mode (G93) without F on its line"
    );
}
