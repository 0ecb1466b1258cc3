//! `farfield-server`: a thin shell over [`farfield_server::cli`].

use std::process::ExitCode;

use clap::Parser;
use farfield_server::cli::{Cli, run};

fn main() -> ExitCode {
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::from_default_env())
        .with_writer(std::io::stderr)
        .init();
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
