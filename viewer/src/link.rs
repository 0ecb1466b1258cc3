//! The camera in a link: `#eye=x,y,z&target=x,y,z&fov=DEG`, so a view can
//! be shared and opened elsewhere at the same place.
//!
//! Numbers are written in Rust's shortest exact form, so a link read back
//! is the very camera that wrote it.

use farfield_client::camera_spec::{CameraSpec, parse_camera};

/// The fragment (without `#`) for a camera at `eye` looking at `target`.
pub fn camera_fragment(spec: &CameraSpec) -> Option<String> {
    let CameraSpec::Eye {
        eye,
        target,
        fov_deg,
    } = spec
    else {
        return None;
    };
    Some(format!(
        "eye={},{},{}&target={},{},{}&fov={}",
        eye.x, eye.y, eye.z, target.x, target.y, target.z, fov_deg
    ))
}

/// The camera of a fragment (with or without `#`); `Ok(None)` when it
/// names none, an error that says what is wrong when it names a bad one.
/// Keys other than `eye`, `target` and `fov` are left to others.
pub fn parse_fragment(fragment: &str) -> Result<Option<CameraSpec>, String> {
    let fragment = fragment.trim_start_matches('#');
    let camera: Vec<&str> = fragment
        .split('&')
        .filter(|part| {
            let key = part.split('=').next().unwrap_or("");
            matches!(key, "eye" | "target" | "fov")
        })
        .collect();
    if camera.is_empty() {
        return Ok(None);
    }
    parse_camera(&camera.join(",")).map(Some)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn a_camera_survives_its_link() {
        let spec = CameraSpec::Eye {
            eye: DVec3::new(0.1 + 0.2, -1e-7, 12345.678901234),
            target: DVec3::new(-3.0, 0.0, 1.0 / 3.0),
            fov_deg: 47.5,
        };
        let fragment = camera_fragment(&spec).unwrap();
        assert_eq!(parse_fragment(&format!("#{fragment}")), Ok(Some(spec)));
        assert_eq!(
            parse_fragment(&format!("panel=0&{fragment}&x=1")),
            Ok(Some(spec))
        );
    }

    #[test]
    fn links_without_or_with_a_bad_camera() {
        assert_eq!(parse_fragment(""), Ok(None));
        assert_eq!(parse_fragment("#panel=0"), Ok(None));
        assert!(parse_fragment("#eye=1,2&target=0,0,0").is_err());
        assert!(parse_fragment("#eye=1,1,1&target=1,1,1").is_err());
        assert!(parse_fragment("#target=0,0,0").is_err());
    }
}
