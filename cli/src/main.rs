//! `farfield`: the client command line. Parsing and dispatch only; the
//! work is in `farfield_cli::commands` and the crates below it.

use std::process::ExitCode;

use clap::Parser;
use farfield_cli::cli::{Cli, run};

/// The demo builds its scene in-process: large build arrays on huge pages,
/// as in `farfield-server` (see [`farfield_builder::allocator`]).
#[global_allocator]
static ALLOCATOR: farfield_builder::allocator::HugePageAlloc =
    farfield_builder::allocator::HugePageAlloc;

fn main() -> ExitCode {
    // SAFETY: first thing in `main`, before any thread is started.
    unsafe { farfield_render::quiet_device_select_when_headless() };
    farfield_memory_server::logs::init(None);
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            // `farfield compare` on images of different sizes.
            let compare = e.downcast_ref::<farfield_image::CompareError>();
            if compare.is_some_and(|c| c.is_size_mismatch()) {
                return ExitCode::from(2);
            }
            ExitCode::FAILURE
        }
    }
}
