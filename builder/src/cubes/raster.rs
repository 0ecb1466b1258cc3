//! Leaf color-cubes: the cell's clipped triangles rendered orthographically
//! through each of the six faces and averaged (Chamberlain et al. 1996,
//! section 4; 1995, section 4.1).
//!
//! Each face is a grid of `samples x samples` points per cube (4 x 4
//! pixels of 4 x 4 samples by default: the papers' small image, with
//! antialiased coverage). A sample takes the nearest triangle behind it,
//! shaded with the client's fixed light ([`shading`]), and the face is
//! the mean over its samples of premultiplied RGBA, uncovered samples
//! counting as transparent black: alpha is the covered share. With a
//! `k x k x k` cluster the grid is `k` times finer and keeps the nearest
//! hit per depth slab, so every sub-cube sees only the geometry inside it.
//!
//! [`shading`]: farfield_protocol::shading

use farfield_protocol::cube_codec::Face;
use farfield_protocol::shading::shade;
use glam::{DVec3, Vec3};

use super::composite::{Faces, SubCubes};
use super::source::Triangle;

/// A leaf's cube and, when clustered, its non-empty sub-cubes.
#[derive(Debug, Clone, PartialEq)]
pub struct LeafCubes {
    pub whole: Faces,
    pub sub: SubCubes,
}

/// Renders the leaf cell `[min, min + edge]` holding `tris` (already
/// clipped to it): `k` sub-cubes per edge, `samples` per cube face edge.
pub fn leaf_cubes(tris: &[Triangle], min: DVec3, edge: f64, k: usize, samples: usize) -> LeafCubes {
    let k = k.max(1);
    let n = samples.max(1);
    let g = k * n;
    let mut whole = [[0.0f32; 4]; 6];
    let mut sub: Vec<[[f32; 4]; 6]> = vec![[[0.0; 4]; 6]; if k > 1 { k * k * k } else { 0 }];
    // Nearest hit per sample and depth slab: (depth, shaded color).
    let mut hits: Vec<(f64, Vec3)> = vec![(f64::INFINITY, Vec3::ZERO); g * g * k];
    for face in Face::ALL {
        hits.fill((f64::INFINITY, Vec3::ZERO));
        let a = face.axis();
        let (u, v) = ((a + 1) % 3, (a + 2) % 3);
        let toward_viewer = face.normal().as_vec3();
        let scale = g as f64 / edge;
        for tri in tris {
            let p = tri.map(|c| {
                let rel = c.position - min;
                let depth = if face.positive() {
                    edge - rel[a]
                } else {
                    rel[a]
                };
                (rel[u] * scale, rel[v] * scale, depth)
            });
            let area =
                (p[1].0 - p[0].0) * (p[2].1 - p[0].1) - (p[2].0 - p[0].0) * (p[1].1 - p[0].1);
            if area == 0.0 {
                continue; // edge-on through this face
            }
            let geometric = {
                let [x, y, z] = tri.map(|c| c.position);
                (y - x).cross(z - x).as_vec3()
            };
            let lo = |i: usize| {
                p.iter()
                    .map(|q| [q.0, q.1][i])
                    .fold(f64::INFINITY, f64::min)
            };
            let hi = |i: usize| {
                p.iter()
                    .map(|q| [q.0, q.1][i])
                    .fold(f64::NEG_INFINITY, f64::max)
            };
            let range = |l: f64, h: f64| {
                let first = (l - 0.5).ceil().max(0.0) as usize;
                let last = ((h - 0.5).floor().min(g as f64 - 1.0)).max(-1.0);
                first..(last + 1.0) as usize
            };
            for j in range(lo(1), hi(1)) {
                let y = j as f64 + 0.5;
                for i in range(lo(0), hi(0)) {
                    let x = i as f64 + 0.5;
                    let w = |s: usize, t: usize| {
                        (p[t].0 - p[s].0) * (y - p[s].1) - (p[t].1 - p[s].1) * (x - p[s].0)
                    };
                    let (w0, w1, w2) = (w(1, 2), w(2, 0), w(0, 1));
                    let inside = (w0 >= 0.0 && w1 >= 0.0 && w2 >= 0.0)
                        || (w0 <= 0.0 && w1 <= 0.0 && w2 <= 0.0);
                    if !inside {
                        continue;
                    }
                    let b = [w0 / area, w1 / area, w2 / area];
                    let depth = b[0] * p[0].2 + b[1] * p[1].2 + b[2] * p[2].2;
                    let slab = ((depth / edge * k as f64).floor().max(0.0) as usize).min(k - 1);
                    let slot = &mut hits[(j * g + i) * k + slab];
                    if depth < slot.0 {
                        let bf = b.map(|x| x as f32);
                        let base =
                            tri[0].color * bf[0] + tri[1].color * bf[1] + tri[2].color * bf[2];
                        let normal = match (tri[0].normal, tri[1].normal, tri[2].normal) {
                            (Some(n0), Some(n1), Some(n2)) => n0 * bf[0] + n1 * bf[1] + n2 * bf[2],
                            _ => geometric,
                        };
                        *slot = (depth, shade(base, normal, toward_viewer));
                    }
                }
            }
        }
        // The whole cube: the nearest hit of any slab.
        let mut sum = [0.0f64; 4];
        for sample in hits.chunks_exact(k) {
            if let Some(h) = sample
                .iter()
                .filter(|h| h.0.is_finite())
                .min_by(|x, y| x.0.total_cmp(&y.0))
            {
                sum[0] += f64::from(h.1.x);
                sum[1] += f64::from(h.1.y);
                sum[2] += f64::from(h.1.z);
                sum[3] += 1.0;
            }
        }
        let count = (g * g) as f64;
        whole[face.index()] = sum.map(|s| (s / count) as f32);
        if k > 1 {
            for (cell, faces) in sub.iter_mut().enumerate() {
                let c = [cell % k, (cell / k) % k, cell / (k * k)];
                let slab = if face.positive() { k - 1 - c[a] } else { c[a] };
                let mut sum = [0.0f64; 4];
                for j in c[v] * n..(c[v] + 1) * n {
                    for i in c[u] * n..(c[u] + 1) * n {
                        let h = hits[(j * g + i) * k + slab];
                        if h.0.is_finite() {
                            sum[0] += f64::from(h.1.x);
                            sum[1] += f64::from(h.1.y);
                            sum[2] += f64::from(h.1.z);
                            sum[3] += 1.0;
                        }
                    }
                }
                faces[face.index()] = sum.map(|s| (s / (n * n) as f64) as f32);
            }
        }
    }
    let sub = sub
        .into_iter()
        .enumerate()
        .filter(|(_, f)| f.iter().any(|rgba| rgba[3] > 0.0))
        .map(|(i, f)| (i as u16, f))
        .collect();
    LeafCubes { whole, sub }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cubes::source::Corner;

    fn quad_x(x: f64, color: Vec3) -> Vec<Triangle> {
        // A square filling the cell's y-z extent at x, normal +x.
        let c = |y: f64, z: f64| Corner {
            position: DVec3::new(x, y, z),
            normal: Some(Vec3::X),
            color,
        };
        vec![
            [c(0.0, 0.0), c(1.0, 0.0), c(1.0, 1.0)],
            [c(0.0, 0.0), c(1.0, 1.0), c(0.0, 1.0)],
        ]
    }

    #[test]
    fn an_axis_aligned_quad_colors_the_two_faces_that_see_it() {
        let color = Vec3::new(0.8, 0.4, 0.2);
        let cubes = leaf_cubes(&quad_x(0.3, color), DVec3::ZERO, 1.0, 1, 16);
        let lit = shade(color, Vec3::X, Vec3::X);
        for face in [Face::PosX, Face::NegX] {
            let f = cubes.whole[face.index()];
            assert!((f[3] - 1.0).abs() < 1e-6, "{face:?} coverage {}", f[3]);
            let expect = shade(color, Vec3::X, face.normal().as_vec3());
            assert!(
                (Vec3::new(f[0], f[1], f[2]) - expect).length() < 1e-5,
                "{face:?}"
            );
        }
        // From +x the quad's lit side shows; from -x its other side, whose
        // normal turns away from the light: ambient only.
        assert!((Vec3::from_slice(&cubes.whole[0][..3]) - lit).length() < 1e-5);
        let ambient = color * farfield_protocol::shading::AMBIENT;
        assert!((Vec3::from_slice(&cubes.whole[1][..3]) - ambient).length() < 1e-5);
        for face in [Face::PosY, Face::NegY, Face::PosZ, Face::NegZ] {
            assert_eq!(cubes.whole[face.index()], [0.0; 4], "{face:?} is edge-on");
        }
    }

    #[test]
    fn coverage_is_the_covered_share_and_clusters_see_their_own_slab() {
        // Half the cell's y extent covered: alpha one half.
        let c = |y: f64, z: f64| Corner {
            position: DVec3::new(0.7, y, z),
            normal: None,
            color: Vec3::ONE,
        };
        let half = vec![
            [c(0.0, 0.0), c(0.5, 0.0), c(0.5, 1.0)],
            [c(0.0, 0.0), c(0.5, 1.0), c(0.0, 1.0)],
        ];
        let cubes = leaf_cubes(&half, DVec3::ZERO, 1.0, 2, 8);
        assert!((cubes.whole[Face::PosX.index()][3] - 0.5).abs() < 1e-6);
        // 2x2x2: only sub-cubes with x = 1 (the quad is at 0.7) and y = 0.
        let cells: Vec<u16> = cubes.sub.iter().map(|s| s.0).collect();
        assert_eq!(cells, vec![1, 5]);
        for (_, f) in &cubes.sub {
            assert!((f[Face::PosX.index()][3] - 1.0).abs() < 1e-6);
        }
    }
}
