//! `farfield bench-cubes`: the 1996 color-cube paper's Table 2 on our
//! scenes. For each distance (in scene radii) the view is rendered with the
//! full geometry and with the hierarchy at `eps`; each time is a median of
//! repeats taken in this one run (traversal, packing, upload, draw and
//! read-back: a whole frame), next to the speedup, the cube faces drawn per
//! octree level, the triangles drawn and the image error against geometry.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use farfield_protocol::camera::Camera;
use farfield_protocol::file::HierarchyKind;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_traverse::cubes::{CubeCut, CubeOptions, traverse_cubes_into};
use serde::Serialize;

use crate::reference::Reference;
use farfield_client::camera_spec::scene_sphere;
use farfield_image::compare;
use farfield_render::{Coverage, Renderer};
use farfield_render::{CubeFrame, draw_cut};

/// What to measure.
#[derive(Debug, Clone)]
pub struct CubeBenchJob {
    /// The cube hierarchy file.
    pub file: PathBuf,
    /// The inputs it was built from (for the geometry reference).
    pub inputs: Vec<String>,
    pub params: Vec<String>,
    pub distances: Vec<f64>,
    /// Degrees off the octree's x axis, about the vertical axis.
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
    pub width: u32,
    pub height: u32,
    pub eps_px: f64,
    pub coverage: Coverage,
    pub repeats: usize,
    /// Folder for the geometry and hierarchy image of every distance.
    pub images: Option<PathBuf>,
}

/// Median, min and max of repeated timings, milliseconds.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Timing {
    pub median_ms: f64,
    pub min_ms: f64,
    pub max_ms: f64,
}

impl Timing {
    fn of(samples: Vec<f64>) -> Self {
        let extreme = |pick: fn(f64, f64) -> f64| samples.iter().copied().reduce(pick);
        Self {
            median_ms: crate::bench::median(&samples),
            min_ms: extreme(f64::min).unwrap_or(f64::NAN),
            max_ms: extreme(f64::max).unwrap_or(f64::NAN),
        }
    }
}

/// One distance of the table.
#[derive(Debug, Clone, Serialize)]
pub struct CubeBenchRow {
    pub distance: f64,
    /// Whole frames: packing on the CPU, upload, draw, read-back.
    pub geometry: Timing,
    pub hierarchy: Timing,
    /// The GPU part alone: from submitting the draw to the image in memory
    /// (what a renderer keeping the geometry on the GPU would pay).
    pub geometry_draw: Timing,
    pub hierarchy_draw: Timing,
    /// geometry median / hierarchy median.
    pub speedup: f64,
    pub cube_faces: usize,
    /// Faces drawn per octree level (index = level).
    pub faces_per_level: Vec<u64>,
    pub triangles_drawn: u64,
    pub reference_triangles: usize,
    pub cells_visited: u64,
    /// Hierarchy image against the geometry image; `None` PSNR = identical.
    pub rmse: f64,
    pub psnr_db: Option<f64>,
    pub wrong_fraction: f64,
}

/// The whole table.
#[derive(Debug, Clone, Serialize)]
pub struct CubeBenchReport {
    pub file: PathBuf,
    pub inputs: Vec<String>,
    pub width: u32,
    pub height: u32,
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
    pub eps_px: f64,
    pub coverage: String,
    pub repeats: usize,
    pub adapter: String,
    pub rows: Vec<CubeBenchRow>,
}

/// Runs the table on an already started renderer.
pub fn run(job: &CubeBenchJob, renderer: &mut Renderer) -> anyhow::Result<CubeBenchReport> {
    let h = farfield_client::viewer::load_file(&job.file)?;
    anyhow::ensure!(
        h.header.kind == HierarchyKind::Cubes,
        "{} is a {} hierarchy; bench-cubes needs one built with --kind cubes",
        job.file.display(),
        h.header.kind.name()
    );
    let reference = Reference::load(&job.inputs, &job.params)?;
    renderer.resize(job.width, job.height);
    if let Some(dir) = &job.images {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    }
    let (center, radius) = scene_sphere(&h.header);
    let repeats = job.repeats.max(1);
    let mut rows = Vec::new();
    for &d in &job.distances {
        let camera = Camera::orbit(
            center,
            radius,
            job.azimuth_deg,
            job.elevation_deg,
            d,
            job.width,
            job.height,
        );
        let mut vertices = Vec::new();
        let mut geometry_ms = Vec::new();
        let mut geometry_draw_ms = Vec::new();
        let mut geometry_image = Vec::new();
        // One warm-up frame of each, then the timed repeats.
        for i in 0..=repeats {
            let t = Instant::now();
            reference.pack(camera.eye, &mut vertices);
            let image = renderer.render_geometry(&camera, &vertices, &[], job.coverage, [0; 3])?;
            if i > 0 {
                geometry_ms.push(t.elapsed().as_secs_f64() * 1e3);
                geometry_draw_ms.push(image.draw_ms);
            }
            geometry_image = image.rgba;
        }
        drop(vertices);
        let mut cut = CubeCut::default();
        let mut hierarchy_ms = Vec::new();
        let mut hierarchy_draw_ms = Vec::new();
        let mut hierarchy_image = Vec::new();
        for i in 0..=repeats {
            let t = Instant::now();
            let image = hierarchy_frame(&h, renderer, &camera, job, &mut cut)?;
            if i > 0 {
                hierarchy_ms.push(t.elapsed().as_secs_f64() * 1e3);
                hierarchy_draw_ms.push(image.draw_ms);
            }
            hierarchy_image = image.rgba;
        }
        let m = compare(&geometry_image, &hierarchy_image, job.width, job.height, 8)?;
        if let Some(dir) = &job.images {
            for (name, rgba) in [
                ("geometry", &geometry_image),
                ("hierarchy", &hierarchy_image),
            ] {
                let path = dir.join(format!("d{d}_{name}.png"));
                farfield_image::write_png(&path, job.width, job.height, rgba)
                    .with_context(|| format!("writing {}", path.display()))?;
            }
        }
        let (geometry, hierarchy) = (Timing::of(geometry_ms), Timing::of(hierarchy_ms));
        rows.push(CubeBenchRow {
            distance: d,
            speedup: geometry.median_ms / hierarchy.median_ms,
            geometry,
            hierarchy,
            geometry_draw: Timing::of(geometry_draw_ms),
            hierarchy_draw: Timing::of(hierarchy_draw_ms),
            cube_faces: cut.faces.len(),
            faces_per_level: cut.faces_per_level.clone(),
            triangles_drawn: cut.triangles,
            reference_triangles: reference.triangles(),
            cells_visited: cut.visited,
            rmse: m.rmse,
            psnr_db: m.psnr_db.is_finite().then_some(m.psnr_db),
            wrong_fraction: m.wrong_fraction,
        });
    }
    Ok(CubeBenchReport {
        file: job.file.clone(),
        inputs: job.inputs.clone(),
        width: job.width,
        height: job.height,
        azimuth_deg: job.azimuth_deg,
        elevation_deg: job.elevation_deg,
        eps_px: job.eps_px,
        coverage: format!("{:?}", job.coverage),
        repeats,
        adapter: renderer.adapter_description(),
        rows,
    })
}

/// One hierarchy frame: traverse, pack the leaves, draw.
fn hierarchy_frame(
    h: &Hierarchy,
    renderer: &mut Renderer,
    camera: &Camera,
    job: &CubeBenchJob,
    cut: &mut CubeCut,
) -> anyhow::Result<farfield_render::RenderOutput> {
    let options = CubeOptions {
        eps_px: job.eps_px,
        min_alpha: job.coverage.min_alpha(),
        ..CubeOptions::default()
    };
    traverse_cubes_into(h, camera, &options, cut);
    let image = draw_cut(
        renderer,
        &CubeFrame {
            hierarchy: h,
            camera,
            cut,
            coverage: job.coverage,
            background: [0; 3],
        },
    )?;
    Ok(image)
}

/// The table as text, one line per distance.
pub fn format_table(r: &CubeBenchReport) -> String {
    let mut s = format!(
        "{} at {}x{}, {} deg off axis, eps {} px, coverage {}, {} repeats, on {}\n",
        r.file.display(),
        r.width,
        r.height,
        r.azimuth_deg,
        r.eps_px,
        r.coverage,
        r.repeats,
        r.adapter
    );
    s.push_str(
        "frame: CPU packing, upload, draw and read-back; draw: GPU submit to image in memory\n",
    );
    s.push_str("d      geometry ms (draw)  hierarchy ms (draw)  speedup  faces   triangles  PSNR dB  faces per level\n");
    for row in &r.rows {
        s.push_str(&format!(
            "{:<6} {:>8.2} ({:>6.2})  {:>9.2} ({:>6.2})  {:>7.2}  {:>6}  {:>9}  {:>7}  {:?}\n",
            row.distance,
            row.geometry.median_ms,
            row.geometry_draw.median_ms,
            row.hierarchy.median_ms,
            row.hierarchy_draw.median_ms,
            row.speedup,
            row.cube_faces,
            row.triangles_drawn,
            row.psnr_db.map_or("inf".to_owned(), |p| format!("{p:.2}")),
            row.faces_per_level
        ));
    }
    s
}
