//! [`DiskTier`]: a local-disk second tier under a store's pages.
//!
//! A replica's page cache is memory and small beside its scenes; a page it
//! loses would cost a request to the store again. The tier keeps pages
//! read from the store in a local folder, bounded in bytes and evicted
//! least recently used, so a lost page costs a local read instead, and
//! pages held there are served while the store is down. A page from the
//! tier is verified like one from the store (a damaged file is dropped
//! and read from the store again); the folder is emptied at start, so
//! nothing of an earlier run, or written half, is ever trusted.

use std::path::{Path, PathBuf};
use std::sync::Mutex;

use lru::LruCache;

/// Pages held in a folder, at most `capacity` bytes of them.
#[derive(Debug)]
pub struct DiskTier {
    dir: PathBuf,
    capacity: u64,
    index: Mutex<Index>,
}

#[derive(Debug)]
struct Index {
    /// File name -> bytes.
    files: LruCache<String, u64>,
    bytes: u64,
}

impl DiskTier {
    /// A tier in `dir` (made, and emptied of what an earlier run left).
    pub fn open(dir: &Path, capacity: u64) -> std::io::Result<Self> {
        std::fs::create_dir_all(dir)?;
        for entry in std::fs::read_dir(dir)? {
            let path = entry?.path();
            if path.is_file() {
                std::fs::remove_file(path)?;
            }
        }
        Ok(Self {
            dir: dir.to_owned(),
            capacity,
            index: Mutex::new(Index {
                files: LruCache::unbounded(),
                bytes: 0,
            }),
        })
    }

    fn index(&self) -> std::sync::MutexGuard<'_, Index> {
        self.index.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// The bytes stored under `name`, if the tier holds them.
    pub fn get(&self, name: &str) -> Option<Vec<u8>> {
        self.index().files.get(name)?;
        match std::fs::read(self.dir.join(name)) {
            Ok(bytes) => Some(bytes),
            Err(_) => {
                self.remove(name);
                None
            }
        }
    }

    /// Forgets `name` (its bytes were found damaged).
    pub fn remove(&self, name: &str) {
        let mut index = self.index();
        if let Some(len) = index.files.pop(name) {
            index.bytes -= len;
        }
        let _ = std::fs::remove_file(self.dir.join(name));
    }

    /// Keeps `bytes` under `name` (written aside, then renamed into place,
    /// so a reader never finds half a file), evicting the least recently
    /// used past the bound. A failure to write only loses the copy.
    pub fn put(&self, name: &str, bytes: &[u8]) -> bool {
        let len = bytes.len() as u64;
        if len > self.capacity {
            return false;
        }
        let temp = self.dir.join(format!(".{name}.tmp"));
        let written =
            std::fs::write(&temp, bytes).and_then(|()| std::fs::rename(&temp, self.dir.join(name)));
        if written.is_err() {
            let _ = std::fs::remove_file(&temp);
            return false;
        }
        let mut index = self.index();
        if let Some(old) = index.files.put(name.to_owned(), len) {
            index.bytes -= old;
        }
        index.bytes += len;
        while index.bytes > self.capacity {
            match index.files.pop_lru() {
                Some((evicted, old)) => {
                    index.bytes -= old;
                    let _ = std::fs::remove_file(self.dir.join(evicted));
                }
                None => break,
            }
        }
        true
    }

    /// Bytes held now.
    pub fn bytes(&self) -> u64 {
        self.index().bytes
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holds_what_fits_and_evicts_the_least_recently_used() {
        let dir = std::env::temp_dir().join(format!("farfield-tier-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join("left-over"), b"from an earlier run").unwrap();
        let tier = DiskTier::open(&dir, 100).unwrap();
        assert!(!dir.join("left-over").exists(), "emptied at start");
        assert!(tier.put("a", &[1; 40]));
        assert!(tier.put("b", &[2; 40]));
        assert_eq!(tier.get("a"), Some(vec![1; 40]), "touch a");
        assert!(tier.put("c", &[3; 40]));
        assert_eq!(tier.get("b"), None, "b was least recently used");
        assert!(!dir.join("b").exists());
        assert_eq!(tier.bytes(), 80);
        assert!(!tier.put("huge", &[0; 101]), "larger than the tier");
        tier.remove("a");
        assert_eq!((tier.get("a"), tier.bytes()), (None, 40));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
