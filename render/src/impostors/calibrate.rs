//! The cost model's constants, measured on this machine at start-up (the
//! paper's "established experimentally on each platform"): drawing
//! triangles, making a cache (a cleared pass the size of the view and a
//! copy of its pixels into the atlas) and drawing cached quads (by count,
//! and by the pixels they cover), each timed to the GPU's completion at
//! two sizes, the difference giving the cost per unit and the smaller the
//! fixed part. Medians of three runs; a slope the noise makes negative
//! is floored, never zero (`UpdateNode` divides nothing by it, but a free
//! triangle would make every cache look too dear).
//!
//! Native only: a browser may not wait for its GPU, so there the model
//! stays [`CostModel::UNMEASURED`] and says so.

use farfield_protocol::camera::Camera;
use farfield_traverse::impostors::CostModel;
use glam::DVec3;
use web_time::Instant;

use super::ImpostorResources;
use super::pack::{GpuQuad, QuadLook, Sequence, Step, encode, upload_sequence};
use crate::geometry::GeometryUniform;
use crate::{GpuVertex, Renderer};

/// The smallest side of the calibration frame, pixels (it is the view's
/// size when that is larger: a cache's pass clears a frame that size).
const SIDE: u32 = 254;
/// The smallest cost per unit kept.
const FLOOR: f64 = 1e-9;

impl Renderer {
    /// Measures the image cache's cost model on this renderer's device.
    pub fn measure_impostor_costs(&mut self) -> anyhow::Result<CostModel> {
        if cfg!(target_arch = "wasm32") {
            return Ok(CostModel::UNMEASURED);
        }
        let format = self.output_format();
        let (width, height) = self.size();
        let (width, height) = (width.max(SIDE), height.max(SIDE));
        let (gpu, pipes, _, _) = self.impostor_parts()?;
        let mut res = ImpostorResources::new(&gpu.device, pipes, format, 512, (width, height))?;
        // At depth 10 with a 90 degree field, a world unit is this many
        // pixels, across and down.
        let px_per_unit = f64::from(height + 2) / 20.0;
        let camera = Camera {
            eye: DVec3::ZERO,
            target: DVec3::NEG_Z,
            up: DVec3::Y,
            fov_y_deg: 90.0,
            width: width + 2,
            height: height + 2,
        };
        let view = camera.view(1.0);
        let uniform = GeometryUniform::new(&view, 1.0, crate::geometry::WHOLE_VIEW);
        gpu.queue
            .write_buffer(&pipes.uniform, 0, bytemuck::bytes_of(&uniform));
        let mut time = |seq: &Sequence, copy: u32| -> f64 {
            upload_sequence(gpu, pipes, Some(&mut res), seq);
            let mut runs = [0.0f64; 3];
            for run in &mut runs {
                let started = Instant::now();
                let mut encoder = gpu.device.create_command_encoder(&Default::default());
                {
                    let mut pass = res.scratch_pass(&mut encoder);
                    encode(&mut pass, pipes, Some(&res), seq, QuadLook::Plain);
                }
                if copy > 0 {
                    res.copy_to_atlas(&mut encoder, (0, 0), copy, copy);
                }
                gpu.queue.submit([encoder.finish()]);
                let _ = gpu.device.poll(wgpu::PollType::wait_indefinitely());
                *run = started.elapsed().as_secs_f64() * 1e3;
            }
            runs.sort_by(f64::total_cmp);
            runs[1]
        };
        let triangles = |n: u32| {
            let mut seq = Sequence::default();
            for i in 0..n {
                // Small triangles scattered over the view at depth 10.
                // Scattered by two primes; in u64, so 200,000 of them
                // cannot overflow.
                let i = u64::from(i);
                let x = f32::from((i * 7919 % 200) as u16) * 0.08 - 8.0;
                let y = f32::from((i * 104_729 % 200) as u16) * 0.08 - 8.0;
                for (dx, dy) in [(0.0, 0.0), (0.15, 0.0), (0.0, 0.15)] {
                    seq.vertices.push(GpuVertex {
                        position: [x + dx, y + dy, -10.0],
                        normal: [0; 4],
                        color: [200, 150, 100, 255],
                    });
                }
            }
            seq.steps.push(Step::Triangles(0..n * 3));
            seq
        };
        // `n` square quads of `side` world units, scattered in the view.
        let quads = |n: u32, side: f32| {
            let mut seq = Sequence::default();
            let span = (16.0 - side).max(0.0) / 120.0;
            for i in 0..n {
                let x = (i * 37 % 120) as f32 * span - 8.0;
                let y = (i * 53 % 120) as f32 * span - 8.0;
                let c = |dx: f32, dy: f32| [x + dx, y + dy, -10.0];
                seq.quads.push(GpuQuad {
                    corners: [c(0.0, side), c(side, side), c(0.0, 0.0), c(side, 0.0)],
                    uv: [0.0, 0.0, 0.1, 0.1],
                });
                seq.steps.push(Step::Quad(i));
            }
            seq
        };
        let (few, many) = (20_000u32, 200_000u32);
        let per_triangle =
            (time(&triangles(many), 0) - time(&triangles(few), 0)) / f64::from(many - few);
        let empty = Sequence::default();
        let (small, large) = (16u32, SIDE + 2);
        let cache_small = time(&empty, small);
        let cache_large = time(&empty, large);
        let per_pixel = (cache_large - cache_small) / f64::from(large * large - small * small);
        let (q_few, q_many, small_side) = (200u32, 2000u32, 0.6f32);
        let per_quad = (time(&quads(q_many, small_side), 0) - time(&quads(q_few, small_side), 0))
            / f64::from(q_many - q_few);
        // The same count of quads, small and large: the difference is fill.
        let large_side = 6.0f32;
        let area = |side: f32| (f64::from(side) * px_per_unit).powi(2);
        let per_quad_pixel = (time(&quads(q_few, large_side), 0)
            - time(&quads(q_few, small_side), 0))
            / (f64::from(q_few) * (area(large_side) - area(small_side)));
        Ok(CostModel {
            ms_per_triangle: per_triangle.max(FLOOR),
            ms_per_cache_pixel: per_pixel.max(FLOOR),
            ms_per_cache: cache_small.max(FLOOR),
            ms_per_quad: per_quad.max(FLOOR),
            ms_per_quad_pixel: per_quad_pixel.max(FLOOR),
            measured: true,
        })
    }
}
