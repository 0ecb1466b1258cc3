//! `farfield-server`: a thin shell over [`farfield_server::cli`].

use std::process::ExitCode;

use clap::Parser;
use farfield_builder::allocator::HugePageAlloc;
use farfield_server::cli::{Cli, run};

/// Large build arrays on huge pages: see [`farfield_builder::allocator`].
#[global_allocator]
static ALLOCATOR: HugePageAlloc = HugePageAlloc;

fn main() -> ExitCode {
    // Info by default so `serve` logs connections; RUST_LOG overrides.
    farfield_memory_server::logs::init(Some("info"));
    let cli = Cli::parse();
    match run(cli) {
        Ok(report) => {
            if report.as_json {
                println!("{}", report.json);
            } else {
                println!("{}", report.text);
            }
            ExitCode::from(report.exit_code)
        }
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
