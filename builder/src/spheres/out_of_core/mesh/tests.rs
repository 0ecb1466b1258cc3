//! Meshes built in chunks against the same meshes built in memory.

use glam::{DAffine3, DQuat, DVec3};

use super::super::chunk::read_leaves;
use super::super::temp::TempDir;
use super::super::tests::{assert_alike, scratch};
use super::super::{Budget, Job};
use super::MeshInput;
use crate::import::stream::Streamed;
use crate::import::up::InputKind;
use crate::progress::Silent;
use crate::scene::{Geometry, Instance, Primitives, Scene};
use crate::spheres::leaves::{Leaf, make_leaves, unpack_normal};
use crate::{BuildOptions, build_spheres};

/// A wavy `side` x `side` grid of jittered vertices, two triangles a cell,
/// colored by height; with a vertex no triangle uses and a triangle of no
/// area, which the in-memory build leaves out.
fn wavy(side: u32, seed: u64) -> Geometry {
    let mut rnd = crate::test_random(seed);
    let mut positions = Vec::new();
    let mut colors = Vec::new();
    for y in 0..side {
        for x in 0..side {
            let (fx, fy) = (f64::from(x) + rnd() * 0.3, f64::from(y) + rnd() * 0.3);
            let z = (fx * 0.2).sin() * 3.0 + (fy * 0.15).cos() * 2.0;
            positions.push(DVec3::new(5000.0 + fx, -200.0 + fy, z));
            colors.push([(z * 20.0 + 128.0) as u8, (x % 256) as u8, 40]);
        }
    }
    let mut triangles = Vec::new();
    for y in 0..side - 1 {
        for x in 0..side - 1 {
            let i = y * side + x;
            triangles.push([i, i + 1, i + side]);
            triangles.push([i + 1, i + side + 1, i + side]);
        }
    }
    // No area: its corners repeat.
    triangles.push([5, 5, 6]);
    // Used by nothing.
    positions.push(DVec3::new(5000.0, -200.0, 100.0));
    colors.push([1, 2, 3]);
    let mut g = Geometry::new("wavy", positions, Primitives::Triangles(triangles));
    g.colors = Some(colors);
    g
}

fn budget(memory: u64, tmp: &std::path::Path) -> Budget {
    Budget {
        memory,
        tmp: tmp.to_owned(),
    }
}

/// Every chunk's leaves, in chunk order, and how many chunks had some.
fn chunk_leaves(scene: Scene, tmp: &std::path::Path) -> (Vec<Leaf>, usize) {
    let temp = TempDir::create(tmp).unwrap();
    let (sized, _) = super::size(
        vec![MeshInput::Scene(scene)],
        &budget(0, tmp),
        &temp,
        &Silent,
    )
    .unwrap();
    let mut leaves = Vec::new();
    for e in &sized.entries {
        leaves.extend(read_leaves(&e.leaves).unwrap());
    }
    (leaves, sized.entries.len())
}

/// Leaves ordered by position, their index in the input forgotten.
fn by_position(mut leaves: Vec<Leaf>) -> Vec<Leaf> {
    for l in &mut leaves {
        l.source = 0;
    }
    leaves.sort_by(|a, b| {
        a.position
            .to_array()
            .partial_cmp(&b.position.to_array())
            .unwrap()
    });
    leaves
}

#[test]
fn vertices_on_chunk_borders_are_sized_as_in_the_whole_mesh() {
    let tmp = scratch("mesh-borders");
    let g = wavy(120, 1);
    let (expected, stats) = make_leaves(Scene::single(g.clone()), true, &Silent);
    assert_eq!(stats.unreferenced_vertices, 1);
    let (leaves, chunks) = chunk_leaves(Scene::single(g), &tmp);
    assert!(chunks >= 10, "{chunks} chunks");
    let (a, b) = (by_position(leaves), by_position(expected));
    assert_eq!(a.len(), b.len());
    let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "{differ} of {} leaves differ", a.len());
    assert!(
        std::fs::read_dir(&tmp).unwrap().next().is_none(),
        "temporary files left behind"
    );
}

#[test]
fn instances_are_placed_as_the_in_memory_build_places_them() {
    let tmp = scratch("mesh-instances");
    let g = wavy(40, 2);
    let place = |angle: f64, scale: f64, x: f64| {
        DAffine3::from_scale_rotation_translation(
            DVec3::splat(scale),
            DQuat::from_rotation_z(angle),
            DVec3::new(x, 0.0, 0.0),
        )
    };
    let scene = Scene {
        geometries: vec![g],
        instances: [(0.0, 1.0, 0.0), (0.7, 2.0, 300.0), (2.0, 0.5, -400.0)]
            .into_iter()
            .map(|(a, s, x)| Instance {
                geometry: 0,
                world_from_local: place(a, s, x),
            })
            .collect(),
    };
    let (expected, _) = make_leaves(scene.clone(), true, &Silent);
    let (leaves, chunks) = chunk_leaves(scene, &tmp);
    assert!(chunks >= 3, "{chunks} chunks");
    let (a, b) = (by_position(leaves), by_position(expected));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        // Placed before sizing here, after in memory: the same up to
        // rounding.
        assert!(x.position.distance(y.position) < 1e-9, "{x:?} {y:?}");
        assert!(
            (x.radius / y.radius - 1.0).abs() < 1e-5,
            "radius {x:?} {y:?}"
        );
        let cos = unpack_normal(x.normal).dot(unpack_normal(y.normal));
        assert!(cos > 0.9999, "normal {x:?} {y:?}");
        assert_eq!(x.color, y.color);
    }
}

#[test]
fn one_chunk_is_the_in_memory_build_byte_for_byte() {
    let tmp = scratch("mesh-one");
    let scene = Scene::single(wavy(30, 3));
    let (expected, _) = build_spheres(scene.clone(), &BuildOptions::default()).unwrap();
    let job = Job {
        sources: Vec::new(),
        meshes: vec![MeshInput::Scene(scene)],
        budget: budget(1 << 30, &tmp),
        names: Vec::new(),
    };
    let (finished, stats) = job.build(&BuildOptions::default(), &Silent).unwrap();
    assert_eq!(stats.chunks, 1);
    assert_eq!(stats.build.unreferenced_vertices, 1);
    assert_eq!(stats.build.input_primitives, 29 * 29 * 2 + 1);
    let file = finished.file.read().unwrap();
    drop(finished);
    assert_eq!(file.to_bytes(), expected.to_bytes());
    assert!(std::fs::read_dir(&tmp).unwrap().next().is_none());
}

#[test]
fn many_chunks_make_a_file_like_the_in_memory_one() {
    let tmp = scratch("mesh-many");
    let scene = Scene::single(wavy(150, 4));
    let (expected, _) = build_spheres(scene.clone(), &BuildOptions::default()).unwrap();
    let job = Job {
        sources: Vec::new(),
        meshes: vec![MeshInput::Scene(scene)],
        budget: budget(0, &tmp),
        names: Vec::new(),
    };
    let (finished, stats) = job.build(&BuildOptions::default(), &Silent).unwrap();
    assert!(stats.chunks >= 15, "{} chunks", stats.chunks);
    assert!(stats.halo_points > 0, "no triangle crosses a border");
    let image = finished.file.read().unwrap().to_bytes();
    drop(finished);
    let h = farfield_protocol::paged_file::read_image(&image).unwrap();
    assert_alike(&h.header, &expected.header);
    assert!(std::fs::read_dir(&tmp).unwrap().next().is_none());
}

/// `g` as a PLY file (binary little-endian, or ASCII): double positions,
/// float normals, byte colors, and its triangles as faces.
fn ply_bytes(g: &Geometry, ascii: bool) -> Vec<u8> {
    let Primitives::Triangles(triangles) = &g.primitives else {
        panic!("a mesh");
    };
    let normals = g.normals.as_ref().expect("normals");
    let colors = g.colors.as_ref().expect("colors");
    let format = if ascii {
        "ascii"
    } else {
        "binary_little_endian"
    };
    let mut out = format!(
        "ply\nformat {format} 1.0\nelement vertex {}\nproperty double x\nproperty double y\nproperty double z\nproperty float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\nproperty uchar blue\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        g.positions.len(),
        triangles.len()
    )
    .into_bytes();
    for ((p, n), c) in g.positions.iter().zip(normals).zip(colors) {
        if ascii {
            let line = format!(
                "{} {} {} {} {} {} {} {} {}\n",
                p.x, p.y, p.z, n.x, n.y, n.z, c[0], c[1], c[2]
            );
            out.extend_from_slice(line.as_bytes());
        } else {
            for v in p.to_array() {
                out.extend_from_slice(&v.to_le_bytes());
            }
            for v in n.to_array() {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(c);
        }
    }
    for t in triangles {
        if ascii {
            out.extend_from_slice(format!("3 {} {} {}\n", t[0], t[1], t[2]).as_bytes());
        } else {
            out.push(3);
            for v in t {
                out.extend_from_slice(&(*v as i32).to_le_bytes());
            }
        }
    }
    out
}

/// Gives `g` random normals facing up, every `zero`th of no length.
fn with_normals(g: &mut Geometry, seed: u64, zero: usize) {
    let mut rnd = crate::test_random(seed);
    g.normals = Some(
        (0..g.positions.len())
            .map(|i| {
                if i % zero == 0 {
                    glam::Vec3::ZERO
                } else {
                    glam::Vec3::new(rnd() as f32 - 0.5, rnd() as f32 - 0.5, 2.0)
                }
            })
            .collect(),
    );
}

/// A PLY mesh is read as a stream, a batch at a time, and its leaves are
/// its in-memory import's: normals made unit alike, and those of no
/// length (here every 97th) repaired from the triangles around them,
/// across chunk borders too.
#[test]
fn a_streamed_ply_mesh_has_the_leaves_of_its_import() {
    let tmp = scratch("mesh-ply");
    // More vertices than a batch (65,536), so batches meet mid-element.
    let mut g = wavy(300, 5);
    with_normals(&mut g, 6, 97);
    for ascii in [false, true] {
        let name = if ascii { "ascii.ply" } else { "binary.ply" };
        assert_streamed_like_import(&tmp, name, &ply_bytes(&g, ascii), (true, true));
    }
}

/// Builds `bytes`, written as `name`, as a stream in chunks and checks its
/// leaves are its in-memory import's; `(normals, colors)` are what its
/// survey must find kept.
fn assert_streamed_like_import(
    tmp: &std::path::Path,
    name: &str,
    bytes: &[u8],
    kept: (bool, bool),
) {
    let path = tmp.join(name);
    std::fs::write(&path, bytes).unwrap();
    let imported = crate::import::load_input(path.to_str().unwrap(), &Default::default()).unwrap();
    let g = &imported.geometries[0];
    assert_eq!((g.normals.is_some(), g.colors.is_some()), kept, "{name}");
    let (expected, _) = make_leaves(imported, true, &Silent);
    let format = Streamed::of(&path).unwrap();
    let info = format.survey(&path).unwrap();
    assert!(info.triangles, "{name}");
    assert_eq!((info.normals, info.colors), kept, "{name}");
    let spill = tmp.join("spill");
    let temp = TempDir::create(&spill).unwrap();
    let input = MeshInput::File {
        path: path.clone(),
        format,
        info,
        place: crate::import::up::Up::Auto.world_from_input(InputKind::MeshFile),
    };
    let (sized, _) = super::size(vec![input], &budget(0, &spill), &temp, &Silent).unwrap();
    assert!(sized.entries.len() >= 20, "{} chunks", sized.entries.len());
    let mut leaves = Vec::new();
    for e in &sized.entries {
        leaves.extend(read_leaves(&e.leaves).unwrap());
    }
    let (a, b) = (by_position(leaves), by_position(expected));
    assert_eq!(a.len(), b.len(), "{name}");
    let differ = a.iter().zip(&b).filter(|(x, y)| x != y).count();
    assert_eq!(differ, 0, "{name}: {differ} of {} leaves differ", a.len());
}

/// `g` as an OFF file with normals and colors (0..255, as numbers).
fn off_text(g: &Geometry) -> String {
    let Primitives::Triangles(triangles) = &g.primitives else {
        panic!("a mesh");
    };
    let normals = g.normals.as_ref().expect("normals");
    let colors = g.colors.as_ref().expect("colors");
    let mut out = format!(
        "NCOFF\n# a comment\n{} {} 0\n",
        g.positions.len(),
        triangles.len()
    );
    for ((p, n), c) in g.positions.iter().zip(normals).zip(colors) {
        out += &format!(
            "{} {} {} {} {} {} {} {} {} 255\n",
            p.x, p.y, p.z, n.x, n.y, n.z, c[0], c[1], c[2]
        );
    }
    for t in triangles {
        out += &format!("3 {} {} {}\n", t[0], t[1], t[2]);
    }
    out
}

/// `g` as an OBJ file: colors as 0..255 numbers on `v` lines, a table of
/// normals in another order than the vertices, and faces whose corners
/// name them. Every 13th face names, for its first corner, its second
/// corner's normal instead: where that corner comes first, it wins. Every
/// 5th face uses negative (relative) vertex indices. The vertex no face
/// uses has no normal.
fn obj_text(g: &Geometry) -> String {
    let Primitives::Triangles(triangles) = &g.primitives else {
        panic!("a mesh");
    };
    let normals = g.normals.as_ref().expect("normals");
    let colors = g.colors.as_ref().expect("colors");
    let n = g.positions.len();
    let mut out = String::from("# wavy\no wavy\n");
    for (p, c) in g.positions.iter().zip(colors) {
        out += &format!("v {} {} {} {} {} {}\n", p.x, p.y, p.z, c[0], c[1], c[2]);
    }
    // The table holds vertex i's normal at n - 1 - i.
    for v in normals.iter().rev() {
        out += &format!("vn {} {} {}\n", v.x, v.y, v.z);
    }
    let normal_of = |v: u32| n - v as usize;
    for (k, t) in triangles.iter().enumerate() {
        let vertex = |v: u32| {
            if k % 5 == 0 {
                format!("-{}", n - v as usize)
            } else {
                (v + 1).to_string()
            }
        };
        let first_normal = if k % 13 == 0 { t[1] } else { t[0] };
        out += &format!(
            "f {}//{} {}//{} {}//{}\n",
            vertex(t[0]),
            normal_of(first_normal),
            vertex(t[1]),
            normal_of(t[1]),
            vertex(t[2]),
            normal_of(t[2])
        );
    }
    out
}

/// OFF and OBJ meshes are read as streams too, and their leaves are their
/// imports': colors scaled alike (0..255 here, which only the whole file
/// tells), and OBJ's normals given by the first face corner that names
/// each vertex, across chunk borders.
#[test]
fn streamed_off_and_obj_meshes_have_the_leaves_of_their_imports() {
    let tmp = scratch("mesh-off-obj");
    let mut g = wavy(300, 9);
    with_normals(&mut g, 10, 89);
    assert_streamed_like_import(&tmp, "wavy.off", off_text(&g).as_bytes(), (true, true));
    assert_streamed_like_import(&tmp, "wavy.obj", obj_text(&g).as_bytes(), (true, true));
    // Without a normal on one corner, an OBJ file's normals are all
    // computed, as its import computes them.
    let text = obj_text(&g) + "f 1 2 3\n";
    assert_streamed_like_import(&tmp, "no-normals.obj", text.as_bytes(), (false, true));
}
