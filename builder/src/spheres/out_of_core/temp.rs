//! The build's temporary folder: made under `--tmp`, removed when the
//! build ends (succeeded or failed), and found and removed by the next
//! build when a killed one left it behind.
//!
//! A folder is owned by the process holding the exclusive lock on its
//! `lock` file. The operating system drops the lock when the process dies,
//! however it dies, so a folder whose lock can be taken belongs to nobody.

use std::fs::File;
use std::io;
use std::path::{Path, PathBuf};
use std::time::{Duration, SystemTime};

/// Name prefix of every build's temporary folder.
const PREFIX: &str = ".farfield-build-";

/// A folder without a lock file younger than this may be a build's being
/// made right now; older, it is a build killed before it took its lock.
const UNLOCKED_GRACE: Duration = Duration::from_secs(60);

/// A build's temporary folder, removed with everything in it when dropped.
#[derive(Debug)]
pub struct TempDir {
    path: PathBuf,
    /// Held for the folder's life: the lock is the claim of ownership.
    _lock: File,
}

impl TempDir {
    /// Makes a fresh folder under `parent` (made if missing), after
    /// removing the folders of builds that are no longer running.
    pub fn create(parent: &Path) -> io::Result<Self> {
        std::fs::create_dir_all(parent)?;
        remove_abandoned(parent);
        let nanos = SystemTime::now()
            .duration_since(SystemTime::UNIX_EPOCH)
            .map_or(0, |d| d.subsec_nanos());
        let path = parent.join(format!("{PREFIX}{}-{nanos}", std::process::id()));
        std::fs::create_dir(&path)?;
        let made = File::create(path.join("lock")).and_then(|lock| {
            lock.try_lock().map_err(io::Error::other)?;
            Ok(lock)
        });
        match made {
            Ok(lock) => Ok(Self { path, _lock: lock }),
            Err(e) => {
                let _ = std::fs::remove_dir_all(&path);
                Err(e)
            }
        }
    }

    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A file in the folder.
    pub fn file(&self, name: &str) -> PathBuf {
        self.path.join(name)
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// Removes the temporary folders under `parent` that no running build
/// owns. Errors are ignored: another build may be removing the same folder.
fn remove_abandoned(parent: &Path) {
    let Ok(entries) = std::fs::read_dir(parent) else {
        return;
    };
    for entry in entries.flatten() {
        if !entry.file_name().to_string_lossy().starts_with(PREFIX) {
            continue;
        }
        let dir = entry.path();
        let abandoned = match File::open(dir.join("lock")) {
            // Taken: its owner is gone (the lock is released at once, when
            // `lock` is dropped below, after the folder is removed).
            Ok(lock) => lock.try_lock().is_ok(),
            Err(_) => entry
                .metadata()
                .and_then(|m| m.modified())
                .ok()
                .and_then(|t| t.elapsed().ok())
                .is_some_and(|age| age > UNLOCKED_GRACE),
        };
        if abandoned {
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("farfield-temp-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_folder_goes_when_dropped_and_an_abandoned_one_at_the_next_build() {
        let parent = scratch("drop");
        let dir = TempDir::create(&parent).unwrap();
        std::fs::write(dir.file("chunk-0"), b"points").unwrap();
        let path = dir.path().to_owned();
        // A live build's folder is left alone by another build.
        let other = TempDir::create(&parent).unwrap();
        assert!(path.join("chunk-0").exists());
        drop(dir);
        assert!(!path.exists());
        drop(other);

        // A killed build's folder: a lock file nobody holds.
        let killed = parent.join(format!("{PREFIX}1-2"));
        std::fs::create_dir(&killed).unwrap();
        std::fs::write(killed.join("lock"), b"").unwrap();
        std::fs::write(killed.join("chunk-3"), b"points").unwrap();
        // Someone else's folder, and a build's being made: kept.
        let foreign = parent.join("mine");
        std::fs::create_dir(&foreign).unwrap();
        let young = parent.join(format!("{PREFIX}4-5"));
        std::fs::create_dir(&young).unwrap();
        let next = TempDir::create(&parent).unwrap();
        assert!(!killed.exists(), "the abandoned folder is removed");
        assert!(foreign.exists() && young.exists());
        drop(next);
        let _ = std::fs::remove_dir_all(&parent);
    }
}
