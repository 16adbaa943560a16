//! The swept-volume engine: what tools of revolution remove as they move.
//!
//! The independent judge of every program: the planner estimates its error, this engine
//! measures it.
//!
//! - [`tool`]: tools of revolution by their meridian region (torus, paraboloid, ball,
//!   corner-radius, flat).
pub mod tool;
