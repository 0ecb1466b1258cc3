//! `farfield-server merge`: the parts of a build on many machines into one
//! scene file.

use std::time::Instant;

use anyhow::Context;
use serde_json::json;

use farfield_builder::BuildOptions;
use farfield_builder::out_of_core;
use farfield_store::{check_target, write_atomic_parts};
use farfield_tools::meters::memory;

use super::build::{Bar, progress_bar};
use super::{MergeArgs, Report, counted, folder_of, publish_and_remove, remote};

pub fn run(args: &MergeArgs) -> anyhow::Result<Report> {
    // Published to a store: merged into a temporary file first (the store
    // is reached before the merge, so a wrong address fails at once).
    let store = args.store.publish_target(&args.out)?;
    let tmp = args.tmp.clone().unwrap_or_else(|| match &store {
        Some(_) => std::env::temp_dir(),
        None => folder_of(&args.out),
    });
    let local = match &store {
        Some(_) => tmp.join(format!(".farfield-merge-{}.ff", std::process::id())),
        None => args.out.clone(),
    };
    check_target(&local)?;
    let options = BuildOptions {
        page_bytes: args
            .page_bytes
            .unwrap_or(farfield_builder::DEFAULT_PAGE_BYTES),
        ..BuildOptions::default()
    };
    let progress = progress_bar(args.json);
    let started = Instant::now();
    // Parts in a store are downloaded first, into a folder that goes when
    // the merge ends.
    let staging = remote::staging_for(args.parts.iter().filter_map(|p| p.to_str()), &tmp)?;
    let parts = match &staging {
        Some(dir) => remote::stage_parts(&args.parts, &args.store, dir.path())?,
        None => args.parts.clone(),
    };
    let (finished, stats) = out_of_core::merge(&parts, &options, &tmp, &Bar(&progress))
        .with_context(|| format!("merging {} parts", args.parts.len()))?;
    let h = finished.file.header.clone();
    let mut bytes = write_atomic_parts(
        &local,
        &finished.file.head(),
        &finished.file.body,
        &finished.file.tail(),
    )?;
    drop(finished);
    drop(staging);
    if let Some(target) = &store {
        bytes = publish_and_remove(&local, target)?;
    }
    progress.finish_and_clear();
    let seconds = started.elapsed().as_secs_f64();
    let text = format!(
        "{}: {} parts merged, {} ({}, {}) in {}, {bytes} bytes, {seconds:.2} s",
        args.out.display(),
        args.parts.len(),
        counted(h.nodes, "node", "nodes"),
        counted(h.leaves, "leaf", "leaves"),
        counted(h.levels, "level", "levels"),
        counted(u64::from(h.page_count), "page", "pages"),
    );
    Ok(Report {
        json: json!({
            "out": args.out,
            "parts": args.parts,
            "file_bytes": bytes,
            "bytes_per_node": bytes as f64 / h.nodes.max(1) as f64,
            "input_vertices": h.input_vertices,
            "bytes_per_input": bytes as f64 / h.input_vertices.max(1) as f64,
            "seconds": seconds,
            "peak_rss_bytes": memory::peak_rss_bytes(),
            "stats": stats,
        }),
        text,
        exit_code: 0,
        as_json: args.json,
    })
}
