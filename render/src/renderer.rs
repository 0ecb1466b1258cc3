//! [`Renderer`]: the device, the output a frame goes to, and each kind of
//! draw data's resources (splats made at once, the rest when first drawn).
//! What each kind draws and how is in its own module (`splats`,
//! `geometry`, `bsp`, `plp`, `impostors`, `item_buffer`).

use anyhow::{Context, bail, ensure};
use farfield_protocol::camera::Camera;
use farfield_traverse::spheres::Splat;

use super::adapter::{self, Gpu};
use super::geometry::GeometryPipelines;
use super::output::{Output, SurfaceOutput};
use super::splats::SplatPipeline;
use super::target::Target;
use super::{RenderOutput, SplatStyle};

/// Draws splats, triangles and cube faces into its [`Output`]: offscreen
/// (read back after every frame) or a surface (presented, not read back).
#[derive(Debug)]
pub struct Renderer {
    gpu: Gpu,
    output: Output,
    /// The splat pipeline and its instance buffers.
    splats: SplatPipeline,
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

    /// The splat pipeline for `output`'s format (the other kinds of draw
    /// data are made when first drawn).
    fn with_output(gpu: Gpu, output: Output) -> anyhow::Result<Self> {
        let splats = SplatPipeline::new(&gpu.device, output.format())?;
        Ok(Self {
            gpu,
            output,
            splats,
            geometry: None,
            capture: None,
            item_buffer: None,
            impostors: None,
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

    /// The largest frame side the device allows.
    pub fn max_side(&self) -> u32 {
        self.gpu.device.limits().max_texture_dimension_2d
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
        self.splats.set_chunk_splats(splats);
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
        self.size_for(camera)?;
        self.splats
            .draw(&self.gpu, &self.output, camera, splats, style)
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
