//! Out-of-core builds against in-memory ones.

use std::path::PathBuf;

use glam::DVec3;

use super::spread::ChunkPoints;
use super::*;
use crate::scene::Geometry;
use crate::spheres::knn;
use crate::spheres::leaves::Leaf;
use crate::{BuildOptions, PagedFile, Silent, build_spheres};

/// A terrain of `n` points over `size` x `size` units, colored by height.
fn terrain(n: usize, size: f64, seed: u64) -> Geometry {
    let mut rnd = crate::test_random(seed);
    let mut positions = Vec::with_capacity(n);
    let mut colors = Vec::with_capacity(n);
    for _ in 0..n {
        let (x, y) = (rnd() * size, rnd() * size);
        let z = (x * 0.3).sin() * 2.0 + (y * 0.2).cos() * 3.0 + rnd() * 0.05;
        positions.push(DVec3::new(1000.0 + x, -500.0 + y, z));
        colors.push([(z * 20.0 + 128.0) as u8, 90, 40]);
    }
    let mut g = Geometry::new("terrain", positions, Primitives::Points);
    g.colors = Some(colors);
    g
}

/// An out-of-core build's header `a` against the in-memory build's `b`:
/// the same leaves, inputs, bounds and record size, nodes within 2 %.
pub(super) fn assert_alike(
    a: &farfield_protocol::file::FileHeader,
    b: &farfield_protocol::file::FileHeader,
) {
    assert_eq!((a.leaves, a.input_vertices), (b.leaves, b.input_vertices));
    assert_eq!((a.bounds_min, a.bounds_max), (b.bounds_min, b.bounds_max));
    assert_eq!(a.node_bytes, b.node_bytes);
    let ratio = a.nodes as f64 / b.nodes as f64;
    assert!(
        (0.98..1.02).contains(&ratio),
        "nodes {} against {}",
        a.nodes,
        b.nodes
    );
}

pub(super) fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("farfield-ooc-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `g` built in memory, and out of core with the smallest chunks (the
/// file read back, its temporary folder gone).
fn both_builds(g: Geometry, tmp: &std::path::Path) -> (PagedFile, PagedFile, OutOfCoreStats) {
    let (in_memory, _) = build_spheres(Scene::single(g.clone()), &BuildOptions::default()).unwrap();
    let job = Job {
        names: Vec::new(),
        meshes: Vec::new(),
        sources: vec![PointSource::Memory(g)],
        budget: Budget {
            memory: 0,
            tmp: tmp.to_owned(),
        },
    };
    let (finished, stats) = job.build(&BuildOptions::default(), &Silent).unwrap();
    let file = finished.file.read().unwrap();
    drop(finished);
    (in_memory, file, stats)
}

fn bytes(file: &PagedFile) -> Vec<u8> {
    file.to_bytes()
}

fn is_empty(dir: &std::path::Path) -> bool {
    std::fs::read_dir(dir).unwrap().next().is_none()
}

#[test]
fn one_chunk_is_the_in_memory_build_byte_for_byte() {
    let tmp = scratch("one");
    let (expected, file, stats) = both_builds(terrain(900, 30.0, 1), &tmp);
    assert_eq!(stats.chunks, 1);
    assert_eq!(bytes(&file), bytes(&expected));
    assert!(is_empty(&tmp), "temporary files left behind");
}

#[test]
fn many_chunks_make_a_valid_file_like_the_in_memory_one() {
    let tmp = scratch("many");
    let (expected, file, stats) = both_builds(terrain(40_000, 200.0, 2), &tmp);
    assert!(stats.chunks >= 20, "{} chunks", stats.chunks);
    assert!(stats.halo_points > 0);
    assert!(is_empty(&tmp), "temporary files left behind");
    // Every page checks and every child range adds up, as a client reads it.
    let image = bytes(&file);
    let h = farfield_protocol::paged_file::read_image(&image).unwrap();
    let (a, b) = (&h.header, &expected.header);
    assert_eq!((a.leaves, a.input_vertices), (40_000, 40_000));
    assert_alike(a, b);
    assert!(
        a.levels.abs_diff(b.levels) <= 4,
        "levels {} against {}",
        a.levels,
        b.levels
    );
    let size = image.len() as f64 / bytes(&expected).len() as f64;
    assert!((0.97..1.03).contains(&size), "file size ratio {size}");
}

#[test]
fn a_failed_build_leaves_no_temporary_files() {
    let tmp = scratch("failed");
    let las = tmp.join("gone.las");
    let job = Job {
        names: Vec::new(),
        meshes: Vec::new(),
        sources: vec![PointSource::Las {
            path: las,
            info: crate::import::las::LasInfo {
                count: 1_000_000,
                has_color: false,
                bounds: (DVec3::ZERO, DVec3::ONE),
            },
            wide: false,
        }],
        budget: Budget {
            memory: 0,
            tmp: tmp.join("spill"),
        },
    };
    let error = job.build(&BuildOptions::default(), &Silent).unwrap_err();
    assert!(error.to_string().contains("gone.las"), "{error}");
    assert!(is_empty(&tmp.join("spill")), "temporary files left behind");
}

/// The radii `size_points` gives the points of a whole cloud.
fn radii(positions: &[DVec3]) -> Vec<f32> {
    let mut leaves: Vec<Leaf> = positions
        .iter()
        .map(|&position| Leaf {
            position,
            radius: 0.0,
            normal: 0,
            color: [0; 3],
            cone: 255,
            source: 0,
        })
        .collect();
    knn::size_points_uncapped(&mut leaves, None);
    leaves.iter().map(|l| l.radius).collect()
}

#[test]
fn a_chunks_halo_keeps_its_border_points_sized_as_in_the_whole_cloud() {
    // Sizes before the cap: the cap is the whole cloud's, applied later.
    let tmp = scratch("halo");
    // A jittered 40 x 40 grid; the chunk is its left half.
    let mut rnd = crate::test_random(5);
    let grid: Vec<DVec3> = (0..1600)
        .map(|i| {
            DVec3::new(
                (i % 40) as f64 + rnd() * 0.3,
                (i / 40) as f64 + rnd() * 0.3,
                0.0,
            )
        })
        .collect();
    let whole = radii(&grid);
    let own: Vec<usize> = (0..1600).filter(|i| i % 40 < 20).collect();
    let halo: Vec<usize> = (0..1600).filter(|i| (20..22).contains(&(i % 40))).collect();
    let chunk = |with_halo: bool| {
        let mut positions: Vec<DVec3> = own.iter().map(|&i| grid[i]).collect();
        if with_halo {
            positions.extend(halo.iter().map(|&i| grid[i]));
        }
        let leaves = tmp.join(format!("leaves-{with_halo}"));
        let mut median = median::RadiusMedian::new();
        chunk::size_chunk(
            ChunkPoints {
                positions,
                own: own.len(),
                ..ChunkPoints::default()
            },
            false,
            &leaves,
            &mut median,
            &tmp.join("radii"),
        )
        .unwrap()
        .unwrap();
        let read = chunk::read_leaves(&leaves).unwrap();
        read.iter().map(|l| l.radius).collect::<Vec<f32>>()
    };
    let border = |radii: &[f32]| -> usize {
        own.iter()
            .zip(radii)
            .filter(|&(&i, &r)| i % 40 == 19 && r != whole[i])
            .count()
    };
    assert_eq!(
        border(&chunk(true)),
        0,
        "border points sized differently with the halo"
    );
    assert!(
        border(&chunk(false)) > 5,
        "the test cannot tell a halo from none"
    );
    let _ = std::fs::remove_dir_all(&tmp);
}

/// A LAS file whose header claims bounds its points are far outside
/// (here all zero) is counted again over the measured bounds: its chunks
/// are cut over the real extent, not all in one cell at the header's
/// corner.
#[test]
fn a_las_header_with_wrong_bounds_is_counted_again() {
    let tmp = scratch("bounds");
    let path = tmp.join("wrong.las");
    let mut builder = ::las::Builder::from((1, 2));
    builder.point_format = ::las::point::Format::new(2).unwrap();
    let mut writer = ::las::Writer::from_path(&path, builder.into_header().unwrap()).unwrap();
    let mut rnd = crate::test_random(9);
    for _ in 0..20_000 {
        writer
            .write_point(::las::Point {
                x: 500.0 + rnd() * 100.0,
                y: 200.0 + rnd() * 100.0,
                z: rnd(),
                color: Some(::las::Color::new(10, 20, 30)),
                ..Default::default()
            })
            .unwrap();
    }
    writer.close().unwrap();
    // The header's max and min x, y, z (LAS 1.2: six f64 from byte 179).
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[179..179 + 48].fill(0);
    std::fs::write(&path, &bytes).unwrap();
    let info = crate::import::las::survey(&path).unwrap();
    assert_eq!(
        info.bounds,
        (DVec3::ZERO, DVec3::ZERO),
        "the header was not damaged"
    );
    let job = Job {
        names: Vec::new(),
        meshes: Vec::new(),
        sources: vec![PointSource::Las {
            path: path.clone(),
            info,
            wide: false,
        }],
        budget: Budget {
            memory: 0,
            tmp: tmp.join("spill"),
        },
    };
    let (finished, stats) = job.build(&BuildOptions::default(), &Silent).unwrap();
    assert!(
        stats.chunks >= 10,
        "{} chunks: cut over the header's bounds",
        stats.chunks
    );
    let h = &finished.file.header;
    assert!(h.bounds_min.x >= 500.0 && h.bounds_max.y <= 300.0 + 1e-9);
    assert_eq!(h.input_vertices, 20_000);
}
