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

/// Which version of a stored scene is served: a file's [`FileStamp`], or
/// an object's [`ObjectStamp`]. The server's watcher compares a served
/// scene's stamp with what its listing says now.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Stamp {
    File(FileStamp),
    Object(ObjectStamp),
}

impl Stamp {
    /// Whether both name the same stored version. Objects are compared as
    /// [`ObjectStamp::same_version`] says.
    pub fn same_version(&self, other: &Self) -> bool {
        match (self, other) {
            (Self::File(a), Self::File(b)) => a == b,
            (Self::Object(a), Self::Object(b)) => a.same_version(b),
            _ => false,
        }
    }
}

/// An object's version, as a store's listing or a HEAD request gives it.
/// Objects are never changed in place, only replaced, so a new entity tag,
/// length or modification time is a new object.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectStamp {
    pub len: u64,
    pub e_tag: Option<String>,
    /// Seconds since the Unix epoch (HTTP dates have no finer unit).
    pub modified_s: i64,
}

impl ObjectStamp {
    /// Whether both name the same version: same length and modification
    /// second, and the same entity tag where both have one (some stores
    /// list objects without theirs).
    pub fn same_version(&self, other: &Self) -> bool {
        self.len == other.len
            && self.modified_s == other.modified_s
            && match (&self.e_tag, &other.e_tag) {
                (Some(a), Some(b)) => a == b,
                _ => true,
            }
    }
}

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
    fn an_object_listed_without_its_tag_is_the_version_opened() {
        let opened = ObjectStamp {
            len: 10,
            e_tag: Some("\"abc\"".into()),
            modified_s: 100,
        };
        let listed = ObjectStamp {
            e_tag: None,
            ..opened.clone()
        };
        assert!(Stamp::Object(opened.clone()).same_version(&Stamp::Object(listed.clone())));
        let retagged = ObjectStamp {
            e_tag: Some("\"def\"".into()),
            ..opened.clone()
        };
        assert!(!opened.same_version(&retagged));
        assert!(!opened.same_version(&ObjectStamp {
            len: 11,
            ..listed.clone()
        }));
        assert!(!opened.same_version(&ObjectStamp {
            modified_s: 101,
            ..listed
        }));
    }

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
