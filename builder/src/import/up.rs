//! Which way is up in an input, so every scene is built Z-up (the
//! viewers' convention, and lidar's) and opens upright.
//!
//! Formats say nothing of it, but their conventions do: meshes from
//! scanners and modelling tools (OBJ, OFF, PLY with faces) are Y-up, as
//! the Stanford and Cyberware scans are; lidar (LAS/LAZ, by its
//! specification, and point clouds in PLY) is Z-up; the generators build
//! Z-up. `--up` overrides the convention for every input but LAS/LAZ,
//! whose Z is the survey's height.

use glam::{DAffine3, DMat3, DVec3};

use crate::scene::Scene;

/// The up axis asked for: found by the input's format, or given.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Up {
    #[default]
    Auto,
    X,
    Y,
    Z,
}

impl std::str::FromStr for Up {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "auto" => Ok(Self::Auto),
            "x" => Ok(Self::X),
            "y" => Ok(Self::Y),
            "z" => Ok(Self::Z),
            _ => Err(format!("--up {s}: expected auto, x, y or z")),
        }
    }
}

/// What an input is, as far as its up axis goes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum InputKind {
    /// LAS/LAZ: Z-up whatever `--up` says.
    Lidar,
    /// A mesh file (OBJ, OFF, PLY with faces): Y-up by convention.
    MeshFile,
    /// Anything else (a point cloud in PLY, atoms, a generated scene).
    Other,
}

impl InputKind {
    /// The kind of a file by its extension and whether it has faces.
    pub fn of(input: &str, has_faces: bool) -> Self {
        let extension = std::path::Path::new(input)
            .extension()
            .and_then(|e| e.to_str())
            .map(str::to_ascii_lowercase);
        match extension.as_deref() {
            _ if input.starts_with("gen:") => Self::Other,
            Some("las" | "laz") => Self::Lidar,
            Some("obj" | "off" | "ply") if has_faces => Self::MeshFile,
            _ => Self::Other,
        }
    }
}

impl Up {
    /// The input's up axis: +X, +Y or +Z.
    fn axis(self, kind: InputKind) -> DVec3 {
        match (self, kind) {
            (_, InputKind::Lidar) => DVec3::Z,
            (Self::Auto, InputKind::MeshFile) => DVec3::Y,
            (Self::Auto | Self::Z, _) => DVec3::Z,
            (Self::Y, _) => DVec3::Y,
            (Self::X, _) => DVec3::X,
        }
    }

    /// The rotation that takes an input of `kind` to Z-up (the identity
    /// for one already Z-up): a right-handed quarter turn, so nothing is
    /// mirrored.
    pub fn world_from_input(self, kind: InputKind) -> DAffine3 {
        let axis = self.axis(kind);
        if axis == DVec3::Y {
            // (x, y, z) -> (x, -z, y): a quarter turn about X.
            DAffine3::from_mat3(DMat3::from_cols(DVec3::X, DVec3::Z, -DVec3::Y))
        } else if axis == DVec3::X {
            // (x, y, z) -> (-z, y, x): a quarter turn about Y.
            DAffine3::from_mat3(DMat3::from_cols(DVec3::Z, DVec3::Y, -DVec3::X))
        } else {
            DAffine3::IDENTITY
        }
    }

    /// `scene`, an input of `kind`, turned Z-up. A file's geometry (placed
    /// as it is) is turned itself, exactly (the turn only swaps and
    /// negates coordinates), as a mesh streamed out of core is turned
    /// vertex by vertex; placed instances (a generated scene's) are turned
    /// with their placements.
    pub fn apply(self, kind: InputKind, mut scene: Scene) -> Scene {
        let turn = self.world_from_input(kind);
        if turn == DAffine3::IDENTITY {
            return scene;
        }
        if scene
            .instances
            .iter()
            .all(|i| i.world_from_local == DAffine3::IDENTITY)
        {
            for g in &mut scene.geometries {
                for p in &mut g.positions {
                    *p = turn.transform_point3(*p);
                }
                for n in g.normals.iter_mut().flatten() {
                    *n = turn_normal(turn, *n);
                }
            }
        } else {
            for instance in &mut scene.instances {
                instance.world_from_local = turn * instance.world_from_local;
            }
        }
        scene
    }
}

/// A normal turned by `turn`, a rotation: unit stays unit, and a turn
/// that swaps and negates coordinates changes no bit of any.
pub fn turn_normal(turn: DAffine3, n: glam::Vec3) -> glam::Vec3 {
    (turn.matrix3 * n.as_dvec3()).as_vec3()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_up_axis_becomes_z_without_a_mirror() {
        for (up, kind, axis) in [
            (Up::Auto, InputKind::MeshFile, DVec3::Y),
            (Up::Y, InputKind::Other, DVec3::Y),
            (Up::X, InputKind::MeshFile, DVec3::X),
        ] {
            let turn = up.world_from_input(kind);
            assert_eq!(turn.transform_vector3(axis), DVec3::Z, "{up:?} {kind:?}");
            assert!(
                (turn.matrix3.determinant() - 1.0).abs() < 1e-12,
                "a rotation"
            );
        }
        for (up, kind) in [
            (Up::Auto, InputKind::Other),
            (Up::Z, InputKind::MeshFile),
            (Up::Y, InputKind::Lidar),
            (Up::Auto, InputKind::Lidar),
        ] {
            assert_eq!(
                up.world_from_input(kind),
                DAffine3::IDENTITY,
                "{up:?} {kind:?}"
            );
        }
    }

    #[test]
    fn kinds_by_name_and_faces() {
        assert_eq!(InputKind::of("a/bunny.OBJ", true), InputKind::MeshFile);
        assert_eq!(InputKind::of("scan.ply", false), InputKind::Other);
        assert_eq!(InputKind::of("tile.laz", false), InputKind::Lidar);
        assert_eq!(InputKind::of("gen:tree", true), InputKind::Other);
        assert_eq!("Y".parse::<Up>(), Ok(Up::Y));
        assert!("w".parse::<Up>().is_err());
    }
}
