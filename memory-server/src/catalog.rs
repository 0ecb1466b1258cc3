//! The scenes a server holds: one [`PageSource`] each (a file read by
//! positional reads, or an object read by range requests), found through
//! the server's [`crate::origin::Origin`] and kept current while the server
//! runs by [`crate::rescan`].
//!
//! A scene also precomputes, per page, the range of pages that hold the
//! children of its nodes, which is what prefetch reads ahead. A scene whose
//! file changed under it is *retired*: it leaves the listing at once, and
//! its open sessions are told through [`ServedScene::retired`].

use std::collections::BTreeMap;
use std::ops::Range;
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, RwLock};

use axum::body::Bytes;
use serde_json::{Value, json};
use tokio::sync::watch;

use super::ServeError;
use farfield_protocol::codec::encode_header_frames;
use farfield_protocol::directory::Directory;
use farfield_protocol::file::{FileHeader, PageLayout};
use farfield_store::{PageSource, Stamp, StoreError};

use super::origin::Location;

/// One scene being served.
#[derive(Debug)]
pub struct ServedScene {
    /// Unique to this version of this scene; part of the page cache key.
    pub id: u32,
    pub name: String,
    /// Where it is stored, and the version opened.
    pub location: Location,
    pub stamp: Stamp,
    /// Where its header and pages come from.
    pub source: Box<dyn PageSource>,
    /// Per page: the pages holding children of its nodes (never itself).
    children: Vec<Range<u32>>,
    /// The header as the frames every session starts with, made once: a
    /// large directory is not copied per connection.
    header_frames: Vec<Bytes>,
    /// Why it was taken out of service, once it was.
    retired: watch::Sender<Option<Arc<str>>>,
}

impl ServedScene {
    pub fn open(id: u32, name: &str, location: &Location) -> Result<Self, StoreError> {
        Ok(Self::with_source(id, name, location, location.open()?))
    }

    /// A scene over a source already open.
    pub fn with_source(
        id: u32,
        name: &str,
        location: &Location,
        source: Box<dyn PageSource>,
    ) -> Self {
        Self {
            id,
            name: name.to_owned(),
            location: location.clone(),
            stamp: source.stamp(),
            children: child_ranges(source.header(), source.directory()),
            header_frames: encode_header_frames(source.header_bytes())
                .into_iter()
                .map(Bytes::from)
                .collect(),
            source,
            retired: watch::Sender::new(None),
        }
    }

    /// The header frames a session sends after its hello, in order.
    pub fn header_frames(&self) -> &[Bytes] {
        &self.header_frames
    }

    /// Bytes of the largest header frame.
    pub fn largest_header_frame(&self) -> usize {
        self.header_frames.iter().map(Bytes::len).max().unwrap_or(0)
    }

    /// Takes the scene out of service, once: new sessions no longer find
    /// it, and open ones are told `reason` and closed.
    pub fn retire(&self, reason: &str) {
        let newly = self.retired.send_if_modified(|r| {
            if r.is_some() {
                return false;
            }
            *r = Some(reason.into());
            true
        });
        if newly {
            tracing::warn!(
                scene = %self.name,
                location = %self.location,
                "scene taken out of service: {reason}"
            );
        }
    }

    pub fn is_retired(&self) -> bool {
        self.retired.borrow().is_some()
    }

    /// Why it was taken out of service, if it was.
    pub fn retired_reason(&self) -> Option<String> {
        self.retired.borrow().as_deref().map(str::to_owned)
    }

    /// Resolves with the reason once the scene is taken out of service.
    pub async fn retired(&self) -> Arc<str> {
        let mut rx = self.retired.subscribe();
        loop {
            if let Some(reason) = rx.borrow_and_update().clone() {
                return reason;
            }
            // The sender lives as long as `self`, so this cannot fail.
            if rx.changed().await.is_err() {
                std::future::pending::<()>().await;
            }
        }
    }

    /// The scene's pages (directory pages not counted).
    pub fn page_count(&self) -> u32 {
        self.source.header().page_count
    }

    /// Every page id a client may ask for: the scene's pages, then the
    /// directory's.
    pub fn id_count(&self) -> u32 {
        self.source.directory().id_count()
    }

    /// Stored length of page id `page` (as the directory says), if it
    /// exists.
    pub fn page_len(&self, page: u32) -> Option<u64> {
        let e = self.source.directory().extent(page)?;
        Some(u64::from(e.length))
    }

    /// Bytes of the largest page, directory pages included.
    pub fn largest_page(&self) -> usize {
        let d = self.source.directory();
        (0..d.id_count())
            .filter_map(|id| d.extent(id))
            .map(|e| e.length as usize)
            .max()
            .unwrap_or(0)
    }

    /// Pages holding the children of `page`'s nodes.
    pub fn child_pages(&self, page: u32) -> Range<u32> {
        self.children.get(page as usize).cloned().unwrap_or(0..0)
    }

    /// The directory pages a client needs, root first, to place `page`:
    /// a page is never pushed before them.
    pub fn directory_path(&self, page: u32) -> Vec<u32> {
        self.source.directory().path_to(page)
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
                "pages": h.page_count,
                "directory_pages": h.directory_pages,
                "page_bytes_max": self.source.directory().entries().map(|(_, p)| p.length).max().unwrap_or(0),
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
///
/// A skeleton-first file (PLP's tessellation, image caching's BSP) has
/// none to offer: its root's children are every leaf, so reading them
/// ahead would read the whole scene. Its clients ask in their own order,
/// which is the prefetch order.
fn child_ranges(h: &FileHeader, d: &Directory) -> Vec<Range<u32>> {
    let n = h.page_count;
    if h.kind.layout() == PageLayout::SkeletonFirst {
        return vec![0..0; n as usize];
    }
    (0..n)
        .map(|p| {
            let (Some(e), Some(end)) = (d.entry(p), d.children_end(p)) else {
                return 0..0;
            };
            let start = e.first_child;
            if end <= start {
                return 0..0;
            }
            match (d.page_of(start), d.page_of(end - 1)) {
                (Some(first), Some(last)) => {
                    let first = first.max(p + 1);
                    if first > last { 0..0 } else { first..last + 1 }
                }
                _ => 0..0,
            }
        })
        .collect()
}

/// The scenes being served, by name: changed while the server runs by the
/// folder watcher ([`crate::rescan`]), read by every request.
#[derive(Debug, Default)]
pub struct Catalog {
    scenes: RwLock<BTreeMap<String, Arc<ServedScene>>>,
    /// Ids are never reused, so a scene's new version never meets its old
    /// one's pages in the cache.
    next_id: AtomicU32,
}

impl Catalog {
    /// Opens each (name, path); a file that fails to open is logged and
    /// skipped so one bad file never takes the others down. Two scenes with
    /// one name are an error: a client could not tell them apart.
    pub fn open(entries: &[(String, Location)]) -> Result<Self, ServeError> {
        let catalog = Self::default();
        let mut seen = std::collections::HashSet::new();
        for (name, location) in entries {
            if !seen.insert(name) {
                return Err(ServeError::DuplicateScene(name.clone()));
            }
            if let Err(e) = catalog.open_scene(name, location) {
                tracing::warn!(scene = %name, "skipping scene: {e}");
            }
        }
        Ok(catalog)
    }

    /// Opens the scene at `location` as scene `name`, in place of any
    /// version served now (sessions open on that one finish on it).
    pub fn open_scene(
        &self,
        name: &str,
        location: &Location,
    ) -> Result<Arc<ServedScene>, StoreError> {
        let id = self.next_id.fetch_add(1, Ordering::Relaxed);
        let scene = Arc::new(ServedScene::open(id, name, location)?);
        tracing::info!(
            scene = %name,
            %location,
            pages = scene.page_count(),
            nodes = scene.source.header().nodes,
            "serving scene"
        );
        self.write().insert(name.to_owned(), scene.clone());
        Ok(scene)
    }

    /// Stops listing `scene` (if it is still the version listed under its
    /// name).
    pub fn remove(&self, scene: &ServedScene) {
        let mut scenes = self.write();
        if scenes.get(&scene.name).is_some_and(|s| s.id == scene.id) {
            scenes.remove(&scene.name);
        }
    }

    fn read(&self) -> std::sync::RwLockReadGuard<'_, BTreeMap<String, Arc<ServedScene>>> {
        self.scenes.read().unwrap_or_else(|e| e.into_inner())
    }

    fn write(&self) -> std::sync::RwLockWriteGuard<'_, BTreeMap<String, Arc<ServedScene>>> {
        self.scenes.write().unwrap_or_else(|e| e.into_inner())
    }

    /// The scene served under `name` now; never one taken out of service.
    pub fn get(&self, name: &str) -> Option<Arc<ServedScene>> {
        self.read().get(name).filter(|s| !s.is_retired()).cloned()
    }

    /// Every scene in service, in name order.
    pub fn list(&self) -> Vec<Arc<ServedScene>> {
        self.read()
            .values()
            .filter(|s| !s.is_retired())
            .cloned()
            .collect()
    }

    /// Every scene listed, in service or not yet removed after it left it.
    pub(crate) fn all(&self) -> Vec<Arc<ServedScene>> {
        self.read().values().cloned().collect()
    }

    pub fn len(&self) -> usize {
        self.list().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}
