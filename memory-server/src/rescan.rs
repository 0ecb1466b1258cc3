//! Keeps the catalog in step with the disk (or the object store) while the
//! server runs, by polling (a stat per scene file, or one listing of a
//! store's prefix, per interval: cheap, and the same on every platform and
//! file system, network ones included, where change notifications are
//! unreliable).
//!
//! On each pass, per scene name:
//! - a file that appeared is served once it has looked the same on two
//!   passes in a row (a file still being copied in is not opened half
//!   written); one that fails to open is warned about once per version;
//! - a file renamed over a served one (an atomic rebuild) is served in its
//!   new version to new sessions, while sessions already open finish on
//!   the old one, whose file they still hold open and which nobody changed;
//! - a served file changed in place (truncated, overwritten) or deleted
//!   retires its scene: the scene leaves the listing and its sessions are
//!   told why and closed; a valid file at the path later is served again.
//!
//! Reading a page also notices a change (`PageSource::read_page`), so a
//! session never waits for the next pass to stop sending a changed file.

use std::collections::HashMap;
use std::sync::Mutex;
use std::time::Duration;

use farfield_store::Stamp;

use super::catalog::Catalog;
use super::origin::{Entry, Origin};

/// How often the scenes folder is polled by default.
pub const DEFAULT_RESCAN_INTERVAL: Duration = Duration::from_secs(1);

/// A stored scene that is not (yet) served.
#[derive(Debug, Clone, PartialEq)]
enum Candidate {
    /// Seen once with this stamp; opened if the next pass sees it again.
    Seen(Stamp),
    /// Failed to open with this stamp; tried again once it changes.
    Failed(Stamp),
}

/// The watcher's memory between passes.
#[derive(Debug)]
pub struct Rescanner {
    origin: Origin,
    candidates: Mutex<HashMap<String, Candidate>>,
    /// Whether the origin itself could not be read on the last pass (warned
    /// once, not every pass).
    origin_failed: Mutex<bool>,
}

impl Rescanner {
    pub fn new(origin: Origin) -> Self {
        Self {
            origin,
            candidates: Mutex::new(HashMap::new()),
            origin_failed: Mutex::new(false),
        }
    }

    /// What the origin holds now, or `None` when it cannot be read
    /// (nothing is retired for that: it may be a blip).
    fn listing(&self) -> Option<Vec<Entry>> {
        let mut failed = self.origin_failed.lock().unwrap_or_else(|e| e.into_inner());
        match self.origin.listing() {
            Ok(listing) => {
                *failed = false;
                Some(listing)
            }
            Err(e) => {
                if !*failed {
                    tracing::warn!("cannot rescan the scenes: {e}");
                }
                *failed = true;
                None
            }
        }
    }

    /// One pass: brings `catalog` in step with what is stored. Blocking
    /// (stats and opens files, or asks a store).
    pub fn pass(&self, catalog: &Catalog) {
        let Some(listing) = self.listing() else {
            return;
        };
        let listed: HashMap<&str, &Entry> = listing.iter().map(|e| (e.name.as_str(), e)).collect();
        for scene in catalog.all() {
            if scene.is_retired() {
                catalog.remove(&scene);
            } else if let Some(why) = scene.source.changed() {
                scene.retire(&format!("its file changed on disk: {why}"));
                catalog.remove(&scene);
            } else if !listed.contains_key(scene.name.as_str()) {
                scene.retire("its file was deleted");
                catalog.remove(&scene);
            }
        }
        let mut candidates = self.candidates.lock().unwrap_or_else(|e| e.into_inner());
        candidates.retain(|name, _| listed.contains_key(name.as_str()));
        for (name, entry) in listed {
            let stamp = match &entry.stamp {
                Ok(stamp) => stamp.clone(),
                Err(e) => {
                    if let Some(scene) = catalog.get(name) {
                        scene.retire(&format!("its file cannot be read: {e}"));
                        catalog.remove(&scene);
                    }
                    candidates.remove(name);
                    continue;
                }
            };
            let served = catalog.get(name);
            if served
                .as_ref()
                .is_some_and(|s| s.stamp.same_version(&stamp))
            {
                candidates.remove(name);
                continue;
            }
            match candidates.get(name) {
                Some(Candidate::Seen(seen)) if *seen == stamp => {}
                Some(Candidate::Failed(failed)) if *failed == stamp => continue,
                _ => {
                    candidates.insert(name.to_owned(), Candidate::Seen(stamp));
                    continue;
                }
            }
            match catalog.open_scene(name, &entry.location) {
                Ok(scene) => {
                    candidates.remove(name);
                    if let Some(old) = served {
                        tracing::info!(
                            scene = %name,
                            "scene replaced: new sessions get the new version, open ones finish on theirs"
                        );
                        // An object replaced in a store is gone: sessions
                        // on the old version cannot finish on it (a file
                        // renamed over keeps the old one open and whole).
                        if matches!(old.stamp, Stamp::Object(_)) {
                            old.retire("it was replaced in the store");
                        }
                    }
                    if !scene.stamp.same_version(&stamp) {
                        // Changed again between the listing and the open:
                        // the next pass looks at it afresh.
                        tracing::debug!(scene = %name, "changed while opening");
                    }
                }
                Err(e) => {
                    tracing::warn!(scene = %name, "cannot serve this version of the scene: {e}");
                    candidates.insert(name.to_owned(), Candidate::Failed(stamp));
                }
            }
        }
    }
}
