//! PLP's triangles ([`PlpCut`]) as the triangle pipeline reads them:
//! camera-relative corners, flat-shaded (the shader takes the normal from
//! the position's derivatives), each with its stored color.

use farfield_protocol::hierarchy::{Hierarchy, PlpPage};
use farfield_traverse::plp::PlpCut;
use glam::DVec3;

use crate::GpuVertex;

/// The cut's triangles, camera-relative, appended to `out`. A page's
/// anchor relative to the eye is taken in f64 once; corners are offsets
/// from it.
pub fn pack_plp(h: &Hierarchy, cut: &PlpCut, eye: DVec3, out: &mut Vec<GpuVertex>) {
    out.reserve(cut.triangles.len() * 3);
    for t in &cut.triangles {
        let Some(PlpPage::Cells(page)) = h.page(t.page as usize).and_then(|p| p.plp()) else {
            continue;
        };
        let Some(stored) = page.triangles.get(t.index as usize) else {
            continue;
        };
        let origin = page.anchor - eye;
        for c in stored.corners {
            out.push(GpuVertex {
                position: (origin + DVec3::from(c.map(f64::from)))
                    .as_vec3()
                    .to_array(),
                normal: [0; 4],
                color: stored.rgba,
            });
        }
    }
}
