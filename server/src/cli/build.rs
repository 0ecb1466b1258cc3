//! `farfield-server build`: inputs -> scene -> hierarchy -> file.

use std::io::IsTerminal;
use std::path::Path;
use std::time::Instant;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use serde_json::json;

use farfield_builder::bsp::BspOptions;
use farfield_builder::cubes::CubeOptions;
use farfield_builder::import::{Params, load_inputs};
use farfield_builder::kinds::BuildSettings;
use farfield_builder::out_of_core::{self, Budget, Plan, Subset, TempDir};
use farfield_builder::plp::PlpOptions;
use farfield_builder::{BuildError, BuildOptions, Progress};
use farfield_objects::is_store_url;
use farfield_store::{check_target, write_atomic, write_atomic_parts};
use farfield_tools::meters::memory;

use super::{BuildArgs, Report, counted, folder_of, publish_and_remove, remote};

/// Steps without a measure of their own (import, writing): a spinner and
/// what is going on.
fn spinner_style() -> ProgressStyle {
    ProgressStyle::with_template("{spinner} {elapsed_precise} {msg}")
        .unwrap_or_else(|_| ProgressStyle::default_spinner())
}

/// The terminal's progress bar as the builder's [`Progress`]: a step's
/// name, a bar, its percentage and the time it has left.
pub(super) struct Bar<'a>(pub(super) &'a ProgressBar);

/// A spinner on a terminal, unless the report is JSON; hidden otherwise.
pub(super) fn progress_bar(json: bool) -> ProgressBar {
    if json || !std::io::stderr().is_terminal() {
        ProgressBar::hidden()
    } else {
        let bar = ProgressBar::new_spinner();
        bar.set_style(spinner_style());
        bar.enable_steady_tick(std::time::Duration::from_millis(100));
        bar
    }
}

/// The memory budget and temporary folder `args` ask for.
fn budget_of(args: &BuildArgs, local: &Path, remote: bool) -> Budget {
    Budget {
        memory: args.memory.unwrap_or_else(out_of_core::default_memory),
        tmp: match &args.tmp {
            Some(dir) => dir.clone(),
            None if remote => std::env::temp_dir(),
            None => folder_of(local),
        },
    }
}

/// `build --subset I/N`: part I of a build on many machines, into the
/// folder `--out`, or under the store prefix `--out` (see
/// `farfield-server merge`).
fn run_subset(
    args: &BuildArgs,
    subset: Subset,
    params: &Params,
    progress: &ProgressBar,
) -> anyhow::Result<Report> {
    anyhow::ensure!(
        args.kind == "spheres",
        "--subset builds spheres only, not {}",
        args.kind
    );
    // A part for a store is built into the temporary folder, then
    // uploaded (the store reached first, so a wrong address fails at once).
    let remote = match args.out.to_str().filter(|o| is_store_url(o)) {
        Some(out) => Some(remote::part_target(&args.store, out)?),
        None => None,
    };
    // A part's temporary files go beside its folder, not inside it.
    let budget = budget_of(args, &args.out, remote.is_some());
    let started = Instant::now();
    let staging = TempDir::create(&budget.tmp)
        .with_context(|| format!("making a temporary folder in {}", budget.tmp.display()))?;
    let staged = remote::stage_inputs(&args.inputs, &args.store, staging.path())?;
    let mut job = out_of_core::plan_out_of_core(&staged.inputs, params, &budget)?;
    for (path, name) in staged.names {
        job.name_input(&path, name);
    }
    let folder = match &remote {
        Some(_) => staging.file("part"),
        None => args.out.clone(),
    };
    let stats = job
        .build_subset(subset, &folder, &Bar(progress))
        .with_context(|| {
            format!(
                "building part {}/{} of {}",
                subset.index,
                subset.count,
                args.inputs.join(" ")
            )
        })?;
    if let Some((bucket, prefix)) = &remote {
        progress.set_message(format!("uploading {}", args.out.display()));
        remote::upload_part(&folder, bucket, prefix)
            .with_context(|| format!("uploading the part to {}", args.out.display()))?;
    }
    drop(staging);
    progress.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let text = format!(
        "{}: part {}/{}, {} of {} chunks, {} of {} points, {seconds:.2} s",
        args.out.display(),
        subset.index,
        subset.count,
        stats.part_chunks,
        stats.chunks,
        stats.part_points,
        stats.points
    );
    Ok(Report {
        json: json!({
            "out": args.out,
            "seconds": seconds,
            "peak_rss_bytes": memory::peak_rss_bytes(),
            "memory_budget": budget.memory,
            "part": stats,
        }),
        text,
        exit_code: 0,
        as_json: args.json,
    })
}

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

/// A finished build: in memory, or with its pages spilled to disk.
enum Made {
    InMemory(farfield_builder::PagedFile),
    Spilled(out_of_core::Finished),
}

impl Made {
    fn header(&self) -> &farfield_protocol::file::FileHeader {
        match self {
            Self::InMemory(file) => &file.header,
            Self::Spilled(f) => &f.file.header,
        }
    }
}

pub fn run(args: &BuildArgs) -> anyhow::Result<Report> {
    let mut params = Params::parse(&args.params).map_err(anyhow::Error::msg)?;
    params.up = args.up;
    if let Some(subset) = args.subset {
        // A part is a folder (or a prefix in a store), not a scene file.
        return run_subset(args, subset, &params, &progress_bar(args.json));
    }
    // Published to a store: built into a temporary file first (the store
    // is reached before the build, so a wrong address fails at once).
    let store = args.store.publish_target(&args.out)?;
    let local = match &store {
        Some(_) => std::env::temp_dir().join(format!("farfield-build-{}.ff", std::process::id())),
        None => args.out.clone(),
    };
    check_target(&local)?;
    let progress = progress_bar(args.json);
    let started = Instant::now();
    progress.set_message("importing");
    let builder = farfield_builder::kinds::builder_named(&args.kind)
        .with_context(|| format!("unknown hierarchy kind {:?}", args.kind))?;
    let budget = budget_of(args, &local, store.is_some());
    // Inputs in a store are downloaded first, into a folder that goes
    // when the build ends.
    let staging = remote::staging_for(args.inputs.iter().map(String::as_str), &budget.tmp)?;
    let inputs = match &staging {
        Some(dir) => remote::stage_inputs(&args.inputs, &args.store, dir.path())?.inputs,
        None => args.inputs.clone(),
    };
    // Only spheres are built out of core; other kinds load the scene.
    let plan = if builder.out_of_core {
        out_of_core::plan(&inputs, &params, &budget)?
    } else {
        Plan::InMemory {
            scene: load_inputs(&inputs, &params)?,
            note: args.memory.map(|_| {
                format!(
                    "--memory bounds sphere builds only: the {} hierarchy is built in memory",
                    builder.name()
                )
            }),
        }
    };
    let seconds_import = started.elapsed().as_secs_f64();
    let build_started = Instant::now();
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
    let (built, out_of_core, note) = match plan {
        Plan::InMemory { scene, note } => {
            if let Some(note) = &note {
                progress.suspend(|| eprintln!("note: {note}"));
            }
            progress.set_message(format!(
                "building {} vertices",
                scene.instanced_vertex_count()
            ));
            let built = (builder.build)(scene, &settings, &Bar(&progress))
                .map(|b| (Made::InMemory(b.file), b.stats, b.nodes));
            (built, false, note)
        }
        Plan::OutOfCore(job) => {
            progress.set_message(format!(
                "building {} points out of core (budget {} MiB)",
                job.points(),
                budget.memory >> 20
            ));
            let built = job
                .build(&settings.spheres_options(), &Bar(&progress))
                .and_then(|(finished, stats)| {
                    let nodes = finished.file.header.nodes;
                    Ok((
                        Made::Spilled(finished),
                        serde_json::to_value(stats)
                            .map_err(|e| BuildError::Invalid(e.to_string()))?,
                        nodes,
                    ))
                });
            (built, true, None)
        }
    };
    let (made, stats, nodes) =
        built.with_context(|| format!("building {}", args.inputs.join(" ")))?;
    let kind = builder.name();
    let seconds_build = build_started.elapsed().as_secs_f64();
    progress.set_style(spinner_style());
    progress.set_message(format!("writing {}", args.out.display()));
    let mut bytes = match &made {
        Made::InMemory(file) => write_atomic(&local, file)?,
        Made::Spilled(f) => {
            write_atomic_parts(&local, &f.file.head(), &f.file.body, &f.file.tail())?
        }
    };
    let h = made.header().clone();
    // The spilled pages and their temporary folder go now.
    drop(made);
    drop(staging);
    if let Some(target) = &store {
        bytes = publish_and_remove(&local, target)?;
    }
    progress.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
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
        "memory_budget": budget.memory,
        "out_of_core": out_of_core,
        "note": note,
        "stats": stats,
    });
    let text = format!(
        "{}: {kind} hierarchy, {} ({}, {}) in {}, {} bytes ({:.2} bytes/node), {:.2} s",
        args.out.display(),
        counted(h.nodes, "node", "nodes"),
        counted(h.leaves, "leaf", "leaves"),
        counted(h.levels, "level", "levels"),
        counted(u64::from(h.page_count), "page", "pages"),
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
