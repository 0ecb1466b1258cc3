//! The item buffer of PLP (Klosowski & Silva): "we color all the triangles
//! with different colors, render them, and read the frame buffer back,
//! recording which triangles contributed to the image".
//!
//! The "colors" are integers: each triangle's id + 1 is written into an
//! `R32Uint` target cleared to 0, so ids never collide or blend and 0 means
//! "no triangle". Coverage and depth are those of
//! [`Renderer::render_geometry`]'s triangles: the same camera-relative
//! positions, the same near plane, the same clip-space formula (the shader
//! is `geometry.wgsl` with `item_buffer.wgsl`'s entry points appended), the
//! same triangle list without culling and the same reversed-Z `Greater`
//! test against depth cleared to 0. So the ids in the item buffer are the
//! triangles the color image shows.

use anyhow::{bail, ensure};
use bytemuck::{Pod, Zeroable};
use farfield_protocol::camera::Camera;

use super::GpuVertex;
use super::adapter::Gpu;
use super::error_scope::ValidationScope;
use super::geometry::{GeometryUniform, WHOLE_VIEW, triangles_near_plane, upload};
use super::pipeline::{PipelineSpec, color_target, depth_test};
use super::renderer::Renderer;
use super::target::Target;
use super::uniform::UniformBinding;

/// The item buffer's format: one id + 1 per pixel.
const ITEM_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Uint;

/// One triangle corner: its position and its triangle's id + 1 (16 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
struct ItemVertex {
    position: [f32; 3],
    item: u32,
}

/// The item pipeline, its uniform and vertex buffer, and the frame it draws
/// into, made on first use and kept by the [`Renderer`].
#[derive(Debug)]
pub(crate) struct ItemBuffer {
    pipeline: wgpu::RenderPipeline,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// The vertex buffer and its capacity in bytes.
    vertex_buffer: Option<(wgpu::Buffer, u64)>,
    /// The frame, for the size it was last drawn at.
    target: Option<Target>,
    scratch: Vec<ItemVertex>,
}

impl ItemBuffer {
    fn new(device: &wgpu::Device) -> anyhow::Result<Self> {
        let scope = ValidationScope::push(device);
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("farfield item buffer"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("geometry.wgsl"),
                    "\n",
                    include_str!("item_buffer.wgsl")
                )
                .into(),
            ),
        });
        let UniformBinding {
            buffer: uniform,
            bind_group,
            pipeline_layout: layout,
            ..
        } = UniformBinding::new(
            device,
            std::mem::size_of::<GeometryUniform>() as u64,
            "farfield item buffer",
        );
        let attributes = wgpu::vertex_attr_array![0 => Float32x3, 1 => Uint32];
        // The triangle pipeline's shape: a list, no culling.
        let pipeline = PipelineSpec {
            label: "farfield item buffer",
            layout: &layout,
            shader: &shader,
            vertex_entry: "vs_item",
            fragment_entry: "fs_item",
            buffers: &[Some(wgpu::VertexBufferLayout {
                array_stride: std::mem::size_of::<ItemVertex>() as u64,
                step_mode: wgpu::VertexStepMode::Vertex,
                attributes: &attributes,
            })],
            topology: wgpu::PrimitiveTopology::TriangleList,
            depth: depth_test(true),
            targets: &[color_target(ITEM_FORMAT, None)],
        }
        .build(device);
        if let Some(e) = scope.pop() {
            bail!("creating the item buffer pipeline: {e}");
        }
        Ok(Self {
            pipeline,
            uniform,
            bind_group,
            vertex_buffer: None,
            target: None,
            scratch: Vec::new(),
        })
    }

    /// Draws `self.scratch` with `uniform` into a `width` x `height` frame
    /// and reads it back: id + 1 per pixel, rows top first.
    fn draw(
        &mut self,
        gpu: &Gpu,
        uniform: &GeometryUniform,
        width: u32,
        height: u32,
    ) -> anyhow::Result<Vec<u32>> {
        let device = &gpu.device;
        let scope = ValidationScope::push(device);
        gpu.queue
            .write_buffer(&self.uniform, 0, bytemuck::bytes_of(uniform));
        let bytes: &[u8] = bytemuck::cast_slice(&self.scratch);
        upload(
            device,
            &gpu.queue,
            &mut self.vertex_buffer,
            bytes,
            "farfield item buffer triangles",
        );
        if self
            .target
            .as_ref()
            .is_none_or(|t| (t.width, t.height) != (width, height))
        {
            self.target = Some(Target::with_color(
                device,
                width,
                height,
                ITEM_FORMAT,
                "farfield item buffer",
            ));
        }
        let Some(target) = self.target.as_ref() else {
            bail!("no item buffer frame");
        };
        let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("farfield item buffer"),
        });
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("farfield item buffer"),
                color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                    view: &target.color_view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations {
                        // Red 0: no triangle.
                        load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                        store: wgpu::StoreOp::Store,
                    },
                })],
                // As the frame's pass: 0 is infinitely far with reversed Z.
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &target.depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load: wgpu::LoadOp::Clear(0.0),
                        store: wgpu::StoreOp::Discard,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            if let (Some((buffer, _)), false) = (&self.vertex_buffer, self.scratch.is_empty()) {
                pass.set_pipeline(&self.pipeline);
                pass.set_bind_group(0, &self.bind_group, &[]);
                pass.set_vertex_buffer(0, buffer.slice(..bytes.len() as u64));
                pass.draw(0..self.scratch.len() as u32, 0..1);
            }
        }
        target.copy_out(&mut encoder);
        gpu.queue.submit([encoder.finish()]);
        // Four bytes a texel: each an id + 1, in the machine's order.
        let read = target.read(device).map(|bytes| {
            bytes
                .chunks_exact(4)
                .map(|b| u32::from_ne_bytes([b[0], b[1], b[2], b[3]]))
                .collect()
        });
        // A validation error explains a failed (or meaningless) readback.
        if let Some(e) = scope.pop() {
            bail!(
                "drawing the item buffer of {} triangles: {e}",
                self.scratch.len() / 3
            );
        }
        read
    }
}

/// The distinct ids (not id + 1) present in an item buffer, ascending.
pub fn visible_ids(buffer: &[u32]) -> Vec<u32> {
    let mut ids: Vec<u32> = Vec::new();
    // Neighbours mostly repeat: skip runs before sorting.
    for &item in buffer {
        if item != 0 && ids.last() != Some(&(item - 1)) {
            ids.push(item - 1);
        }
    }
    ids.sort_unstable();
    ids.dedup();
    ids
}

impl Renderer {
    /// Per pixel (row-major, top row first, width*height entries) the id + 1 of the triangle
    /// nearest the eye there, 0 where none covers the pixel.
    ///
    /// `vertices` are three per triangle, camera-relative, as
    /// [`Self::render_geometry`] takes them, and `ids[i]` is triangle
    /// `i`'s id (below `u32::MAX`). Coverage and depth are exactly that
    /// function's for the same camera and vertices (without cube faces),
    /// so [`visible_ids`] of the result are the triangles its image shows.
    pub fn item_buffer(
        &mut self,
        camera: &Camera,
        vertices: &[GpuVertex],
        ids: &[u32],
    ) -> anyhow::Result<Vec<u32>> {
        let (width, height) = self.size_for(camera)?;
        ensure!(
            vertices.len().is_multiple_of(3),
            "{} vertices are not whole triangles (three vertices each, one of the ids per triangle)",
            vertices.len()
        );
        ensure!(
            ids.len().checked_mul(3) == Some(vertices.len()),
            "{} triangles need as many ids, not {}",
            vertices.len() / 3,
            ids.len()
        );
        ensure!(
            !ids.contains(&u32::MAX),
            "triangle id {} has no id + 1 in 32 bits",
            u32::MAX
        );
        ensure!(
            u32::try_from(vertices.len()).is_ok(),
            "{} triangles are more than one draw takes",
            ids.len()
        );
        // As render_geometry: `near` here only clamps View's planes.
        let view = camera.view(1.0);
        let near = triangles_near_plane(vertices, &view);
        // geometry.wgsl's own frame: the same clip-space formula.
        let uniform = GeometryUniform::new(&view, near, WHOLE_VIEW);
        // Taken out while the device is borrowed, and put back after.
        let mut slot = self.item_buffer.take();
        let result = (|| {
            // The renderer's way to its device (it also makes the triangle
            // pipelines, once, which render_geometry would anyway).
            let (gpu, _, _) = self.geometry_parts()?;
            let limit = gpu.device.limits().max_buffer_size;
            let bytes = vertices.len() as u64 * std::mem::size_of::<ItemVertex>() as u64;
            ensure!(
                bytes <= limit,
                "{} triangles exceed this adapter's largest buffer ({limit} bytes)",
                ids.len()
            );
            if slot.is_none() {
                slot = Some(ItemBuffer::new(&gpu.device)?);
            }
            let Some(items) = slot.as_mut() else {
                bail!("no item buffer pipeline");
            };
            items.scratch.clear();
            items.scratch.extend(
                vertices
                    .chunks_exact(3)
                    .zip(ids)
                    .flat_map(|(corners, &id)| {
                        corners.iter().map(move |v| ItemVertex {
                            position: v.position,
                            item: id + 1,
                        })
                    }),
            );
            items.draw(gpu, &uniform, width, height)
        })();
        self.item_buffer = slot;
        result
    }
}

#[cfg(test)]
mod tests {
    use farfield_protocol::camera::Camera;
    use glam::{DVec3, Vec3};

    use super::visible_ids;
    use crate::{Coverage, GpuVertex, Renderer, headless_or_skip};

    const W: u32 = 64;
    const H: u32 = 48;

    fn renderer() -> Option<Renderer> {
        headless_or_skip(W, H).expect("no GPU adapter")
    }

    /// Eye at the origin looking along +X, +Z up: image right is world -Y.
    fn camera() -> Camera {
        Camera {
            eye: DVec3::ZERO,
            target: DVec3::X,
            up: DVec3::Z,
            fov_y_deg: 60.0,
            width: W,
            height: H,
        }
    }

    /// The camera-relative point `depth` ahead that projects onto image
    /// position (`x`, `y`) in pixels (0, 0 the top left corner).
    fn at(depth: f64, [x, y]: [f64; 2]) -> Vec3 {
        let per_px = depth * 30f64.to_radians().tan() / f64::from(H / 2);
        let right = -(x - f64::from(W / 2)) * per_px;
        let up = -(y - f64::from(H / 2)) * per_px;
        Vec3::new(depth as f32, right as f32, up as f32)
    }

    fn vertex(p: Vec3, color: [u8; 3]) -> GpuVertex {
        GpuVertex {
            position: p.to_array(),
            normal: [0; 4],
            color: [color[0], color[1], color[2], 255],
        }
    }

    /// A triangle facing the eye at `depth`, given by its corners' pixels.
    fn facing(depth: f64, corners: [[f64; 2]; 3], color: [u8; 3]) -> [GpuVertex; 3] {
        corners.map(|c| vertex(at(depth, c), color))
    }

    fn item(buffer: &[u32], x: u32, y: u32) -> u32 {
        buffer[(y * W + x) as usize]
    }

    fn count(buffer: &[u32], id: u32) -> usize {
        buffer.iter().filter(|&&v| v == id + 1).count()
    }

    #[test]
    fn the_front_triangle_hides_and_the_back_one_shows_around_it() {
        let Some(mut r) = renderer() else {
            eprintln!("SKIPPED: no adapter");
            return;
        };
        let white = [255; 3];
        // Upper right, far; overlapped on its left by the front triangle.
        let back = (
            3,
            facing(20.0, [[26.0, 4.0], [62.0, 4.0], [62.0, 44.0]], white),
        );
        // Area 24 * 28 / 2 = 336 px, near.
        let front = (
            7,
            facing(10.0, [[20.0, 12.0], [44.0, 12.0], [32.0, 40.0]], white),
        );
        // Between the two, entirely inside the front triangle's outline.
        let hidden = (
            5,
            facing(15.0, [[28.0, 16.0], [36.0, 16.0], [32.0, 24.0]], white),
        );
        // Left of the image, and behind the eye.
        let outside = (
            9,
            facing(10.0, [[-40.0, 10.0], [-20.0, 10.0], [-30.0, 30.0]], white),
        );
        let behind = (11, mirrored(front.1));
        let orders = [
            [back, front, hidden, outside, behind],
            [behind, outside, hidden, front, back],
        ];
        for order in orders {
            let vertices: Vec<GpuVertex> = order.iter().flat_map(|t| t.1).collect();
            let ids: Vec<u32> = order.iter().map(|t| t.0).collect();
            let buffer = r.item_buffer(&camera(), &vertices, &ids).unwrap();
            assert_eq!(buffer.len(), (W * H) as usize);
            assert_eq!(visible_ids(&buffer), [3, 7], "order {ids:?}");
            // Where the hidden triangle lies behind the front one.
            assert_eq!(item(&buffer, 32, 20), 7 + 1);
            // Only the back triangle there.
            assert_eq!(item(&buffer, 55, 10), 3 + 1);
            for (x, y) in [(2, 2), (2, H - 2), (W - 1, H - 1), (10, 40), (40, 44)] {
                assert_eq!(item(&buffer, x, y), 0, "background at {x},{y}");
            }
            let front_px = count(&buffer, 7);
            assert!(
                (300..=372).contains(&front_px),
                "front covers {front_px} px"
            );
            let back_px = count(&buffer, 3);
            // 720 px in all, some of them behind the front triangle.
            assert!((300..700).contains(&back_px), "back shows {back_px} px");
            let background = buffer.iter().filter(|&&v| v == 0).count();
            assert_eq!(front_px + back_px + background, buffer.len());
        }
    }

    /// The triangle mirrored behind the eye (negative depth).
    fn mirrored(mut t: [GpuVertex; 3]) -> [GpuVertex; 3] {
        for v in &mut t {
            v.position[0] = -v.position[0];
        }
        t
    }

    /// A small deterministic generator (xorshift64*), in 0..1.
    struct Rng(u64);

    impl Rng {
        fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }

        fn range(&mut self, lo: f64, hi: f64) -> f64 {
            lo + (hi - lo) * self.next()
        }
    }

    /// Which of red, green, blue are lit: 1..=7 for the colors below.
    fn channels(rgb: &[u8]) -> u32 {
        rgb.iter()
            .enumerate()
            .map(|(i, &c)| u32::from(c > 0) << i)
            .sum()
    }

    #[test]
    fn coverage_equals_the_color_images() {
        let Some(mut r) = renderer() else {
            eprintln!("SKIPPED: no adapter");
            return;
        };
        // Triangles of random size and orientation at random depths, many
        // overlapping and crossing each other, some reaching behind the
        // eye (clipped by the near plane), some partly off-screen. Each is
        // drawn in a bright color of channels (i % 7) + 1; shading scales
        // a lit channel (to at least the ambient 30 %) and leaves an unlit
        // one 0, so the image says which color group covers each pixel.
        let mut rng = Rng(0x00f0_f1e1_d000_0001);
        let mut vertices = Vec::new();
        let mut ids = Vec::new();
        for i in 0..80u32 {
            let group = i % 7 + 1;
            let color = [0, 1, 2].map(|c| if group >> c & 1 == 1 { 255 } else { 0 });
            let (center_depth, spread) = if i % 10 == 0 {
                (rng.range(0.5, 3.0), 6.0)
            } else {
                (rng.range(2.0, 40.0), 0.0)
            };
            let center = at(
                center_depth,
                [rng.range(-10.0, 74.0), rng.range(-10.0, 58.0)],
            );
            let size = center_depth as f32 * rng.range(0.05, 0.6) as f32;
            for _ in 0..3 {
                let offset = Vec3::new(
                    rng.range(-1.0, 1.0) as f32 * (size + spread),
                    rng.range(-1.0, 1.0) as f32 * size,
                    rng.range(-1.0, 1.0) as f32 * size,
                );
                vertices.push(vertex(center + offset, color));
            }
            ids.push(1000 + i);
        }
        assert!(
            vertices.iter().any(|v| v.position[0] < 0.0),
            "some triangle reaches behind the eye"
        );
        let camera = camera();
        let image = r
            .render_geometry(&camera, &vertices, &[], Coverage::Alpha, [0, 0, 0])
            .unwrap();
        let buffer = r.item_buffer(&camera, &vertices, &ids).unwrap();
        assert_eq!(buffer.len() * 4, image.rgba.len());
        let (mut mismatched, mut covered) = (0, 0);
        for (i, (&item, rgba)) in buffer.iter().zip(image.rgba.chunks(4)).enumerate() {
            let shown = channels(&rgba[..3]);
            let expected = match item {
                0 => 0,
                id => (id - 1 - 1000) % 7 + 1,
            };
            if shown != expected {
                mismatched += 1;
                eprintln!(
                    "pixel {},{}: item {item}, color {:?}",
                    i as u32 % W,
                    i as u32 / W,
                    &rgba[..3]
                );
            }
            covered += usize::from(item != 0);
        }
        // Same positions, same clip formula, same rasterizer: no pixel
        // may differ (llvmpipe and lavapipe agree exactly).
        assert_eq!(
            mismatched, 0,
            "pixels where the item buffer and image differ"
        );
        assert!(
            covered > buffer.len() / 4 && covered < buffer.len(),
            "{covered} of {} pixels covered",
            buffer.len()
        );
        assert!(visible_ids(&buffer).len() > 10);
    }

    #[test]
    fn ids_must_match_the_triangles_and_the_camera_the_renderer() {
        let Some(mut r) = renderer() else {
            eprintln!("SKIPPED: no adapter");
            return;
        };
        let t = facing(10.0, [[20.0, 12.0], [44.0, 12.0], [32.0, 40.0]], [255; 3]);
        let vertices: Vec<GpuVertex> = t.iter().chain(&t).copied().collect();
        for ids in [&[1][..], &[1, 2, 3], &[]] {
            let e = r.item_buffer(&camera(), &vertices, ids).unwrap_err();
            assert!(format!("{e}").contains("ids"), "{e}");
        }
        // Not a whole number of triangles.
        assert!(r.item_buffer(&camera(), &vertices[..5], &[1, 2]).is_err());
        assert!(r.item_buffer(&camera(), &vertices, &[1, u32::MAX]).is_err());
        let small = Camera {
            width: W / 2,
            ..camera()
        };
        assert!(r.item_buffer(&small, &vertices, &[1, 2]).is_err());
        // The renderer still works after refusing.
        let buffer = r.item_buffer(&camera(), &vertices, &[1, 2]).unwrap();
        assert_eq!(visible_ids(&buffer), [1]);
    }

    #[test]
    fn no_triangles_give_zeros_at_the_renderers_size() {
        let Some(mut r) = renderer() else {
            eprintln!("SKIPPED: no adapter");
            return;
        };
        let buffer = r.item_buffer(&camera(), &[], &[]).unwrap();
        assert_eq!(buffer.len(), (W * H) as usize);
        assert!(buffer.iter().all(|&v| v == 0));
        // A drawn frame first, so the cleared one is not just fresh memory.
        let t = facing(10.0, [[0.0, 0.0], [64.0, 0.0], [0.0, 48.0]], [255; 3]);
        let buffer = r.item_buffer(&camera(), &t, &[4]).unwrap();
        assert_eq!(visible_ids(&buffer), [4]);
        let buffer = r.item_buffer(&camera(), &[], &[]).unwrap();
        assert!(buffer.iter().all(|&v| v == 0));
        // After a resize the buffer follows the renderer (rows padded
        // differently: 3 * 4 bytes per row).
        r.resize(3, 5);
        let small = Camera {
            width: 3,
            height: 5,
            ..camera()
        };
        let t = facing(
            10.0,
            [[-100.0, -100.0], [200.0, -100.0], [0.0, 200.0]],
            [255; 3],
        );
        let buffer = r.item_buffer(&small, &t, &[0]).unwrap();
        assert_eq!(buffer, vec![1; 15]);
    }

    #[test]
    fn visible_ids_are_distinct_ascending_and_without_the_offset() {
        assert_eq!(visible_ids(&[]), Vec::<u32>::new());
        assert_eq!(visible_ids(&[0, 0]), Vec::<u32>::new());
        assert_eq!(visible_ids(&[5, 5, 0, 2, 5, 1, 2]), [0, 1, 4]);
    }
}
