//! Parsing of the camera, orbit and size arguments shared by commands.
//!
//! `--camera eye=x,y,z,target=x,y,z,fov=DEG` places the eye in world units;
//! `--orbit azimuth=DEG,elevation=DEG,distance=R` circles the scene centre
//! at R scene radii (the papers' d = 1.75 ... 14). Both resolve to a
//! [`Camera`] once the scene's bounds are known.

use farfield_protocol::camera::Camera;
use farfield_protocol::file::FileHeader;
use glam::DVec3;

/// Where to look from, before the scene is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum CameraSpec {
    Eye {
        eye: DVec3,
        target: DVec3,
        fov_deg: f64,
    },
    Orbit {
        azimuth_deg: f64,
        elevation_deg: f64,
        distance: f64,
    },
}

impl Default for CameraSpec {
    fn default() -> Self {
        Self::Orbit {
            azimuth_deg: 30.0,
            elevation_deg: 25.0,
            distance: 2.5,
        }
    }
}

/// The scene's centre and radius: the middle and half-diagonal of its bounds.
pub fn scene_sphere(header: &FileHeader) -> (DVec3, f64) {
    let center = (header.bounds_min + header.bounds_max) * 0.5;
    let radius =
        ((header.bounds_max - header.bounds_min).length() * 0.5).max(header.root_radius * 1e-9);
    (center, if radius > 0.0 { radius } else { 1.0 })
}

impl CameraSpec {
    /// The camera for a scene and image size.
    pub fn resolve(&self, header: &FileHeader, width: u32, height: u32) -> Camera {
        match *self {
            Self::Eye {
                eye,
                target,
                fov_deg,
            } => Camera {
                eye,
                target,
                up: DVec3::Z,
                fov_y_deg: fov_deg,
                width,
                height,
            },
            Self::Orbit {
                azimuth_deg,
                elevation_deg,
                distance,
            } => {
                let (center, radius) = scene_sphere(header);
                Camera::orbit(
                    center,
                    radius,
                    azimuth_deg,
                    elevation_deg,
                    distance,
                    width,
                    height,
                )
            }
        }
    }
}

/// Parses `key=value` pairs separated by commas, where values of `eye` and
/// `target` are themselves three comma-separated numbers.
fn pairs(s: &str) -> Result<Vec<(String, Vec<f64>)>, String> {
    let mut out: Vec<(String, Vec<f64>)> = Vec::new();
    for part in s.split(',') {
        let part = part.trim();
        if let Some((key, value)) = part.split_once('=') {
            let v: f64 = value
                .trim()
                .parse()
                .map_err(|_| format!("'{value}' is not a number in '{s}'"))?;
            out.push((key.trim().to_owned(), vec![v]));
        } else {
            let v: f64 = part
                .parse()
                .map_err(|_| format!("'{part}' is not a number in '{s}'"))?;
            match out.last_mut() {
                Some((_, values)) => values.push(v),
                None => return Err(format!("'{s}' must start with key=value")),
            }
        }
    }
    if let Some((key, _)) = out.iter().find(|(_, v)| v.iter().any(|x| !x.is_finite())) {
        return Err(format!("{key} must be finite"));
    }
    Ok(out)
}

fn vec3(values: &[f64], key: &str) -> Result<DVec3, String> {
    match values {
        [x, y, z] => Ok(DVec3::new(*x, *y, *z)),
        _ => Err(format!("{key} needs three numbers x,y,z")),
    }
}

/// `eye=x,y,z,target=x,y,z[,fov=DEG]`.
pub fn parse_camera(s: &str) -> Result<CameraSpec, String> {
    let (mut eye, mut target, mut fov) = (None, None, 45.0);
    for (key, values) in pairs(s)? {
        match key.as_str() {
            "eye" => eye = Some(vec3(&values, "eye")?),
            "target" => target = Some(vec3(&values, "target")?),
            "fov" if values.len() == 1 && values[0] > 0.0 && values[0] < 180.0 => fov = values[0],
            "fov" => return Err("fov must be one number between 0 and 180 degrees".into()),
            other => return Err(format!("unknown camera key '{other}' (eye, target, fov)")),
        }
    }
    let (eye, target) = (
        eye.ok_or("--camera needs eye=x,y,z")?,
        target.ok_or("--camera needs target=x,y,z")?,
    );
    if eye == target {
        return Err("eye and target must differ".into());
    }
    Ok(CameraSpec::Eye {
        eye,
        target,
        fov_deg: fov,
    })
}

/// `azimuth=DEG,elevation=DEG,distance=R` (any may be left out).
pub fn parse_orbit(s: &str) -> Result<CameraSpec, String> {
    let (mut azimuth_deg, mut elevation_deg, mut distance) = (30.0, 25.0, 2.5);
    for (key, values) in pairs(s)? {
        let [v] = values[..] else {
            return Err(format!("{key} takes one number"));
        };
        match key.as_str() {
            "azimuth" => azimuth_deg = v,
            "elevation" if (-90.0..=90.0).contains(&v) => elevation_deg = v,
            "elevation" => return Err("elevation must be between -90 and 90 degrees".into()),
            "distance" if v > 0.0 => distance = v,
            "distance" => return Err("distance must be positive (in scene radii)".into()),
            other => {
                return Err(format!(
                    "unknown orbit key '{other}' (azimuth, elevation, distance)"
                ));
            }
        }
    }
    Ok(CameraSpec::Orbit {
        azimuth_deg,
        elevation_deg,
        distance,
    })
}

/// `WIDTHxHEIGHT`, each 1..=8192.
pub fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size '{s}' is not WIDTHxHEIGHT"))?;
    let w: u32 = w
        .trim()
        .parse()
        .map_err(|_| format!("bad width in '{s}'"))?;
    let h: u32 = h
        .trim()
        .parse()
        .map_err(|_| format!("bad height in '{s}'"))?;
    if !(1..=8192).contains(&w) || !(1..=8192).contains(&h) {
        return Err(format!("size {w}x{h} is out of range (1..=8192)"));
    }
    Ok((w, h))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_cameras_orbits_and_sizes() {
        assert_eq!(
            parse_camera("eye=1,2,3,target=0,0,0,fov=60").unwrap(),
            CameraSpec::Eye {
                eye: DVec3::new(1.0, 2.0, 3.0),
                target: DVec3::ZERO,
                fov_deg: 60.0
            }
        );
        assert_eq!(
            parse_orbit("azimuth=10,elevation=-5,distance=7").unwrap(),
            CameraSpec::Orbit {
                azimuth_deg: 10.0,
                elevation_deg: -5.0,
                distance: 7.0
            }
        );
        assert_eq!(parse_size("640x480").unwrap(), (640, 480));
        for bad in [
            "eye=1,2,target=0,0,0",
            "eye=1,2,3,target=1,2,3",
            "eye=nan,0,0,target=0,0,0",
            "fov=30",
        ] {
            assert!(parse_camera(bad).is_err(), "{bad}");
        }
        for bad in ["distance=0", "elevation=100", "zoom=3", "azimuth=1,2"] {
            assert!(parse_orbit(bad).is_err(), "{bad}");
        }
        for bad in ["0x10", "10", "axb", "9000x10"] {
            assert!(parse_size(bad).is_err(), "{bad}");
        }
    }
}
