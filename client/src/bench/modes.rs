//! Rendering modes the bench sweeps. A mode turns (camera, parameter,
//! value) into one frame; the harness does the rest (references, repeats,
//! streaming, tables, plots), so a new mode (a budgeted traversal, an image
//! cache) plugs in by implementing [`Mode`] and nothing else.

use std::time::Instant;

use anyhow::{Context, bail};
use farfield_protocol::camera::Camera;
use farfield_protocol::file::HierarchyKind;

use crate::commands::render::{Cuts, draw_frame};
use crate::reference::Reference;
use crate::render::{Coverage, Kernel, Renderer, SplatStyle};
use crate::viewer::Viewer;

/// One rendered frame and what it cost.
#[derive(Debug, Clone, Default)]
pub struct ModeFrame {
    pub rgba: Vec<u8>,
    pub traverse_ms: f64,
    pub upload_ms: f64,
    pub draw_ms: f64,
    /// Primitives drawn.
    pub drawn: u64,
    /// Bytes of the pages the frame's traversal touched.
    pub touched_bytes: u64,
    /// Whether the view needs no page it lacks.
    pub complete: bool,
}

/// A way of drawing a scene, swept over one parameter.
pub trait Mode {
    /// The name in tables and plots.
    fn name(&self) -> &str;
    /// Parameters it can sweep, the default first.
    fn params(&self) -> &[&'static str];
    /// Whether frames come from the scene's hierarchy (streamed or from a
    /// file); `false` for modes that draw the input geometry.
    fn uses_hierarchy(&self) -> bool {
        true
    }
    /// The hierarchy kind it draws, when it needs one kind.
    fn kind(&self) -> Option<HierarchyKind> {
        None
    }
    /// Draws `camera` with `settings`, (parameter, value) pairs applied in
    /// order: the fixed ones (`--set`), then the swept one.
    fn frame(
        &mut self,
        viewer: &mut Viewer,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &[(String, String)],
    ) -> anyhow::Result<ModeFrame>;
}

/// A mode by name (`spheres`, `cubes`, `geometry`); `reference` is the
/// input geometry, which `geometry` needs.
pub fn mode_named(
    name: &str,
    reference: Option<std::rc::Rc<Reference>>,
) -> anyhow::Result<Box<dyn Mode>> {
    Ok(match name {
        "spheres" => Box::new(Hierarchical {
            name: "spheres",
            kind: HierarchyKind::Spheres,
            params: &["threshold", "kernel"],
            cuts: Cuts::default(),
        }),
        "cubes" => Box::new(Hierarchical {
            name: "cubes",
            kind: HierarchyKind::Cubes,
            params: &["eps", "coverage"],
            cuts: Cuts::default(),
        }),
        "geometry" => Box::new(Geometry {
            reference: reference.context("mode geometry needs the input: give --input")?,
        }),
        other => bail!("unknown mode {other} (known: spheres, cubes, geometry)"),
    })
}

/// Splats (spheres) or color-cubes (cubes): the client's own render loop
/// frame, with the swept setting.
struct Hierarchical {
    name: &'static str,
    kind: HierarchyKind,
    params: &'static [&'static str],
    cuts: Cuts,
}

impl Mode for Hierarchical {
    fn name(&self) -> &str {
        self.name
    }

    fn params(&self) -> &[&'static str] {
        self.params
    }

    fn kind(&self) -> Option<HierarchyKind> {
        Some(self.kind)
    }

    fn frame(
        &mut self,
        viewer: &mut Viewer,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &[(String, String)],
    ) -> anyhow::Result<ModeFrame> {
        let (threshold, style) = hierarchy_settings(self.name, self.params, settings)?;
        let mut rgba = Vec::new();
        let times = draw_frame(
            viewer,
            renderer,
            camera,
            threshold,
            &style,
            &mut self.cuts,
            &mut rgba,
        )?;
        let touched_bytes = viewer.hierarchy().map_or(0, |h| {
            self.cuts
                .touched_pages()
                .iter()
                .map(|&p| u64::from(h.header.pages[p as usize].length))
                .sum()
        });
        Ok(ModeFrame {
            rgba,
            traverse_ms: times.traverse_ms,
            upload_ms: times.upload_ms,
            draw_ms: times.draw_ms,
            drawn: self.cuts.drawn() as u64,
            touched_bytes,
            // Pages given up on will not come: waiting for them would only
            // run the bench into its timeout.
            complete: self.cuts.wanted().iter().all(|w| viewer.gave_up(w.page)),
        })
    }
}

/// The threshold (or eps) and style that `settings` give a hierarchy mode;
/// the bench's reference uses it too, so fixed settings (a kernel, a
/// coverage) hold for the reference as for the sweep.
pub fn hierarchy_settings(
    mode: &str,
    params: &[&str],
    settings: &[(String, String)],
) -> anyhow::Result<(f64, SplatStyle)> {
    let mut style = SplatStyle::default();
    let mut threshold = 1.0;
    for (param, value) in settings {
        let (param, value) = (param.as_str(), value.as_str());
        match param {
            "threshold" | "eps" => {
                threshold = value
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && *v >= 0.0)
                    .with_context(|| format!("{param} {value} is not a non-negative number"))?;
            }
            "kernel" => {
                style.kernel = match value {
                    "square" => Kernel::Square,
                    "round" => Kernel::Round,
                    _ => bail!("kernel {value} is not square or round"),
                }
            }
            "coverage" => style.coverage = value.parse::<Coverage>().map_err(anyhow::Error::msg)?,
            _ => bail!("mode {mode} takes {}, not {param}", params.join(" or ")),
        }
    }
    Ok((threshold, style))
}

/// Every triangle of the input, drawn once (the papers' "geometric time").
struct Geometry {
    reference: std::rc::Rc<Reference>,
}

impl Mode for Geometry {
    fn name(&self) -> &str {
        "geometry"
    }

    fn params(&self) -> &[&'static str] {
        &["full"]
    }

    fn uses_hierarchy(&self) -> bool {
        false
    }

    fn frame(
        &mut self,
        _viewer: &mut Viewer,
        renderer: &mut Renderer,
        camera: &Camera,
        _settings: &[(String, String)],
    ) -> anyhow::Result<ModeFrame> {
        let started = Instant::now();
        let mut vertices = Vec::new();
        self.reference.pack(camera.eye, &mut vertices);
        let pack_ms = started.elapsed().as_secs_f64() * 1e3;
        let image = renderer.render_geometry(camera, &vertices, &[], Coverage::Alpha, [0; 3])?;
        Ok(ModeFrame {
            rgba: image.rgba,
            traverse_ms: 0.0,
            upload_ms: image.upload_ms + pack_ms,
            draw_ms: image.draw_ms,
            drawn: self.reference.triangles() as u64,
            touched_bytes: 0,
            complete: true,
        })
    }
}
