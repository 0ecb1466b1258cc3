//! A real S3-compatible store on loopback for the object-storage tests:
//! `s3s-fs` (the `s3s` project's file-system store, installed by
//! `cargo install s3s-fs --features binary`, as `.ci/run` does), each
//! bucket a folder under its root and each object a plain file, so a test
//! can damage a stored object in place.
//!
//! Where the binary is missing the tests say they were skipped and pass;
//! `FARFIELD_REQUIRE_S3=1` (set by `.ci/run`) turns that into a failure.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::Duration;

use farfield_objects::{Bucket, BucketOptions, StoreUrl};

pub(crate) const ACCESS_KEY: &str = "farfield-test";
pub(crate) const SECRET_KEY: &str = "farfield-test-secret";

/// The store's binary, if this machine has it.
fn binary() -> Option<PathBuf> {
    if let Some(path) = std::env::var_os("FARFIELD_S3S_FS") {
        return Some(path.into());
    }
    let on_path = Command::new("s3s-fs")
        .arg("--help")
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .is_ok();
    if on_path {
        return Some("s3s-fs".into());
    }
    let home = std::env::var_os("CARGO_HOME")
        .map(PathBuf::from)
        .or_else(|| std::env::var_os("HOME").map(|h| Path::new(&h).join(".cargo")))?;
    let installed = home.join("bin/s3s-fs");
    installed.exists().then_some(installed)
}

/// A running store; killed on drop.
pub(crate) struct S3Store {
    child: Option<Child>,
    root: PathBuf,
    pub(crate) port: u16,
}

impl S3Store {
    /// A store on a free port over `root` (made, with a folder per bucket
    /// in `buckets`), or `None` when the binary is missing and the test
    /// may skip.
    pub(crate) fn start_or_skip(root: &Path, buckets: &[&str]) -> Option<Self> {
        if binary().is_none() {
            if std::env::var_os("FARFIELD_REQUIRE_S3").is_some_and(|v| v == "1") {
                panic!("FARFIELD_REQUIRE_S3=1 but s3s-fs is not installed");
            }
            eprintln!(
                "SKIPPED: no s3s-fs (cargo install s3s-fs --version 0.14.1 --features binary)"
            );
            return None;
        }
        for bucket in buckets {
            std::fs::create_dir_all(root.join(bucket)).expect("bucket folder");
        }
        let mut store = Self {
            child: None,
            root: root.to_owned(),
            port: 0,
        };
        store.start_on(0);
        Some(store)
    }

    /// Starts the store (again) on `port` (0: a free one).
    pub(crate) fn start_on(&mut self, port: u16) {
        let mut child = Command::new(binary().expect("s3s-fs"))
            .args(["--host", "127.0.0.1", "--port", &port.to_string()])
            .args(["--access-key", ACCESS_KEY, "--secret-key", SECRET_KEY])
            .arg(&self.root)
            .env("RUST_LOG", "info")
            .env("NO_COLOR", "1")
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn s3s-fs");
        let (tx, rx) = std::sync::mpsc::channel();
        for out in [
            Box::new(child.stdout.take().expect("stdout")) as Box<dyn std::io::Read + Send>,
            Box::new(child.stderr.take().expect("stderr")),
        ] {
            let tx = tx.clone();
            std::thread::spawn(move || {
                for line in BufReader::new(out).lines().map_while(Result::ok) {
                    let _ = tx.send(line);
                }
            });
        }
        let marker = "server is running at http://";
        self.port = loop {
            let line = rx
                .recv_timeout(Duration::from_secs(20))
                .expect("s3s-fs printed no address");
            if let Some(at) = line.find(marker) {
                let address = line[at + marker.len()..].trim();
                let port = address.rsplit(':').next().and_then(|p| p.parse().ok());
                break port.expect("s3s-fs's port");
            }
        };
        self.child = Some(child);
    }

    /// Kills the store (its files stay).
    pub(crate) fn stop(&mut self) {
        if let Some(mut child) = self.child.take() {
            let _ = child.kill();
            let _ = child.wait();
        }
    }

    pub(crate) fn endpoint(&self) -> String {
        format!("http://127.0.0.1:{}", self.port)
    }

    /// Where object `key` of `bucket` lies on disk.
    pub(crate) fn object_file(&self, bucket: &str, key: &str) -> PathBuf {
        self.root.join(bucket).join(key)
    }

    /// A client of `url` (`s3://bucket/prefix`) with these credentials.
    pub(crate) fn bucket(&self, url: &str, timeout: Duration) -> Arc<Bucket> {
        self.bucket_with(url, timeout, farfield_objects::DEFAULT_COALESCE_BYTES)
    }

    /// As [`S3Store::bucket`], coalescing neighbours up to `coalesce_bytes`.
    pub(crate) fn bucket_with(
        &self,
        url: &str,
        timeout: Duration,
        coalesce_bytes: u64,
    ) -> Arc<Bucket> {
        self.bucket_options(
            url,
            BucketOptions {
                timeout,
                coalesce_bytes,
                ..BucketOptions::default()
            },
        )
    }

    /// A client of `url` with `options`, and this store's address and keys.
    pub(crate) fn bucket_options(&self, url: &str, options: BucketOptions) -> Arc<Bucket> {
        let options = BucketOptions {
            endpoint: Some(self.endpoint()),
            credentials: Some((ACCESS_KEY.into(), SECRET_KEY.into())),
            ..options
        };
        let url = StoreUrl::parse(url).expect("store url");
        Arc::new(Bucket::open(&url, &options, Default::default()).expect("bucket"))
    }

    /// The environment a child process reaches this store with.
    pub(crate) fn env(&self) -> [(&'static str, String); 4] {
        [
            ("AWS_ENDPOINT_URL", self.endpoint()),
            ("AWS_ACCESS_KEY_ID", ACCESS_KEY.into()),
            ("AWS_SECRET_ACCESS_KEY", SECRET_KEY.into()),
            ("AWS_REGION", "us-east-1".into()),
        ]
    }
}

impl Drop for S3Store {
    fn drop(&mut self) {
        self.stop();
    }
}
