//! The color-cube hierarchy's renderer: leaf triangles and cube faces.
//!
//! Triangles (leaf geometry, or a whole scene's for the geometry
//! reference) are drawn first, opaque and depth-tested. Cube faces follow:
//! with [`Coverage::Threshold`] faces under the threshold were dropped by
//! the traversal and the rest are opaque (the 1995 report); with
//! [`Coverage::Alpha`] they are blended, premultiplied, back to front over
//! what is already drawn, without writing depth (the 1996 paper). Both
//! pass through [`Renderer::render_geometry`].

use web_time::Instant;

use anyhow::{bail, ensure};
use bytemuck::{Pod, Zeroable};
use farfield_protocol::camera::Camera;
use farfield_protocol::cube_codec;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_protocol::octahedral::unpack_normal;
use farfield_protocol::shading;
use farfield_traverse::cubes::{CubeCut, FaceDraw};
use glam::{DVec3, Vec3};

use super::RenderOutput;
use super::error_scope::ValidationScope;
use super::instances::{DEFAULT_COLOR, snorm16};
use super::pipeline::{PipelineSpec, color_target, depth_test};
use super::renderer::Renderer;
use super::uniform::UniformBinding;
use crate::bsp::{GpuInstance, INSTANCE_ATTRIBUTES, Instanced, PrototypeBuffers};

/// How cube faces use their coverage.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Coverage {
    /// Faces covered at least this much (0..=1) are drawn opaque, the
    /// others not at all (Chamberlain et al. 1995).
    Threshold(f32),
    /// Coverage is transparency (Chamberlain et al. 1996).
    #[default]
    Alpha,
}

impl Coverage {
    /// The smallest alpha byte a face needs to be drawn.
    pub fn min_alpha(self) -> u8 {
        match self {
            Coverage::Threshold(t) => (t.clamp(0.0, 1.0) * 255.0).round().max(1.0) as u8,
            Coverage::Alpha => 1,
        }
    }
}

impl std::str::FromStr for Coverage {
    type Err = String;
    /// `alpha`, or `threshold` (0.5), or `threshold:T`.
    fn from_str(s: &str) -> Result<Self, String> {
        match s.split_once(':') {
            None if s == "alpha" => Ok(Self::Alpha),
            None if s == "threshold" => Ok(Self::Threshold(0.5)),
            Some(("threshold", t)) => match t.parse::<f32>() {
                Ok(t) if (0.0..=1.0).contains(&t) => Ok(Self::Threshold(t)),
                _ => Err(format!("coverage threshold {t} is not a number in 0..=1")),
            },
            _ => Err(format!(
                "coverage must be alpha, threshold or threshold:T, not {s}"
            )),
        }
    }
}

/// One triangle corner as the vertex shader reads it (24 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct GpuVertex {
    /// Camera-relative position, world axes.
    pub position: [f32; 3],
    /// Unit normal as snorm16, w = 32767 when present (else flat-shaded).
    pub normal: [i16; 4],
    /// sRGB bytes; alpha unused.
    pub color: [u8; 4],
}

/// One cube face as the vertex shader reads it (instance step, 24 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
struct GpuFace {
    min_corner: [f32; 3],
    edge: f32,
    face: u32,
    rgba: [u8; 4],
}

#[repr(C)]
#[derive(Debug, Clone, Copy, Pod, Zeroable)]
pub(crate) struct GeometryUniform {
    right: [f32; 4],
    up: [f32; 4],
    forward: [f32; 4],
    proj: [f32; 4],
    light: [f32; 4],
    params: [f32; 4],
    /// Narrows the frustum to a window of the view: clip xy are scaled by
    /// xy and offset by zw (times w). [`WHOLE_VIEW`] leaves it as is.
    window: [f32; 4],
}

/// The window of the whole view.
pub(crate) const WHOLE_VIEW: [f32; 4] = [1.0, 1.0, 0.0, 0.0];

impl GeometryUniform {
    /// The frame for `view` with near plane `near`, narrowed to `window`.
    pub(crate) fn new(view: &farfield_protocol::camera::View, near: f64, window: [f32; 4]) -> Self {
        let light = shading::light_dir();
        let v4 = |v: DVec3| [v.x as f32, v.y as f32, v.z as f32, 0.0];
        Self {
            right: v4(view.right),
            up: v4(view.up),
            forward: v4(view.forward),
            proj: [
                (1.0 / view.tan_half_x) as f32,
                (1.0 / view.tan_half_y) as f32,
                near as f32,
                0.0,
            ],
            light: [light.x, light.y, light.z, 0.0],
            params: [shading::AMBIENT, shading::DIFFUSE, 0.0, 0.0],
            window,
        }
    }
}

/// The triangle and face pipelines, made on first use.
#[derive(Debug)]
pub(crate) struct GeometryPipelines {
    pub(crate) triangles: wgpu::RenderPipeline,
    faces_opaque: wgpu::RenderPipeline,
    faces_blended: wgpu::RenderPipeline,
    /// Prototype triangles placed by per-instance transforms (BSP leaves).
    pub(crate) instanced: wgpu::RenderPipeline,
    pub(crate) uniform: wgpu::Buffer,
    pub(crate) bind_group: wgpu::BindGroup,
    /// The uniform's group layout: group 0 of the image caches' quads too.
    pub(crate) bind_layout: wgpu::BindGroupLayout,
    pub(crate) vertex_buffer: Option<(wgpu::Buffer, u64)>,
    face_buffer: Option<(wgpu::Buffer, u64)>,
    pub(crate) instance_buffer: Option<(wgpu::Buffer, u64)>,
    /// Prototypes' triangles, uploaded once each.
    pub(crate) prototypes: PrototypeBuffers,
}

impl GeometryPipelines {
    pub(crate) fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> anyhow::Result<Self> {
        let scope = ValidationScope::push(device);
        let shader = device.create_shader_module(wgpu::include_wgsl!("geometry.wgsl"));
        let UniformBinding {
            buffer: uniform,
            bind_group,
            bind_layout,
            pipeline_layout: layout,
        } = UniformBinding::new(
            device,
            std::mem::size_of::<GeometryUniform>() as u64,
            "farfield geometry",
        );
        let vertex_attributes =
            wgpu::vertex_attr_array![0 => Float32x3, 1 => Snorm16x4, 2 => Unorm8x4];
        let face_attributes =
            wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32, 2 => Uint32, 3 => Unorm8x4];
        let make = |label: &str,
                    vs: &str,
                    fs: &str,
                    buffer: wgpu::VertexBufferLayout,
                    topology,
                    depth_write: bool,
                    blend: Option<wgpu::BlendState>| {
            PipelineSpec {
                label,
                layout: &layout,
                shader: &shader,
                vertex_entry: vs,
                fragment_entry: fs,
                buffers: &[Some(buffer)],
                topology,
                depth: depth_test(depth_write),
                targets: &[color_target(format, blend)],
            }
            .build(device)
        };
        let vertex_layout = || wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<GpuVertex>() as u64,
            step_mode: wgpu::VertexStepMode::Vertex,
            attributes: &vertex_attributes,
        };
        let instance_layout = wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<GpuInstance>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &INSTANCE_ATTRIBUTES,
        };
        let instanced = PipelineSpec {
            label: "farfield instanced triangles",
            layout: &layout,
            shader: &shader,
            vertex_entry: "vs_instanced",
            fragment_entry: "fs_triangle",
            buffers: &[Some(vertex_layout()), Some(instance_layout)],
            topology: wgpu::PrimitiveTopology::TriangleList,
            depth: depth_test(true),
            targets: &[color_target(format, None)],
        }
        .build(device);
        let face_layout = || wgpu::VertexBufferLayout {
            array_stride: std::mem::size_of::<GpuFace>() as u64,
            step_mode: wgpu::VertexStepMode::Instance,
            attributes: &face_attributes,
        };
        let strip = wgpu::PrimitiveTopology::TriangleStrip;
        let triangles = make(
            "farfield triangles",
            "vs_triangle",
            "fs_triangle",
            vertex_layout(),
            wgpu::PrimitiveTopology::TriangleList,
            true,
            None,
        );
        let faces_opaque = make(
            "farfield faces (threshold)",
            "vs_face",
            "fs_face_opaque",
            face_layout(),
            strip,
            true,
            None,
        );
        let faces_blended = make(
            "farfield faces (alpha)",
            "vs_face",
            "fs_face_blended",
            face_layout(),
            strip,
            false,
            Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
        );
        if let Some(e) = scope.pop() {
            bail!("creating the geometry pipelines: {e}");
        }
        Ok(Self {
            triangles,
            faces_opaque,
            faces_blended,
            instanced,
            uniform,
            bind_group,
            bind_layout,
            vertex_buffer: None,
            face_buffer: None,
            instance_buffer: None,
            prototypes: PrototypeBuffers::default(),
        })
    }
}

/// The triangles of the cut's leaves, camera-relative, appended to `out`.
/// Each leaf's vertices are decoded once, then expanded by its indices.
pub fn pack_leaves(h: &Hierarchy, cut: &CubeCut, eye: DVec3, out: &mut Vec<GpuVertex>) {
    out.reserve(cut.triangles as usize * 3);
    let mut decoded: Vec<GpuVertex> = Vec::new();
    for leaf in &cut.leaves {
        let Some(g) = h
            .page(leaf.page as usize)
            .and_then(|p| p.cubes())
            .and_then(|c| c.payload(leaf.local as usize))
            .and_then(|p| p.geometry.as_ref())
        else {
            continue;
        };
        // Cell-relative offsets are exact in f32; only the cell's corner
        // relative to the eye needs f64.
        let origin = cube_codec::dequantize_in_cell([0; 3], leaf.min, leaf.edge, eye).as_vec3();
        let step = (leaf.edge * cube_codec::POSITION_SPAN / cube_codec::POSITION_STEPS) as f32;
        decoded.clear();
        decoded.extend(g.positions.iter().enumerate().map(|(i, q)| {
            GpuVertex {
                position: (origin + Vec3::from(q.map(f32::from)) * step).to_array(),
                normal: g
                    .normals
                    .as_ref()
                    .map_or([0; 4], |n| snorm4(unpack_normal(n[i]))),
                color: g
                    .colors
                    .as_ref()
                    .map_or(rgb4(DEFAULT_COLOR), |c| rgb4(c[i])),
            }
        }));
        for t in &g.triangles {
            out.extend(t.map(|i| decoded[i as usize]));
        }
    }
}

/// A unit normal as the shaders read it: snorm16, w = 1 for "present".
pub fn snorm4(n: Vec3) -> [i16; 4] {
    [snorm16(n.x), snorm16(n.y), snorm16(n.z), i16::MAX]
}

fn rgb4(c: [u8; 3]) -> [u8; 4] {
    [c[0], c[1], c[2], 255]
}

fn pack_faces(faces: &[FaceDraw], eye: DVec3, coverage: Coverage, out: &mut Vec<GpuFace>) {
    let gpu = |f: &FaceDraw| GpuFace {
        min_corner: (f.min - eye).as_vec3().to_array(),
        edge: f.edge as f32,
        face: f.face.index() as u32,
        rgba: f.rgba,
    };
    out.clear();
    if coverage == Coverage::Alpha {
        // Back to front, so each face blends over what lies behind it.
        let mut order: Vec<(f64, &FaceDraw)> = faces
            .iter()
            .map(|f| (f.center().distance_squared(eye), f))
            .collect();
        order.sort_by(|a, b| b.0.total_cmp(&a.0));
        out.extend(order.into_iter().map(|(_, f)| gpu(f)));
    } else {
        out.extend(faces.iter().map(gpu));
    }
}

impl Renderer {
    /// Draws triangles (`vertices`, three per triangle, camera-relative)
    /// and cube faces for `camera`; `near` is the near-plane distance.
    pub fn render_geometry(
        &mut self,
        camera: &Camera,
        vertices: &[GpuVertex],
        faces: &[FaceDraw],
        coverage: Coverage,
        background: [u8; 3],
    ) -> anyhow::Result<RenderOutput> {
        self.render_geometry_with(
            camera,
            vertices,
            faces,
            &Instanced::default(),
            coverage,
            background,
        )
    }

    /// [`Self::render_geometry`], and prototypes placed by `instanced`
    /// (their buffers made by [`Self::prototype_buffer`]).
    pub(crate) fn render_geometry_with(
        &mut self,
        camera: &Camera,
        vertices: &[GpuVertex],
        faces: &[FaceDraw],
        instanced: &Instanced,
        coverage: Coverage,
        background: [u8; 3],
    ) -> anyhow::Result<RenderOutput> {
        let (width, height) = self.size_for(camera)?;
        let started = Instant::now();
        let view = camera.view(1.0);
        let mut gpu_faces = Vec::with_capacity(faces.len());
        pack_faces(faces, camera.eye, coverage, &mut gpu_faces);
        let near = near_plane_of(
            vertex_and_face_depths(vertices, &gpu_faces, &view)
                .chain(instanced.depths.iter().copied()),
        );
        let uniform = GeometryUniform::new(&view, near, WHOLE_VIEW);
        let (gpu, pipes, output) = self.geometry_parts()?;
        let scope = ValidationScope::push(&gpu.device);
        gpu.queue
            .write_buffer(&pipes.uniform, 0, bytemuck::bytes_of(&uniform));
        let vertex_bytes: &[u8] = bytemuck::cast_slice(vertices);
        let face_bytes: &[u8] = bytemuck::cast_slice(&gpu_faces);
        let instance_bytes: &[u8] = bytemuck::cast_slice(&instanced.instances);
        let limit = gpu.device.limits().max_buffer_size;
        ensure!(
            (instance_bytes.len() as u64) <= limit,
            "{} instances exceed this adapter's largest buffer ({limit} bytes)",
            instanced.instances.len()
        );
        ensure!(
            (vertex_bytes.len() as u64) <= limit && (face_bytes.len() as u64) <= limit,
            "{} triangles or {} faces exceed this adapter's largest buffer ({limit} bytes)",
            vertices.len() / 3,
            faces.len()
        );
        upload(
            &gpu.device,
            &gpu.queue,
            &mut pipes.vertex_buffer,
            vertex_bytes,
            "farfield triangles",
        );
        upload(
            &gpu.device,
            &gpu.queue,
            &mut pipes.face_buffer,
            face_bytes,
            "farfield faces",
        );
        upload(
            &gpu.device,
            &gpu.queue,
            &mut pipes.instance_buffer,
            instance_bytes,
            "farfield instances",
        );
        let upload_ms = started.elapsed().as_secs_f64() * 1e3;

        let started = Instant::now();
        let frame = output.begin(&gpu.device)?;
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("farfield geometry frame"),
            });
        {
            let mut pass = frame.begin_pass(&mut encoder, "farfield geometry", background);
            pass.set_bind_group(0, &pipes.bind_group, &[]);
            if let (Some((buffer, _)), false) = (&pipes.vertex_buffer, vertices.is_empty()) {
                pass.set_pipeline(&pipes.triangles);
                pass.set_vertex_buffer(0, buffer.slice(..vertex_bytes.len() as u64));
                pass.draw(0..vertices.len() as u32, 0..1);
            }
            if let (Some((buffer, _)), false) =
                (&pipes.instance_buffer, instanced.instances.is_empty())
            {
                pass.set_pipeline(&pipes.instanced);
                pass.set_vertex_buffer(1, buffer.slice(..instance_bytes.len() as u64));
                for batch in &instanced.batches {
                    let Some((prototype, corners)) = pipes.prototypes.get(batch.prototype) else {
                        continue;
                    };
                    pass.set_vertex_buffer(0, prototype.slice(..));
                    pass.draw(0..corners, batch.first..batch.first + batch.count);
                }
            }
            if let (Some((buffer, _)), false) = (&pipes.face_buffer, gpu_faces.is_empty()) {
                pass.set_pipeline(match coverage {
                    Coverage::Threshold(_) => &pipes.faces_opaque,
                    Coverage::Alpha => &pipes.faces_blended,
                });
                pass.set_vertex_buffer(0, buffer.slice(..face_bytes.len() as u64));
                pass.draw(0..4, 0..gpu_faces.len() as u32);
            }
        }
        let rgba = output.finish(gpu, frame, encoder)?;
        let draw_ms = started.elapsed().as_secs_f64() * 1e3;
        if let Some(e) = scope.pop() {
            bail!(
                "rendering {} triangles, {} faces and {} instances: {e}",
                vertices.len() / 3,
                faces.len(),
                instanced.instances.len()
            );
        }
        Ok(RenderOutput {
            rgba,
            width,
            height,
            upload_ms,
            draw_ms,
        })
    }
}

/// Writes `bytes` into a vertex buffer grown to the next power of two as
/// needed.
pub(crate) fn upload(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    slot: &mut Option<(wgpu::Buffer, u64)>,
    bytes: &[u8],
    label: &str,
) {
    if bytes.is_empty() {
        return;
    }
    let len = bytes.len() as u64;
    if slot.as_ref().is_none_or(|(_, cap)| *cap < len) {
        let cap = len
            .next_power_of_two()
            .min(device.limits().max_buffer_size)
            .max(len);
        *slot = Some((
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: cap,
                usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            }),
            cap,
        ));
    }
    if let Some((buffer, _)) = slot {
        queue.write_buffer(buffer, 0, bytes);
    }
}

/// Depths (along the view direction) of the vertices and of the faces'
/// nearest and farthest reach.
fn vertex_and_face_depths<'a>(
    vertices: &'a [GpuVertex],
    faces: &'a [GpuFace],
    view: &farfield_protocol::camera::View,
) -> impl Iterator<Item = f64> + 'a {
    let f = view.forward;
    let depth =
        move |p: [f32; 3]| f64::from(p[0]) * f.x + f64::from(p[1]) * f.y + f64::from(p[2]) * f.z;
    // The face's corner nearest the eye is within a diagonal of it.
    let face_depths = faces.iter().flat_map(move |g| {
        let d = depth(g.min_corner);
        let reach = f64::from(g.edge) * 3f64.sqrt();
        [d - reach, d + reach]
    });
    vertices
        .iter()
        .map(move |v| depth(v.position))
        .chain(face_depths)
}

/// The near plane for triangles alone (the item buffer's, which must draw
/// exactly what [`Renderer::render_geometry`] draws without faces).
pub(crate) fn triangles_near_plane(
    vertices: &[GpuVertex],
    view: &farfield_protocol::camera::View,
) -> f64 {
    near_plane_of(vertex_and_face_depths(vertices, &[], view))
}

/// The near plane: half the nearest positive depth of what is drawn (a
/// little in front of it), but at least 1e-6 of the farthest (geometry
/// around the eye is clipped there, which is the best reversed Z can do);
/// 1 with nothing ahead.
pub(crate) fn near_plane_of(depths: impl Iterator<Item = f64>) -> f64 {
    let (mut nearest, mut farthest) = (f64::INFINITY, 0.0f64);
    for d in depths {
        if d > 0.0 {
            nearest = nearest.min(d);
        }
        farthest = farthest.max(d);
    }
    if farthest <= 0.0 {
        return 1.0;
    }
    (nearest * 0.5).max(farthest * 1e-6).max(f64::MIN_POSITIVE)
}
