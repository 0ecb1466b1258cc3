//! Splats, QSplat's draw data: each an instanced, screen-aligned quad sized
//! by its projected radius, depth-tested and Lambert-shaded (`splat.wgsl`).
//! Packed camera-relative in f64 (`instances`), uploaded in chunks of at
//! most [`MAX_CHUNK_BYTES`], drawn in one pass.

use web_time::Instant;

use anyhow::bail;
use farfield_protocol::camera::{Camera, View};
use farfield_traverse::spheres::Splat;
use glam::{DVec3, Vec3};

use crate::adapter::Gpu;
use crate::edl::EdlPass;
use crate::error_scope::ValidationScope;
use crate::instances::{self, GpuSplat, STRIDE};
use crate::output::Output;
use crate::pipeline::{PipelineSpec, color_target, depth_test};
use crate::uniform::UniformBinding;
use crate::{Kernel, RenderOutput, SplatStyle};

/// Smallest radius a splat is drawn with, in pixels: a disc this large
/// always covers a pixel center (the farthest a point can be from one is
/// 1/sqrt(2) = 0.707 px), so sub-pixel splats leave no holes.
pub const MIN_RADIUS_PX: f64 = 0.75;

/// Largest single instance buffer: bigger splat lists are drawn in chunks.
const MAX_CHUNK_BYTES: u64 = 128 << 20;

/// The per-frame uniform block (see `splat.wgsl`).
#[repr(C)]
#[derive(Debug, Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FrameUniform {
    proj: [f32; 4],
    light_world: [f32; 4],
    light_view: [f32; 4],
    flags: [f32; 4],
}

/// The splat pipeline, its uniform and its instance buffers.
#[derive(Debug)]
pub(crate) struct SplatPipeline {
    pipeline: wgpu::RenderPipeline,
    /// The same, writing each fragment's depth (paraboloid splats).
    paraboloid: wgpu::RenderPipeline,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// Eye-dome lighting, drawn after the splats when the style asks.
    edl: EdlPass,
    /// Instance buffers, one per chunk, each with its capacity in splats.
    chunks: Vec<(wgpu::Buffer, u64)>,
    /// Splats per chunk: the most one buffer may hold.
    chunk_splats: u64,
    scratch: Vec<GpuSplat>,
}

impl SplatPipeline {
    /// The pipeline for frames of `format`.
    pub(crate) fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> anyhow::Result<Self> {
        let limits = device.limits();
        let scope = ValidationScope::push(device);
        let shader = device.create_shader_module(wgpu::include_wgsl!("splat.wgsl"));
        let UniformBinding {
            buffer: uniform,
            bind_group,
            pipeline_layout: layout,
            ..
        } = UniformBinding::new(
            device,
            std::mem::size_of::<FrameUniform>() as u64,
            "farfield splats",
        );
        let attributes = wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Float32, 2 => Snorm16x4, 3 => Unorm8x4
        ];
        let spec = |fragment_entry| {
            PipelineSpec {
                label: "farfield splats",
                layout: &layout,
                shader: &shader,
                vertex_entry: "vs_main",
                fragment_entry,
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: STRIDE,
                    step_mode: wgpu::VertexStepMode::Instance,
                    attributes: &attributes,
                })],
                topology: wgpu::PrimitiveTopology::TriangleStrip,
                depth: depth_test(true),
                targets: &[color_target(format, None)],
            }
            .build(device)
        };
        let pipeline = spec("fs_main");
        let paraboloid = spec("fs_paraboloid");
        if let Some(e) = scope.pop() {
            bail!("creating the splat pipeline: {e}");
        }
        let chunk_splats = (limits.max_buffer_size.min(MAX_CHUNK_BYTES) / STRIDE).max(1);
        Ok(Self {
            pipeline,
            paraboloid,
            uniform,
            bind_group,
            edl: EdlPass::new(device, format),
            chunks: Vec::new(),
            chunk_splats,
            scratch: Vec::new(),
        })
    }

    /// Limits chunks to `splats` instances, to exercise chunked drawing.
    #[cfg(test)]
    pub(crate) fn set_chunk_splats(&mut self, splats: u64) {
        self.chunk_splats = splats.max(1);
        self.chunks.clear();
    }

    /// Draws `splats` for `camera` (of the output's size, `width` x
    /// `height`) into `output`.
    pub(crate) fn draw(
        &mut self,
        gpu: &Gpu,
        output: &Output,
        camera: &Camera,
        splats: &[Splat],
        style: &SplatStyle,
    ) -> anyhow::Result<RenderOutput> {
        let (width, height) = (camera.width, camera.height);
        let scope = ValidationScope::push(&gpu.device);
        let started = Instant::now();
        // `near` here only clamps View's planes, which are not used.
        let view = camera.view(1.0);
        let near = instances::pack(&view, splats, style.color_by, style.clip, &mut self.scratch);
        gpu.queue.write_buffer(
            &self.uniform,
            0,
            bytemuck::bytes_of(&frame_uniform(&view, near, style)),
        );
        let draws = self.upload(gpu);
        let upload_ms = started.elapsed().as_secs_f64() * 1e3;

        let started = Instant::now();
        let frame = output.begin(&gpu.device)?;
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("farfield frame"),
            });
        {
            let mut pass = frame.begin_pass(&mut encoder, "farfield splats", style.background);
            pass.set_pipeline(match style.kernel {
                Kernel::Paraboloid => &self.paraboloid,
                Kernel::Square | Kernel::Round => &self.pipeline,
            });
            pass.set_bind_group(0, &self.bind_group, &[]);
            for (chunk, count) in self.chunks.iter().zip(draws) {
                pass.set_vertex_buffer(0, chunk.0.slice(..count * STRIDE));
                pass.draw(0..4, 0..count as u32);
            }
        }
        if let Some(edl) = style.edl {
            let (device, queue) = (&gpu.device, &gpu.queue);
            self.edl
                .draw(device, queue, &mut encoder, &frame.color, &frame.depth, edl);
        }
        let rgba = output.finish(gpu, frame, encoder)?;
        let draw_ms = started.elapsed().as_secs_f64() * 1e3;
        if let Some(e) = scope.pop() {
            bail!("rendering {} splats: {e}", splats.len());
        }
        Ok(RenderOutput {
            rgba,
            width,
            height,
            upload_ms,
            draw_ms,
        })
    }

    /// Writes the packed splats into the chunk buffers (growing them to the
    /// next power of two as needed) and returns the splat count per chunk.
    fn upload(&mut self, gpu: &Gpu) -> Vec<u64> {
        let device = &gpu.device;
        let per_chunk = self.chunk_splats as usize;
        let mut draws = Vec::new();
        for (i, part) in self.scratch.chunks(per_chunk).enumerate() {
            let count = part.len() as u64;
            if self.chunks.get(i).is_none_or(|c| c.1 < count) {
                let capacity = count.next_power_of_two().min(self.chunk_splats);
                let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("farfield splats"),
                    size: capacity * STRIDE,
                    usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                if i < self.chunks.len() {
                    self.chunks[i] = (buffer, capacity);
                } else {
                    self.chunks.push((buffer, capacity));
                }
            }
            gpu.queue
                .write_buffer(&self.chunks[i].0, 0, bytemuck::cast_slice(part));
            draws.push(count);
        }
        draws
    }
}

/// Projection, light directions and flags for one frame.
fn frame_uniform(view: &View, near: f64, style: &SplatStyle) -> FrameUniform {
    // A zero light direction becomes a headlight (toward the eye).
    let light = style
        .light_dir
        .as_dvec3()
        .try_normalize()
        .unwrap_or(-view.forward);
    let to_view = |v: DVec3| {
        Vec3::new(
            v.dot(view.right) as f32,
            v.dot(view.up) as f32,
            -v.dot(view.forward) as f32,
        )
    };
    let l_view = to_view(light);
    let l_world = light.as_vec3();
    FrameUniform {
        proj: [
            (1.0 / view.tan_half_x) as f32,
            (1.0 / view.tan_half_y) as f32,
            near as f32,
            (MIN_RADIUS_PX * 2.0 * view.tan_half_y / f64::from(view.height.max(1))) as f32,
        ],
        light_world: [l_world.x, l_world.y, l_world.z, 0.0],
        light_view: [l_view.x, l_view.y, l_view.z, 0.0],
        flags: [
            match style.kernel {
                Kernel::Square => 0.0,
                Kernel::Round => 1.0,
                Kernel::Paraboloid => 2.0,
            },
            f32::from(u8::from(style.two_sided)),
            0.0,
            0.0,
        ],
    }
}
