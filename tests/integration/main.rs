//! Integration tests: one binary, shared helpers in `util`.

mod cli;
mod dry_run;
mod link;
mod linkage;
mod python_client;
mod sim;
mod stream;
mod sweep;
mod util;
mod verify;
