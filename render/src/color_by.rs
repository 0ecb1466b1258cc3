//! What colors a splat: its own RGB, or its height on a ramp (Potree's
//! elevation colouring, what a lidar user looks at first when a cloud
//! has no colour, or to read terrain).

use glam::DVec3;

/// What colors a splat.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum ColorBy {
    /// The splat's color (or [`crate::DEFAULT_COLOR`]).
    #[default]
    Rgb,
    /// Its height (world Z) on [`RAMP`], from `low` to `high`; the scene's
    /// bounds when `None` (the renderer knows them when it draws).
    Elevation(Option<[f64; 2]>),
}

impl ColorBy {
    /// Every mode, in the order a panel lists them.
    pub const ALL: [ColorBy; 2] = [ColorBy::Rgb, ColorBy::Elevation(None)];

    /// Its name on command lines and in links.
    pub fn name(self) -> &'static str {
        match self {
            ColorBy::Rgb => "rgb",
            ColorBy::Elevation(_) => "elevation",
        }
    }

    /// The mode of that name (an elevation over the scene's bounds).
    pub fn from_name(name: &str) -> Option<ColorBy> {
        ColorBy::ALL.into_iter().find(|c| c.name() == name)
    }

    /// The mode with the scene's height range filled in where it is not
    /// given.
    pub fn for_bounds(self, min: DVec3, max: DVec3) -> ColorBy {
        match self {
            ColorBy::Elevation(None) => ColorBy::Elevation(Some([min.z, max.z])),
            other => other,
        }
    }

    /// The color of a splat at `center` whose own color is `rgb`.
    pub(crate) fn color(self, center: DVec3, rgb: [u8; 3]) -> [u8; 3] {
        match self {
            ColorBy::Rgb | ColorBy::Elevation(None) => rgb,
            ColorBy::Elevation(Some([low, high])) => {
                let span = high - low;
                // A flat scene (or a range given backwards) sits mid-ramp.
                let t = if span > 0.0 && span.is_finite() {
                    (center.z - low) / span
                } else {
                    0.5
                };
                ramp(t)
            }
        }
    }
}

/// The elevation ramp, low to high: ColorBrewer's Spectral, from violet
/// blue through yellow to dark red (Potree's default gradient).
pub const RAMP: [[u8; 3]; 11] = [
    [94, 79, 162],
    [50, 136, 189],
    [102, 194, 165],
    [171, 221, 164],
    [230, 245, 152],
    [255, 255, 191],
    [254, 224, 139],
    [253, 174, 97],
    [244, 109, 67],
    [213, 62, 79],
    [158, 1, 66],
];

/// The ramp's color at `t` (0 low, 1 high; clamped, NaN low).
pub fn ramp(t: f64) -> [u8; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let x = t * (RAMP.len() - 1) as f64;
    let i = (x.floor() as usize).min(RAMP.len() - 2);
    let f = x - i as f64;
    let (a, b) = (RAMP[i], RAMP[i + 1]);
    [0, 1, 2].map(|c| (f64::from(a[c]) + (f64::from(b[c]) - f64::from(a[c])) * f).round() as u8)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_runs_from_its_first_stop_to_its_last() {
        assert_eq!(ramp(0.0), RAMP[0]);
        assert_eq!(ramp(1.0), RAMP[10]);
        assert_eq!(ramp(0.5), RAMP[5]);
        assert_eq!(ramp(-3.0), RAMP[0]);
        assert_eq!(ramp(f64::NAN), RAMP[0]);
        assert_eq!(ramp(7.0), RAMP[10]);
    }

    #[test]
    fn heights_map_between_the_bounds_and_rgb_is_kept() {
        let by = ColorBy::Elevation(None).for_bounds(DVec3::splat(-1.0), DVec3::new(1.0, 1.0, 9.0));
        assert_eq!(by, ColorBy::Elevation(Some([-1.0, 9.0])));
        assert_eq!(by.color(DVec3::new(5.0, 5.0, -1.0), [1, 2, 3]), RAMP[0]);
        assert_eq!(by.color(DVec3::new(0.0, 0.0, 9.0), [1, 2, 3]), RAMP[10]);
        assert_eq!(by.color(DVec3::new(0.0, 0.0, 4.0), [1, 2, 3]), RAMP[5]);
        let flat = ColorBy::Elevation(Some([2.0, 2.0]));
        assert_eq!(flat.color(DVec3::ZERO, [1, 2, 3]), RAMP[5]);
        assert_eq!(ColorBy::Rgb.color(DVec3::ZERO, [1, 2, 3]), [1, 2, 3]);
        assert_eq!(
            ColorBy::from_name("elevation"),
            Some(ColorBy::Elevation(None))
        );
    }
}
