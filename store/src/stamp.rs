//! [`FileStamp`]: which version of a file is on disk.
//!
//! A served scene remembers the stamp of the file it opened. Comparing it
//! with the stamp of the path now tells the server's folder watcher whether
//! a scene was replaced (a new file renamed over the path: another device
//! or inode), and comparing it with the stamp of the open descriptor tells
//! whether the opened file itself was changed in place (its length or
//! modification time moved), after which none of its pages can be trusted.

use std::fs::Metadata;
use std::time::SystemTime;

/// A file's identity and version, as `stat` gives them.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FileStamp {
    /// Device and inode: which file (zero where the platform has none).
    pub dev: u64,
    pub ino: u64,
    pub len: u64,
    pub modified: Option<SystemTime>,
}

impl FileStamp {
    pub fn of(meta: &Metadata) -> Self {
        #[cfg(unix)]
        let (dev, ino) = {
            use std::os::unix::fs::MetadataExt;
            (meta.dev(), meta.ino())
        };
        #[cfg(not(unix))]
        let (dev, ino) = (0, 0);
        Self {
            dev,
            ino,
            len: meta.len(),
            modified: meta.modified().ok(),
        }
    }

    /// Whether both stamps name the same file (whatever its contents).
    pub fn same_file(&self, other: &Self) -> bool {
        self.dev == other.dev && self.ino == other.ino
    }

    /// How the same file changed from `self` to `now`, if it did.
    pub fn change_to(&self, now: &Self) -> Option<String> {
        if !self.same_file(now) {
            Some("it is another file now".into())
        } else if now.len != self.len {
            Some(format!(
                "its length went from {} to {} bytes",
                self.len, now.len
            ))
        } else if now.modified != self.modified {
            Some("it was written to".into())
        } else {
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn changes_are_named_and_sameness_is_by_inode() {
        let dir = std::env::temp_dir().join(format!("farfield-stamp-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a"), dir.join("b"));
        std::fs::write(&a, b"one").unwrap();
        std::fs::write(&b, b"one").unwrap();
        let stamp = |p: &std::path::Path| FileStamp::of(&std::fs::metadata(p).unwrap());
        let first = stamp(&a);
        assert_eq!(first.change_to(&stamp(&a)), None);
        assert!(!first.same_file(&stamp(&b)) || cfg!(not(unix)));
        std::fs::write(&a, b"longer").unwrap();
        let why = first.change_to(&stamp(&a)).expect("changed");
        assert!(why.contains("from 3 to 6"), "{why}");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
