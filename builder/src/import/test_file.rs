//! [`TestFile`]: a file the importers' tests write, read and forget.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use super::{ImportError, Params, load_input};
use crate::scene::Scene;

/// A file under a name of its own in the temporary folder (so tests on
/// several threads never share one), removed when dropped.
#[derive(Debug)]
pub(crate) struct TestFile(PathBuf);

impl TestFile {
    /// Writes `bytes` to a new file whose name ends in `name` (its
    /// extension picks the importer).
    pub fn new(name: &str, bytes: impl AsRef<[u8]>) -> Self {
        static N: AtomicUsize = AtomicUsize::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        let path = std::env::temp_dir().join(format!("ff-{}-{n}-{name}", std::process::id()));
        std::fs::write(&path, bytes).expect("writing a test file");
        Self(path)
    }

    pub fn path(&self) -> &Path {
        &self.0
    }

    /// The file through [`load_input`], as the command line reads it
    /// (validation included).
    pub fn load_input(&self) -> Result<Scene, ImportError> {
        load_input(
            self.0.to_str().expect("temporary paths are UTF-8"),
            &Params::default(),
        )
    }
}

impl Drop for TestFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}
