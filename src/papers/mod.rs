//! The swept-volume engine: what tools of revolution remove as they move.
//!
//! The independent judge of every program: the planner estimates its error, this engine
//! measures it.
//!
//! - [`cusp`]: the cusp between adjacent passes: engine section, closed forms, seed 003 checked.
//! - [`grazing`]: the envelope by the grazing condition N · V = 0 (seeds 001, 004), an
//!   independent check on [`section`].
//! - [`helix`]: seed 000's helical motion (pure translation along a helix about y).
//! - [`section`]: the machined section in a plane through the screw axis, seed 000's method.
//! - [`tool`]: tools of revolution by their meridian region (torus, paraboloid, ball,
//!   corner-radius, flat).
pub mod cusp;
pub mod grazing;
pub mod helix;
pub mod section;
pub mod tool;
