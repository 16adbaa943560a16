//! Integration tests: one binary, shared helpers in `util`.

mod can_session;
mod can_wire;
mod cli;
mod control;
mod dry_run;
mod faults_fieldbus;
mod faults_serial;
mod grbl_open;
mod layers;
mod link;
mod linkage;
mod logs;
mod machines;
mod modbus_map;
mod modbus_wire;
mod outputs;
mod profiles;
mod python_client;
mod sim;
mod stream;
mod sweep;
mod util;
mod verify;
