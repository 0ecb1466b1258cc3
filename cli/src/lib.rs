//! farfield-cli: the `farfield` command line, as a library so tests run
//! the same code in-process (`main.rs` only parses, runs and exits).
//!
//! - [`cli`]: the arguments and the dispatch.
//! - [`commands`]: `render` (one view, or a flythrough), `traverse`,
//!   `compare`, `demo` (build, embedded server, flight, sweep), and the
//!   measuring subcommands over `farfield-tools`.
//!
//! The client core it drives is `farfield-client` (resident pages, frame
//! loop), `farfield-net` (the session), `farfield-traverse` and
//! `farfield-render`.

pub mod cli;
pub mod commands;
