//! farfield-server: the `farfield-server` command line, as a library so
//! tests run the same code in-process (`main.rs` only parses, prints and
//! exits).
//!
//! The work is in the crates below it: `farfield-builder` (importers and
//! builders), `farfield-store` (the paged file on disk), `farfield-memory-server`
//! (the memory server) and, for `bench`, `farfield-tools`.

pub mod cli;
