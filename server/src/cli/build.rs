//! `farfield-server build`: inputs -> scene -> hierarchy -> file.

use std::io::IsTerminal;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use farfield_builder::bsp::BspOptions;
use farfield_builder::cubes::CubeOptions;
use farfield_builder::import::{Params, load_inputs};
use farfield_builder::kinds::{BuildSettings, Built};
use farfield_builder::plp::PlpOptions;
use farfield_builder::{BuildOptions, Progress};
use farfield_store::{check_target, write_atomic};
use farfield_tools::meters::memory;

use super::{BuildArgs, Report, counted};

/// Steps without a measure of their own (import, writing): a spinner and
/// what is going on.
fn spinner_style() -> ProgressStyle {
    ProgressStyle::with_template("{spinner} {elapsed_precise} {msg}")
        .unwrap_or_else(|_| ProgressStyle::default_spinner())
}

/// The terminal's progress bar as the builder's [`Progress`]: a step's
/// name, a bar, its percentage and the time it has left.
struct Bar<'a>(&'a ProgressBar);

impl Progress for Bar<'_> {
    fn begin(&self, step: &'static str, total: u64) {
        // Position first: a tick between these calls must not draw the
        // last step's position against this step's length.
        self.0.set_position(0);
        self.0.set_length(total);
        self.0.reset_eta();
        self.0.set_message(step);
        self.0.set_style(
            ProgressStyle::with_template(
                "{spinner} {elapsed_precise} building: {msg:7} [{bar:30}] {percent:>3}% ({eta} left)",
            )
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
        );
    }

    fn advance(&self, done: u64) {
        self.0.inc(done);
    }
}

pub fn run(args: &BuildArgs) -> anyhow::Result<Report> {
    let params = Params::parse(&args.params).map_err(anyhow::Error::msg)?;
    // Published to a store: built into a temporary file first (the store
    // is reached before the build, so a wrong address fails at once).
    let store = match args
        .out
        .to_str()
        .filter(|o| farfield_objects::is_store_url(o))
    {
        Some(url) => {
            let (bucket, url) = args.store.bucket(url, Default::default())?;
            anyhow::ensure!(
                !url.key.is_empty(),
                "{url}: name the object to write (s3://bucket/key.ff)"
            );
            match bucket.head(&url.key) {
                Ok(_) | Err(farfield_objects::RemoteError::NotFound(_)) => {}
                Err(e) => anyhow::bail!("cannot reach the store: {e}"),
            }
            Some((bucket, url))
        }
        None => None,
    };
    let local = match &store {
        Some(_) => std::env::temp_dir().join(format!("farfield-build-{}.ff", std::process::id())),
        None => args.out.clone(),
    };
    check_target(&local)?;
    let progress = if args.json || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::new_spinner();
        bar.set_style(spinner_style());
        bar.enable_steady_tick(std::time::Duration::from_millis(100));
        bar
    };
    let started = Instant::now();
    progress.set_message("importing");
    let scene = load_inputs(&args.inputs, &params)?;
    let seconds_import = started.elapsed().as_secs_f64();
    progress.set_message(format!(
        "building {} vertices",
        scene.instanced_vertex_count()
    ));
    let build_started = Instant::now();
    let builder = farfield_builder::kinds::builder_named(&args.kind)
        .with_context(|| format!("unknown hierarchy kind {:?}", args.kind))?;
    let settings = BuildSettings {
        page_bytes: args.page_bytes,
        spheres: BuildOptions::default(),
        cubes: CubeOptions {
            samples: args.face_samples,
            cluster: args.cluster,
            max_depth: args.max_depth,
            composite: args.composite,
            cube_cost: args.cube_cost,
            ..CubeOptions::default()
        },
        plp: PlpOptions {
            leaf_fraction: args.leaf_fraction,
            seed: args.seed,
            ..PlpOptions::default()
        },
        bsp: BspOptions {
            directions: args.bsp_directions,
            inflation: args.inflation,
            leaf_triangles: args.leaf_triangles,
            ..BspOptions::default()
        },
    };
    let Built { file, stats, nodes } = (builder.build)(scene, &settings, &Bar(&progress))
        .with_context(|| format!("building {}", args.inputs.join(" ")))?;
    let kind = builder.name();
    let seconds_build = build_started.elapsed().as_secs_f64();
    progress.set_style(spinner_style());
    progress.set_message(format!("writing {}", args.out.display()));
    let mut bytes = write_atomic(&local, &file)?;
    if let Some((bucket, url)) = &store {
        let published = farfield_objects::publish(&local, bucket, &url.key);
        let _ = std::fs::remove_file(&local);
        bytes = published?;
    }
    progress.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let h = &file.header;
    let json = json!({
        "out": args.out,
        "kind": kind,
        "file_bytes": bytes,
        "bytes_per_node": bytes as f64 / nodes as f64,
        // Points, vertices or atoms read: bytes a point is how lidar
        // tools compare their files.
        "input_vertices": h.input_vertices,
        "bytes_per_input": bytes as f64 / h.input_vertices.max(1) as f64,
        "seconds": seconds,
        "seconds_import": seconds_import,
        "seconds_build": seconds_build,
        "vertices_per_second": h.input_vertices as f64 / seconds,
        "peak_rss_bytes": memory::peak_rss_bytes(),
        "stats": stats,
    });
    let text = format!(
        "{}: {kind} hierarchy, {} ({}, {}) in {}, {} bytes ({:.2} bytes/node), {:.2} s",
        args.out.display(),
        counted(h.nodes, "node", "nodes"),
        counted(h.leaves, "leaf", "leaves"),
        counted(h.levels, "level", "levels"),
        counted(h.pages.len() as u64, "page", "pages"),
        bytes,
        bytes as f64 / nodes as f64,
        seconds
    );
    Ok(Report {
        json,
        text,
        exit_code: 0,
        as_json: args.json,
    })
}
