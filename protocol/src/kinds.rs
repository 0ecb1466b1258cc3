//! The format's registry of hierarchy kinds: what each kind's header must
//! say and how its pages decode. Everything in this crate that depends on
//! the kind asks here, so a new kind is a variant, its codec module and
//! the arms below (the compiler finds each `match`).

use crate::file::FileHeader;
use crate::hierarchy::{Hierarchy, PagePayload};
use crate::page::Page;
use crate::sphere_codec::NodeLayout;
use crate::{FormatError, bsp_codec, cube_codec, plp_codec};

/// Which hierarchy the nodes form.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum HierarchyKind {
    /// QSplat's bounding-sphere hierarchy.
    Spheres = 1,
    /// Chamberlain et al.'s color-cube octree.
    Cubes = 2,
    /// Klosowski and Silva's PLP tessellation: a root whose children are
    /// Delaunay cells (`plp_codec`).
    Plp = 3,
    /// Shade et al.'s image-caching BSP: a root whose children are shared
    /// prototypes and BSP leaves, a page each (`bsp_codec`).
    Bsp = 4,
}

impl HierarchyKind {
    /// Every kind, in the order of their numbers in the file.
    pub const ALL: [HierarchyKind; 4] = [Self::Spheres, Self::Cubes, Self::Plp, Self::Bsp];

    pub(crate) fn from_u8(v: u8) -> Result<Self, FormatError> {
        match v {
            1 => Ok(Self::Spheres),
            2 => Ok(Self::Cubes),
            3 => Ok(Self::Plp),
            4 => Ok(Self::Bsp),
            other => Err(FormatError::BadHeader(format!(
                "unknown hierarchy kind {other}"
            ))),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Self::Spheres => "spheres",
            Self::Cubes => "cubes",
            Self::Plp => "plp",
            Self::Bsp => "bsp",
        }
    }

    /// Whether the kind's pages carry a payload after their node records
    /// (cells' colors and triangles, tessellation cells, BSP leaves); a
    /// sphere page is its records and nothing more.
    pub fn pages_carry_payload(self) -> bool {
        self != Self::Spheres
    }

    /// How the kind's nodes are laid out in pages: what a reader may assume
    /// of a page's children without knowing the kind.
    pub fn layout(self) -> PageLayout {
        match self {
            Self::Spheres | Self::Cubes => PageLayout::BreadthFirst,
            Self::Plp | Self::Bsp => PageLayout::SkeletonFirst,
        }
    }

    /// Whether page 0 holds the root alone, its skeleton (the directory's
    /// root page is checked for it: the header cannot say).
    pub(crate) fn root_page_alone(self) -> bool {
        self.layout() == PageLayout::SkeletonFirst
    }

    /// Whether the nodes are QSplat's quantized spheres, which the
    /// reference decoder ([`Hierarchy::decode_all`]) reads.
    pub fn nodes_are_spheres(self) -> bool {
        self == Self::Spheres
    }

    /// What this kind's header must say beyond what every header must:
    /// node size, cluster size, and for two-level kinds the shape of the
    /// page directory. `Err` is the reason, for [`FormatError::BadHeader`].
    pub(crate) fn check_header(self, h: &FileHeader) -> Result<(), String> {
        match self {
            HierarchyKind::Spheres if h.node_bytes == 0 || h.node_bytes > 8 => {
                return Err(format!("node size {} is out of range", h.node_bytes));
            }
            HierarchyKind::Spheres if h.cluster != 0 => {
                return Err(format!("a sphere hierarchy has cluster size {}", h.cluster));
            }
            HierarchyKind::Cubes if h.node_bytes != cube_codec::RECORD_BYTES as u32 => {
                return Err(format!(
                    "cube node size {} is not {}",
                    h.node_bytes,
                    cube_codec::RECORD_BYTES
                ));
            }
            HierarchyKind::Cubes if !cube_codec::valid_cluster(h.cluster) => {
                return Err(format!(
                    "cluster size {} is not a power of two up to {}",
                    h.cluster,
                    cube_codec::MAX_CLUSTER
                ));
            }
            HierarchyKind::Plp if h.node_bytes != plp_codec::NODE_BYTES as u32 => {
                return Err(format!(
                    "PLP node size {} is not {}",
                    h.node_bytes,
                    plp_codec::NODE_BYTES
                ));
            }
            HierarchyKind::Bsp if h.node_bytes != bsp_codec::NODE_BYTES as u32 => {
                return Err(format!(
                    "BSP node size {} is not {}",
                    h.node_bytes,
                    bsp_codec::NODE_BYTES
                ));
            }
            HierarchyKind::Bsp
                if h.cluster != 0
                    || h.leaves.checked_add(1) != Some(h.nodes)
                    || h.levels != 2
                    || u64::from(h.page_count) != h.nodes
                    || h.root_directory.first_child != 1 =>
            {
                return Err(format!(
                    "a BSP file is a root alone in page 0 and one prototype or leaf a page after it ({} nodes, {} pages, cluster {})",
                    h.nodes, h.page_count, h.cluster
                ));
            }
            HierarchyKind::Plp
                if h.cluster != 0
                    || h.leaves.checked_add(1) != Some(h.nodes)
                    || h.levels != 2
                    || h.root_directory.first_child != 1 =>
            {
                return Err(format!(
                    "a PLP tessellation is a root alone in page 0 and its cells after ({} nodes, {} leaves, cluster {})",
                    h.nodes, h.leaves, h.cluster
                ));
            }
            _ => {}
        }
        Ok(())
    }

    /// A sphere file's node size must be what its attributes make (the
    /// other kinds' records have a fixed size, checked with the header).
    pub(crate) fn check_node_layout(
        self,
        layout: NodeLayout,
        node_bytes: u32,
    ) -> Result<(), FormatError> {
        if self == Self::Spheres && layout.bytes() != node_bytes {
            return Err(FormatError::BadHeader(format!(
                "node size {} does not match the attributes ({} expected)",
                node_bytes,
                layout.bytes()
            )));
        }
        Ok(())
    }

    /// A checked page of this kind decoded: each node's child count and
    /// the page's payload.
    pub(crate) fn decode_page(
        self,
        h: &Hierarchy,
        page: &Page,
    ) -> Result<(Vec<u32>, PagePayload), FormatError> {
        Ok(match self {
            Self::Spheres => (h.sphere_child_counts(page)?, PagePayload::Spheres),
            Self::Cubes => {
                let cubes = h.cube_page(page)?;
                let counts = cubes
                    .records
                    .iter()
                    .map(cube_codec::CubeRecord::child_count)
                    .collect();
                (counts, PagePayload::Cubes(cubes))
            }
            Self::Plp => {
                let (counts, plp) = h.plp_page(page)?;
                (counts, PagePayload::Plp(plp))
            }
            Self::Bsp => {
                let (counts, bsp) = h.bsp_page(page)?;
                (counts, PagePayload::Bsp(bsp))
            }
        })
    }
}

/// The two shapes of a file's pages.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PageLayout {
    /// Nodes breadth first, a subtree's top levels to a page: the children
    /// of a page's nodes are the next pages' (a page's `first_child` to the
    /// next page's), so they are worth reading ahead.
    BreadthFirst,
    /// A skeleton in page 0 whose root's children are every leaf, then a
    /// page or more per leaf: a root's "children" are the whole scene, so
    /// reading them ahead would read it all; clients ask in their own
    /// order.
    SkeletonFirst,
}
