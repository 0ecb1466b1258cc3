//! The image-cache atlas, the scratch frame caches are drawn in, and the
//! quad pipeline, made once per atlas size and view size.

use std::collections::HashMap;

use anyhow::{bail, ensure};

use super::pack::GpuQuad;
use crate::error_scope::ValidationScope;
use crate::geometry::GeometryPipelines;
use crate::pipeline::{PipelineSpec, color_target, depth_test, fragment_sampler, fragment_texture};
use crate::target::Target;

/// The atlas, the scratch frame caches are drawn in, and the quad
/// pipelines (plain, and outlined for a viewer that shows its caches).
#[derive(Debug)]
pub(crate) struct ImpostorResources {
    pub(super) atlas: wgpu::Texture,
    pub(super) atlas_side: u32,
    pub(super) scratch: Target,
    pub(super) quad_pipeline: wgpu::RenderPipeline,
    pub(super) outlined_pipeline: wgpu::RenderPipeline,
    pub(super) texture_group: wgpu::BindGroup,
    pub(super) quad_buffer: Option<(wgpu::Buffer, u64)>,
    /// Block origin -> the serial of the cache it holds.
    pub(super) held: HashMap<(u32, u32), u64>,
    pub(super) stale: u64,
}

impl ImpostorResources {
    pub(super) fn new(
        device: &wgpu::Device,
        pipes: &GeometryPipelines,
        format: wgpu::TextureFormat,
        atlas_side: u32,
        (width, height): (u32, u32),
    ) -> anyhow::Result<Self> {
        let limit = device.limits().max_texture_dimension_2d;
        ensure!(
            atlas_side <= limit,
            "an image-cache atlas of {atlas_side} texels exceeds this adapter's largest texture ({limit})"
        );
        let scope = ValidationScope::push(device);
        let atlas = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("farfield impostor atlas"),
            size: wgpu::Extent3d {
                width: atlas_side,
                height: atlas_side,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        let scratch = Target::with_color(
            device,
            width + 2,
            height + 2,
            format,
            "farfield impostor scratch",
        );
        let texture_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("farfield quads atlas"),
            entries: &[
                fragment_texture(0, wgpu::TextureSampleType::Float { filterable: true }),
                fragment_sampler(1, wgpu::SamplerBindingType::Filtering),
            ],
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("farfield atlas sampler"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            ..Default::default()
        });
        let view = atlas.create_view(&Default::default());
        let texture_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("farfield quads atlas"),
            layout: &texture_layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::TextureView(&view),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Sampler(&sampler),
                },
            ],
        });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("farfield quads"),
            bind_group_layouts: &[Some(&pipes.bind_layout), Some(&texture_layout)],
            immediate_size: 0,
        });
        let shader = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("farfield quads"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("../geometry.wgsl"),
                    "\n",
                    include_str!("quads.wgsl")
                )
                .into(),
            ),
        });
        let attributes = wgpu::vertex_attr_array![
            0 => Float32x3, 1 => Float32x3, 2 => Float32x3, 3 => Float32x3, 4 => Float32x4
        ];
        // Quads are drawn over the frame in order, blended, and never hide
        // one another: depth is neither tested nor written.
        let no_depth_test = wgpu::DepthStencilState {
            depth_write_enabled: Some(false),
            depth_compare: Some(wgpu::CompareFunction::Always),
            ..depth_test(false)
        };
        let make_quad_pipeline = |fragment: &str| {
            PipelineSpec {
                label: "farfield quads",
                layout: &layout,
                shader: &shader,
                vertex_entry: "vs_quad",
                fragment_entry: fragment,
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<GpuQuad>() as u64,
                    step_mode: wgpu::VertexStepMode::Instance,
                    attributes: &attributes,
                })],
                topology: wgpu::PrimitiveTopology::TriangleStrip,
                depth: no_depth_test.clone(),
                targets: &[color_target(
                    format,
                    Some(wgpu::BlendState::PREMULTIPLIED_ALPHA_BLENDING),
                )],
            }
            .build(device)
        };
        let outlined_pipeline = make_quad_pipeline("fs_quad_outlined");
        let quad_pipeline = make_quad_pipeline("fs_quad");
        if let Some(e) = scope.pop() {
            bail!("creating the image-cache atlas and quad pipeline: {e}");
        }
        Ok(Self {
            atlas,
            atlas_side,
            scratch,
            quad_pipeline,
            outlined_pipeline,
            texture_group,
            quad_buffer: None,
            held: HashMap::new(),
            stale: 0,
        })
    }
}

impl ImpostorResources {
    /// A pass on the scratch frame, cleared to transparent.
    pub(super) fn scratch_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
    ) -> wgpu::RenderPass<'e> {
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("farfield make cache"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.scratch.color_view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.scratch.depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(0.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        })
    }

    /// Records the copy of the scratch frame's top-left `w` x `h` texels
    /// into the atlas at `at`.
    pub(super) fn copy_to_atlas(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        at: (u32, u32),
        w: u32,
        h: u32,
    ) {
        encoder.copy_texture_to_texture(
            wgpu::TexelCopyTextureInfo {
                texture: self.scratch.color_texture(),
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyTextureInfo {
                texture: &self.atlas,
                mip_level: 0,
                origin: wgpu::Origin3d {
                    x: at.0,
                    y: at.1,
                    z: 0,
                },
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: 1,
            },
        );
    }
}
