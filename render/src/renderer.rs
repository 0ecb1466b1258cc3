//! The headless splat renderer: one pipeline, growable instance buffers,
//! one offscreen frame read back per call.

use web_time::Instant;

use anyhow::{Context, bail, ensure};
use farfield_protocol::camera::{Camera, View};
use farfield_traverse::spheres::Splat;
use glam::{DVec3, Vec3};

use super::adapter::{self, Gpu};
use super::error_scope::ValidationScope;
use super::geometry::GeometryPipelines;
use super::instances::{self, GpuSplat, STRIDE};
use super::output::{Output, SurfaceOutput};
use super::target::{Target, color_target, depth_test};
use super::uniform::UniformBinding;
use super::{Kernel, RenderOutput, SplatStyle};

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

/// Draws splats, triangles and cube faces into its [`Output`]: offscreen
/// (read back after every frame) or a surface (presented, not read back).
#[derive(Debug)]
pub struct Renderer {
    gpu: Gpu,
    pipeline: wgpu::RenderPipeline,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    output: Output,
    /// Instance buffers, one per chunk, each with its capacity in splats.
    chunks: Vec<(wgpu::Buffer, u64)>,
    /// Splats per chunk: the most one buffer may hold.
    chunk_splats: u64,
    scratch: Vec<GpuSplat>,
    /// Triangle and cube-face pipelines, made when first needed.
    geometry: Option<GeometryPipelines>,
    /// A capture under way ([`Self::request_capture`]): set when mapped.
    capture: Option<CaptureSlot>,
    /// The item buffer's pipeline and frame ([`Self::item_buffer`]), made
    /// when first needed.
    pub(super) item_buffer: Option<super::item_buffer::ItemBuffer>,
    /// The image-cache atlas and quad pipeline, made when first needed.
    impostors: Option<super::impostors::ImpostorResources>,
}

/// Where a capture's mapping result lands.
type CaptureSlot = std::sync::Arc<std::sync::Mutex<Option<Result<(), wgpu::BufferAsyncError>>>>;

impl Renderer {
    /// Opens an adapter (see [`super::BACKEND_ENV`]) and prepares a
    /// `width` x `height` frame; fails with an explanation when no adapter
    /// exists.
    pub fn new_headless(width: u32, height: u32) -> anyhow::Result<Self> {
        ensure!(
            width > 0 && height > 0,
            "frame size {width}x{height} is empty"
        );
        let gpu = adapter::open()?;
        check_size(&gpu.device, width, height)?;
        let output = Output::Offscreen(Target::new(&gpu.device, width, height));
        Self::with_output(gpu, output)
    }

    /// A renderer that draws into `surface` (a window's or a canvas's),
    /// which `instance` made, at `width` x `height`: every frame is
    /// presented and none is read back, so [`RenderOutput::rgba`] is empty.
    /// The surface's format is its first non-sRGB one when it has one, so
    /// colors are written as the offscreen frame writes them.
    pub async fn for_surface(
        instance: &wgpu::Instance,
        surface: wgpu::Surface<'static>,
        width: u32,
        height: u32,
    ) -> anyhow::Result<Self> {
        let gpu = adapter::open_for_surface(instance, &surface).await?;
        check_size(&gpu.device, width, height)?;
        let caps = surface.get_capabilities(&gpu.adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(|f| !f.is_srgb())
            .or_else(|| caps.formats.first().copied())
            .context("the surface supports no format on this adapter")?;
        let mut config = surface
            .get_default_config(&gpu.adapter, width, height)
            .context("this adapter cannot draw to the surface")?;
        config.format = format;
        let output = Output::Surface(SurfaceOutput::new(&gpu.device, surface, config));
        Self::with_output(gpu, output)
    }

    /// A renderer on a device someone else opened (a viewer's, whose UI
    /// toolkit owns the window), drawing into a `width` x `height` texture
    /// that the caller shows ([`Self::shown_texture`]) and never reads
    /// back, so no frame waits for the GPU: in a browser none may.
    pub fn for_texture(
        adapter: wgpu::Adapter,
        device: wgpu::Device,
        queue: wgpu::Queue,
        width: u32,
        height: u32,
    ) -> anyhow::Result<Self> {
        let info = adapter.get_info();
        let gpu = Gpu {
            adapter,
            device,
            queue,
            info,
        };
        check_size(&gpu.device, width, height)?;
        let output = Output::Shown(Target::new(&gpu.device, width, height));
        Self::with_output(gpu, output)
    }

    /// The texture a [`Self::for_texture`] renderer draws into, and a
    /// number that changes whenever it is a new texture (after a resize),
    /// so its user knows to register it again; `None` for other outputs.
    pub fn shown_texture(&self) -> Option<(&wgpu::TextureView, u64)> {
        match &self.output {
            Output::Shown(t) => Some((&t.color_view, t.generation)),
            _ => None,
        }
    }

    /// Starts reading back the last frame of a [`Self::for_texture`]
    /// renderer, without waiting; [`Self::poll_capture`] hands it over once
    /// the GPU has it. For a viewer's screenshots: the scene as drawn,
    /// without the UI around it.
    pub fn request_capture(&mut self) -> anyhow::Result<()> {
        let Output::Shown(target) = &self.output else {
            bail!("only a renderer that draws into a shown texture captures its frames");
        };
        if self.capture.is_some() {
            return Ok(());
        }
        let done = std::sync::Arc::default();
        let encoder = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("farfield capture"),
            });
        target.read_later(&self.gpu.queue, encoder, std::sync::Arc::clone(&done));
        self.capture = Some(done);
        Ok(())
    }

    /// Whether a capture is under way.
    pub fn capture_pending(&self) -> bool {
        self.capture.is_some()
    }

    /// The frame [`Self::request_capture`] asked for, once it is back:
    /// `(width, height, RGBA rows, top first)`. Never waits (natively it
    /// polls the device once).
    pub fn poll_capture(&mut self) -> Option<anyhow::Result<(u32, u32, Vec<u8>)>> {
        let done = self.capture.as_ref()?;
        // A browser runs map callbacks itself; natively they run in poll.
        let _ = self.gpu.device.poll(wgpu::PollType::Poll);
        let result = done.lock().ok()?.take()?;
        self.capture = None;
        let Output::Shown(target) = &self.output else {
            return Some(Err(anyhow::anyhow!("the output changed during a capture")));
        };
        Some(match result {
            Ok(()) => target
                .take_mapped()
                .map(|rgba| (target.width, target.height, rgba)),
            Err(e) => Err(anyhow::anyhow!("reading the frame back: {e}")),
        })
    }

    /// The pipelines for `output`'s format.
    fn with_output(gpu: Gpu, output: Output) -> anyhow::Result<Self> {
        let device = &gpu.device;
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
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("farfield splats"),
            layout: Some(&layout),
            vertex: wgpu::VertexState {
                module: &shader,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: STRIDE,
                    step_mode: wgpu::VertexStepMode::Instance,
                    attributes: &attributes,
                })],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleStrip,
                ..Default::default()
            },
            depth_stencil: Some(depth_test(true)),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: &shader,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[color_target(output.format(), None)],
            }),
            multiview_mask: None,
            cache: None,
        });
        if let Some(e) = scope.pop() {
            bail!("creating the splat pipeline: {e}");
        }
        let chunk_splats = (limits.max_buffer_size.min(MAX_CHUNK_BYTES) / STRIDE).max(1);
        Ok(Self {
            pipeline,
            uniform,
            bind_group,
            output,
            chunks: Vec::new(),
            chunk_splats,
            scratch: Vec::new(),
            geometry: None,
            capture: None,
            item_buffer: None,
            impostors: None,
            gpu,
        })
    }

    /// The device, the geometry pipelines (made on first use) and the frame.
    pub(super) fn geometry_parts(
        &mut self,
    ) -> anyhow::Result<(&Gpu, &mut GeometryPipelines, &Output)> {
        if self.geometry.is_none() {
            let format = self.output.format();
            self.geometry = Some(GeometryPipelines::new(&self.gpu.device, format)?);
        }
        match self.geometry.as_mut() {
            Some(pipes) => Ok((&self.gpu, pipes, &self.output)),
            None => bail!("no geometry pipelines"),
        }
    }

    /// The device, the geometry pipelines, the image-cache resources (made
    /// by the caller when missing) and the frame.
    pub(super) fn impostor_parts(
        &mut self,
    ) -> anyhow::Result<(
        &Gpu,
        &mut GeometryPipelines,
        &mut Option<super::impostors::ImpostorResources>,
        &Output,
    )> {
        if self.geometry.is_none() {
            let format = self.output.format();
            self.geometry = Some(GeometryPipelines::new(&self.gpu.device, format)?);
        }
        let pipes = self.geometry.as_mut().context("no geometry pipelines")?;
        Ok((&self.gpu, pipes, &mut self.impostors, &self.output))
    }

    pub(super) fn impostor_resources(&self) -> Option<&super::impostors::ImpostorResources> {
        self.impostors.as_ref()
    }

    /// The color format frames are drawn in.
    pub(super) fn output_format(&self) -> wgpu::TextureFormat {
        self.output.format()
    }

    /// The frame's size, which `camera` must have: a camera of another
    /// size is an error (resize first), not a stretched image.
    pub(crate) fn size_for(&self, camera: &Camera) -> anyhow::Result<(u32, u32)> {
        let (width, height) = self.size();
        ensure!(
            (camera.width, camera.height) == (width, height),
            "camera is {}x{} but the renderer is {width}x{height}; resize it first",
            camera.width,
            camera.height
        );
        Ok((width, height))
    }

    /// The adapter in use, e.g. `llvmpipe (LLVM 15.0.7, 256 bits) / Vulkan (...)`.
    pub fn adapter_description(&self) -> String {
        adapter::describe(&self.gpu.info)
    }

    /// The frame size in pixels.
    pub fn size(&self) -> (u32, u32) {
        self.output.size()
    }

    /// Changes the frame size, clamped to 1 pixel and to the adapter's
    /// largest texture (a camera of another size is then refused by
    /// [`Self::render`]).
    pub fn resize(&mut self, width: u32, height: u32) {
        let max = self.gpu.device.limits().max_texture_dimension_2d;
        let (width, height) = (width.clamp(1, max), height.clamp(1, max));
        if (width, height) != self.size() {
            self.output.resize(&self.gpu.device, width, height);
            // A capture of the old frame cannot be read from the new one.
            self.capture = None;
        }
    }

    /// Limits chunks to `splats` instances, to exercise chunked drawing.
    #[cfg(test)]
    pub(crate) fn set_chunk_splats(&mut self, splats: u64) {
        self.chunk_splats = splats.max(1);
        self.chunks.clear();
    }

    /// Draws the splats for this camera and returns tightly packed RGBA8
    /// rows (`width * height * 4` bytes, top row first). The camera's image
    /// size must equal [`Self::size`].
    pub fn render(
        &mut self,
        camera: &Camera,
        splats: &[Splat],
        style: &SplatStyle,
    ) -> anyhow::Result<RenderOutput> {
        let (width, height) = self.size_for(camera)?;
        let scope = ValidationScope::push(&self.gpu.device);
        let started = Instant::now();
        // `near` here only clamps View's planes, which are not used.
        let view = camera.view(1.0);
        let near = instances::pack(&view, splats, &mut self.scratch);
        self.gpu.queue.write_buffer(
            &self.uniform,
            0,
            bytemuck::bytes_of(&frame_uniform(&view, near, style)),
        );
        let draws = self.upload();
        let upload_ms = started.elapsed().as_secs_f64() * 1e3;

        let started = Instant::now();
        let frame = self.output.begin(&self.gpu.device)?;
        let mut encoder = self
            .gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("farfield frame"),
            });
        {
            let mut pass = frame.begin_pass(&mut encoder, "farfield splats", style.background);
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.bind_group, &[]);
            for (chunk, count) in self.chunks.iter().zip(draws) {
                pass.set_vertex_buffer(0, chunk.0.slice(..count * STRIDE));
                pass.draw(0..4, 0..count as u32);
            }
        }
        let rgba = self.output.finish(&self.gpu, frame, encoder)?;
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
    fn upload(&mut self) -> Vec<u64> {
        let device = &self.gpu.device;
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
            self.gpu
                .queue
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
            f32::from(u8::from(style.kernel == Kernel::Round)),
            f32::from(u8::from(style.two_sided)),
            0.0,
            0.0,
        ],
    }
}

/// Refuses a frame larger than the adapter's largest texture.
fn check_size(device: &wgpu::Device, width: u32, height: u32) -> anyhow::Result<()> {
    let max = device.limits().max_texture_dimension_2d;
    ensure!(
        width <= max && height <= max,
        "frame size {width}x{height} exceeds this adapter's {max} pixels"
    );
    Ok(())
}
