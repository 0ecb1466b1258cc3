//! A survey delivered as LAS tiles, each with its own coordinate offset,
//! builds as one scene: from the folder, or from the files listed.

use farfield_tests::scratch;

/// Generated tiles (`farfield-server lidar-tiles`) built from their folder
/// are the same file as from the list of tiles, hold every point, and span
/// the tiles' union; a folder with nothing to read is an error.
#[test]
fn a_folder_of_las_tiles_builds_one_scene() {
    let dir = scratch("tiles");
    let tiles = dir.join("survey");
    let made = crate::cli(&[
        "lidar-tiles",
        "--points",
        "20000",
        "--grid",
        "3",
        "--out",
        tiles.to_str().unwrap(),
    ])
    .expect("lidar-tiles");
    let listed: Vec<String> = made.json["tiles"]
        .as_array()
        .unwrap()
        .iter()
        .map(|t| t.as_str().unwrap().to_string())
        .collect();
    assert_eq!(listed.len(), 9);
    let from_folder = dir.join("folder.ff");
    let from_list = dir.join("list.ff");
    let report = crate::cli(&[
        "build",
        tiles.to_str().unwrap(),
        "--out",
        from_folder.to_str().unwrap(),
        "--json",
    ])
    .expect("build the folder");
    assert_eq!(report.json["input_vertices"], 20000, "{}", report.json);
    let mut args = vec!["build"];
    args.extend(listed.iter().map(String::as_str));
    args.extend(["--out", from_list.to_str().unwrap()]);
    crate::cli(&args).expect("build the list");
    assert_eq!(
        std::fs::read(&from_folder).unwrap(),
        std::fs::read(&from_list).unwrap(),
        "the folder and the list build the same file"
    );
    // The scene spans every tile: the union of the tiles' bounds.
    let scene = farfield_store::SceneFile::open(&from_folder).expect("open");
    let (mut min, mut max) = ([f64::MAX; 2], [f64::MIN; 2]);
    for tile in &listed {
        let header = las::Reader::from_path(tile).unwrap().header().clone();
        let b = header.bounds();
        min = [min[0].min(b.min.x), min[1].min(b.min.y)];
        max = [max[0].max(b.max.x), max[1].max(b.max.y)];
    }
    let h = &scene.header;
    for (axis, (lo, hi)) in [(0, (min[0], max[0])), (1, (min[1], max[1]))] {
        assert!(
            (h.bounds_min[axis] - lo).abs() < 0.01 && (h.bounds_max[axis] - hi).abs() < 0.01,
            "axis {axis}: scene {}..{}, tiles {lo}..{hi}",
            h.bounds_min[axis],
            h.bounds_max[axis]
        );
    }
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    std::fs::write(empty.join("notes.txt"), "not a tile").unwrap();
    let e = crate::cli(&[
        "build",
        empty.to_str().unwrap(),
        "--out",
        dir.join("empty.ff").to_str().unwrap(),
    ])
    .unwrap_err();
    assert!(e.to_string().contains("no geometry"), "{e}");
}
