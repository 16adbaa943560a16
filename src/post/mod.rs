//! Posts: the neutral program ([`crate::program`]) in the form a controller takes.
//!
//! - [`gcode`]: G-code text for grblHAL or LinuxCNC, and the reader of such text.
//! - [`modbus`]: segments of the Modbus register map for a PLC.
//! - [`setpoints`]: cyclic set-points in drive counts for CiA 402 drives.

pub mod gcode;
pub mod modbus;
pub mod setpoints;
