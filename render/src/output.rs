//! Where the renderer's frames go: an offscreen texture read back after
//! every frame (PNGs, metrics, tests), one a viewer shows in its UI, or a
//! window's or canvas's surface, presented and never read back.
//!
//! Both draw the same passes; only the start and the end of a frame
//! differ ([`Output::begin`], [`Output::finish`]).

use anyhow::bail;

use crate::adapter::Gpu;
use crate::target::{DEPTH_FORMAT, Target};

/// The frame's destination.
#[derive(Debug)]
pub(crate) enum Output {
    Offscreen(Target),
    /// Offscreen, but shown by the caller (a viewer's panel) and not read back.
    Shown(Target),
    Surface(SurfaceOutput),
}

/// A configured surface and the depth buffer that goes with it.
#[derive(Debug)]
pub(crate) struct SurfaceOutput {
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    depth_view: wgpu::TextureView,
}

/// One frame being drawn: the views its passes draw into.
#[derive(Debug)]
pub(crate) struct Frame {
    pub color: wgpu::TextureView,
    pub depth: wgpu::TextureView,
    /// The surface's texture, presented when the frame ends.
    presented: Option<wgpu::SurfaceTexture>,
}

impl Frame {
    /// The one render pass of a frame: color cleared to `background` (sRGB
    /// bytes), depth cleared to 0, which with reversed Z is infinitely far,
    /// and kept after the pass (eye-dome lighting reads it).
    pub fn begin_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
        background: [u8; 3],
    ) -> wgpu::RenderPass<'e> {
        let [r, g, b] = background.map(|c| f64::from(c) / 255.0);
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some(label),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.color,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a: 1.0 }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }
}

impl SurfaceOutput {
    /// Configures `surface` for `device` at `width` x `height` in `format`.
    pub fn new(
        device: &wgpu::Device,
        surface: wgpu::Surface<'static>,
        mut config: wgpu::SurfaceConfiguration,
    ) -> Self {
        config.width = config.width.max(1);
        config.height = config.height.max(1);
        surface.configure(device, &config);
        let depth_view = depth_texture(device, config.width, config.height);
        Self {
            surface,
            config,
            depth_view,
        }
    }
}

fn depth_texture(device: &wgpu::Device, width: u32, height: u32) -> wgpu::TextureView {
    device
        .create_texture(&wgpu::TextureDescriptor {
            label: Some("farfield surface depth"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: DEPTH_FORMAT,
            // A texture too: eye-dome lighting reads it.
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        })
        .create_view(&Default::default())
}

impl Output {
    pub fn size(&self) -> (u32, u32) {
        match self {
            Self::Offscreen(t) | Self::Shown(t) => (t.width, t.height),
            Self::Surface(s) => (s.config.width, s.config.height),
        }
    }

    /// The color format the pipelines must write.
    pub fn format(&self) -> wgpu::TextureFormat {
        match self {
            Self::Offscreen(_) | Self::Shown(_) => crate::target::COLOR_FORMAT,
            Self::Surface(s) => s.config.format,
        }
    }

    /// Reallocates for a new size (each side at least 1 pixel).
    pub fn resize(&mut self, device: &wgpu::Device, width: u32, height: u32) {
        match self {
            Self::Offscreen(t) | Self::Shown(t) => *t = Target::new(device, width, height),
            Self::Surface(s) => {
                s.config.width = width.max(1);
                s.config.height = height.max(1);
                s.surface.configure(device, &s.config);
                s.depth_view = depth_texture(device, s.config.width, s.config.height);
            }
        }
    }

    /// Starts a frame. A surface that is outdated or lost is configured
    /// again once; one that times out or is hidden is an error the caller
    /// may skip the frame for.
    pub fn begin(&self, device: &wgpu::Device) -> anyhow::Result<Frame> {
        let s = match self {
            Self::Offscreen(t) | Self::Shown(t) => {
                return Ok(Frame {
                    color: t.color_view.clone(),
                    depth: t.depth_view.clone(),
                    presented: None,
                });
            }
            Self::Surface(s) => s,
        };
        let mut texture = s.surface.get_current_texture();
        if matches!(
            texture,
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost
        ) {
            s.surface.configure(device, &s.config);
            texture = s.surface.get_current_texture();
        }
        let texture = match texture {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            other => bail!(
                "the surface has no frame to draw: {}",
                surface_state(&other)
            ),
        };
        Ok(Frame {
            color: texture.texture.create_view(&Default::default()),
            depth: s.depth_view.clone(),
            presented: Some(texture),
        })
    }

    /// Ends a frame: submits `encoder`, then reads the image back
    /// (offscreen: tightly packed RGBA rows, top row first) or presents it
    /// (surface: nothing is read, the returned image is empty).
    pub fn finish(
        &self,
        gpu: &Gpu,
        frame: Frame,
        mut encoder: wgpu::CommandEncoder,
    ) -> anyhow::Result<Vec<u8>> {
        match (self, frame.presented) {
            (Self::Offscreen(t), _) => {
                t.copy_out(&mut encoder);
                gpu.queue.submit([encoder.finish()]);
                t.read(&gpu.device)
            }
            (Self::Shown(_), _) => {
                gpu.queue.submit([encoder.finish()]);
                Ok(Vec::new())
            }
            (Self::Surface(_), Some(texture)) => {
                gpu.queue.submit([encoder.finish()]);
                gpu.queue.present(texture);
                Ok(Vec::new())
            }
            (Self::Surface(_), None) => bail!("ending a surface frame that has no surface texture"),
        }
    }
}

fn surface_state(t: &wgpu::CurrentSurfaceTexture) -> &'static str {
    match t {
        wgpu::CurrentSurfaceTexture::Success(_) | wgpu::CurrentSurfaceTexture::Suboptimal(_) => {
            "ready"
        }
        wgpu::CurrentSurfaceTexture::Timeout => "timed out",
        wgpu::CurrentSurfaceTexture::Occluded => "the window is hidden",
        wgpu::CurrentSurfaceTexture::Outdated => "outdated",
        wgpu::CurrentSurfaceTexture::Lost => "lost",
        wgpu::CurrentSurfaceTexture::Validation => "a validation error",
    }
}
