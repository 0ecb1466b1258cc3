//! Hierarchical image caching on the GPU: making the caches the planner
//! asks for ([`ImpostorCut::jobs`]) and drawing a frame of leaves and
//! cached quads back to front ([`ImpostorCut::items`]).
//!
//! A cache is made as the paper's `CreateCache`: the node's contents drawn
//! from the current eye with the frustum narrowed to its screen rectangle
//! (the geometry shader's `window`), into a scratch frame cleared to
//! transparent, then copied with a one-texel transparent border into its
//! block of the atlas, so linear filtering at its edge reads no neighbour.
//! Geometry writes alpha 1 and the background stays 0: the image is
//! premultiplied, and quads are blended "one, one minus source alpha"
//! without a halo. Quads test no depth and write none: items come back to
//! front, so a later item is never behind an earlier one.
//!
//! The planner owns the atlas's layout; the renderer remembers which
//! cache (serial) each block holds and draws nothing for a quad whose
//! block holds another (counted in [`Renderer::stale_quads`]): never
//! another node's image.

mod calibrate;
mod pack;
mod resources;

use anyhow::{Context, bail, ensure};
use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_traverse::impostors::plan::{CacheJob, ImpostorCut};
use web_time::Instant;

use crate::adapter::Gpu;
use crate::error_scope::ValidationScope;
use crate::geometry::{GeometryPipelines, GeometryUniform, WHOLE_VIEW, near_plane_of};
use crate::{RenderOutput, Renderer, SplatStyle};
use pack::{FrameInput, QuadLook, Sequence, encode, pack, upload_sequence};
pub(crate) use resources::ImpostorResources;

impl Renderer {
    /// Makes the cut's caches, then draws its items.
    pub(crate) fn draw_impostors(
        &mut self,
        h: &Hierarchy,
        camera: &Camera,
        cut: &ImpostorCut,
        style: &SplatStyle,
    ) -> anyhow::Result<RenderOutput> {
        let (width, height) = self.size_for(camera)?;
        let started = Instant::now();
        let format = self.output_format();
        let (gpu, pipes, slot, output) = self.impostor_parts()?;
        let fits = slot.as_ref().is_some_and(|r| {
            r.atlas_side == cut.atlas_side
                && (r.scratch.width, r.scratch.height) == (width + 2, height + 2)
        });
        if !fits && !cut.items.is_empty() {
            *slot = Some(ImpostorResources::new(
                &gpu.device,
                pipes,
                format,
                cut.atlas_side.max(16),
                (width, height),
            )?);
        }
        let scope = ValidationScope::push(&gpu.device);
        let view = camera.view(1.0);
        pipes.prototypes.next_frame();
        let input = FrameInput { h, camera, cut };
        if let Some(res) = slot.as_mut() {
            for job in &cut.jobs {
                make_cache(gpu, pipes, res, input, job)?;
            }
        }
        let mut seq = Sequence::default();
        pack(gpu, pipes, slot.as_mut(), input, &cut.items, &mut seq);
        let near = near_plane_of(seq.depths.iter().copied());
        let uniform = GeometryUniform::new(&view, near, WHOLE_VIEW);
        gpu.queue
            .write_buffer(&pipes.uniform, 0, bytemuck::bytes_of(&uniform));
        upload_sequence(gpu, pipes, slot.as_mut(), &seq);
        let upload_ms = started.elapsed().as_secs_f64() * 1e3;
        let started = Instant::now();
        let frame = output.begin(&gpu.device)?;
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("farfield impostor frame"),
            });
        {
            let mut pass =
                frame.begin_pass(&mut encoder, "farfield impostor frame", style.background);
            let look = if style.outline_caches {
                QuadLook::Outlined
            } else {
                QuadLook::Plain
            };
            encode(&mut pass, pipes, slot.as_ref(), &seq, look);
        }
        let rgba = output.finish(gpu, frame, encoder)?;
        let draw_ms = started.elapsed().as_secs_f64() * 1e3;
        if let Some(e) = scope.pop() {
            bail!(
                "drawing {} cached images and {} items: {e}",
                cut.jobs.len(),
                cut.items.len()
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

    /// Quads skipped because their block held another cache (a planner
    /// and a renderer out of step); 0 in a consistent frame loop.
    pub fn stale_quads(&self) -> u64 {
        self.impostor_resources().map_or(0, |r| r.stale)
    }
}

/// Draws `job`'s contents aside and copies them into its block.
fn make_cache(
    gpu: &Gpu,
    pipes: &mut GeometryPipelines,
    res: &mut ImpostorResources,
    input: FrameInput,
    job: &CacheJob,
) -> anyhow::Result<()> {
    let FrameInput { camera, cut, .. } = input;
    let [x, y] = [job.rect[0], job.rect[1]];
    let [rw, rh] = [job.rect[2], job.rect[3]].map(|v| v.max(1) as u32);
    let (w, hgt) = (
        f64::from(camera.width.max(1)),
        f64::from(camera.height.max(1)),
    );
    ensure!(
        rw >= 1 && rh >= 1 && rw + 2 <= res.scratch.width && rh + 2 <= res.scratch.height,
        "a cache of {rw}x{rh} does not fit the {}x{} view",
        camera.width,
        camera.height
    );
    ensure!(
        job.block.x + rw + 2 <= res.atlas_side && job.block.y + rh + 2 <= res.atlas_side,
        "cache block {:?} does not hold {rw}x{rh} in a {} atlas",
        job.block,
        res.atlas_side
    );
    let items = cut
        .job_items
        .get(job.items.clone())
        .context("a cache's items out of range")?;
    let mut seq = Sequence::default();
    pack(gpu, pipes, Some(res), input, items, &mut seq);
    // The rectangle's centre and scale in normalized device coordinates.
    let cx = (f64::from(x) + f64::from(rw) * 0.5) / w * 2.0 - 1.0;
    let cy = 1.0 - (f64::from(y) + f64::from(rh) * 0.5) / hgt * 2.0;
    let (sx, sy) = (w / f64::from(rw), hgt / f64::from(rh));
    let window = [sx, sy, -cx * sx, -cy * sy].map(|v| v as f32);
    let view = camera.view(1.0);
    let near = near_plane_of(seq.depths.iter().copied());
    let uniform = GeometryUniform::new(&view, near, window);
    gpu.queue
        .write_buffer(&pipes.uniform, 0, bytemuck::bytes_of(&uniform));
    upload_sequence(gpu, pipes, Some(res), &seq);
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("farfield make cache"),
        });
    {
        let mut pass = res.scratch_pass(&mut encoder);
        pass.set_viewport(1.0, 1.0, rw as f32, rh as f32, 0.0, 1.0);
        pass.set_scissor_rect(1, 1, rw, rh);
        encode(&mut pass, pipes, Some(res), &seq, QuadLook::Plain);
    }
    res.copy_to_atlas(&mut encoder, (job.block.x, job.block.y), rw + 2, rh + 2);
    // Submitted now: the next cache rewrites the uniform and buffers.
    gpu.queue.submit([encoder.finish()]);
    res.held.insert((job.block.x, job.block.y), job.serial);
    Ok(())
}
