//! The image-caching BSP's cut ([`BspCut`]) as the GPU draws it: each
//! leaf's own triangles packed camera-relative (as PLP's), and placed
//! prototypes as instances: a prototype's triangles are uploaded once, in
//! its own frame, and each placement is one 48-byte transform per frame.
//! The island's 1117 trees of 36,230 triangles are 40 million triangles
//! placed, but one tree's vertex buffer and 54 kB of transforms.
//!
//! Precision: a placement's translation is taken relative to the eye in
//! f64 before it becomes f32, so what the GPU adds is small near the
//! camera; prototype coordinates are small by construction (their own
//! frame).

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use farfield_protocol::bsp_codec::LeafPage;
use farfield_protocol::bsp_codec::{ContentPage, FlatTriangle};
use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::{BspPage, Hierarchy};
use farfield_traverse::bsp::{BspCut, InstanceDraw, box_corners, leaf_page};

use crate::adapter::Gpu;
use glam::DVec3;
use web_time::Instant;

use crate::{GpuVertex, RenderOutput, Renderer, SplatStyle};

/// One placement as the vertex shader reads it (instance step, 48 bytes):
/// the columns of its linear part and its translation, camera-relative.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(crate) struct GpuInstance {
    pub columns: [[f32; 3]; 3],
    pub translation: [f32; 3],
}

/// The instance attributes, after the vertex's three.
pub(crate) const INSTANCE_ATTRIBUTES: [wgpu::VertexAttribute; 4] =
    wgpu::vertex_attr_array![3 => Float32x3, 4 => Float32x3, 5 => Float32x3, 6 => Float32x3];

/// A prototype's buffer: its page, and the page's checksum (a page number
/// alone would outlive a change of file).
pub(crate) type PrototypeKey = (u32, u32);

/// Instances `first..first + count` place prototype `prototype`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) struct Batch {
    pub prototype: PrototypeKey,
    pub first: u32,
    pub count: u32,
}

/// Placed prototypes for one frame.
#[derive(Debug, Clone, Default)]
pub(crate) struct Instanced {
    pub instances: Vec<GpuInstance>,
    pub batches: Vec<Batch>,
    /// Nearest and farthest depth of each instance's bounds (the near
    /// plane must not clip them).
    pub depths: Vec<f64>,
}

/// The most bytes of prototype buffers kept between frames; past it,
/// buffers the frame does not use are dropped (a frame that needs more
/// keeps what it needs: the resident pages bound it).
const PROTOTYPE_BYTES: u64 = 256 << 20;

/// Prototypes' vertex buffers, uploaded once each.
#[derive(Debug, Default)]
pub(crate) struct PrototypeBuffers {
    buffers: HashMap<PrototypeKey, (wgpu::Buffer, u32, u64)>,
    bytes: u64,
    frame: u64,
}

impl PrototypeBuffers {
    /// The buffer and its vertex count.
    pub fn get(&self, key: PrototypeKey) -> Option<(&wgpu::Buffer, u32)> {
        self.buffers.get(&key).map(|(b, n, _)| (b, *n))
    }

    /// Starts a frame: buffers not used from here on may be dropped.
    pub fn next_frame(&mut self) {
        self.frame += 1;
    }

    /// Makes `key`'s buffer from `triangles` unless it exists; marks it
    /// used this frame.
    pub fn ensure(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        key: PrototypeKey,
        triangles: &[FlatTriangle],
    ) {
        let frame = self.frame;
        if let Some(entry) = self.buffers.get_mut(&key) {
            entry.2 = frame;
            return;
        }
        if triangles.is_empty() {
            return;
        }
        let vertices: Vec<GpuVertex> = triangles
            .iter()
            .flat_map(|t| {
                t.corners.map(|c| GpuVertex {
                    position: c,
                    normal: [0; 4],
                    color: t.rgba,
                })
            })
            .collect();
        let bytes: &[u8] = bytemuck::cast_slice(&vertices);
        if self.bytes + bytes.len() as u64 > PROTOTYPE_BYTES {
            self.buffers.retain(|_, (b, _, used)| {
                let keep = *used == frame;
                if !keep {
                    b.destroy();
                }
                keep
            });
            self.bytes = self.buffers.values().map(|(b, _, _)| b.size()).sum();
        }
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("farfield prototype"),
            size: bytes.len() as u64,
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        queue.write_buffer(&buffer, 0, bytes);
        self.bytes += bytes.len() as u64;
        self.buffers
            .insert(key, (buffer, vertices.len() as u32, frame));
    }
}

/// The cut's leaves' own triangles, camera-relative, appended to `out`.
pub fn pack_bsp_leaves(h: &Hierarchy, cut: &BspCut, eye: DVec3, out: &mut Vec<GpuVertex>) {
    for l in &cut.leaves {
        if let Some(page) = leaf_page(h, l.page) {
            pack_leaf(page, page.own_triangles as usize, eye, out);
        }
    }
}

/// A leaf page's first `count` triangles (its own, or all with the
/// borrowed), camera-relative, appended to `out`. The page's anchor
/// relative to the eye is taken in f64 once; corners are offsets from it.
pub(crate) fn pack_leaf(page: &LeafPage, count: usize, eye: DVec3, out: &mut Vec<GpuVertex>) {
    let origin = page.anchor - eye;
    for t in page.triangles.iter().take(count) {
        for c in t.corners {
            out.push(GpuVertex {
                position: (origin + DVec3::from(c.map(f64::from)))
                    .as_vec3()
                    .to_array(),
                normal: [0; 4],
                color: t.rgba,
            });
        }
    }
}

/// One placement made ready for the GPU: its prototype's buffer made if
/// new, its transform camera-relative, and the view depths of its box's
/// corners appended to `depths` (the near plane must not clip it). `None`
/// when the prototype's page is not resident.
pub(crate) fn place(
    gpu: &Gpu,
    prototypes: &mut PrototypeBuffers,
    h: &Hierarchy,
    draw: &InstanceDraw,
    eye: DVec3,
    forward: DVec3,
    depths: &mut Vec<f64>,
) -> Option<(PrototypeKey, GpuInstance)> {
    let page = draw.prototype_page;
    let Some(BspPage::Content(ContentPage::Prototype(proto))) =
        h.page(page as usize).and_then(|p| p.bsp())
    else {
        return None;
    };
    let key = (page, h.directory().entry(page)?.checksum);
    prototypes.ensure(&gpu.device, &gpu.queue, key, &proto.triangles);
    let world = draw.world_from_local;
    if let Some(info) = h
        .bsp_skeleton()
        .and_then(|s| s.prototypes.get(proto.prototype as usize))
    {
        for c in box_corners(info.box_min, info.box_max) {
            depths.push((world.transform_point3(c) - eye).dot(forward));
        }
    }
    let m = world.matrix3;
    Some((
        key,
        GpuInstance {
            columns: [m.x_axis, m.y_axis, m.z_axis].map(|c| c.as_vec3().to_array()),
            translation: (world.translation - eye).as_vec3().to_array(),
        },
    ))
}

impl Renderer {
    /// Draws a BSP cut: leaves' own triangles, then placed prototypes.
    pub(crate) fn draw_bsp(
        &mut self,
        h: &Hierarchy,
        camera: &Camera,
        cut: &BspCut,
        style: &SplatStyle,
    ) -> anyhow::Result<RenderOutput> {
        let started = Instant::now();
        let mut vertices = Vec::new();
        pack_bsp_leaves(h, cut, camera.eye, &mut vertices);
        let instanced = self.place_prototypes(h, camera, cut)?;
        let pack_ms = started.elapsed().as_secs_f64() * 1e3;
        let mut image = self.render_geometry_with(
            camera,
            &vertices,
            &[],
            &instanced,
            style.coverage,
            style.background,
        )?;
        image.upload_ms += pack_ms;
        Ok(image)
    }

    /// The cut's placements grouped by prototype, each prototype's buffer
    /// made if new.
    fn place_prototypes(
        &mut self,
        h: &Hierarchy,
        camera: &Camera,
        cut: &BspCut,
    ) -> anyhow::Result<Instanced> {
        let mut order: Vec<usize> = (0..cut.instances.len()).collect();
        order.sort_by_key(|&i| cut.instances[i].prototype_page);
        let forward = camera.view(1.0).forward;
        let (gpu, pipes, _) = self.geometry_parts()?;
        pipes.prototypes.next_frame();
        let mut out = Instanced::default();
        for i in order {
            let Some((key, instance)) = place(
                gpu,
                &mut pipes.prototypes,
                h,
                &cut.instances[i],
                camera.eye,
                forward,
                &mut out.depths,
            ) else {
                continue;
            };
            out.instances.push(instance);
            match out.batches.last_mut() {
                Some(b) if b.prototype == key => b.count += 1,
                _ => out.batches.push(Batch {
                    prototype: key,
                    first: out.instances.len() as u32 - 1,
                    count: 1,
                }),
            }
        }
        Ok(out)
    }
}
