//! Assigning the primitives to the cells (section 3.1): "each of these
//! primitives is either completely contained in c_i, or it intersects one
//! of its boundary faces", so a triangle belongs to every cell it meets.
//!
//! The paper scan-converts the geometry into the mesh. Here each triangle
//! starts at the cell holding its centroid (a walk from the last
//! triangle's cell, which input order keeps near) and spreads over face
//! neighbours while they intersect it: the cells a convex triangle meets
//! are face-connected. The intersection test is the separating-axis test
//! of a triangle and a tetrahedron, which counts touching as meeting, so a
//! triangle lying in a shared face belongs to both sides (never to none).

use glam::DVec3;
use rayon::prelude::*;

use super::delaunay::{NONE, Tetrahedralization, face, locate};

/// The cells each triangle meets, ascending.
pub fn assign(t: &Tetrahedralization, triangles: &[[DVec3; 3]]) -> Result<Vec<Vec<u32>>, String> {
    // Chunks keep the walk's locality (input order) and run in parallel.
    const CHUNK: usize = 4096;
    let chunks: Vec<Result<Vec<Vec<u32>>, String>> = triangles
        .par_chunks(CHUNK)
        .map(|chunk| {
            let mut last = 0u32;
            // Per cell, the triangle (numbered from 1 in this chunk) that
            // last looked at it: a large triangle meets thousands of cells.
            let mut seen = vec![0u32; t.cells.len()];
            let mut out = Vec::with_capacity(chunk.len());
            for (k, tri) in chunk.iter().enumerate() {
                let mark = k as u32 + 1;
                let centroid = (tri[0] + tri[1] + tri[2]) / 3.0;
                let start = locate(t, centroid, last)?;
                last = start;
                let mut cells = vec![start];
                seen[start as usize] = mark;
                let mut next = 0;
                while next < cells.len() {
                    let c = cells[next];
                    next += 1;
                    for &n in &t.neighbours[c as usize] {
                        if n == NONE || seen[n as usize] == mark {
                            continue;
                        }
                        seen[n as usize] = mark;
                        if meets(t, n, tri) {
                            cells.push(n);
                        }
                    }
                }
                cells.sort_unstable();
                out.push(cells);
            }
            Ok(out)
        })
        .collect();
    let mut out = Vec::with_capacity(triangles.len());
    for chunk in chunks {
        out.extend(chunk?);
    }
    Ok(out)
}

/// Whether triangle `tri` meets cell `c` (touching counts).
pub fn meets(t: &Tetrahedralization, c: u32, tri: &[DVec3; 3]) -> bool {
    let cell = t.cells[c as usize];
    let v = cell.map(|i| t.points[i as usize]);
    // A little slack, relative to the sizes involved, so rounding never
    // separates what touches: a triangle may land in one cell too many,
    // never in one too few.
    let scale = v
        .iter()
        .chain(tri)
        .fold(0.0f64, |m, p| m.max(p.abs().max_element()));
    let slack = 1e-9 * scale.max(f64::MIN_POSITIVE);
    let separated = |axis: DVec3| -> bool {
        let len = axis.length();
        if len.is_nan() || len <= 1e-300 {
            return false;
        }
        let axis = axis / len;
        let (lo_t, hi_t) = span(tri.iter(), axis);
        let (lo_c, hi_c) = span(v.iter(), axis);
        hi_t < lo_c - slack || hi_c < lo_t - slack
    };
    let tri_normal = (tri[1] - tri[0]).cross(tri[2] - tri[0]);
    if separated(tri_normal) {
        return false;
    }
    for i in 0..4 {
        let [a, b, cc] = face(cell, i).map(|k| t.points[k as usize]);
        if separated((b - a).cross(cc - a)) {
            return false;
        }
    }
    let tri_edges = [tri[1] - tri[0], tri[2] - tri[1], tri[0] - tri[2]];
    let cell_edges = [
        v[1] - v[0],
        v[2] - v[0],
        v[3] - v[0],
        v[2] - v[1],
        v[3] - v[1],
        v[3] - v[2],
    ];
    for e in tri_edges {
        for f in cell_edges {
            if separated(e.cross(f)) {
                return false;
            }
        }
    }
    true
}

fn span<'a>(points: impl Iterator<Item = &'a DVec3>, axis: DVec3) -> (f64, f64) {
    points.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
        let d = p.dot(axis);
        (lo.min(d), hi.max(d))
    })
}

#[cfg(test)]
mod tests {
    use super::super::delaunay::tetrahedralize;
    use super::*;

    fn grid_points(n: u32) -> Vec<DVec3> {
        (0..n * n * n)
            .map(|i| {
                let (x, y, z) = (i % n, i / n % n, i / n / n);
                // Jittered so nothing is degenerate, deterministic.
                let j = f64::from(i.wrapping_mul(2_654_435_761) % 1000) * 1e-5;
                (DVec3::new(f64::from(x), f64::from(y), f64::from(z)) + 0.5 + j) / f64::from(n)
            })
            .collect()
    }

    #[test]
    fn a_small_triangle_is_in_the_cell_that_contains_it_and_a_huge_one_in_many() {
        let t =
            tetrahedralize(DVec3::splat(-0.1), DVec3::splat(1.1), &grid_points(4)).expect("builds");
        let small = [
            DVec3::new(0.30, 0.30, 0.30),
            DVec3::new(0.3001, 0.30, 0.30),
            DVec3::new(0.30, 0.3001, 0.30),
        ];
        let huge = [
            DVec3::new(-0.05, -0.05, 0.5),
            DVec3::new(1.05, -0.05, 0.5),
            DVec3::new(-0.05, 1.05, 0.5),
        ];
        let cells = assign(&t, &[small, huge]).expect("assigns");
        assert!(
            !cells[0].is_empty() && cells[0].len() <= 4,
            "{:?}",
            cells[0]
        );
        assert!(cells[1].len() > 20, "{} cells", cells[1].len());
        // Every cell the brute force finds is found by the spread, and
        // the other way round.
        for (tri, found) in [small, huge].iter().zip(&cells) {
            let brute: Vec<u32> = (0..t.cells.len() as u32)
                .filter(|&c| meets(&t, c, tri))
                .collect();
            assert_eq!(&brute, found);
        }
    }

    #[test]
    fn separated_and_touching_are_told_apart() {
        let t = tetrahedralize(DVec3::splat(-1.0), DVec3::splat(1.0), &[]).expect("box");
        // A triangle far outside every cell of the box meets none.
        let outside = [
            DVec3::splat(5.0),
            DVec3::new(6.0, 5.0, 5.0),
            DVec3::new(5.0, 6.0, 5.0),
        ];
        assert!((0..t.cells.len() as u32).all(|c| !meets(&t, c, &outside)));
        // One lying on the box's face touches the cells below it.
        let on_face = [
            DVec3::new(-0.5, -0.5, 1.0),
            DVec3::new(0.5, -0.5, 1.0),
            DVec3::new(-0.5, 0.5, 1.0),
        ];
        assert!((0..t.cells.len() as u32).any(|c| meets(&t, c, &on_face)));
    }
}
