//! The report of a view: what a render did, for `--json`, the CSVs and the
//! benchmarks.

use std::path::PathBuf;

use farfield_net::{FailedPage, NetStats};
use farfield_render::Renderer;
use serde::Serialize;

use crate::frame_loop::Settle;
use crate::viewer::Viewer;

/// What a render reports (`--json`).
#[derive(Debug, Clone, Serialize)]
pub struct RenderReport {
    pub out: Option<PathBuf>,
    pub width: u32,
    pub height: u32,
    pub time_to_first_image_ms: Option<f64>,
    pub time_to_refined_ms: Option<f64>,
    pub refined: bool,
    pub frames: u64,
    /// The session's counters (bytes and pages received, requested,
    /// cancelled, rejected; disconnects), flattened into the JSON.
    #[serde(flatten)]
    pub net: NetStats,
    /// Splats, or cube faces plus leaf triangles.
    pub nodes_drawn: usize,
    pub nodes_visited: u64,
    /// Cubes: faces and triangles of the last frame.
    pub cube_faces_drawn: usize,
    pub triangles_drawn: u64,
    pub threshold_px: f64,
    /// Bytes received / bytes of the pages the final cut touched.
    pub overfetch_ratio: Option<f64>,
    pub adapter: String,
    pub last_traverse_ms: f64,
    pub last_upload_ms: f64,
    pub last_draw_ms: f64,
    pub last_error: Option<String>,
    /// Pages given up on (corrupt on the server, or failing their checksum
    /// on arrival too often), with why: their parts are drawn from coarser
    /// pages.
    pub pages_failed: Vec<FailedPage>,
    /// Image caching (BSP files): the cost model measured at start-up,
    /// and the last frame's caches.
    pub impostor_costs: Option<farfield_traverse::impostors::CostModel>,
    pub impostors: Option<farfield_traverse::impostors::plan::ImpostorStats>,
}

impl Settle {
    /// The report of what happened, with the viewer's network counters.
    pub fn report(&self, viewer: &Viewer, renderer: &Renderer) -> RenderReport {
        let stats = viewer.stats();
        let overfetch_ratio = viewer
            .hierarchy()
            .filter(|_| viewer.is_streamed())
            .and_then(|h| {
                let needed: u64 = self
                    .cut
                    .touched_pages()
                    .iter()
                    .filter_map(|&p| h.directory().extent(p))
                    .map(|e| u64::from(e.length))
                    .sum();
                (needed > 0).then(|| stats.bytes_received as f64 / needed as f64)
            });
        let (cube_faces_drawn, triangles_drawn) = self
            .cut
            .draw_list()
            .map_or((0, 0), |list| list.faces_and_triangles());
        let (width, height) = renderer.size();
        RenderReport {
            out: None,
            width,
            height,
            time_to_first_image_ms: self.time_to_first_image_ms,
            time_to_refined_ms: self.time_to_refined_ms,
            refined: self.time_to_refined_ms.is_some(),
            frames: self.frame_count,
            net: stats.clone(),
            nodes_drawn: self.cut.drawn(),
            nodes_visited: self.cut.visited(),
            cube_faces_drawn,
            triangles_drawn,
            threshold_px: self.threshold,
            overfetch_ratio,
            adapter: renderer.adapter_description(),
            last_traverse_ms: self.last.traverse_ms,
            last_upload_ms: self.last.upload_ms,
            last_draw_ms: self.last.draw_ms,
            last_error: self.error.clone().or(stats.last_error.clone()),
            pages_failed: viewer.failed_pages(),
            impostor_costs: self.cut.costs,
            impostors: self.cut.draw_list().and_then(|l| l.impostor_stats()),
        }
    }
}
