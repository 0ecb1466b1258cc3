//! PLP's visible coverage ratio `ε = |V ∩ T| / |V|` (Klosowski & Silva,
//! section 2) for any bench that draws triangles: `V` is read once per
//! camera from an item buffer of the reference frame (each triangle's id
//! drawn with depth test), `T` is what a frame drew. Streamed, this is the
//! paper's measure against bytes received and time since connect, so PLP's
//! projection order can be set beside plain nearest-first.

use farfield_protocol::camera::Camera;
use farfield_protocol::hierarchy::Hierarchy;
use farfield_render::{Renderer, pack_plp, visible_ids};
use farfield_traverse::DrawList;

/// The ascending ids of the triangles that cover at least one pixel when
/// `list` is drawn for `camera`; `None` when the list is not triangles
/// (splats and cubes have no per-triangle visibility).
pub fn visible_set(
    renderer: &mut Renderer,
    hierarchy: &Hierarchy,
    camera: &Camera,
    list: DrawList<'_>,
) -> anyhow::Result<Option<Vec<u32>>> {
    let DrawList::Triangles(cut) = list else {
        return Ok(None);
    };
    let mut vertices = Vec::new();
    pack_plp(hierarchy, cut, camera.eye, &mut vertices);
    let ids: Vec<u32> = cut.triangles.iter().map(|t| t.id).collect();
    let items = renderer.item_buffer(camera, &vertices, &ids)?;
    Ok(Some(visible_ids(&items)))
}

/// `ε` of a frame that drew `list`, against the reference's `visible`
/// set; `None` when either is not triangles. An empty visible set is
/// covered whole (1): nothing was there to miss.
pub fn coverage(visible: Option<&[u32]>, list: Option<DrawList<'_>>) -> Option<f64> {
    let (visible, Some(DrawList::Triangles(cut))) = (visible?, list) else {
        return None;
    };
    if visible.is_empty() {
        return Some(1.0);
    }
    let found = common_count(visible, cut.triangles.iter().map(|t| t.id));
    Some(found as f64 / visible.len() as f64)
}

/// How many of the ascending `drawn` ids are in the ascending `visible`,
/// in one pass over both.
pub fn common_count(visible: &[u32], drawn: impl Iterator<Item = u32>) -> usize {
    let mut i = 0;
    let mut n = 0;
    for id in drawn {
        while i < visible.len() && visible[i] < id {
            i += 1;
        }
        if i < visible.len() && visible[i] == id {
            n += 1;
        }
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use farfield_traverse::plp::{PlpCut, TriangleDraw};

    #[test]
    fn common_ids_are_counted_once() {
        assert_eq!(
            common_count(&[1, 3, 5, 9], [0, 1, 2, 5, 9, 10].into_iter()),
            3
        );
        assert_eq!(common_count(&[], [1, 2].into_iter()), 0);
        assert_eq!(common_count(&[4], std::iter::empty()), 0);
    }

    fn cut(ids: &[u32]) -> PlpCut {
        PlpCut {
            triangles: ids
                .iter()
                .map(|&id| TriangleDraw {
                    id,
                    page: 1,
                    index: 0,
                })
                .collect(),
            ..PlpCut::default()
        }
    }

    #[test]
    fn coverage_is_the_share_of_the_visible_set_drawn() {
        let drawn = cut(&[2, 4, 7, 8]);
        let list = Some(DrawList::Triangles(&drawn));
        assert_eq!(coverage(Some(&[1, 2, 3, 4]), list), Some(0.5));
        assert_eq!(coverage(Some(&[]), list), Some(1.0));
        assert_eq!(coverage(None, list), None);
        assert_eq!(coverage(Some(&[1]), None), None);
        assert_eq!(coverage(Some(&[1]), Some(DrawList::Splats(&[]))), None);
    }
}
