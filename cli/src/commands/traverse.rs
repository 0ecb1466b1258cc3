//! `farfield traverse`: one traversal of a whole file, of whichever kind
//! it is, and the counts of its cut.

use std::path::Path;
use std::time::Instant;

use farfield_client::camera_spec::CameraSpec;
use farfield_traverse::TraversalOptions;

pub fn run(
    file: &Path,
    orbit: CameraSpec,
    size: (u32, u32),
    threshold: f64,
    json: bool,
) -> anyhow::Result<()> {
    anyhow::ensure!(
        threshold.is_finite() && threshold >= 0.0,
        "threshold must be a non-negative number"
    );
    let hierarchy = farfield_client::viewer::load_file(file)?;
    let camera = orbit.resolve(&hierarchy.header, size.0, size.1);
    let mut traversal = farfield_traverse::for_hierarchy(hierarchy.header.kind);
    let started = Instant::now();
    traversal.traverse(
        &hierarchy,
        &camera,
        &TraversalOptions {
            threshold_px: threshold,
            ..Default::default()
        },
    );
    let ms = started.elapsed().as_secs_f64() * 1e3;
    let cut = traversal.counts();
    if json {
        // `splats` is what the cut draws: splats, or cube faces and leaf
        // triangles for a cube hierarchy (`kind` says which).
        let j = serde_json::json!({
            "kind": traversal.registered().name,
            "splats": cut.drawn, "visited": cut.visited, "frustum_culled": cut.frustum_culled,
            "backface_culled": cut.backface_culled, "traverse_ms": ms,
        });
        println!("{j}");
    } else {
        println!(
            "{}: {} splats from {} nodes visited ({} frustum-culled, {} backface-culled) in {ms:.2} ms",
            file.display(),
            cut.drawn,
            cut.visited,
            cut.frustum_culled,
            cut.backface_culled
        );
    }
    Ok(())
}
