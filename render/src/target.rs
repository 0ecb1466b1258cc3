//! The offscreen frame: color and depth textures and the readback buffer
//! (the other destination, a surface, is in `output`).
//!
//! Color is `Rgba8Unorm` (not sRGB) so the bytes of the scene come back
//! unchanged; depth is `Depth32Float`, used reversed (1 near, 0 far).
//! Texture-to-buffer copies need rows padded to 256 bytes; [`Target::read`]
//! strips the padding.

use std::sync::mpsc;

use anyhow::Context;

/// Color format of the frame.
pub(crate) const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
/// Depth format of the frame.
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

/// Textures and readback buffer for one frame size.
#[derive(Debug)]
pub(crate) struct Target {
    pub width: u32,
    pub height: u32,
    color: wgpu::Texture,
    pub color_view: wgpu::TextureView,
    pub depth_view: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
    /// Distinguishes this allocation from earlier ones of the same output.
    pub generation: u64,
}

/// Counts texture allocations, so a shown target's user can tell a new one.
static GENERATIONS: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);

impl Target {
    /// Allocates a frame of `width` x `height` (each at least 1).
    pub fn new(device: &wgpu::Device, width: u32, height: u32) -> Self {
        Self::with_color(device, width, height, COLOR_FORMAT, "farfield color")
    }

    /// A frame whose color texture has `format`, any of 4 bytes a texel
    /// (the item buffer's `R32Uint`); [`Self::read`] returns its bytes.
    pub fn with_color(
        device: &wgpu::Device,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
        label: &'static str,
    ) -> Self {
        let (width, height) = (width.max(1), height.max(1));
        let size = wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        };
        let texture = |label, format, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size,
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = texture(
            label,
            format,
            wgpu::TextureUsages::RENDER_ATTACHMENT
                | wgpu::TextureUsages::COPY_SRC
                | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        // A texture too: eye-dome lighting reads it.
        let depth = texture(
            "farfield depth",
            DEPTH_FORMAT,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
        );
        let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let padded_row = (width * 4).div_ceil(align) * align;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("farfield readback"),
            size: u64::from(padded_row) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Self {
            width,
            height,
            color_view: color.create_view(&Default::default()),
            depth_view: depth.create_view(&Default::default()),
            color,
            readback,
            padded_row,
            generation: GENERATIONS.fetch_add(1, std::sync::atomic::Ordering::Relaxed),
        }
    }

    /// The color texture (a cache's scratch frame is copied from it).
    pub fn color_texture(&self) -> &wgpu::Texture {
        &self.color
    }

    /// Records the copy of the color texture into the readback buffer.
    pub fn copy_out(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.color,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
    }

    /// Waits for the copy submitted after [`Self::copy_out`] and returns
    /// tightly packed RGBA rows, top row first.
    pub fn read(&self, device: &wgpu::Device) -> anyhow::Result<Vec<u8>> {
        let (tx, rx) = mpsc::channel();
        self.readback.map_async(wgpu::MapMode::Read, .., move |r| {
            // The receiver outlives the poll below; a failed send cannot happen.
            let _ = tx.send(r);
        });
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .context("waiting for the GPU")?;
        rx.recv()
            .context("readback callback never ran")?
            .context("mapping the readback buffer")?;
        self.take_mapped()
    }

    /// Starts reading the color texture back without waiting: the copy
    /// is submitted and the buffer mapped when the GPU is done, which
    /// `done` then says. Nothing blocks, so a browser may call it.
    pub fn read_later(
        &self,
        queue: &wgpu::Queue,
        mut encoder: wgpu::CommandEncoder,
        done: std::sync::Arc<std::sync::Mutex<Option<Result<(), wgpu::BufferAsyncError>>>>,
    ) {
        self.copy_out(&mut encoder);
        queue.submit([encoder.finish()]);
        self.readback.map_async(wgpu::MapMode::Read, .., move |r| {
            if let Ok(mut slot) = done.lock() {
                *slot = Some(r);
            }
        });
    }

    /// The mapped readback buffer as tightly packed RGBA rows, top row
    /// first; unmaps it.
    pub fn take_mapped(&self) -> anyhow::Result<Vec<u8>> {
        let row = self.width as usize * 4;
        let mut rgba = Vec::with_capacity(row * self.height as usize);
        {
            let mapped = self
                .readback
                .get_mapped_range(..)
                .context("reading the readback buffer")?;
            for padded in mapped.chunks(self.padded_row as usize) {
                rgba.extend_from_slice(&padded[..row]);
            }
        }
        self.readback.unmap();
        Ok(rgba)
    }
}
