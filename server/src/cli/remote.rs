//! Builds whose inputs or parts are in object storage, as a build on many
//! machines runs (Entwine's subset builds read and write a store): the
//! builder reads and writes local files only, so inputs named by store
//! addresses are downloaded into the build's temporary folder first, a
//! part built for a store address is uploaded when it is whole (its
//! manifest last, so a part is never seen half-written), and the merge
//! downloads the parts it is given by address.

use std::path::{Path, PathBuf};

use anyhow::Context;
use farfield_builder::import::{READABLE, is_readable};
use farfield_builder::out_of_core::{MANIFEST, TempDir};
use farfield_objects::{
    Bucket, ObjectFile, RemoteError, download_file, is_store_url, list_files, upload_file,
};

use super::StoreArgs;

/// A temporary folder under `tmp` for what is downloaded from a store,
/// when any of `names` is a store address (gone when dropped; a killed
/// command's is removed by the next build).
pub(super) fn staging_for<'a>(
    mut names: impl Iterator<Item = &'a str>,
    tmp: &Path,
) -> anyhow::Result<Option<TempDir>> {
    if !names.any(is_store_url) {
        return Ok(None);
    }
    let dir = TempDir::create(tmp)
        .with_context(|| format!("making a temporary folder in {}", tmp.display()))?;
    Ok(Some(dir))
}

/// A build's inputs as the builder reads them: local paths, with each
/// store address replaced by the files downloaded for it.
pub(super) struct Staged {
    pub inputs: Vec<String>,
    /// Each downloaded file and the address it came from (what a part's
    /// manifest names it, the same on every machine).
    pub names: Vec<(PathBuf, String)>,
}

/// Downloads the inputs of `inputs` that are store addresses into `dir`:
/// an object (`s3://bucket/tile.las`), or every object under a prefix
/// whose extension a build reads (`s3://bucket/survey/`, as a folder of
/// tiles is read). Other inputs are left as they are.
pub(super) fn stage_inputs(
    inputs: &[String],
    store: &StoreArgs,
    dir: &Path,
) -> anyhow::Result<Staged> {
    let mut staged = Staged {
        inputs: Vec::new(),
        names: Vec::new(),
    };
    for input in inputs {
        if !is_store_url(input) {
            staged.inputs.push(input.clone());
            continue;
        }
        let (bucket, url) = store.bucket(input, Default::default())?;
        let folder = input.ends_with('/') || url.key.is_empty();
        for object in objects_of(&bucket, &url.key, folder).with_context(|| input.clone())? {
            let name = format!("s3://{}/{}", url.bucket, object.key);
            // Numbered: two prefixes may hold files of one name.
            let file_name = object.key.rsplit('/').next().unwrap_or(&object.key);
            let local = dir.join(format!("{}-{file_name}", staged.names.len()));
            download_file(&bucket, &object.key, &object.stamp, &local)
                .with_context(|| format!("downloading {name}"))?;
            staged.inputs.push(local.display().to_string());
            staged.names.push((local, name));
        }
    }
    Ok(staged)
}

/// The readable objects under the prefix `key/` when `folder` (the input
/// ended in `/`), else the object `key` if there is one, else those under
/// `key/`, by key. (A folder is not asked for as an object: some stores
/// answer that with an error rather than "not found".)
fn objects_of(bucket: &Bucket, key: &str, folder: bool) -> anyhow::Result<Vec<ObjectFile>> {
    if !folder {
        match bucket.head(key) {
            Ok(stamp) => {
                return Ok(vec![ObjectFile {
                    key: key.to_owned(),
                    stamp,
                }]);
            }
            Err(RemoteError::NotFound(_)) => {}
            Err(e) => return Err(e.into()),
        }
    }
    let readable: Vec<ObjectFile> = list_files(bucket, key)?
        .into_iter()
        .filter(|o| is_readable(Path::new(&o.key)))
        .collect();
    anyhow::ensure!(
        !readable.is_empty(),
        "no such object, and no object under it that a build reads ({})",
        READABLE.join(", ")
    );
    Ok(readable)
}

/// Where a part goes when `--out` is a store address: its bucket and the
/// prefix its files go under, after checking that no part is there yet.
pub(super) fn part_target(
    store: &StoreArgs,
    out: &str,
) -> anyhow::Result<(std::sync::Arc<Bucket>, String)> {
    let (bucket, url) = store.bucket(out, Default::default())?;
    let prefix = url.key.trim_end_matches('/').to_owned();
    anyhow::ensure!(
        !prefix.is_empty(),
        "{out}: name the part's prefix (s3://bucket/parts/1)"
    );
    match bucket.head(&format!("{prefix}/{MANIFEST}")) {
        Err(RemoteError::NotFound(_)) => Ok((bucket, prefix)),
        Ok(_) => anyhow::bail!("{out}: already holds a part; remove it or choose another prefix"),
        Err(e) => anyhow::bail!("cannot reach the store: {e}"),
    }
}

/// Uploads the part in the folder `part` under `prefix`: its chunks'
/// files, then its manifest, whose presence says the part is whole.
pub(super) fn upload_part(part: &Path, bucket: &Bucket, prefix: &str) -> anyhow::Result<u64> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(part)
        .with_context(|| format!("reading {}", part.display()))?
        .map(|e| e.map(|e| e.path()))
        .collect::<Result<_, _>>()
        .with_context(|| format!("reading {}", part.display()))?;
    // The manifest last.
    files.sort_by_key(|f| (f.file_name().is_some_and(|n| n == MANIFEST), f.clone()));
    let mut bytes = 0;
    for file in files {
        let Some(name) = file.file_name().and_then(|n| n.to_str()) else {
            continue;
        };
        bytes += upload_file(bucket, &file, &format!("{prefix}/{name}"))?;
    }
    Ok(bytes)
}

/// The parts as local folders: a part given by store address
/// (`s3://bucket/parts/1`) is downloaded into a folder of `dir`; one on
/// disk is taken as it is.
pub(super) fn stage_parts(
    parts: &[PathBuf],
    store: &StoreArgs,
    dir: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut local = Vec::with_capacity(parts.len());
    for (n, part) in parts.iter().enumerate() {
        let Some(address) = part.to_str().filter(|p| is_store_url(p)) else {
            local.push(part.clone());
            continue;
        };
        let (bucket, url) = store.bucket(address, Default::default())?;
        let prefix = url.key.trim_end_matches('/');
        let files = list_files(&bucket, prefix).with_context(|| address.to_owned())?;
        anyhow::ensure!(
            files
                .iter()
                .any(|f| f.key == format!("{prefix}/{MANIFEST}")),
            "{address}: not a finished part (no {MANIFEST} under it)"
        );
        let folder = dir.join(format!("part-{n}"));
        std::fs::create_dir_all(&folder).with_context(|| format!("making {}", folder.display()))?;
        for file in files {
            let Some(name) = file
                .key
                .strip_prefix(prefix)
                .map(|n| n.trim_start_matches('/'))
                .filter(|n| !n.is_empty() && !n.contains('/') && !n.starts_with('.'))
            else {
                // A part is one level of files named by the build; anything
                // deeper, or `..`, is not its (and must not be written
                // outside its folder).
                continue;
            };
            download_file(&bucket, &file.key, &file.stamp, &folder.join(name))
                .with_context(|| format!("downloading s3://{}/{}", url.bucket, file.key))?;
        }
        local.push(folder);
    }
    Ok(local)
}
