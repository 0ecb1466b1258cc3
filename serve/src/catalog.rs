//! The scenes a server holds: one [`PageSource`] each (a [`SceneFile`],
//! read by positional reads, for now), found by scanning a folder for `*.ff` or given
//! as (name, path) pairs.
//!
//! A scene also precomputes, per page, the range of pages that hold the
//! children of its nodes, which is what prefetch reads ahead.

use std::collections::HashMap;
use std::ops::Range;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use serde_json::{Value, json};

use super::ServeError;
use farfield_protocol::file::FileHeader;
use farfield_store::{PageSource, SceneFile, StoreError};

/// The extension of the paged files a scenes folder is scanned for.
pub const SCENE_EXTENSION: &str = "ff";

/// One scene being served.
#[derive(Debug)]
pub struct ServedScene {
    /// Index in the catalog; part of the page cache key.
    pub id: u32,
    pub name: String,
    /// Where its header and pages come from.
    pub source: Box<dyn PageSource>,
    /// Per page: the pages holding children of its nodes (never itself).
    children: Vec<Range<u32>>,
}

impl ServedScene {
    pub fn open(id: u32, name: &str, path: &Path) -> Result<Self, StoreError> {
        let source = SceneFile::open(path)?;
        let children = child_ranges(&source.header);
        Ok(Self {
            id,
            name: name.to_owned(),
            source: Box::new(source),
            children,
        })
    }

    pub fn page_count(&self) -> u32 {
        u32::try_from(self.source.header().pages.len()).unwrap_or(u32::MAX)
    }

    /// Stored length of `page` (as the directory says), if it exists.
    pub fn page_len(&self, page: u32) -> Option<u64> {
        let e = self.source.header().pages.get(page as usize)?;
        Some(u64::from(e.length))
    }

    /// Pages holding the children of `page`'s nodes.
    pub fn child_pages(&self, page: u32) -> Range<u32> {
        self.children.get(page as usize).cloned().unwrap_or(0..0)
    }

    /// The short description `GET /scenes` lists.
    pub fn summary(&self) -> Value {
        let h = &self.source.header();
        json!({
            "name": self.name,
            "kind": h.kind.name(),
            "bounds_min": h.bounds_min.to_array(),
            "bounds_max": h.bounds_max.to_array(),
            "nodes": h.nodes,
            "bytes": self.source.stored_len(),
        })
    }

    /// The summary plus pages and attributes, for `GET /scenes/{name}`.
    pub fn details(&self) -> Value {
        let h = &self.source.header();
        let mut v = self.summary();
        if let Value::Object(map) = &mut v {
            let extra = json!({
                "pages": h.pages.len(),
                "page_bytes_max": h.pages.iter().map(|p| p.length).max().unwrap_or(0),
                "levels": h.levels,
                "leaves": h.leaves,
                "node_bytes": h.node_bytes,
                "attributes": {
                    "color": h.attributes.color,
                    "normals": h.attributes.normals,
                    "leaf_geometry": h.attributes.leaf_geometry,
                },
                "root_center": h.root_center.to_array(),
                "root_radius": h.root_radius,
            });
            if let Value::Object(extra) = extra {
                map.extend(extra);
            }
        }
        v
    }
}

/// Children of page p's nodes are the breadth-first range from p's
/// `first_child` to the next page's (or to the node count for the last
/// page); the pages holding that range are found through the directory.
fn child_ranges(h: &FileHeader) -> Vec<Range<u32>> {
    let n = h.pages.len();
    (0..n)
        .map(|p| {
            let start = h.pages[p].first_child;
            let end = h.pages.get(p + 1).map_or(h.nodes, |e| e.first_child);
            if end <= start {
                return 0..0;
            }
            match (h.page_of(start), h.page_of(end - 1)) {
                (Some(first), Some(last)) => {
                    let first = first.max(p + 1);
                    let (first, last) = (first as u32, last as u32);
                    if first > last { 0..0 } else { first..last + 1 }
                }
                _ => 0..0,
            }
        })
        .collect()
}

/// Every scene, by id and by name.
#[derive(Debug, Default)]
pub struct Catalog {
    scenes: Vec<Arc<ServedScene>>,
    by_name: HashMap<String, usize>,
}

impl Catalog {
    /// Opens each (name, path); a file that fails to open is logged and
    /// skipped so one bad file never takes the others down. Two scenes with
    /// one name are an error: a client could not tell them apart.
    pub fn open(entries: &[(String, PathBuf)]) -> Result<Self, ServeError> {
        let mut catalog = Self::default();
        for (name, path) in entries {
            if catalog.by_name.contains_key(name) {
                return Err(ServeError::DuplicateScene(name.clone()));
            }
            let id = u32::try_from(catalog.scenes.len()).unwrap_or(u32::MAX);
            match ServedScene::open(id, name, path) {
                Ok(scene) => {
                    tracing::info!(
                        scene = %name,
                        path = %path.display(),
                        pages = scene.page_count(),
                        nodes = scene.source.header().nodes,
                        "serving scene"
                    );
                    catalog.by_name.insert(name.clone(), catalog.scenes.len());
                    catalog.scenes.push(Arc::new(scene));
                }
                Err(e) => tracing::warn!(scene = %name, "skipping scene: {e}"),
            }
        }
        Ok(catalog)
    }

    pub fn get(&self, name: &str) -> Option<&Arc<ServedScene>> {
        self.by_name.get(name).map(|&i| &self.scenes[i])
    }

    pub fn by_id(&self, id: u32) -> Option<&Arc<ServedScene>> {
        self.scenes.get(id as usize)
    }

    /// Scenes in name order.
    pub fn iter(&self) -> impl Iterator<Item = &Arc<ServedScene>> {
        self.scenes.iter()
    }

    pub fn len(&self) -> usize {
        self.scenes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.scenes.is_empty()
    }
}

/// The `*.ff` files directly in `dir`, named by file stem, sorted by name.
pub fn scan_dir(dir: &Path) -> Result<Vec<(String, PathBuf)>, ServeError> {
    let io = |error| ServeError::ScenesDir {
        path: dir.to_owned(),
        error,
    };
    let mut out = Vec::new();
    for entry in std::fs::read_dir(dir).map_err(io)? {
        let path = entry.map_err(io)?.path();
        if path.extension().and_then(|e| e.to_str()) != Some(SCENE_EXTENSION) || !path.is_file() {
            continue;
        }
        match path.file_stem().and_then(|s| s.to_str()) {
            Some(stem) if !stem.is_empty() => out.push((stem.to_owned(), path.clone())),
            _ => tracing::warn!(path = %path.display(), "skipping scene: name is not UTF-8"),
        }
    }
    out.sort();
    Ok(out)
}
