//! The two command lines' own helpers (their crates build no test binary
//! of their own: each would link the whole stack again for a few tests).

use farfield_cli::commands::path::path_json;
use farfield_client::path::{CameraPath, Keyframe};
use farfield_server::cli::counted;

#[test]
fn counts_say_their_noun_in_the_right_number() {
    assert_eq!(counted(1u32, "level", "levels"), "1 level");
    assert_eq!(counted(0u32, "leaf", "leaves"), "0 leaves");
    assert_eq!(counted(11u64, "page", "pages"), "11 pages");
}

/// The JSON is what the camera-path reader accepts, keyframe for keyframe.
#[test]
fn paths_read_back_as_camera_paths() {
    for (input, params, count) in [
        ("gen:city", vec!["grid=3".to_owned()], 160),
        ("gen:cars", vec!["cars=2".to_owned()], 200),
    ] {
        let json = path_json(input, &params).expect("a path");
        let keys: Vec<Keyframe> = serde_json::from_str(&json).expect("keyframes");
        assert_eq!(keys.len(), count);
        let path = CameraPath::from_keyframes(&keys).expect("a valid path");
        assert_eq!(path.key_times().len(), count);
    }
}

#[test]
fn scenes_without_paths_and_bad_inputs_are_errors() {
    let e = path_json("gen:tree", &[]).expect_err("no path").to_string();
    assert!(e.contains("gen:city") && e.contains("gen:cars"), "{e}");
    let e = path_json("gen:meadow", &[])
        .expect_err("unknown")
        .to_string();
    assert!(e.contains("unknown generator"), "{e}");
    let e = path_json("scan.ply", &[]).expect_err("a file").to_string();
    assert!(e.contains("gen:NAME"), "{e}");
    let e = path_json("gen:city", &["gird=3".to_owned()])
        .expect_err("typo")
        .to_string();
    assert!(e.contains("gird") && e.contains("grid"), "{e}");
}
