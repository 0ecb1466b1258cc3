//! The clipping box (Potree's): splats whose centers are outside it (or,
//! kept outside, inside it) are not drawn, so a building's inside or a
//! slice of terrain shows. The box is given as fractions of the scene's
//! bounds, so a link keeps it for any scene, and becomes world units
//! where the renderer meets the hierarchy.

use glam::DVec3;

/// Which side of the box is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Keep {
    Inside,
    Outside,
}

/// A clipping box: `lo` and `hi` as fractions of the scene's bounds (0 to
/// 1 on each axis) until [`Clip::in_bounds`] makes them world units.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clip {
    pub lo: DVec3,
    pub hi: DVec3,
    pub keep: Keep,
    /// `lo` and `hi` are world units.
    pub world: bool,
}

impl Clip {
    /// A box of fractions of the scene's bounds.
    pub fn fractions(lo: DVec3, hi: DVec3, keep: Keep) -> Self {
        Self {
            lo: lo.min(hi),
            hi: hi.max(lo),
            keep,
            world: false,
        }
    }

    /// A box of fractions from [`parse_box`]'s six numbers.
    pub fn from_corners([x0, y0, z0, x1, y1, z1]: [f64; 6], keep: Keep) -> Self {
        Self::fractions(DVec3::new(x0, y0, z0), DVec3::new(x1, y1, z1), keep)
    }

    /// The box in world units for a scene within `min`..`max`.
    pub fn in_bounds(self, min: DVec3, max: DVec3) -> Self {
        if self.world {
            return self;
        }
        let at = |f: DVec3| min + (max - min) * f;
        Self {
            lo: at(self.lo),
            hi: at(self.hi),
            world: true,
            ..self
        }
    }

    /// Whether a splat centered at `p` is drawn (a box not yet in world
    /// units draws everything).
    pub fn keeps(&self, p: DVec3) -> bool {
        if !self.world {
            return true;
        }
        let inside = p.cmpge(self.lo).all() && p.cmple(self.hi).all();
        inside == (self.keep == Keep::Inside)
    }
}

/// `x0,y0,z0,x1,y1,z1`: a box's corners as fractions of the scene's
/// bounds, each from 0 to 1.
pub fn parse_box(text: &str) -> Result<[f64; 6], String> {
    let values: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|_| format!("clip box {text}: not six numbers"))?;
    let corners: [f64; 6] = values
        .try_into()
        .map_err(|_| format!("clip box {text}: not six numbers"))?;
    if corners.iter().any(|v| !(0.0..=1.0).contains(v)) {
        return Err(format!(
            "clip box {text}: each number is a share of the scene, 0 to 1"
        ));
    }
    Ok(corners)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_of_fractions_keeps_its_side_of_the_scene() {
        let clip = Clip::fractions(DVec3::new(0.0, 0.0, 0.5), DVec3::ONE, Keep::Inside)
            .in_bounds(DVec3::splat(-10.0), DVec3::splat(10.0));
        assert_eq!((clip.lo.z, clip.hi.z), (0.0, 10.0));
        assert!(clip.keeps(DVec3::new(-9.0, 9.0, 1.0)));
        assert!(!clip.keeps(DVec3::new(0.0, 0.0, -1.0)));
        let out = Clip {
            keep: Keep::Outside,
            ..clip
        };
        assert!(!out.keeps(DVec3::new(-9.0, 9.0, 1.0)));
        assert!(out.keeps(DVec3::new(0.0, 0.0, -1.0)));
        // Corners given in any order make the same box.
        let swapped = Clip::fractions(DVec3::ONE, DVec3::new(0.0, 0.0, 0.5), Keep::Inside);
        assert_eq!(swapped.lo, DVec3::new(0.0, 0.0, 0.5));
        assert_eq!(
            parse_box("0,0,0.5,1,1,1"),
            Ok([0.0, 0.0, 0.5, 1.0, 1.0, 1.0])
        );
        assert!(parse_box("0,0,0,1,1").is_err());
        assert!(parse_box("0,0,0,1,1,2").is_err());
        assert!(parse_box("0,0,0,1,1,x").is_err());
    }
}
