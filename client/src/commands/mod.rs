//! One module per `farfield` subcommand; `main.rs` only parses and dispatches.

pub mod bench_cubes;
pub mod bench_stream;
pub mod demo;
pub mod fly;
pub mod render;
