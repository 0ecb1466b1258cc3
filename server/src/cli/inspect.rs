//! `farfield-server inspect`: counts, attributes and a checksum of every page.

use serde_json::json;

use super::{InspectArgs, Report, counted};
use farfield_store::SceneFile;

pub fn run(args: &InspectArgs) -> anyhow::Result<Report> {
    let file = SceneFile::open(&args.file)?;
    let h = &file.header;
    let survey = file.survey_pages();
    let corrupt = &survey.corrupt;
    let d = &file.directory;
    let first = d.entry(0);
    let first_page_nodes = first.map_or(0, |p| p.node_count);
    // The first image's bytes: the header, the root directory page and
    // page 0, whatever the scene's size.
    let first_read = file.header_bytes().len() as u64
        + d.extent(d.root_id()).map_or(0, |e| u64::from(e.length))
        + first.map_or(0, |e| u64::from(e.length));
    let json = json!({
        "file": args.file,
        "kind": h.kind.name(),
        "format_version": farfield_protocol::file::FORMAT_VERSION,
        "nodes": h.nodes,
        "leaves": h.leaves,
        "levels": h.levels,
        "input_vertices": h.input_vertices,
        "has_color": h.attributes.color,
        "has_normals": h.attributes.normals,
        "node_bytes": h.node_bytes,
        "pages": h.page_count,
        "directory_pages": h.directory_pages,
        "directory_bytes": d.directory_extents().map(|(_, e)| u64::from(e.length)).sum::<u64>(),
        // What a client reads before any page: the header, the same for
        // every scene.
        "header_bytes": file.header_bytes().len(),
        "first_image_bytes": first_read,
        "compressed_pages": survey.compressed,
        "page_body_bytes_stored": survey.stored_bytes,
        "page_body_bytes_decoded": survey.decoded_bytes,
        "bytes_per_input": file.len() as f64 / h.input_vertices.max(1) as f64,
        "page_bytes_max": d.entries().map(|(_, p)| p.length).max().unwrap_or(0),
        "first_page_nodes": first_page_nodes,
        "first_page_levels": first.map_or(0, |p| u32::from(p.level_max) + 1),
        "file_bytes": file.len(),
        "bytes_per_node": file.len() as f64 / h.nodes as f64,
        "bounds_min": h.bounds_min.to_array(),
        "bounds_max": h.bounds_max.to_array(),
        "root_center": h.root_center.to_array(),
        "root_radius": h.root_radius,
        "corrupt_pages": corrupt.len(),
        "corrupt": corrupt.iter().map(|(i, e)| json!({"page": i, "error": e.to_string()})).collect::<Vec<_>>(),
    });
    let mut text = format!(
        "{}: {} hierarchy, {} ({}), {}, color {}, normals {}, {}, {} bytes ({:.2} bytes/node)",
        args.file.display(),
        h.kind.name(),
        counted(h.nodes, "node", "nodes"),
        counted(h.leaves, "leaf", "leaves"),
        counted(h.levels, "level", "levels"),
        h.attributes.color,
        h.attributes.normals,
        counted(u64::from(h.page_count), "page", "pages"),
        file.len(),
        file.len() as f64 / h.nodes as f64
    );
    if survey.decoded_bytes > 0 {
        text.push_str(&format!(
            "; {} of {} compressed, bodies {} bytes stored for {} decoded ({:.2}x)",
            survey.compressed,
            counted(u64::from(h.page_count), "page", "pages"),
            survey.stored_bytes,
            survey.decoded_bytes,
            survey.decoded_bytes as f64 / survey.stored_bytes.max(1) as f64
        ));
    }
    for (i, e) in corrupt {
        text.push_str(&format!("\ncorrupt page {i}: {e}"));
    }
    Ok(Report {
        json,
        text,
        exit_code: if corrupt.is_empty() { 0 } else { 2 },
        as_json: args.json,
    })
}
