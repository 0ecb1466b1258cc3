//! farfield-render: the wgpu renderer, draw lists + camera -> an RGBA image.
//!
//! Each splat is an instanced, screen-aligned quad sized by its projected
//! radius (at least [`MIN_RADIUS_PX`], so sub-pixel splats leave no holes),
//! depth-tested (reversed Z, no blending) and Lambert-shaded; a
//! splat without a normal is drawn as a lit ball (an atom). Positions are
//! made camera-relative in f64 before they become f32, so scenes far from
//! the origin render as precisely as scenes at it. The frame is offscreen
//! and read back, which is what tests, evaluation and the `render` command
//! need, or a window's or canvas's surface, presented and never read back
//! ([`Renderer::for_surface`]); it runs on a real GPU or on Mesa's CPU
//! drivers (lavapipe, llvmpipe).
//!
//! - [`Renderer`]: the device, the output, and each kind of draw data's
//!   resources: splats (`splats`), triangles and cube faces (`geometry`),
//!   instanced prototypes (`bsp`), PLP's triangles (`plp`), image caches
//!   (`impostors`), the item buffer (`item_buffer`); `pipeline` makes their
//!   pipelines.
//! - [`SplatStyle`], [`Kernel`]: how splats look; [`RenderOutput`]: an image
//!   with its upload and draw times.
//! - [`Renderer::render_geometry`] ([`geometry`]): triangles and color-cube
//!   faces, for the cube hierarchy and the full-geometry reference.
//! - [`Renderer::draw`] (`draw_list`): whatever a traversal yields
//!   ([`farfield_traverse::DrawList`]), so callers never name the kind.
//! - [`headless_or_skip`]: a renderer for tests, or a clear failure.

mod adapter;
mod bsp;
pub mod clip;
mod color_by;
mod draw_list;
mod edl;
mod error_scope;
mod geometry;
mod impostors;
mod instances;
mod item_buffer;
mod output;
mod pipeline;
mod plp;
mod renderer;
mod splats;
mod target;
#[cfg(test)]
mod tests;
mod uniform;

pub use adapter::{
    ALLOW_NO_GPU_ENV, BACKEND_ENV, DEVICE_SELECT_OFF, device_select_unwanted,
    quiet_device_select_when_headless,
};
pub use bsp::pack_bsp_leaves;
pub use clip::{Clip, Keep};
pub use color_by::{ColorBy, RAMP, ramp};
pub use draw_list::{CubeFrame, draw_cut};
pub use geometry::snorm4;
pub use geometry::{Coverage, GpuVertex, pack_leaves};
pub use instances::DEFAULT_COLOR;
pub use item_buffer::visible_ids;
pub use plp::pack_plp;
pub use renderer::Renderer;
pub use splats::MIN_RADIUS_PX;

/// The footprint of a splat with a normal.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Kernel {
    /// The whole screen-aligned square around the projected sphere.
    Square,
    /// The disc inscribed in that square.
    #[default]
    Round,
    /// That disc as a paraboloid bulging toward the eye (Potree's): its
    /// depth varies across it, so overlapping splats meet along curves and
    /// eye-dome lighting shades them like a surface, not as flat cards.
    Paraboloid,
}

impl Kernel {
    /// Every kernel, in the order a panel lists them.
    pub const ALL: [Kernel; 3] = [Kernel::Square, Kernel::Round, Kernel::Paraboloid];

    /// Its name on command lines, in links and in demo sessions.
    pub fn name(self) -> &'static str {
        match self {
            Kernel::Square => "square",
            Kernel::Round => "round",
            Kernel::Paraboloid => "paraboloid",
        }
    }

    /// The kernel of that name.
    pub fn from_name(name: &str) -> Option<Kernel> {
        Kernel::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// How splats are drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplatStyle {
    /// Footprint of splats with normals; splats without one are always round.
    pub kernel: Kernel,
    /// Background color (sRGB bytes).
    pub background: [u8; 3],
    /// World-space direction toward the light; zero means a headlight.
    pub light_dir: glam::Vec3,
    /// Light both sides of a splat (`|n.l|`), for scenes whose normals have
    /// no consistent orientation.
    pub two_sided: bool,
    /// Cube hierarchies: how face coverage is used.
    pub coverage: Coverage,
    /// Image caching: outline each cached image's quad (a viewer shows
    /// which parts of the picture are caches; never in a measured image).
    pub outline_caches: bool,
    /// Eye-dome lighting over splats, or none.
    pub edl: Option<Edl>,
    /// What colors splats.
    pub color_by: ColorBy,
    /// The clipping box splats are drawn on one side of, or none.
    pub clip: Option<Clip>,
}

/// Eye-dome lighting: each pixel darkened by how far its neighbours, at
/// `radius_px`, stand in front of it in log depth, as Potree shades point
/// clouds (its defaults: strength 1, radius 1.4).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Edl {
    pub strength: f32,
    pub radius_px: f32,
}

impl Default for Edl {
    fn default() -> Self {
        Self {
            strength: 1.0,
            radius_px: 1.4,
        }
    }
}

impl Default for SplatStyle {
    /// Round splats on black, lit from above and the side.
    fn default() -> Self {
        Self {
            kernel: Kernel::Round,
            background: [0, 0, 0],
            light_dir: glam::Vec3::new(0.4, 0.3, 0.866),
            two_sided: false,
            coverage: Coverage::default(),
            outline_caches: false,
            edl: None,
            color_by: ColorBy::Rgb,
            clip: None,
        }
    }
}

/// One rendered frame.
#[derive(Debug, Clone, PartialEq)]
pub struct RenderOutput {
    /// Tightly packed RGBA8 rows, top row first (`width * height * 4` bytes);
    /// empty when the renderer draws to a surface, which is never read back.
    pub rgba: Vec<u8>,
    pub width: u32,
    pub height: u32,
    /// Packing the splats and queueing the buffer writes, in milliseconds
    /// (a backend may do the copy itself at submit, inside `draw_ms`).
    pub upload_ms: f64,
    /// From submitting the draw until the image is back in memory (or, on a
    /// surface, handed to the compositor).
    pub draw_ms: f64,
}

impl RenderOutput {
    /// The RGBA of pixel (`x`, `y`), `y` counted from the top; `None`
    /// outside the image.
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 4]> {
        if x >= self.width || y >= self.height {
            return None;
        }
        let i = (y as usize * self.width as usize + x as usize) * 4;
        self.rgba.get(i..i + 4)?.try_into().ok()
    }
}

/// A headless renderer for tests. Without any adapter this is an error
/// that says what to install, unless [`ALLOW_NO_GPU_ENV`] is `1`: then it
/// prints why and returns `None`, and the caller skips its test.
pub fn headless_or_skip(width: u32, height: u32) -> anyhow::Result<Option<Renderer>> {
    match Renderer::new_headless(width, height) {
        Ok(r) => Ok(Some(r)),
        Err(e) if adapter::no_gpu_allowed() => {
            eprintln!("skipping a GPU test ({ALLOW_NO_GPU_ENV}=1): {e:#}");
            Ok(None)
        }
        Err(e) => Err(e.context(format!(
            "GPU tests need an adapter; set {ALLOW_NO_GPU_ENV}=1 to skip them"
        ))),
    }
}
