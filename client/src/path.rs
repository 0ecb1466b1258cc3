//! Camera paths for flythroughs: a JSON list of keyframes, interpolated
//! linearly in time.
//!
//! ```json
//! [ {"t": 0, "orbit": {"azimuth": 0, "elevation": 30, "distance": 4}},
//!   {"t": 5, "eye": [10, 0, 3], "target": [0, 0, 0], "fov": 50} ]
//! ```
//!
//! Orbit keyframes are in scene radii around the scene centre, so one path
//! fits any scene; eye keyframes are in world units. Two neighbouring orbit
//! keyframes interpolate their angles and distance (a smooth circle); any
//! other pair interpolates eye and target.

use std::path::Path;

use anyhow::{Context, bail};
use farfield_protocol::camera::Camera;
use farfield_protocol::file::FileHeader;
use glam::DVec3;
use serde::Deserialize;

use crate::camera_spec::{CameraSpec, scene_sphere};

/// One keyframe as written in the file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Seconds from the start of the path.
    pub t: f64,
    #[serde(default)]
    pub orbit: Option<OrbitKey>,
    #[serde(default)]
    pub eye: Option<[f64; 3]>,
    #[serde(default)]
    pub target: Option<[f64; 3]>,
    #[serde(default)]
    pub fov: Option<f64>,
}

#[derive(Debug, Clone, Copy, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrbitKey {
    pub azimuth: f64,
    pub elevation: f64,
    pub distance: f64,
}

/// A validated path.
#[derive(Debug, Clone)]
pub struct CameraPath {
    keys: Vec<(f64, CameraSpec)>,
}

impl CameraPath {
    /// Reads and checks a path file: at least one keyframe, times finite and
    /// strictly increasing, each keyframe either an orbit or an eye+target.
    pub fn load(path: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
        let keys: Vec<Keyframe> = serde_json::from_str(&text)
            .with_context(|| format!("{}: not a list of keyframes", path.display()))?;
        Self::from_keyframes(&keys).with_context(|| format!("{}", path.display()))
    }

    pub fn from_keyframes(keys: &[Keyframe]) -> anyhow::Result<Self> {
        if keys.is_empty() {
            bail!("a camera path needs at least one keyframe");
        }
        let mut out = Vec::with_capacity(keys.len());
        for (i, k) in keys.iter().enumerate() {
            if !k.t.is_finite() || out.last().is_some_and(|&(t, _)| k.t <= t) {
                bail!("keyframe {i}: times must be finite and increasing");
            }
            let spec = match (k.orbit, k.eye, k.target) {
                (Some(o), None, None) => {
                    let s = format!(
                        "azimuth={},elevation={},distance={}",
                        o.azimuth, o.elevation, o.distance
                    );
                    crate::camera_spec::parse_orbit(&s)
                        .map_err(|e| anyhow::anyhow!("keyframe {i}: {e}"))?
                }
                (None, Some(eye), Some(target)) => {
                    let fov = k.fov.unwrap_or(45.0);
                    let (eye, target) = (DVec3::from(eye), DVec3::from(target));
                    if !(eye.is_finite() && target.is_finite() && fov > 0.0 && fov < 180.0)
                        || eye == target
                    {
                        bail!(
                            "keyframe {i}: eye and target must be finite and distinct, fov in (0, 180)"
                        );
                    }
                    CameraSpec::Eye {
                        eye,
                        target,
                        fov_deg: fov,
                    }
                }
                _ => bail!("keyframe {i}: give either \"orbit\" or both \"eye\" and \"target\""),
            };
            out.push((k.t, spec));
        }
        Ok(Self { keys: out })
    }

    /// The keyframes' times from the path's start: one camera each, for
    /// the bench.
    pub fn key_times(&self) -> Vec<f64> {
        let start = self.keys.first().map_or(0.0, |k| k.0);
        self.keys.iter().map(|k| k.0 - start).collect()
    }

    /// Duration in seconds (0 for a single keyframe).
    pub fn duration(&self) -> f64 {
        self.keys.last().map_or(0.0, |k| k.0) - self.keys.first().map_or(0.0, |k| k.0)
    }

    /// The camera at `t` seconds from the path's start (clamped to the ends).
    pub fn camera_at(&self, t: f64, header: &FileHeader, width: u32, height: u32) -> Camera {
        let t = t + self.keys[0].0;
        let i = self.keys.partition_point(|k| k.0 <= t);
        if i == 0 {
            return self.keys[0].1.resolve(header, width, height);
        }
        if i >= self.keys.len() {
            return self.keys[self.keys.len() - 1]
                .1
                .resolve(header, width, height);
        }
        let ((t0, a), (t1, b)) = (self.keys[i - 1], self.keys[i]);
        let f = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
        let lerp = |x: f64, y: f64| x + (y - x) * f;
        match (a, b) {
            (
                CameraSpec::Orbit {
                    azimuth_deg: a0,
                    elevation_deg: e0,
                    distance: d0,
                },
                CameraSpec::Orbit {
                    azimuth_deg: a1,
                    elevation_deg: e1,
                    distance: d1,
                },
            ) => CameraSpec::Orbit {
                azimuth_deg: lerp(a0, a1),
                elevation_deg: lerp(e0, e1),
                distance: lerp(d0, d1),
            }
            .resolve(header, width, height),
            _ => {
                let (ca, cb) = (
                    a.resolve(header, width, height),
                    b.resolve(header, width, height),
                );
                let eye = ca.eye.lerp(cb.eye, f);
                let mut target = ca.target.lerp(cb.target, f);
                if target == eye {
                    target = eye + (cb.target - cb.eye);
                }
                Camera {
                    eye,
                    target,
                    fov_y_deg: lerp(ca.fov_y_deg, cb.fov_y_deg),
                    ..ca
                }
            }
        }
    }

    /// The demo's built-in flight: a descending half-circle around the
    /// scene that ends close in, looking at the centre.
    pub fn builtin(seconds: f64) -> Self {
        let key = |t: f64, azimuth: f64, elevation: f64, distance: f64| Keyframe {
            t,
            orbit: Some(OrbitKey {
                azimuth,
                elevation,
                distance,
            }),
            eye: None,
            target: None,
            fov: None,
        };
        let s = seconds.max(1.0);
        let keys = [
            key(0.0, 200.0, 55.0, 3.0),
            key(s * 0.5, 270.0, 35.0, 1.6),
            key(s, 330.0, 20.0, 0.9),
        ];
        // Keyframes are valid by construction.
        Self::from_keyframes(&keys).unwrap_or(Self {
            keys: vec![(0.0, CameraSpec::default())],
        })
    }

    /// The scene's centre and radius, for callers that place extra cameras.
    pub fn scene_sphere(header: &FileHeader) -> (DVec3, f64) {
        scene_sphere(header)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bad_paths_are_refused() {
        let parse = |s: &str| -> anyhow::Result<CameraPath> {
            let keys: Vec<Keyframe> = serde_json::from_str(s)?;
            CameraPath::from_keyframes(&keys)
        };
        assert!(parse("[]").is_err());
        assert!(parse(r#"[{"t":0,"orbit":{"azimuth":0,"elevation":10,"distance":3}},{"t":0,"orbit":{"azimuth":0,"elevation":10,"distance":3}}]"#).is_err());
        assert!(parse(r#"[{"t":0,"eye":[0,0,0],"target":[0,0,0]}]"#).is_err());
        assert!(parse(r#"[{"t":0}]"#).is_err());
        assert!(parse(r#"[{"t":0,"orbit":{"azimuth":0,"elevation":10,"distance":-1}}]"#).is_err());
        assert!(parse(r#"[{"t":0,"zoom":3}]"#).is_err());
        let ok = parse(r#"[{"t":1,"orbit":{"azimuth":0,"elevation":10,"distance":3}},{"t":3,"eye":[5,0,0],"target":[0,0,0],"fov":60}]"#).unwrap();
        assert_eq!(ok.duration(), 2.0);
    }
}
