//! Generated lidar for benchmarks: a rolling terrain sampled by `points`
//! random points with RGB, written as a square grid of LAS 1.2 tiles
//! (point format 2) as surveys are delivered, each tile with its own
//! coordinate offset. `farfield-server lidar-tiles` writes them;
//! `benches/peers.sh` builds them with farfield and PotreeConverter.
//!
//! Points are generated and written tile by tile, a chunk at a time, so
//! memory does not grow with the point count (a billion points is 26 GB
//! of files, not of memory). Every value depends only on the seed, the
//! tile and the point's index in it: the same job writes the same bytes.

use std::path::{Path, PathBuf};

use anyhow::Context;
use farfield_builder::generate::noise::fbm_and_ridged;
use farfield_builder::generate::rng::{Rng, hash};
use rayon::prelude::*;

/// Points a square metre: an airborne survey's density.
const POINTS_PER_SQUARE_METRE: f64 = 10.0;
/// Where the grid starts: a UTM-like easting and northing, so coordinates
/// need their offsets (f64 at 5e6 m resolves 1e-9 m).
const ORIGIN: [f64; 2] = [500_000.0, 5_000_000.0];
/// LAS stores coordinates as integers times this: millimetres.
const SCALE: f64 = 0.001;

/// What to write.
#[derive(Debug, Clone)]
pub struct LidarJob {
    pub points: u64,
    /// Tiles along each side of the square: `grid * grid` files.
    pub grid: u32,
    pub seed: u64,
    pub out: PathBuf,
}

/// The written tiles, in row order.
pub fn write_tiles(job: &LidarJob) -> anyhow::Result<Vec<PathBuf>> {
    anyhow::ensure!(job.points > 0, "no points to write");
    anyhow::ensure!(job.grid > 0, "a grid of at least one tile");
    std::fs::create_dir_all(&job.out).with_context(|| format!("creating {}", job.out.display()))?;
    let tiles = u64::from(job.grid) * u64::from(job.grid);
    // A tile without points is a LAS file no build reads.
    anyhow::ensure!(
        job.points >= tiles,
        "{} points cannot fill {tiles} tiles",
        job.points
    );
    let side = (job.points as f64 / POINTS_PER_SQUARE_METRE).sqrt();
    let tile_side = side / f64::from(job.grid);
    (0..tiles)
        .into_par_iter()
        .map(|t| {
            // The remainder goes to the first tiles, one each.
            let count = job.points / tiles + u64::from(t < job.points % tiles);
            let (col, row) = (t % u64::from(job.grid), t / u64::from(job.grid));
            let min = [
                ORIGIN[0] + col as f64 * tile_side,
                ORIGIN[1] + row as f64 * tile_side,
            ];
            let path = job.out.join(format!("tile-{row:03}-{col:03}.las"));
            write_tile(&path, hash(job.seed, t), min, tile_side, side, count)
                .with_context(|| format!("writing {}", path.display()))?;
            Ok(path)
        })
        .collect()
}

/// One tile of `count` points over the square from `min` of edge `edge`;
/// `extent` is the whole survey's edge (the terrain's scale).
fn write_tile(
    path: &Path,
    seed: u64,
    min: [f64; 2],
    edge: f64,
    extent: f64,
    count: u64,
) -> anyhow::Result<()> {
    let mut builder = las::Builder::from((1, 2));
    builder.point_format = las::point::Format::new(2)?;
    builder.transforms = las::Vector {
        x: las::Transform {
            scale: SCALE,
            offset: min[0].floor(),
        },
        y: las::Transform {
            scale: SCALE,
            offset: min[1].floor(),
        },
        z: las::Transform {
            scale: SCALE,
            offset: 0.0,
        },
    };
    builder.generating_software = "farfield lidar-tiles".into();
    let header = builder.into_header()?;
    let file = std::fs::File::create(path)?;
    let mut writer = las::Writer::new(std::io::BufWriter::with_capacity(1 << 20, file), header)?;
    let mut rng = Rng::new(seed);
    for _ in 0..count {
        let x = min[0] + rng.next_f64() * edge;
        let y = min[1] + rng.next_f64() * edge;
        let (z, shade) = terrain(x - ORIGIN[0], y - ORIGIN[1], extent);
        // A few centimetres of noise, as a scanner's range error.
        let z = z + (rng.next_f64() - 0.5) * 0.05;
        writer.write_point(las::Point {
            x,
            y,
            z,
            intensity: (shade * 40_000.0) as u16,
            color: Some(color(z, extent, shade)),
            ..Default::default()
        })?;
    }
    writer.close()?;
    Ok(())
}

/// Height in metres at `(u, v)` metres from the survey's corner, and a
/// 0..1 shade of the ground there.
fn terrain(u: f64, v: f64, extent: f64) -> (f64, f64) {
    // Hills about a tenth of the survey across, and detail down to metres.
    let scale = (extent / 10.0).max(1.0);
    let (rolling, ridges) = fbm_and_ridged(7, u / scale, v / scale, 10);
    let height = scale * 0.05 * (rolling * 2.0 + ridges * 3.0);
    (height, (0.5 + 0.5 * rolling).clamp(0.0, 1.0))
}

/// Green lowlands, brown slopes, grey and white tops, in 16-bit LAS color.
fn color(z: f64, extent: f64, shade: f64) -> las::Color {
    let top = (extent / 10.0).max(1.0) * 0.25;
    let t = (z / top).clamp(0.0, 1.0);
    let (r, g, b) = if t < 0.4 {
        (0.25 + 0.3 * t, 0.45 + 0.2 * t, 0.2)
    } else if t < 0.8 {
        (0.45 + 0.2 * t, 0.35 + 0.1 * t, 0.25)
    } else {
        (0.85, 0.85, 0.88)
    };
    let s = 0.75 + 0.25 * shade;
    let c = |v: f64| ((v * s).clamp(0.0, 1.0) * 65_535.0) as u16;
    las::Color::new(c(r), c(g), c(b))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_hold_every_point_with_their_own_offsets_and_read_back() {
        let dir = std::env::temp_dir().join(format!("farfield-lidar-{}", std::process::id()));
        let job = LidarJob {
            points: 10_001,
            grid: 2,
            seed: 3,
            out: dir.clone(),
        };
        let tiles = write_tiles(&job).unwrap();
        assert_eq!(tiles.len(), 4);
        let mut total = 0;
        let mut offsets = Vec::new();
        for path in &tiles {
            let mut reader = las::Reader::from_path(path).unwrap();
            let header = reader.header().clone();
            offsets.push(header.transforms().x.offset);
            let points: Vec<las::Point> = reader
                .read_all()
                .unwrap()
                .points()
                .map(Result::unwrap)
                .collect();
            assert_eq!(points.len() as u64, header.number_of_points());
            let bounds = header.bounds();
            for p in &points {
                assert!(p.x >= bounds.min.x && p.x <= bounds.max.x);
                assert!(p.color.is_some());
            }
            total += points.len();
        }
        assert_eq!(total, 10_001);
        offsets.sort_by(f64::total_cmp);
        offsets.dedup();
        assert_eq!(offsets.len(), 2, "two columns, two x offsets: {offsets:?}");
        // The same job writes the same bytes.
        let first = std::fs::read(&tiles[0]).unwrap();
        write_tiles(&job).unwrap();
        assert_eq!(std::fs::read(&tiles[0]).unwrap(), first);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
