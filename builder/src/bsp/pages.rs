//! Laying the BSP out in pages: the tree in page 0, each prototype in a
//! page of its own after it, then one page per leaf (in the tree's
//! preorder, so neighbouring leaves are neighbouring pages).

use farfield_protocol::FormatError;
use farfield_protocol::bsp_codec::{
    self, BspNode, BspSkeleton, FlatTriangle, LeafPage, Placement as StoredPlacement,
    PrototypeInfo, PrototypePage, Split,
};
use farfield_protocol::file::{AttributeFlags, HierarchyKind};
use glam::DVec3;

use super::inflate::Inflated;
use super::objects::Collected;
use super::split::{Built, Tree};
use crate::PagedFile;
use crate::page_writer::{SceneFacts, SkeletonFirst};

/// What the header records besides the tree.
#[derive(Debug, Clone, Copy)]
pub struct LayoutInfo {
    pub input_vertices: u64,
    pub inflation: f32,
}

/// The file and what laying it out counted.
#[derive(Debug)]
pub struct Laid {
    pub file: PagedFile,
    /// Mesh triangles stored over all leaves (inflation repeats some).
    pub stored_triangles: u64,
    /// Placements stored over all leaves.
    pub stored_placements: u64,
    pub scene_triangles: u64,
    pub bounds_min: DVec3,
    pub bounds_max: DVec3,
}

/// Writes `tree` (leaves holding `inflated`) as a paged file.
pub fn lay_out(
    scene: &Collected,
    directions: &[DVec3],
    tree: &Tree,
    inflated: &[Inflated],
    info: &LayoutInfo,
) -> Result<Laid, FormatError> {
    // Leaf boxes and triangle counts, then interior ones (children come
    // after parents, so a reverse pass sees children first).
    let mut boxes = vec![(DVec3::INFINITY, DVec3::NEG_INFINITY); tree.nodes.len()];
    let mut triangles = vec![0u64; tree.nodes.len()];
    for (i, node) in tree.nodes.iter().enumerate().rev() {
        match *node {
            Built::Leaf(leaf) => {
                let content = &inflated[leaf as usize];
                let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
                for &t in &content.mesh {
                    for c in scene.mesh.corners[t as usize] {
                        lo = lo.min(c);
                        hi = hi.max(c);
                    }
                }
                // Drawn as geometry, a leaf draws its own part alone.
                let mut count = content.own_mesh as u64;
                for (k, &p) in content.instances.iter().enumerate() {
                    let p = &scene.placements[p as usize];
                    lo = lo.min(p.box_min);
                    hi = hi.max(p.box_max);
                    if k < content.own_instances {
                        count += p.triangles;
                    }
                }
                boxes[i] = (lo, hi);
                triangles[i] = count;
            }
            Built::Plane { back, front, .. } => {
                let (b, f) = (boxes[back as usize], boxes[front as usize]);
                boxes[i] = (b.0.min(f.0), b.1.max(f.1));
                triangles[i] = triangles[back as usize] + triangles[front as usize];
            }
        }
    }
    let (bounds_min, bounds_max) = boxes[0];
    let centre = (bounds_min + bounds_max) * 0.5;
    let scene_triangles =
        scene.mesh.corners.len() as u64 + scene.placements.iter().map(|p| p.triangles).sum::<u64>();
    let skeleton = BspSkeleton {
        directions: directions.to_vec(),
        nodes: tree
            .nodes
            .iter()
            .enumerate()
            .map(|(i, node)| BspNode {
                box_min: boxes[i].0,
                box_max: boxes[i].1,
                triangles: triangles[i],
                split: match *node {
                    Built::Leaf(leaf) => Split::Leaf { leaf },
                    Built::Plane {
                        direction,
                        offset,
                        back,
                        front,
                    } => Split::Plane {
                        direction: direction as u8,
                        // Stored relative to the root centre.
                        offset: offset - directions[direction].dot(centre),
                        back,
                        front,
                    },
                },
            })
            .collect(),
        prototypes: scene
            .prototypes
            .iter()
            .map(|p| PrototypeInfo {
                triangles: p.triangles.len() as u32,
                box_min: p.box_min,
                box_max: p.box_max,
            })
            .collect(),
        leaves: tree.leaves.len() as u32,
        scene_triangles,
        inflation: info.inflation,
    };
    let children = (scene.prototypes.len() + tree.leaves.len()) as u64;
    let mut pages = SkeletonFirst::new(children, &skeleton.encode(centre));
    for (p, proto) in scene.prototypes.iter().enumerate() {
        let (records, payload) = PrototypePage {
            prototype: p as u32,
            triangles: proto.triangles.clone(),
        }
        .encode();
        pages.push_leaves(1, &records, &payload);
    }
    let (mut stored_triangles, mut stored_placements) = (0u64, 0u64);
    for (leaf, content) in inflated.iter().enumerate() {
        let page = leaf_page(scene, leaf as u32, content);
        stored_triangles += page.triangles.len() as u64;
        stored_placements += page.placements.len() as u64;
        let (records, payload) = page.encode();
        pages.push_leaves(1, &records, &payload);
    }
    let file = pages.finish(SceneFacts {
        kind: HierarchyKind::Bsp,
        attributes: AttributeFlags {
            color: true,
            normals: false,
            leaf_geometry: true,
        },
        node_bytes: bsp_codec::NODE_BYTES as u32,
        input_vertices: info.input_vertices,
        bounds_min,
        bounds_max,
        root_center: centre,
        // A scene that is one point still has a sphere.
        root_radius: ((bounds_max - bounds_min).length() * 0.5).max(1e-6),
    })?;
    Ok(Laid {
        file,
        stored_triangles,
        stored_placements,
        scene_triangles,
        bounds_min,
        bounds_max,
    })
}

/// A leaf's page: its triangles relative to their lowest corner, its
/// placements relative to the same anchor.
fn leaf_page(scene: &Collected, leaf: u32, content: &Inflated) -> LeafPage {
    let mut anchor = content
        .mesh
        .iter()
        .flat_map(|&t| scene.mesh.corners[t as usize])
        .fold(DVec3::INFINITY, DVec3::min);
    for &p in &content.instances {
        anchor = anchor.min(scene.placements[p as usize].box_min);
    }
    let anchor = if anchor.is_finite() {
        anchor
    } else {
        DVec3::ZERO
    };
    LeafPage {
        leaf,
        anchor,
        own_triangles: content.own_mesh as u32,
        own_placements: content.own_instances as u32,
        triangles: content
            .mesh
            .iter()
            .map(|&t| FlatTriangle {
                corners: scene.mesh.corners[t as usize].map(|c| (c - anchor).as_vec3().to_array()),
                rgba: scene.mesh.rgba[t as usize],
            })
            .collect(),
        placements: content
            .instances
            .iter()
            .map(|&p| {
                let p = &scene.placements[p as usize];
                let m = p.world_from_local.matrix3;
                StoredPlacement {
                    prototype: p.prototype,
                    matrix: [m.x_axis, m.y_axis, m.z_axis].map(|c| c.as_vec3().to_array()),
                    translation: (p.world_from_local.translation - anchor)
                        .as_vec3()
                        .to_array(),
                }
            })
            .collect(),
    }
}
