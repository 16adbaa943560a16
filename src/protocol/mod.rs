//! Controller protocols as sans-I/O state machines: values in, values out.
//!
//! A protocol here never touches a port, a socket, a task or a clock. It takes what the
//! transport read and the time the transport saw, and hands back what to write and the
//! events that happened; the async transports ([`crate::transport`]) and the tests drive
//! it. So every rule of a protocol can be tested byte for byte, and the same code runs
//! against a real machine and the simulator.
//!
//! - [`grbl`]: a G-code program streamed to grbl/grblHAL by character counting.
//! - [`modbus`]: segments through the register ring of `docs/modbus.md`.
//! - [`canopen`]: CANopen (CiA 301) and CiA 402 drives, through slcan or socketcan.
//! - [`linuxcnc`]: a program run on LinuxCNC through its remote shell, `linuxcncrsh`.

pub mod canopen;
pub mod grbl;
pub mod linuxcnc;
pub mod modbus;
