//! Items to GPU buffers and draws: leaves' triangles camera-relative,
//! placements in runs of one prototype, quads with their atlas rectangles.

use std::ops::Range;

use bytemuck::{Pod, Zeroable};
use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_traverse::bsp::leaf_page;
use farfield_traverse::impostors::plan::{ImpostorCut, Item};
use glam::DVec3;

use super::ImpostorResources;
use crate::GpuVertex;
use crate::adapter::Gpu;
use crate::bsp::{GpuInstance, PrototypeKey, pack_leaf, place};
use crate::geometry::{GeometryPipelines, upload};

/// What a sequence is packed from.
#[derive(Debug, Clone, Copy)]
pub(super) struct FrameInput<'a> {
    pub h: &'a Hierarchy,
    pub camera: &'a Camera,
    pub cut: &'a ImpostorCut,
}

/// A quad as the vertex shader reads it (instance step, 64 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub(super) struct GpuQuad {
    /// Camera-relative corners: top-left, top-right, bottom-left,
    /// bottom-right.
    pub corners: [[f32; 3]; 4],
    /// The image in the atlas: u0, v0, u1, v1.
    pub uv: [f32; 4],
}

/// One draw of a sequence, in order.
#[derive(Debug, Clone)]
pub(super) enum Step {
    Triangles(Range<u32>),
    Instances {
        prototype: PrototypeKey,
        instances: Range<u32>,
    },
    Quad(u32),
}

/// Items packed for the GPU.
#[derive(Debug, Default)]
pub(super) struct Sequence {
    pub(super) vertices: Vec<GpuVertex>,
    pub(super) instances: Vec<GpuInstance>,
    pub(super) quads: Vec<GpuQuad>,
    /// Depths along the view of what is drawn, for the near plane.
    pub(super) depths: Vec<f64>,
    pub(super) steps: Vec<Step>,
}

/// Packs `items` camera-relative: leaves' triangles, their placements in
/// runs of one prototype, and quads whose block holds their image.
pub(super) fn pack(
    gpu: &Gpu,
    pipes: &mut GeometryPipelines,
    mut res: Option<&mut ImpostorResources>,
    input: FrameInput,
    items: &[Item],
    seq: &mut Sequence,
) {
    let FrameInput { h, camera, cut } = input;
    let eye = camera.eye;
    let forward = camera.view(1.0).forward;
    let depth = |p: DVec3| (p - eye).dot(forward);
    for item in items {
        match item {
            Item::Leaf {
                page,
                all,
                instances,
                ..
            } => {
                let Some(content) = leaf_page(h, *page) else {
                    continue;
                };
                let count = if *all {
                    content.triangles.len()
                } else {
                    content.own_triangles as usize
                };
                let first = seq.vertices.len();
                pack_leaf(content, count, eye, &mut seq.vertices);
                let f = forward.as_vec3();
                seq.depths.extend(
                    seq.vertices[first..]
                        .iter()
                        .map(|v| f64::from(glam::Vec3::from(v.position).dot(f))),
                );
                if seq.vertices.len() > first {
                    seq.steps
                        .push(Step::Triangles(first as u32..seq.vertices.len() as u32));
                }
                let range = instances.start as usize..instances.end as usize;
                for draw in cut.instances.get(range).unwrap_or(&[]) {
                    let Some((key, instance)) = place(
                        gpu,
                        &mut pipes.prototypes,
                        h,
                        draw,
                        eye,
                        forward,
                        &mut seq.depths,
                    ) else {
                        continue;
                    };
                    seq.instances.push(instance);
                    let i = seq.instances.len() as u32 - 1;
                    match seq.steps.last_mut() {
                        Some(Step::Instances {
                            prototype,
                            instances,
                        }) if *prototype == key && instances.end == i => instances.end += 1,
                        _ => seq.steps.push(Step::Instances {
                            prototype: key,
                            instances: i..i + 1,
                        }),
                    }
                }
            }
            Item::Quad {
                serial,
                block,
                width,
                height,
                corners,
                ..
            } => {
                let Some(res) = res.as_deref_mut() else {
                    continue;
                };
                if res.held.get(&(block.x, block.y)) != Some(serial) {
                    res.stale += 1;
                    continue;
                }
                let side = f64::from(res.atlas_side.max(1));
                let u0 = f64::from(block.x + 1) / side;
                let v0 = f64::from(block.y + 1) / side;
                let u1 = f64::from(block.x + 1 + width) / side;
                let v1 = f64::from(block.y + 1 + height) / side;
                for c in corners {
                    seq.depths.push(depth(*c));
                }
                seq.quads.push(GpuQuad {
                    corners: corners.map(|c| (c - eye).as_vec3().to_array()),
                    uv: [u0, v0, u1, v1].map(|v| v as f32),
                });
                seq.steps.push(Step::Quad(seq.quads.len() as u32 - 1));
            }
        }
    }
}

/// Writes a sequence's vertices, instances and quads to their buffers.
pub(super) fn upload_sequence(
    gpu: &Gpu,
    pipes: &mut GeometryPipelines,
    res: Option<&mut ImpostorResources>,
    seq: &Sequence,
) {
    upload(
        &gpu.device,
        &gpu.queue,
        &mut pipes.vertex_buffer,
        bytemuck::cast_slice(&seq.vertices),
        "farfield triangles",
    );
    upload(
        &gpu.device,
        &gpu.queue,
        &mut pipes.instance_buffer,
        bytemuck::cast_slice(&seq.instances),
        "farfield instances",
    );
    if let Some(res) = res {
        upload(
            &gpu.device,
            &gpu.queue,
            &mut res.quad_buffer,
            bytemuck::cast_slice(&seq.quads),
            "farfield quads",
        );
    }
}

/// Records a sequence's draws in order.
/// How cached quads are drawn: as they are, or outlined (a viewer's
/// final frame only; a cache never holds an outline).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum QuadLook {
    Plain,
    Outlined,
}

pub(super) fn encode(
    pass: &mut wgpu::RenderPass<'_>,
    pipes: &GeometryPipelines,
    res: Option<&ImpostorResources>,
    seq: &Sequence,
    quads: QuadLook,
) {
    for step in &seq.steps {
        match step {
            Step::Triangles(range) => {
                let Some((buffer, _)) = &pipes.vertex_buffer else {
                    continue;
                };
                pass.set_pipeline(&pipes.triangles);
                pass.set_bind_group(0, &pipes.bind_group, &[]);
                pass.set_vertex_buffer(0, buffer.slice(..));
                pass.draw(range.clone(), 0..1);
            }
            Step::Instances {
                prototype,
                instances,
            } => {
                let (Some((corners_buffer, corners)), Some((buffer, _))) =
                    (pipes.prototypes.get(*prototype), &pipes.instance_buffer)
                else {
                    continue;
                };
                pass.set_pipeline(&pipes.instanced);
                pass.set_bind_group(0, &pipes.bind_group, &[]);
                pass.set_vertex_buffer(0, corners_buffer.slice(..));
                pass.set_vertex_buffer(1, buffer.slice(..));
                pass.draw(0..corners, instances.clone());
            }
            Step::Quad(i) => {
                let Some(res) = res else { continue };
                let Some((buffer, _)) = &res.quad_buffer else {
                    continue;
                };
                pass.set_pipeline(match quads {
                    QuadLook::Plain => &res.quad_pipeline,
                    QuadLook::Outlined => &res.outlined_pipeline,
                });
                pass.set_bind_group(0, &pipes.bind_group, &[]);
                pass.set_bind_group(1, &res.texture_group, &[]);
                pass.set_vertex_buffer(0, buffer.slice(..));
                pass.draw(0..4, *i..*i + 1);
            }
        }
    }
}
