//! Rendering modes the bench sweeps. A mode turns (camera, parameter,
//! value) into one frame; the harness does the rest (references, repeats,
//! streaming, tables, plots).
//!
//! The hierarchy modes are the client's traversal kinds themselves
//! ([`farfield_traverse::KINDS`]), drawn by the client's own frame
//! ([`draw_frame`]): a kind registered there (a budgeted traversal, an
//! image cache) is a bench mode with no change here. `geometry`, every
//! input triangle drawn once, is the one mode that is not a traversal.

use std::rc::Rc;
use std::time::Instant;

use anyhow::{Context, bail};
use farfield_client::frame_loop::{FrameState, draw_frame};
use farfield_client::viewer::Viewer;
use farfield_protocol::camera::Camera;
use farfield_protocol::file::HierarchyKind;
use farfield_render::{Coverage, Kernel, Renderer, SplatStyle};
use farfield_traverse::{Budget, DrawList, Registered};

use crate::reference::Reference;

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
#[derive(Debug)]
pub enum Mode {
    /// A registered traversal kind (`spheres`, `cubes`, ...).
    Traversal {
        kind: &'static Registered,
        cut: FrameState,
    },
    /// Every triangle of the input, drawn once (the papers' "geometric time").
    Geometry { reference: Rc<Reference> },
}

impl Mode {
    /// A mode by name: a registered traversal kind, or `geometry`, which
    /// needs `reference` (the input geometry).
    pub fn named(name: &str, reference: Option<Rc<Reference>>) -> anyhow::Result<Self> {
        if name == "geometry" {
            return Ok(Self::Geometry {
                reference: reference.context("mode geometry needs the input: give --input")?,
            });
        }
        let Some(kind) = farfield_traverse::named(name) else {
            let known: Vec<&str> = farfield_traverse::KINDS.iter().map(|k| k.name).collect();
            bail!(
                "unknown mode {name} (known: {}, geometry)",
                known.join(", ")
            );
        };
        Ok(Self::Traversal {
            kind,
            cut: FrameState::of_kind(kind),
        })
    }

    /// The name in tables and plots.
    pub fn name(&self) -> &str {
        match self {
            Self::Traversal { kind, .. } => kind.name,
            Self::Geometry { .. } => "geometry",
        }
    }

    /// Parameters it can sweep, the default first.
    pub fn params(&self) -> &[&'static str] {
        match self {
            Self::Traversal { kind, .. } => kind.params,
            Self::Geometry { .. } => &["full"],
        }
    }

    /// Whether frames come from the scene's hierarchy (streamed or from a
    /// file); `false` for the input geometry.
    pub fn uses_hierarchy(&self) -> bool {
        matches!(self, Self::Traversal { .. })
    }

    /// The hierarchy kind it draws, when it needs one kind.
    pub fn kind(&self) -> Option<HierarchyKind> {
        match self {
            Self::Traversal { kind, .. } => Some(kind.hierarchy),
            Self::Geometry { .. } => None,
        }
    }

    /// What the last frame drew, for a traversal that has drawn one.
    pub fn draw_list(&self) -> Option<DrawList<'_>> {
        match self {
            Self::Traversal { cut, .. } => cut.draw_list(),
            Self::Geometry { .. } => None,
        }
    }

    /// Draws `camera` with `settings`, (parameter, value) pairs applied in
    /// order: the fixed ones (`--set`), then the swept one.
    pub fn frame(
        &mut self,
        viewer: &mut Viewer,
        renderer: &mut Renderer,
        camera: &Camera,
        settings: &[(String, String)],
    ) -> anyhow::Result<ModeFrame> {
        match self {
            Self::Traversal { kind, cut } => {
                let (threshold, style) = hierarchy_settings(kind.name, kind.params, settings)?;
                cut.budget = budget_setting(settings)?;
                traversal_frame(viewer, renderer, camera, threshold, &style, cut)
            }
            Self::Geometry { reference } => geometry_frame(reference, renderer, camera),
        }
    }
}

/// The client's own render-loop frame, with the swept setting.
fn traversal_frame(
    viewer: &mut Viewer,
    renderer: &mut Renderer,
    camera: &Camera,
    threshold: f64,
    style: &SplatStyle,
    cut: &mut FrameState,
) -> anyhow::Result<ModeFrame> {
    let mut rgba = Vec::new();
    let times = draw_frame(viewer, renderer, camera, threshold, style, cut, &mut rgba)?;
    let touched_bytes = viewer.hierarchy().map_or(0, |h| {
        cut.touched_pages()
            .iter()
            .filter_map(|&p| h.directory().extent(p))
            .map(|e| u64::from(e.length))
            .sum()
    });
    Ok(ModeFrame {
        rgba,
        traverse_ms: times.traverse_ms,
        upload_ms: times.upload_ms,
        draw_ms: times.draw_ms,
        drawn: cut.drawn() as u64,
        touched_bytes,
        // Pages given up on will not come: waiting for them would only
        // run the bench into its timeout.
        complete: cut.wanted().iter().all(|w| viewer.gave_up(w.page)),
    })
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
            "threshold" | "eps" | "epsilon" => {
                threshold = value
                    .parse::<f64>()
                    .ok()
                    .filter(|v| v.is_finite() && *v >= 0.0)
                    .with_context(|| format!("{param} {value} is not a non-negative number"))?;
            }
            "kernel" => {
                style.kernel = Kernel::from_name(value)
                    .with_context(|| format!("kernel {value} is not square, round or paraboloid"))?
            }
            "coverage" => style.coverage = value.parse::<Coverage>().map_err(anyhow::Error::msg)?,
            // Read by `budget_setting`.
            "budget" if params.contains(&"budget") => {}
            _ => bail!("mode {mode} takes {}, not {param}", params.join(" or ")),
        }
    }
    Ok((threshold, style))
}

/// The triangle budget `settings` give a budgeted mode (PLP): the last
/// `budget` setting, or none.
pub fn budget_setting(settings: &[(String, String)]) -> anyhow::Result<Budget> {
    let mut budget = Budget::Unlimited;
    for (param, value) in settings {
        if param == "budget" {
            budget = value.parse::<Budget>().map_err(anyhow::Error::msg)?;
        }
    }
    Ok(budget)
}

/// Every triangle of the input, drawn once.
fn geometry_frame(
    reference: &Reference,
    renderer: &mut Renderer,
    camera: &Camera,
) -> anyhow::Result<ModeFrame> {
    let started = Instant::now();
    let mut vertices = Vec::new();
    reference.pack(camera.eye, &mut vertices);
    let pack_ms = started.elapsed().as_secs_f64() * 1e3;
    let image = renderer.render_geometry(camera, &vertices, &[], Coverage::Alpha, [0; 3])?;
    Ok(ModeFrame {
        rgba: image.rgba,
        traverse_ms: 0.0,
        upload_ms: image.upload_ms + pack_ms,
        draw_ms: image.draw_ms,
        drawn: reference.triangles() as u64,
        touched_bytes: 0,
        complete: true,
    })
}
