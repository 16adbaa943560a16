//! Integration tests: one binary, shared helpers in `util`.

mod cli;
mod linkage;
mod sim;
mod stream;
mod sweep;
mod util;
mod verify;
