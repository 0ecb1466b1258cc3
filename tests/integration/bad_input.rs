//! Bad input gets a clear one-line error naming the input and the element,
//! or is handled; never a panic, a hang, or a half-written file.

use std::path::Path;

use farfield_builder::cubes::{CubeOptions, build_cubes};
use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::{Geometry, Primitives, Scene};
use farfield_builder::{BuildError, BuildOptions, build_spheres};
use farfield_tests::{scratch, shared_data};
use glam::DVec3;

use crate::{build, cli, resident};

fn error_of(input: &Path) -> String {
    match load_input(input.to_str().unwrap(), &Params::default()) {
        Ok(_) => panic!("{} should not load", input.display()),
        Err(e) => e.to_string(),
    }
}

/// The one-line error of `build INPUT --out OUT`, which must fail.
fn build_error(input: &Path, out: &Path) -> String {
    let err = cli(&[
        "build",
        input.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ])
    .unwrap_err();
    format!("{err:#}")
}

/// A failed build writes nothing at the target and leaves no temporary file.
fn assert_build_fails_cleanly(dir: &Path, input: &Path, expect: &[&str]) {
    let out = dir.join("out.ff");
    let message = build_error(input, &out);
    for e in expect {
        assert!(message.contains(e), "error '{message}' lacks '{e}'");
    }
    assert!(!message.contains('\n'), "error is not one line: {message}");
    assert_says_each_part_once(&message);
    assert!(!out.exists(), "half file left at {}", out.display());
    assert_no_temporary_files(dir);
}

fn assert_no_temporary_files(dir: &Path) {
    let leftovers: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(Result::ok)
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");
}

/// An error chain whose cause is both printed by one error and returned as
/// its `source` says the cause twice ("x: No such file: No such file").
fn assert_says_each_part_once(message: &str) {
    let parts: Vec<&str> = message.split(": ").collect();
    for (i, part) in parts.iter().enumerate() {
        assert!(
            !parts[i + 1..].contains(part),
            "error repeats '{part}': {message}"
        );
    }
}

#[test]
fn missing_and_unknown_inputs() {
    let dir = scratch("missing");
    assert_build_fails_cleanly(&dir, &dir.join("nope.obj"), &["nope.obj", "No such file"]);
    let missing_file = dir.join("nope.ff");
    let err = cli(&["inspect", missing_file.to_str().unwrap(), "--json"]).unwrap_err();
    let message = format!("{err:#}");
    assert!(message.contains("nope.ff"), "{message}");
    assert_says_each_part_once(&message);
    std::fs::write(dir.join("scene.xyz"), "1 2 3\n").unwrap();
    assert_build_fails_cleanly(
        &dir,
        &dir.join("scene.xyz"),
        &["scene.xyz", "unknown input format"],
    );
}

#[test]
fn an_unwritable_output_fails_before_the_import() {
    let dir = scratch("unwritable");
    let input = dir.join("tri.obj");
    std::fs::write(&input, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").unwrap();
    let message = build_error(&input, &dir.join("no-such-folder").join("out.ff"));
    assert!(message.contains("no-such-folder"), "{message}");
    assert_says_each_part_once(&message);
    let message = build_error(&input, &dir);
    assert!(message.contains("is a folder"), "{message}");
    // Checked first: a missing input is not even opened.
    let message = build_error(
        &dir.join("missing.obj"),
        &dir.join("no-such-folder").join("out.ff"),
    );
    assert!(
        message.contains("no-such-folder") && !message.contains("missing.obj"),
        "{message}"
    );
    assert_no_temporary_files(&dir);
}

#[test]
fn truncated_binary_ply_names_the_element() {
    let Some(data) = shared_data() else { return };
    let dir = scratch("truncated");
    let bytes = std::fs::read(data.join("horse.ply")).unwrap();
    let cut = dir.join("horse.ply");
    std::fs::write(&cut, &bytes[..bytes.len() * 2 / 3]).unwrap();
    let e = error_of(&cut);
    assert!(e.contains("horse.ply") && e.contains("face"), "{e}");
    assert_build_fails_cleanly(&dir, &cut, &["horse.ply"]);
}

#[test]
fn out_of_range_index_nan_and_empty_files() {
    let dir = scratch("malformed");
    let bad_index = dir.join("bad_index.obj");
    std::fs::write(&bad_index, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n").unwrap();
    let e = error_of(&bad_index);
    assert!(e.contains("bad_index.obj") && e.contains("line 4"), "{e}");

    let nan = dir.join("nan.off");
    std::fs::write(&nan, "OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n").unwrap();
    let e = error_of(&nan);
    assert!(e.contains("nan.off") && e.contains("vertex 1"), "{e}");

    let inf = dir.join("inf.obj");
    std::fs::write(&inf, "v 0 0 0\nv 1 0 inf\nv 0 1 0\nf 1 2 3\n").unwrap();
    assert!(error_of(&inf).contains("vertex 1"));

    let empty = dir.join("empty.obj");
    std::fs::write(&empty, "# nothing here\n").unwrap();
    assert!(error_of(&empty).contains("no geometry"));
    assert_build_fails_cleanly(&dir, &empty, &["empty.obj", "no geometry"]);
}

#[test]
fn identical_duplicate_and_degenerate_inputs_are_handled() {
    // A million copies of one point: collapse into one leaf, quickly.
    let scene = Scene::single(Geometry::new(
        "dups",
        vec![DVec3::new(1.0, 2.0, 3.0); 1_000_000],
        Primitives::Points,
    ));
    let file = build(scene);
    assert_eq!(file.header.leaves, 1);
    assert_eq!(file.header.input_vertices, 1_000_000);

    // Zero-area triangles (a collinear strip, a point) have no surface:
    // alone they are nothing to build, with either builder ...
    let flat = Geometry::new(
        "flat",
        vec![
            DVec3::ZERO,
            DVec3::X,
            DVec3::X * 2.0,
            DVec3::ONE,
            DVec3::ONE,
            DVec3::ONE,
        ],
        Primitives::Triangles(vec![[0, 1, 2], [3, 4, 5]]),
    );
    let spheres = build_spheres(Scene::single(flat.clone()), &BuildOptions::default());
    assert!(matches!(spheres, Err(BuildError::Empty)), "{spheres:?}");
    let cubes = build_cubes(Scene::single(flat.clone()), &CubeOptions::default());
    assert!(matches!(cubes, Err(BuildError::Empty)), "{cubes:?}");
    // ... and beside a real triangle they add no leaf: its three corners.
    let mut mixed = flat;
    mixed.positions.extend([
        DVec3::Z * 5.0,
        DVec3::new(1.0, 0.0, 5.0),
        DVec3::new(0.0, 1.0, 5.0),
    ]);
    if let Primitives::Triangles(t) = &mut mixed.primitives {
        t.push([6, 7, 8]);
    }
    let file = build(Scene::single(mixed));
    let nodes = resident(&file).decode_all();
    assert_eq!(file.header.leaves, 3, "the real triangle's corners only");
    assert!(nodes.iter().all(|n| n.center.is_finite() && n.radius > 0.0));
}
