//! Drawing whatever a traversal yields ([`DrawList`]), so the frame loop
//! never asks which hierarchy kind it is drawing.

use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_traverse::DrawList;
use farfield_traverse::cubes::CubeCut;
use web_time::Instant;

use crate::{Coverage, RenderOutput, Renderer, SplatStyle, pack_leaves};

impl Renderer {
    /// Draws `list`, the last traversal of `hierarchy` for `camera`.
    pub fn draw(
        &mut self,
        hierarchy: &Hierarchy,
        camera: &Camera,
        list: DrawList<'_>,
        style: &SplatStyle,
    ) -> anyhow::Result<RenderOutput> {
        match list {
            DrawList::Splats(splats) => {
                // An elevation ramp over the scene's heights, unless given.
                let h = &hierarchy.header;
                let style = SplatStyle {
                    color_by: style.color_by.for_bounds(h.bounds_min, h.bounds_max),
                    clip: style.clip.map(|c| c.in_bounds(h.bounds_min, h.bounds_max)),
                    ..*style
                };
                self.render(camera, splats, &style)
            }
            DrawList::Cubes(cut) => draw_cut(
                self,
                &CubeFrame {
                    hierarchy,
                    camera,
                    cut,
                    coverage: style.coverage,
                    background: style.background,
                },
            ),
            DrawList::Triangles(cut) => {
                let started = Instant::now();
                let mut vertices = Vec::new();
                crate::plp::pack_plp(hierarchy, cut, camera.eye, &mut vertices);
                let pack_ms = started.elapsed().as_secs_f64() * 1e3;
                let mut image =
                    self.render_geometry(camera, &vertices, &[], style.coverage, style.background)?;
                image.upload_ms += pack_ms;
                Ok(image)
            }
            DrawList::Bsp(cut) => self.draw_bsp(hierarchy, camera, cut, style),
            DrawList::Impostors(cut) => self.draw_impostors(hierarchy, camera, cut, style),
        }
    }
}

/// What drawing one cube cut needs.
#[derive(Debug, Clone, Copy)]
pub struct CubeFrame<'a> {
    pub hierarchy: &'a Hierarchy,
    pub camera: &'a Camera,
    pub cut: &'a CubeCut,
    pub coverage: Coverage,
    pub background: [u8; 3],
}

/// Draws a cube cut: its leaves' triangles (packed camera-relative here,
/// counted in the upload time) and its faces.
pub fn draw_cut(renderer: &mut Renderer, frame: &CubeFrame) -> anyhow::Result<RenderOutput> {
    let started = Instant::now();
    let mut vertices = Vec::new();
    pack_leaves(frame.hierarchy, frame.cut, frame.camera.eye, &mut vertices);
    let pack_ms = started.elapsed().as_secs_f64() * 1e3;
    let mut image = renderer.render_geometry(
        frame.camera,
        &vertices,
        &frame.cut.faces,
        frame.coverage,
        frame.background,
    )?;
    image.upload_ms += pack_ms;
    Ok(image)
}
