//! Integration tests: one binary, shared helpers in `util`.

mod angles;
mod can_eds;
mod can_session;
mod can_wire;
mod cli;
mod control;
mod drawings;
mod dry_run;
mod fastest;
mod faults_fieldbus;
mod faults_serial;
mod grbl_open;
// The console tests' HTTP client, some of whose helpers these tests do not use.
#[path = "../console/http.rs"]
#[allow(dead_code)]
mod http;
mod layers;
mod link;
mod linkage;
mod logs;
mod machines;
mod measure;
mod modbus_map;
mod modbus_wire;
mod mosquitto;
mod nut;
mod opcua;
mod outputs;
mod overrides;
mod postgres;
mod profile_view;
mod profiles;
mod provenance;
mod python_client;
mod records;
mod sim;
mod stream;
mod sweep;
mod telemetry;
mod telemetry_tls;
mod thread_forms;
mod util;
mod verify;
