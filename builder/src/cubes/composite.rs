//! Interior color-cubes from their children (1996, section 4, Figure 3):
//! per face, the four children in front are composited over the four
//! behind, then the four results are averaged.
//!
//! Two ways to composite, both premultiplied:
//! - [`Composite::Over`], Porter and Duff's over (the 1996 paper);
//! - [`Composite::Disjoint`], the 1995 report's variant, which assumes the
//!   front and back coverages overlap as little as possible, so two halves
//!   of one opaque surface add up to an opaque face instead of 3/4: opaque
//!   surfaces stay opaque at coarse levels. The default.

use farfield_protocol::cube_codec::Face;

/// Premultiplied RGBA of the six faces, in [`Face::ALL`] order.
pub type Faces = [[f32; 4]; 6];

/// Sub-cubes of a cluster that are not empty: (index in the cluster, faces),
/// sorted by index.
pub type SubCubes = Vec<(u16, Faces)>;

/// How a front face is combined with the face behind it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Composite {
    /// Porter-Duff over: `front + back * (1 - front alpha)`.
    Over,
    /// Coverage assumed disjoint: the back adds as much as fits.
    #[default]
    Disjoint,
}

impl std::str::FromStr for Composite {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "over" => Ok(Self::Over),
            "disjoint" => Ok(Self::Disjoint),
            _ => Err(format!("composite must be over or disjoint, not {s}")),
        }
    }
}

/// `front` composited over `back`, premultiplied.
pub fn over(front: [f32; 4], back: [f32; 4], mode: Composite) -> [f32; 4] {
    let af = front[3].clamp(0.0, 1.0);
    let share = match mode {
        Composite::Over => 1.0 - af,
        Composite::Disjoint => {
            let ab = back[3];
            if ab <= 0.0 {
                0.0
            } else {
                // The fraction of the back that fits beside the front.
                (1.0 - af).min(ab) / ab
            }
        }
    };
    std::array::from_fn(|i| front[i] + back[i] * share)
}

/// The faces of a cube made of 2 x 2 x 2 cubes; `eight[o]` is the cube in
/// octant `o` (bit 0: upper x, bit 1: y, bit 2: z), `None` when empty.
pub fn combine(eight: &[Option<&Faces>; 8], mode: Composite) -> Faces {
    let empty = [0.0f32; 4];
    let mut out = [[0.0f32; 4]; 6];
    for face in Face::ALL {
        let bit = 1u8 << face.axis();
        let mut sum = [0.0f32; 4];
        for lower in (0..8u8).filter(|o| o & bit == 0) {
            let (front, back) = if face.positive() {
                (lower | bit, lower)
            } else {
                (lower, lower | bit)
            };
            let get = |o: u8| eight[o as usize].map_or(empty, |f| f[face.index()]);
            let c = over(get(front), get(back), mode);
            for i in 0..4 {
                sum[i] += c[i];
            }
        }
        out[face.index()] = sum.map(|s| s * 0.25);
    }
    out
}

/// A parent's cluster from its children's: parent sub-cube (x, y, z) of a
/// `k`-cluster covers child octant (2x / k, 2y / k, 2z / k) and there the
/// 2 x 2 x 2 child sub-cubes from (2x mod k, ...). `children[o]` is the
/// cluster of the child in octant `o`.
pub fn combine_clusters(children: &[Option<&SubCubes>; 8], k: usize, mode: Composite) -> SubCubes {
    let mut out = Vec::new();
    let find = |cluster: &SubCubes, cell: usize| {
        cluster
            .binary_search_by_key(&(cell as u16), |s| s.0)
            .ok()
            .map(|i| cluster[i].1)
    };
    for cell in 0..k * k * k {
        let c = [cell % k, (cell / k) % k, cell / (k * k)];
        let octant = (0..3).fold(0u8, |o, a| o | (u8::from(2 * c[a] >= k) << a));
        let Some(child) = children[octant as usize] else {
            continue;
        };
        let mut eight: [Option<Faces>; 8] = [None; 8];
        for (o, slot) in eight.iter_mut().enumerate() {
            let s: [usize; 3] = std::array::from_fn(|a| (2 * c[a]) % k + ((o >> a) & 1));
            *slot = find(child, s[0] + k * (s[1] + k * s[2]));
        }
        if eight.iter().all(Option::is_none) {
            continue;
        }
        let refs: [Option<&Faces>; 8] = std::array::from_fn(|o| eight[o].as_ref());
        let faces = combine(&refs, mode);
        if faces.iter().any(|f| f[3] > 0.0) {
            out.push((cell as u16, faces));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn solid(rgb: [f32; 3], alpha: f32) -> [f32; 4] {
        [rgb[0] * alpha, rgb[1] * alpha, rgb[2] * alpha, alpha]
    }

    #[test]
    fn over_and_disjoint_on_known_values() {
        let red_half = solid([1.0, 0.0, 0.0], 0.5);
        let blue_half = solid([0.0, 0.0, 1.0], 0.5);
        // Over: 0.5 + 0.5 * 0.5 = 0.75 coverage, blue weighted 0.25.
        let o = over(red_half, blue_half, Composite::Over);
        assert_eq!(o, [0.5, 0.0, 0.25, 0.75]);
        // Disjoint: the two halves side by side cover everything.
        let d = over(red_half, blue_half, Composite::Disjoint);
        assert_eq!(d, [0.5, 0.0, 0.5, 1.0]);
        // An opaque front hides the back either way.
        let opaque = solid([0.0, 1.0, 0.0], 1.0);
        for mode in [Composite::Over, Composite::Disjoint] {
            assert_eq!(over(opaque, blue_half, mode), opaque);
            // An empty back adds nothing; an empty front lets the back through.
            assert_eq!(over(red_half, [0.0; 4], mode), red_half);
            assert_eq!(over([0.0; 4], blue_half, mode), blue_half);
        }
        // Disjoint never exceeds full coverage.
        let d = over(
            solid([1.0; 3], 0.8),
            solid([1.0; 3], 0.7),
            Composite::Disjoint,
        );
        assert!((d[3] - 1.0).abs() < 1e-6 && d[0] <= 1.0 + 1e-6);
    }

    #[test]
    fn combining_children_front_over_back_then_averaging() {
        // Child octant 1 (upper x, lower y, lower z) opaque white on +x;
        // octant 0 behind it opaque black; everything else empty.
        let mut white = [[0.0; 4]; 6];
        white[Face::PosX.index()] = [1.0; 4];
        let mut black = [[0.0; 4]; 6];
        black[Face::PosX.index()] = [0.0, 0.0, 0.0, 1.0];
        let mut eight: [Option<&Faces>; 8] = [None; 8];
        eight[1] = Some(&white);
        eight[0] = Some(&black);
        let f = combine(&eight, Composite::Disjoint);
        // Only one of four quadrants is covered, by the white front.
        assert_eq!(f[Face::PosX.index()], [0.25, 0.25, 0.25, 0.25]);
        // An empty child adds nothing: the same without octant 7 present.
        let empty = [[0.0; 4]; 6];
        eight[7] = Some(&empty);
        assert_eq!(combine(&eight, Composite::Disjoint), f);
        // From -x the black cube is in front.
        assert_eq!(f[Face::NegX.index()], [0.0; 4]);
    }

    #[test]
    fn clusters_combine_the_child_sub_cubes_under_each_parent_sub_cube() {
        // k = 2: parent sub-cube 0 covers child octant 0, all 8 of its
        // sub-cubes. Only child sub-cube 7 (upper x, y, z) has a face.
        let mut faces = [[0.0; 4]; 6];
        faces[Face::PosX.index()] = [1.0; 4];
        let child: SubCubes = vec![(7, faces)];
        let mut children: [Option<&SubCubes>; 8] = [None; 8];
        children[0] = Some(&child);
        let parent = combine_clusters(&children, 2, Composite::Disjoint);
        assert_eq!(parent.len(), 1);
        assert_eq!(parent[0].0, 0);
        assert_eq!(parent[0].1[Face::PosX.index()], [0.25; 4]);
        // The same child in octant 7 lands in parent sub-cube 7.
        children[0] = None;
        children[7] = Some(&child);
        let parent = combine_clusters(&children, 2, Composite::Disjoint);
        assert_eq!(parent.iter().map(|s| s.0).collect::<Vec<_>>(), vec![7]);
    }
}
