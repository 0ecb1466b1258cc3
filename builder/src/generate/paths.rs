//! Camera paths that belong to generated scenes: the flythroughs the PLP
//! paper measures its scenes on, one keyframe per frame at 30 frames per
//! second, in the camera-path JSON format (`farfield-client`'s `path.rs`:
//! a list of `{"t", "eye", "target", "fov"}`, times strictly increasing,
//! eyes in world units).
//!
//! - `gen:city`: a walk at eye height along a street between two rows of
//!   houses, round the corner at a crossing and up the cross street, the
//!   gaze swinging gently toward the houses on either side so doors and
//!   windows come into view. The streets it uses are picked from `grid`,
//!   so the walk stays on streets (near the city's middle) for any grid.
//! - `gen:cars`: once round the row of cars, slightly above it, at each
//!   azimuth at the distance where the row fills the view.
//! - `gen:island`: the image-caching paper's walkthrough (section 5): a
//!   uniform cubic B-spline that first tracks the coast three quarters of
//!   the way round, looking in over the island, then flies in toward the
//!   centre at about tree-top height; 1200 frames.
//!
//! Paths read the same params as their scenes (and reject the same bad
//! ones), so `farfield path gen:city --param grid=8` fits the scene
//! `gen:city --param grid=8`. They are deterministic like the scenes.

use glam::DVec3;
use serde::Serialize;

use super::cars::{self, CarsParams};
use super::city::{self, CityParams};
use super::trig::sin_cos;
use super::{GENERATORS, ImportError, Params};

/// Keyframes per second of path.
pub const FPS: f64 = 30.0;
/// Keyframes of the city walk and of the orbit round the cars.
pub const CITY_FRAMES: usize = 160;
pub const CARS_FRAMES: usize = 200;
pub const ISLAND_FRAMES: usize = 1200;
/// The width-to-height ratio the cars' orbit frames the row for: the
/// renders' and benches' 4:3 sizes (640x480, 800x600, 1024x768).
pub const ASPECT: f64 = 4.0 / 3.0;
/// Eye height above the street.
pub const EYE_HEIGHT: f64 = 1.7;

/// One keyframe of a camera path, as the camera-path JSON writes it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct PathKey {
    /// Seconds from the start of the path.
    pub t: f64,
    /// Where the camera is, in world units.
    pub eye: [f64; 3],
    /// The point it looks at.
    pub target: [f64; 3],
    /// Vertical field of view, degrees.
    pub fov: f64,
}

/// The camera path of generator `name` (without `gen:`) for `params`, or
/// `None` for a generator that has none. Unknown generators and bad params
/// are errors, as for [`super::generate`].
pub fn camera_path(name: &str, params: &Params) -> Result<Option<Vec<PathKey>>, ImportError> {
    match name {
        "city" => Ok(Some(city_walk(&super::city_params(params)?))),
        "cars" => Ok(Some(cars_orbit(&super::cars_params(params)?))),
        "island" => Ok(Some(island_walk(&super::island_params(params)?))),
        _ if GENERATORS.contains(&name) => Ok(None),
        _ => Err(super::unknown_generator(name)),
    }
}

/// A keyframe at frame `k`.
fn key(k: usize, eye: DVec3, target: DVec3, fov: f64) -> PathKey {
    PathKey {
        t: k as f64 / FPS,
        eye: eye.to_array(),
        target: target.to_array(),
        fov,
    }
}

/// The walk through the city (see the module docs): along the street
/// between rows `j0 - 1` and `j0` (an odd `j0`, where doors face each
/// other; the city's edge street for a single house), turning left at the
/// crossing with the street left of column `c`, up that street to the next
/// crossing. The corner is a quarter circle, the pace even.
fn city_walk(p: &CityParams) -> Vec<PathKey> {
    let g = p.grid;
    let j0 = if g >= 2 { (g / 2) | 1 } else { 0 };
    let c = (g / 2).max(1);
    let half = city::STREET / 2.0;
    let y_street = f64::from(j0) * city::PITCH_Y + half;
    let x_street = f64::from(c) * city::PITCH_X + half;
    let z = city::STREET_TOP + EYE_HEIGHT;
    let (run, radius) = (12.0, 3.0);
    // Straight along +x, the corner, straight along +y.
    let first = run - radius;
    let arc = std::f64::consts::FRAC_PI_2 * radius;
    let length = 2.0 * first + arc;
    let at = |s: f64| -> (DVec3, DVec3) {
        let s = s.clamp(0.0, length);
        if s <= first {
            (DVec3::new(x_street - run + s, y_street, z), DVec3::X)
        } else if s <= first + arc {
            let a = (s - first) / radius;
            let (sa, ca) = sin_cos(a);
            let centre = DVec3::new(x_street - radius, y_street + radius, z);
            (
                centre + DVec3::new(sa, -ca, 0.0) * radius,
                DVec3::new(ca, sa, 0.0),
            )
        } else {
            let along = s - first - arc;
            (DVec3::new(x_street, y_street + radius + along, z), DVec3::Y)
        }
    };
    (0..CITY_FRAMES)
        .map(|k| {
            let s = length * k as f64 / (CITY_FRAMES - 1) as f64;
            let (eye, _) = at(s);
            // Look ahead of the feet (into the turn before taking it), the
            // gaze swinging up to about 25 degrees toward either side.
            let (_, ahead) = at(s + 3.0);
            let (sw, cw) = sin_cos(0.45 * sin_cos(std::f64::consts::TAU * s / 14.0).0);
            let side = DVec3::new(-ahead.y, ahead.x, 0.0);
            let gaze = ahead * cw + side * sw;
            key(k, eye, eye + gaze * 10.0 - DVec3::Z * 0.5, 60.0)
        })
        .collect()
}

/// The orbit round the row of cars (see the module docs): round the
/// row's centre, 15 degrees above it, at each azimuth as close as lets the
/// whole row's box fit the view (45 degrees high, [`ASPECT`] wide) with a
/// 5% margin: broadside the row spans the width, end-on the nearest car
/// fills the view with the others behind it. So the circle is an oval.
fn cars_orbit(p: &CarsParams) -> Vec<PathKey> {
    let fov: f64 = 45.0;
    let first = cars::car_centre(0);
    let last = cars::car_centre(p.cars - 1);
    let centre = (first + last) * 0.5 + DVec3::Z * (cars::HEIGHT * 0.5);
    let half = DVec3::new(
        (last.x - first.x + cars::LENGTH) * 0.5,
        cars::WIDTH * 0.5,
        cars::HEIGHT * 0.5,
    );
    let corners: Vec<DVec3> = (0..8)
        .map(|k| {
            let s = |bit: u32| if k >> bit & 1 == 1 { 1.0 } else { -1.0 };
            half * DVec3::new(s(0), s(1), s(2))
        })
        .collect();
    let (s, c) = sin_cos((fov * 0.5).to_radians());
    let (ty, tx) = (s / c, s / c * ASPECT);
    let (se, ce) = sin_cos(15f64.to_radians());
    (0..CARS_FRAMES)
        .map(|k| {
            let (sa, ca) = sin_cos(std::f64::consts::TAU * k as f64 / CARS_FRAMES as f64);
            let back = DVec3::new(ce * ca, ce * sa, se);
            let (forward, right) = (-back, DVec3::new(-sa, ca, 0.0));
            let up = right.cross(forward);
            // A corner q (from the centre) is in view from centre + back * d
            // when |q.right| <= tx (q.forward + d), and likewise up and down.
            let distance = corners
                .iter()
                .map(|q| (q.dot(right).abs() / tx).max(q.dot(up).abs() / ty) - q.dot(forward))
                .fold(0.0, f64::max);
            key(k, centre + back * (distance * 1.05), centre, fov)
        })
        .collect()
}

/// The island walkthrough (see the module docs). The control points: a
/// ring round the coast at 0.42 of the extent from the centre and half the
/// peak's height, then three points in toward the centre at three
/// quarters of the peak's height (the highest trees stand at half of it,
/// 13 units tall at most).
fn island_walk(p: &super::island::IslandParams) -> Vec<PathKey> {
    let (r, h) = (p.extent * 0.42, p.height);
    let ring = |a: f64, z: f64| {
        let (s, c) = sin_cos(a);
        DVec3::new(c * r, s * r, z)
    };
    let mut points: Vec<DVec3> = (0..8)
        .map(|k| ring(std::f64::consts::TAU * 0.75 * f64::from(k) / 7.0, h * 0.5))
        .collect();
    let last = points[points.len() - 1];
    for f in [0.7, 0.45, 0.25] {
        points.push(DVec3::new(last.x * f, last.y * f, h * 0.75));
    }
    let at = |u: f64| bspline(&points, u);
    let span = (points.len() - 3) as f64;
    (0..ISLAND_FRAMES)
        .map(|k| {
            let u = span * k as f64 / (ISLAND_FRAMES - 1) as f64;
            let eye = at(u);
            let ahead = at((u + 0.15).min(span));
            let along = (ahead - eye).try_normalize().unwrap_or(DVec3::X);
            // Half along the path, half in toward the centre, a little down.
            let inward = (-DVec3::new(eye.x, eye.y, 0.0))
                .try_normalize()
                .unwrap_or(along);
            let gaze = (along + inward).try_normalize().unwrap_or(along) - DVec3::Z * 0.25;
            key(k, eye, eye + gaze * r * 0.25, 60.0)
        })
        .collect()
}

/// The uniform cubic B-spline of `points` at `u` in `0..=len - 3`.
fn bspline(points: &[DVec3], u: f64) -> DVec3 {
    let i = (u.floor() as usize).min(points.len().saturating_sub(4));
    let t = u - i as f64;
    let (t2, t3) = (t * t, t * t * t);
    let b = [
        (1.0 - t).powi(3) / 6.0,
        (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t3 / 6.0,
    ];
    (0..4).map(|k| points[i + k] * b[k]).sum()
}
