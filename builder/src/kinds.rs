//! The builders by hierarchy kind, listed once, as `farfield_traverse::KINDS`
//! lists the traversals: the command line and the tests find a kind's
//! builder here instead of matching on the kind.

use farfield_protocol::file::HierarchyKind;

use crate::bsp::{BspOptions, build_bsp};
use crate::cubes::{CubeOptions, build_cubes};
use crate::plp::{PlpOptions, build_plp};
use crate::scene::Scene;
use crate::{BuildError, BuildOptions, PagedFile, Progress, build_spheres_reporting};

/// Every kind's options together: a caller (the command line) fills in all
/// it knows, and each kind's builder reads its own.
#[derive(Debug, Clone, Copy, Default)]
pub struct BuildSettings {
    /// The most bytes a page may hold; `None` keeps each kind's default
    /// (kinds whose pages are one leaf each, the BSP's, have none).
    pub page_bytes: Option<usize>,
    pub spheres: BuildOptions,
    pub cubes: CubeOptions,
    pub plp: PlpOptions,
    pub bsp: BspOptions,
}

impl BuildSettings {
    /// The sphere builder's options, `page_bytes` applied.
    pub fn spheres_options(&self) -> BuildOptions {
        BuildOptions {
            page_bytes: self.page_bytes.unwrap_or(self.spheres.page_bytes),
            ..self.spheres
        }
    }
}

/// What a build made: the file, the kind's own statistics (for `--json`
/// summaries) and its node count.
#[derive(Debug)]
pub struct Built {
    pub file: PagedFile,
    pub stats: serde_json::Value,
    pub nodes: u64,
}

/// One hierarchy kind's builder.
#[derive(Debug)]
pub struct KindBuilder {
    pub kind: HierarchyKind,
    /// What the command line's `--kind` help says of it.
    pub about: &'static str,
    /// Builds the kind's file from a scene, consumed: a builder that needs
    /// the scene whole frees it as soon as it is done with it.
    pub build: fn(Scene, &BuildSettings, &dyn Progress) -> Result<Built, BuildError>,
    /// Whether `crate::out_of_core` can build the kind within a memory
    /// budget; the others load the scene whole.
    pub out_of_core: bool,
}

impl KindBuilder {
    /// The kind's name, as `--kind` takes it and reports give it.
    pub fn name(&self) -> &'static str {
        self.kind.name()
    }
}

/// Every kind's builder, one per [`HierarchyKind`].
pub const BUILDERS: &[KindBuilder] = &[
    KindBuilder {
        kind: HierarchyKind::Spheres,
        about: "QSplat's bounding spheres",
        build: build_spheres_kind,
        out_of_core: true,
    },
    KindBuilder {
        kind: HierarchyKind::Cubes,
        about: "the color-cube octree of Chamberlain et al., the geometry at its leaves",
        build: build_cubes_kind,
        out_of_core: false,
    },
    KindBuilder {
        kind: HierarchyKind::Plp,
        about: "PLP's Delaunay tessellation (Klosowski and Silva), for budgeted rendering",
        build: build_plp_kind,
        out_of_core: false,
    },
    KindBuilder {
        kind: HierarchyKind::Bsp,
        about: "the BSP by gaps of Shade et al.'s hierarchical image caching",
        build: build_bsp_kind,
        out_of_core: false,
    },
];

/// The builder of `kind`.
pub fn builder_for(kind: HierarchyKind) -> &'static KindBuilder {
    BUILDERS
        .iter()
        .find(|b| b.kind == kind)
        .unwrap_or_else(|| unreachable!("every hierarchy kind has a builder (a test checks)"))
}

/// The builder named `name` (`--kind`), if any.
pub fn builder_named(name: &str) -> Option<&'static KindBuilder> {
    BUILDERS.iter().find(|b| b.name() == name)
}

impl Built {
    /// `stats` as JSON (plain structs of numbers: they always serialize; a
    /// failure would leave the summary without them).
    fn new(file: PagedFile, stats: impl serde::Serialize, nodes: u64) -> Self {
        let stats = serde_json::to_value(stats).unwrap_or(serde_json::Value::Null);
        Self { file, stats, nodes }
    }
}

fn build_spheres_kind(
    scene: Scene,
    settings: &BuildSettings,
    progress: &dyn Progress,
) -> Result<Built, BuildError> {
    let options = settings.spheres_options();
    let (file, stats) = build_spheres_reporting(scene, &options, progress)?;
    let nodes = stats.nodes;
    Ok(Built::new(file, stats, nodes))
}

fn build_cubes_kind(
    scene: Scene,
    settings: &BuildSettings,
    _: &dyn Progress,
) -> Result<Built, BuildError> {
    let mut options = settings.cubes;
    options.page_bytes = settings.page_bytes.unwrap_or(options.page_bytes);
    let (file, stats) = build_cubes(scene, &options)?;
    let nodes = stats.nodes;
    Ok(Built::new(file, stats, nodes))
}

fn build_plp_kind(
    scene: Scene,
    settings: &BuildSettings,
    _: &dyn Progress,
) -> Result<Built, BuildError> {
    let mut options = settings.plp;
    options.page_bytes = settings.page_bytes.unwrap_or(options.page_bytes);
    let (file, stats) = build_plp(&scene, &options)?;
    drop(scene);
    let nodes = file.header.nodes;
    Ok(Built::new(file, stats, nodes))
}

fn build_bsp_kind(
    scene: Scene,
    settings: &BuildSettings,
    _: &dyn Progress,
) -> Result<Built, BuildError> {
    let (file, stats) = build_bsp(&scene, &settings.bsp)?;
    drop(scene);
    let nodes = file.header.nodes;
    Ok(Built::new(file, stats, nodes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_hierarchy_kind_has_one_builder() {
        for kind in HierarchyKind::ALL {
            let found: Vec<_> = BUILDERS.iter().filter(|b| b.kind == kind).collect();
            assert_eq!(found.len(), 1, "{kind:?}");
            assert_eq!(builder_for(kind).kind, kind);
            assert_eq!(builder_named(kind.name()).map(|b| b.kind), Some(kind));
        }
        assert_eq!(BUILDERS.len(), HierarchyKind::ALL.len());
        assert!(builder_named("octree").is_none());
    }
}
