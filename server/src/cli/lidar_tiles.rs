//! `farfield-server lidar-tiles`: generated LAS tiles for benchmarks
//! (`farfield_tools::lidar_tiles`).

use std::time::Instant;

use farfield_tools::lidar_tiles::{LidarJob, write_tiles};
use serde_json::json;

use super::{LidarTilesArgs, Report};

pub fn run(args: &LidarTilesArgs) -> anyhow::Result<Report> {
    let started = Instant::now();
    let tiles = write_tiles(&LidarJob {
        points: args.points,
        grid: args.grid,
        seed: args.seed,
        out: args.out.clone(),
    })?;
    let bytes: u64 = tiles
        .iter()
        .map(|t| std::fs::metadata(t).map_or(0, |m| m.len()))
        .sum();
    let seconds = started.elapsed().as_secs_f64();
    Ok(Report {
        json: json!({
            "points": args.points,
            "tiles": tiles,
            "bytes": bytes,
            "seconds": seconds,
        }),
        text: format!(
            "{} points in {} tiles under {} ({bytes} bytes) in {seconds:.1} s",
            args.points,
            tiles.len(),
            args.out.display()
        ),
        exit_code: 0,
        as_json: false,
    })
}
