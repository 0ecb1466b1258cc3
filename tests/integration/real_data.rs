//! Every file in ../shared/data builds, and inspect's counts match the
//! input as the data README states it and as counted independently here.

use std::collections::HashSet;

use farfield_builder::import::{Params, load_input};
use farfield_builder::scene::{Primitives, Scene};
use farfield_tests::{scratch, shared_data};

use crate::cli;

/// Distinct positions among the vertices that become leaves: every vertex
/// of a cloud or molecule, only vertices used by a triangle of a mesh.
fn expected_leaves(scene: &Scene) -> u64 {
    let mut seen = HashSet::new();
    for g in &scene.geometries {
        let used: Vec<bool> = match &g.primitives {
            Primitives::Triangles(t) => {
                let mut used = vec![false; g.positions.len()];
                t.iter().flatten().for_each(|&i| used[i as usize] = true);
                used
            }
            _ => vec![true; g.positions.len()],
        };
        for (p, u) in g.positions.iter().zip(used) {
            if u {
                seen.insert(p.to_array().map(f64::to_bits));
            }
        }
    }
    seen.len() as u64
}

#[test]
fn every_shared_file_builds_and_inspect_counts_match() {
    let Some(data) = shared_data() else { return };
    let dir = scratch("real");
    // (file, input vertices from the data README or the file's own header, color, normals)
    let cases: [(&str, Option<u64>, bool, bool); 7] = [
        ("stanford-bunny.obj", Some(35_947), false, true),
        ("horse.ply", Some(48_485), false, true),
        ("igea.ply", Some(134_345), false, true),
        ("beast.obj", Some(32_311), false, true),
        ("spot.obj", Some(2_930), false, true),
        ("autzen_trim.las", None, true, true),
        ("2XHE.pdb", None, true, false),
    ];
    let mut names: Vec<String> = std::fs::read_dir(&data)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n != "README.md")
        .collect();
    names.sort();
    let mut covered: Vec<String> = cases.iter().map(|c| c.0.to_owned()).collect();
    covered.sort();
    assert_eq!(names, covered, "a file in shared/data has no case here");

    for (name, vertices, color, normals) in cases {
        let input = data.join(name);
        let input = input.to_str().unwrap();
        let scene = load_input(input, &Params::default()).unwrap();
        let input_vertices = scene.instanced_vertex_count();
        if let Some(v) = vertices {
            assert_eq!(input_vertices, v, "{name}: vertex count");
        }
        let leaves = expected_leaves(&scene);
        let out = dir.join(format!("{name}.ff"));
        let built = cli(&["build", input, "--out", out.to_str().unwrap(), "--json"]).unwrap();
        assert_eq!(built.exit_code, 0);
        let report = cli(&["inspect", out.to_str().unwrap(), "--json"]).unwrap();
        let j = &report.json;
        assert_eq!(j["kind"], "spheres", "{name}");
        assert_eq!(j["input_vertices"], input_vertices, "{name}");
        assert_eq!(
            j["leaves"], leaves,
            "{name}: leaves = distinct used positions"
        );
        assert_eq!(j["has_color"], color, "{name}");
        assert_eq!(j["has_normals"], normals, "{name}");
        assert_eq!(j["corrupt_pages"], 0, "{name}");
        let nodes = j["nodes"].as_u64().unwrap();
        assert!(
            nodes > leaves && nodes < 2 * leaves,
            "{name}: {nodes} nodes for {leaves} leaves"
        );
        let per_node = j["bytes_per_node"].as_f64().unwrap();
        let limit = if color { 6.5 } else { 4.5 };
        assert!(per_node <= limit, "{name}: {per_node} bytes per node");
        assert_eq!(
            j["file_bytes"],
            std::fs::metadata(&out).unwrap().len(),
            "{name}"
        );
        eprintln!(
            "{name}: {} nodes, {} leaves, {} levels, {per_node:.3} bytes/node",
            nodes, leaves, j["levels"]
        );
    }
}

#[test]
fn the_molecule_has_one_sphere_per_atom_record() {
    let Some(data) = shared_data() else { return };
    let text = std::fs::read_to_string(data.join("2XHE.pdb")).unwrap();
    // First model only (the file has one); ATOM and HETATM records.
    let atoms = text
        .lines()
        .take_while(|l| !l.starts_with("ENDMDL"))
        .filter(|l| l.starts_with("ATOM") || l.starts_with("HETATM"))
        .count();
    let scene = load_input(data.join("2XHE.pdb").to_str().unwrap(), &Params::default()).unwrap();
    assert_eq!(scene.instanced_vertex_count(), atoms as u64);
    assert!(matches!(
        scene.geometries[0].primitives,
        Primitives::Spheres(_)
    ));
}
