//! The program model: what the planner produces and the writers consume.
//!
//! A [`Program`] is a plain list of [`Block`]s in the machine frame of
//! `kinematics.md`, with no dialect in it: X is the ring-centre offset from the spindle
//! axis (a radius, mm), Z the axial position (mm), C the workpiece turn (degrees, as the
//! G-code carries it). How a block is spelled (G93 or G94, X as radius or diameter, how
//! many decimals) is the writer's business ([`super::post`]).
//!
//! C may be renamed mid-program ([`Block::RebaseC`], G92) so that controllers holding
//! coordinates as 32-bit floats keep their precision, and the renaming cancelled again
//! ([`Block::ClearRebase`], G92.1) so that a program leaves no offset behind. Consumers
//! that need one continuous frame (a limit checker, a simulator, a cycle-time estimate)
//! walk the program with [`Program::steps`], which undoes the renaming.

use std::fmt;

/// A machine axis of the whirling lathe.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Axis {
    /// Ring-centre offset from the spindle axis, mm (a radius).
    X,
    /// Axial position of the whirling unit, mm.
    Z,
    /// Workpiece turn, degrees.
    C,
}

impl Axis {
    /// The three axes in the order G-code words are written: X, Z, C.
    pub const ALL: [Axis; 3] = [Axis::X, Axis::Z, Axis::C];

    /// The G-code letter of the axis.
    pub fn letter(self) -> char {
        match self {
            Axis::X => 'X',
            Axis::Z => 'Z',
            Axis::C => 'C',
        }
    }

    /// The unit of the axis' positions: `"mm"` for X and Z, `"deg"` for C.
    pub fn unit(self) -> &'static str {
        match self {
            Axis::X | Axis::Z => "mm",
            Axis::C => "deg",
        }
    }
}

impl fmt::Display for Axis {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}", self.letter())
    }
}

/// One block of a whirling program in the kinematics.md machine frame:
/// X the ring-centre offset (mm, a radius), Z axial (mm), C the workpiece turn (degrees).
#[derive(Debug, Clone, PartialEq)]
pub enum Block {
    /// A comment for the operator; writers sanitize it for their dialect.
    Comment(String),
    /// G0: rapid positioning; `None` axes do not move.
    Rapid {
        /// Target X, mm (radius).
        x: Option<f64>,
        /// Target Z, mm.
        z: Option<f64>,
        /// Target C, degrees.
        c: Option<f64>,
    },
    /// G1 in units-per-minute mode (G94): plunge and retract moves; feed in mm/min.
    ///
    /// How the feed is shared between linear and rotary axes differs between controllers
    /// (see [`crate::config::machine::check_limits`]); the planner keeps C out of these moves.
    Feed {
        /// Target X, mm (radius).
        x: Option<f64>,
        /// Target Z, mm.
        z: Option<f64>,
        /// Target C, degrees.
        c: Option<f64>,
        /// Feed rate, mm/min (deg/min for a move of C alone).
        feed: f64,
    },
    /// G1 in inverse-time mode (G93): a linked C/X/Z move that takes `minutes`.
    Linked {
        /// Target X, mm (radius).
        x: f64,
        /// Target Z, mm.
        z: f64,
        /// Target C, degrees.
        c: f64,
        /// Duration of the move, minutes.
        minutes: f64,
    },
    /// `G92 C<value>`: rename the current C position (rebasing C so f32 controllers keep precision).
    RebaseC {
        /// The name the current C position gets, degrees.
        c: f64,
    },
    /// `G92.1`: cancel the G92 offset, so that C reads the controller's unrebased position
    /// again and the next program starts in the frame this one started in.
    ///
    /// The machine does not move. Targets after it are in the unrebased frame (the
    /// continuous frame of [`Program::steps`]); a [`Block::RebaseC`] after it starts a new
    /// offset from there. G92.1 cancels the G92 offsets of every axis, X and Z included,
    /// which the program never renames; the model assumes none is active when the program
    /// starts. (LinuxCNC also zeroes the stored offset parameters #5211–#5219.)
    ClearRebase,
    /// Whirling-ring spindle on (`M3 S<rpm>`).
    SpindleOn {
        /// Ring speed, revolutions per minute.
        rpm: f64,
    },
    /// Whirling-ring spindle off (M5).
    SpindleOff,
}

impl Block {
    /// The target of a motion block in the controller's (possibly rebased) C frame, with
    /// `None` for axes the block leaves alone; `None` for blocks that do not move.
    pub fn target(&self) -> Option<Pose> {
        match *self {
            Block::Rapid { x, z, c } | Block::Feed { x, z, c, .. } => Some(Pose { x, z, c }),
            Block::Linked { x, z, c, .. } => Some(Pose::known(x, z, c)),
            Block::Comment(_)
            | Block::RebaseC { .. }
            | Block::ClearRebase
            | Block::SpindleOn { .. }
            | Block::SpindleOff => None,
        }
    }
}

/// A machine position, axis by axis; `None` where it is not known (before the program
/// has positioned that axis, when the start was not given).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Pose {
    /// X, mm (radius).
    pub x: Option<f64>,
    /// Z, mm.
    pub z: Option<f64>,
    /// C, degrees.
    pub c: Option<f64>,
}

impl Pose {
    /// Nothing known: where a program starts when the caller does not know the machine's
    /// position.
    pub const UNKNOWN: Pose = Pose {
        x: None,
        z: None,
        c: None,
    };

    /// A fully known position.
    pub fn known(x: f64, z: f64, c: f64) -> Pose {
        Pose {
            x: Some(x),
            z: Some(z),
            c: Some(c),
        }
    }

    /// The position of one axis.
    pub fn get(&self, axis: Axis) -> Option<f64> {
        match axis {
            Axis::X => self.x,
            Axis::Z => self.z,
            Axis::C => self.c,
        }
    }
}

/// A whirling program: the blocks in execution order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Program {
    /// The blocks, in order. Error messages elsewhere name a block by its index here.
    pub blocks: Vec<Block>,
}

impl Program {
    /// Walks the program block by block, giving each block's start and end position in
    /// one continuous frame: the controller's frame at program start, with every
    /// [`Block::RebaseC`] undone (so C keeps counting whole turns across G92).
    ///
    /// The controller is taken to have no G92 offset active when the program starts, so
    /// the continuous frame is its unrebased frame: after a [`Block::ClearRebase`] the
    /// controller's C equals the continuous C, and later targets are read as they are.
    ///
    /// `start` is where the machine is when the program starts ([`Pose::UNKNOWN`] when
    /// that is not known: an axis then becomes known at the first block that positions
    /// it). If C is unknown when a block renames it, the continuous frame is anchored at
    /// that renaming (C takes the new name's value there); speeds and turn counts, all a
    /// rotary axis needs, stay right. Such an anchored frame has no known relation to the
    /// unrebased one, so a [`Block::ClearRebase`] after it makes C unknown again (its step
    /// ends with C `None`) until a block positions C.
    pub fn steps(&self, start: Pose) -> Steps<'_> {
        Steps {
            blocks: self.blocks.iter().enumerate(),
            position: start,
            c_offset: 0.0,
            c_anchored: false,
        }
    }
}

/// One block of a program with the positions it moves between; see [`Program::steps`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Step<'a> {
    /// Index of the block in [`Program::blocks`].
    pub index: usize,
    /// The block.
    pub block: &'a Block,
    /// Position before the block, in the unrebased frame.
    pub from: Pose,
    /// Position after the block, in the unrebased frame (equal to `from` for blocks that
    /// do not move, except that a [`Block::ClearRebase`] can make C unknown; see
    /// [`Program::steps`]).
    pub to: Pose,
}

/// Iterator over the [`Step`]s of a program; see [`Program::steps`].
#[derive(Debug, Clone)]
pub struct Steps<'a> {
    blocks: std::iter::Enumerate<std::slice::Iter<'a, Block>>,
    position: Pose,
    /// Unrebased C minus the controller's C.
    c_offset: f64,
    /// The continuous frame was anchored at a renaming of an unknown C, so it is not the
    /// controller's unrebased frame.
    c_anchored: bool,
}

impl<'a> Iterator for Steps<'a> {
    type Item = Step<'a>;

    fn next(&mut self) -> Option<Step<'a>> {
        let (index, block) = self.blocks.next()?;
        let from = self.position;
        if let Some(target) = block.target() {
            if target.x.is_some() {
                self.position.x = target.x;
            }
            if target.z.is_some() {
                self.position.z = target.z;
            }
            if let Some(c) = target.c {
                self.position.c = Some(c + self.c_offset);
            }
        } else if let Block::RebaseC { c } = *block {
            match self.position.c {
                Some(unrebased) => self.c_offset = unrebased - c,
                None => {
                    self.c_offset = 0.0;
                    self.position.c = Some(c);
                    self.c_anchored = true;
                }
            }
        } else if let Block::ClearRebase = *block {
            // The controller's C is the unrebased C again: the continuous C, unless the
            // frame was anchored at a renaming, when it is not known.
            self.c_offset = 0.0;
            if self.c_anchored {
                self.c_anchored = false;
                self.position.c = None;
            }
        }
        Some(Step {
            index,
            block,
            from,
            to: self.position,
        })
    }

    fn size_hint(&self) -> (usize, Option<usize>) {
        self.blocks.size_hint()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_undo_c_rebasing() {
        // Two full turns, a G92 renaming 720° as 0°, then another turn: the continuous
        // frame must read 1080° at the end.
        let program = Program {
            blocks: vec![
                Block::Rapid {
                    x: Some(10.0),
                    z: Some(0.0),
                    c: Some(0.0),
                },
                Block::Linked {
                    x: 10.0,
                    z: 2.0,
                    c: 720.0,
                    minutes: 0.1,
                },
                Block::RebaseC { c: 0.0 },
                Block::Linked {
                    x: 10.0,
                    z: 3.0,
                    c: 360.0,
                    minutes: 0.05,
                },
            ],
        };
        let steps: Vec<Step<'_>> = program.steps(Pose::UNKNOWN).collect();
        assert_eq!(steps.len(), 4);
        assert_eq!(steps[0].from, Pose::UNKNOWN);
        assert_eq!(steps[0].to, Pose::known(10.0, 0.0, 0.0));
        assert_eq!(steps[1].to.c, Some(720.0));
        // Renaming does not move the machine.
        assert_eq!(steps[2].from, steps[2].to);
        assert_eq!(steps[3].from.c, Some(720.0));
        assert_eq!(steps[3].to.c, Some(1080.0));
        assert_eq!(steps[3].to.z, Some(3.0));
        assert_eq!(steps[3].index, 3);
    }

    #[test]
    fn axes_left_out_keep_their_position() {
        let program = Program {
            blocks: vec![
                Block::Rapid {
                    x: None,
                    z: Some(5.0),
                    c: None,
                },
                Block::Feed {
                    x: Some(1.0),
                    z: None,
                    c: None,
                    feed: 100.0,
                },
            ],
        };
        let steps: Vec<Step<'_>> = program.steps(Pose::known(9.0, 0.0, 45.0)).collect();
        assert_eq!(steps[0].to, Pose::known(9.0, 5.0, 45.0));
        assert_eq!(steps[1].to, Pose::known(1.0, 5.0, 45.0));
    }

    #[test]
    fn renaming_an_unknown_c_anchors_the_frame() {
        let program = Program {
            blocks: vec![
                Block::RebaseC { c: 30.0 },
                Block::Rapid {
                    x: None,
                    z: None,
                    c: Some(40.0),
                },
                Block::RebaseC { c: 0.0 },
                Block::Rapid {
                    x: None,
                    z: None,
                    c: Some(5.0),
                },
            ],
        };
        let to: Vec<Option<f64>> = program.steps(Pose::UNKNOWN).map(|s| s.to.c).collect();
        assert_eq!(to, vec![Some(30.0), Some(40.0), Some(40.0), Some(45.0)]);
    }

    #[test]
    fn non_motion_blocks_have_no_target() {
        assert_eq!(Block::SpindleOff.target(), None);
        assert_eq!(Block::RebaseC { c: 1.0 }.target(), None);
        assert_eq!(Block::Comment("x".into()).target(), None);
        assert_eq!(Block::SpindleOn { rpm: 1.0 }.target(), None);
        assert_eq!(Block::ClearRebase.target(), None);
    }

    #[test]
    fn steps_stay_continuous_across_rebase_then_clear() {
        // 720° renamed as 0°, a turn to 360° (1080° unrebased), G92.1: the controller reads
        // 1080° again, so C1170 is a quarter turn on. A second G92 after the clear renames
        // 1170° as 90°, and C180 is another quarter turn.
        let program = Program {
            blocks: vec![
                Block::Rapid {
                    x: Some(10.0),
                    z: Some(0.0),
                    c: Some(0.0),
                },
                Block::Linked {
                    x: 10.0,
                    z: 2.0,
                    c: 720.0,
                    minutes: 0.1,
                },
                Block::RebaseC { c: 0.0 },
                Block::Linked {
                    x: 10.0,
                    z: 3.0,
                    c: 360.0,
                    minutes: 0.05,
                },
                Block::ClearRebase,
                Block::Linked {
                    x: 10.0,
                    z: 3.25,
                    c: 1170.0,
                    minutes: 0.0125,
                },
                Block::Rapid {
                    x: Some(12.0),
                    z: None,
                    c: None,
                },
                Block::RebaseC { c: 90.0 },
                Block::Rapid {
                    x: None,
                    z: None,
                    c: Some(180.0),
                },
            ],
        };
        let steps: Vec<Step<'_>> = program.steps(Pose::UNKNOWN).collect();
        let c: Vec<(Option<f64>, Option<f64>)> = steps.iter().map(|s| (s.from.c, s.to.c)).collect();
        assert_eq!(
            c,
            vec![
                (None, Some(0.0)),
                (Some(0.0), Some(720.0)),
                (Some(720.0), Some(720.0)),
                (Some(720.0), Some(1080.0)),
                (Some(1080.0), Some(1080.0)),
                (Some(1080.0), Some(1170.0)),
                (Some(1170.0), Some(1170.0)),
                (Some(1170.0), Some(1170.0)),
                (Some(1170.0), Some(1260.0)),
            ]
        );
        // The clear moves nothing.
        assert_eq!(steps[4].from, steps[4].to);
        assert_eq!(steps[4].to, Pose::known(10.0, 3.0, 1080.0));
        assert_eq!(steps[6].to, Pose::known(12.0, 3.25, 1170.0));
    }

    #[test]
    fn clearing_an_anchored_frame_makes_c_unknown() {
        // C was never positioned before G92 C30: the frame is anchored there, and after
        // G92.1 the controller reads a C the program never learned.
        let program = Program {
            blocks: vec![
                Block::RebaseC { c: 30.0 },
                Block::Rapid {
                    x: None,
                    z: None,
                    c: Some(40.0),
                },
                Block::ClearRebase,
                Block::Rapid {
                    x: None,
                    z: None,
                    c: Some(500.0),
                },
                Block::Rapid {
                    x: None,
                    z: None,
                    c: Some(510.0),
                },
            ],
        };
        let to: Vec<Option<f64>> = program.steps(Pose::UNKNOWN).map(|s| s.to.c).collect();
        assert_eq!(
            to,
            vec![Some(30.0), Some(40.0), None, Some(500.0), Some(510.0)]
        );
        // A clear with nothing renamed changes nothing.
        let plain = Program {
            blocks: vec![Block::ClearRebase],
        };
        let start = Pose::known(1.0, 2.0, 3.0);
        let step = plain.steps(start).next().unwrap();
        assert_eq!((step.from, step.to), (start, start));
    }
}
