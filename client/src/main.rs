//! `farfield`: the client command line.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use clap::{Parser, Subcommand};
use farfield_protocol::camera::Camera;
use farfield_protocol::traverse::{TraverseOptions, traverse};

/// Browse farfield scenes.
#[derive(Debug, Parser)]
#[command(name = "farfield", version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Run the reference traversal on a paged file and report the cut.
    Traverse {
        #[arg(long)]
        file: PathBuf,
        /// Camera orbit: azimuth,elevation (degrees),distance (scene radii).
        #[arg(long, default_value = "30,25,3")]
        orbit: String,
        /// Image size, WIDTHxHEIGHT.
        #[arg(long, default_value = "1024x768")]
        size: String,
        /// Projected-size threshold in pixels.
        #[arg(long, default_value_t = 1.0)]
        threshold: f64,
        #[arg(long)]
        json: bool,
    },
}

fn parse_triple(s: &str) -> anyhow::Result<[f64; 3]> {
    let v: Vec<f64> = s
        .split(',')
        .map(|x| x.trim().parse::<f64>())
        .collect::<Result<_, _>>()?;
    match v[..] {
        [a, b, c] if v.iter().all(|x| x.is_finite()) => Ok([a, b, c]),
        _ => anyhow::bail!("expected three finite numbers separated by commas, got '{s}'"),
    }
}

fn parse_size(s: &str) -> anyhow::Result<(u32, u32)> {
    let (w, h) = s
        .split_once('x')
        .ok_or_else(|| anyhow::anyhow!("size '{s}' is not WIDTHxHEIGHT"))?;
    let (w, h): (u32, u32) = (w.parse()?, h.parse()?);
    anyhow::ensure!(
        w > 0 && h > 0 && w <= 16384 && h <= 16384,
        "size {w}x{h} is out of range"
    );
    Ok((w, h))
}

fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Traverse {
            file,
            orbit,
            size,
            threshold,
            json,
        } => {
            let [az, el, dist] = parse_triple(&orbit)?;
            let (w, h) = parse_size(&size)?;
            anyhow::ensure!(
                threshold.is_finite() && threshold >= 0.0,
                "threshold must be a non-negative number"
            );
            let hierarchy = farfield_client::local::load_file(&file)?;
            let header = &hierarchy.header;
            let camera = Camera::orbit(header.root_center, header.root_radius, az, el, dist, w, h);
            let started = Instant::now();
            let cut = traverse(
                &hierarchy,
                &camera,
                &TraverseOptions {
                    threshold_px: threshold,
                    ..Default::default()
                },
            );
            let ms = started.elapsed().as_secs_f64() * 1e3;
            if json {
                println!(
                    "{{\"splats\":{},\"visited\":{},\"frustum_culled\":{},\"backface_culled\":{},\"traverse_ms\":{ms}}}",
                    cut.splats.len(),
                    cut.visited,
                    cut.frustum_culled,
                    cut.backface_culled
                );
            } else {
                println!(
                    "{}: {} splats from {} nodes visited ({} frustum-culled, {} backface-culled) in {ms:.2} ms",
                    file.display(),
                    cut.splats.len(),
                    cut.visited,
                    cut.frustum_culled,
                    cut.backface_culled
                );
            }
            Ok(())
        }
    }
}

fn main() -> ExitCode {
    match run(Cli::parse()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
