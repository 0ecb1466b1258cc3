//! The full-geometry reference for color-cube hierarchies: the input
//! scene's own triangles (atoms tessellated exactly as the cube builder
//! does), drawn once each with the same triangle pipeline as the leaves.
//! This is the papers' "geometric time" and the image cube renders are
//! measured against.

use anyhow::Context;
use farfield_builder::cubes::source::Source;
use farfield_builder::scene::Scene;
use glam::DVec3;

use farfield_render::GpuVertex;

/// A scene's triangles in world space, compact (36 bytes a corner).
#[derive(Debug, Default)]
pub struct Reference {
    positions: Vec<DVec3>,
    /// snorm16 normal (w = 32767 when present) and sRGB color per corner.
    normals: Vec<[i16; 4]>,
    colors: Vec<[u8; 4]>,
}

impl Reference {
    /// Imports and merges `inputs` (files or `gen:` scenes).
    pub fn load(inputs: &[String], params: &[String]) -> anyhow::Result<Self> {
        let params = farfield_builder::import::Params::parse(params).map_err(anyhow::Error::msg)?;
        let mut scene = Scene::default();
        for input in inputs {
            scene.merge(
                farfield_builder::import::load_input(input, &params)
                    .with_context(|| format!("loading {input}"))?,
            );
        }
        Self::from_scene(&scene)
    }

    pub fn from_scene(scene: &Scene) -> anyhow::Result<Self> {
        let src = Source::new(scene).map_err(anyhow::Error::msg)?;
        let mut out = Self::default();
        let mut tris = Vec::new();
        for r in src.refs() {
            tris.clear();
            src.triangles(&r, &mut tris);
            for t in &tris {
                for c in t {
                    out.positions.push(c.position);
                    out.normals
                        .push(c.normal.map_or([0; 4], farfield_render::snorm4));
                    let [r, g, b] = c.rgb8();
                    out.colors.push([r, g, b, 255]);
                }
            }
        }
        Ok(out)
    }

    pub fn triangles(&self) -> usize {
        self.positions.len() / 3
    }

    /// Every triangle, camera-relative, into `out` (cleared first).
    pub fn pack(&self, eye: DVec3, out: &mut Vec<GpuVertex>) {
        out.clear();
        out.extend(
            self.positions
                .iter()
                .zip(&self.normals)
                .zip(&self.colors)
                .map(|((p, n), c)| GpuVertex {
                    position: (*p - eye).as_vec3().to_array(),
                    normal: *n,
                    color: *c,
                }),
        );
    }
}
