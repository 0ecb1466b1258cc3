//! [`ObjectScene`]: a scene stored as one object, read by range requests.

use std::ops::Range;
use std::sync::Arc;

use bytes::Bytes;
use farfield_protocol::FormatError;
use farfield_protocol::directory::Directory;
use farfield_protocol::file::FileHeader;
use farfield_store::verify::{HeaderError, page_extent, read_header, verify_page};
use farfield_store::{ObjectStamp, PageError, PageSource, RemoteStats, Stamp, StoreError};

use crate::{Bucket, RemoteError};

/// A scene in object storage: its header and directory read once, at
/// open, and each page read by one range request when asked for and
/// checked as a file's page is. Every read names the version opened (its
/// entity tag), so a scene replaced in the store is noticed by the first
/// read after it, never mixed with the old one.
#[derive(Debug)]
pub struct ObjectScene {
    bucket: Arc<Bucket>,
    key: String,
    header: FileHeader,
    directory: Directory,
    header_bytes: Vec<u8>,
    stamp: ObjectStamp,
    /// A hash of the bucket, key and version: the tier's name for it.
    version: u64,
}

impl ObjectScene {
    /// Opens object `key` of `bucket`: its size and version, then its
    /// header and directory (one range request for the header and the
    /// root directory page, one for the directory pages at its end).
    pub fn open(bucket: Arc<Bucket>, key: &str) -> Result<Self, StoreError> {
        let location = format!("s3://{}/{key}", bucket.url().bucket);
        let remote = |e: RemoteError| StoreError::Remote {
            location: location.clone(),
            message: e.to_string(),
        };
        let stamp = bucket.head(key).map_err(remote)?;
        let e_tag = stamp.e_tag.as_deref();
        let stored = read_header(stamp.len, |offset, n| {
            bucket
                .get_range(key, offset..offset + n, e_tag)
                .map(|b| b.to_vec())
        })
        .map_err(|e| match e {
            HeaderError::Read(e) => remote(e),
            HeaderError::Format(error) => StoreError::RemoteFormat {
                location: location.clone(),
                error,
            },
        })?;
        let version = {
            use std::hash::{Hash, Hasher};
            let mut h = std::collections::hash_map::DefaultHasher::new();
            (
                &bucket.url().bucket,
                key,
                &stamp.e_tag,
                stamp.len,
                stamp.modified_s,
            )
                .hash(&mut h);
            h.finish()
        };
        Ok(Self {
            bucket,
            key: key.to_owned(),
            header: stored.header,
            directory: stored.directory,
            header_bytes: stored.bytes,
            stamp,
            version,
        })
    }

    /// The object's key in its bucket.
    pub fn key(&self) -> &str {
        &self.key
    }

    /// Page `index` from the store, verified, and kept in the tier.
    fn fetch_page(&self, index: u32) -> Result<Vec<u8>, PageError> {
        let entry = page_extent(&self.directory, index as usize)?;
        let bytes = self.get(entry.offset..entry.offset + u64::from(entry.length))?;
        verify_page(&self.header, &self.directory, index as usize, &bytes)?;
        self.keep_in_tier(index, &bytes);
        Ok(bytes.to_vec())
    }

    /// Pages `pages` from the store: one range request when they lie side
    /// by side within the coalescing limit, else one each.
    fn fetch_pages(&self, pages: Range<u32>) -> Vec<Result<Vec<u8>, PageError>> {
        let each = || pages.clone().map(|p| self.fetch_page(p)).collect();
        let entries: Option<Vec<_>> = pages
            .clone()
            .map(|p| page_extent(&self.directory, p as usize).ok())
            .collect();
        let entries = match entries {
            Some(entries) if entries.len() > 1 => entries,
            _ => return each(),
        };
        let (first, last) = (entries[0], entries[entries.len() - 1]);
        let end = last.offset + u64::from(last.length);
        let side_by_side = entries
            .windows(2)
            .all(|w| w[0].offset + u64::from(w[0].length) == w[1].offset);
        if !side_by_side || end - first.offset > self.bucket.coalesce_bytes() {
            return each();
        }
        let span = match self.get(first.offset..end) {
            Ok(span) => span,
            Err(e) => return vec![Err(e); entries.len()],
        };
        pages
            .clone()
            .zip(&entries)
            .map(|(index, entry)| {
                let at = (entry.offset - first.offset) as usize;
                let bytes =
                    span.get(at..at + entry.length as usize)
                        .ok_or(FormatError::Truncated {
                            what: "page",
                            needed: u64::from(entry.length),
                            have: span.len().saturating_sub(at) as u64,
                        })?;
                verify_page(&self.header, &self.directory, index as usize, bytes)?;
                self.keep_in_tier(index, bytes);
                Ok(bytes.to_vec())
            })
            .collect()
    }

    /// The tier's file name of page `index` of this version.
    fn tier_name(&self, index: u32) -> String {
        format!("{:016x}-{index}", self.version)
    }

    /// Page `index` from the second tier, if it holds it whole (a damaged
    /// copy is dropped).
    fn tier_copy(&self, index: u32) -> Option<Vec<u8>> {
        let tier = self.bucket.tier()?;
        let name = self.tier_name(index);
        let bytes = tier.get(&name)?;
        if verify_page(&self.header, &self.directory, index as usize, &bytes).is_err() {
            tier.remove(&name);
            return None;
        }
        RemoteStats::add(&self.bucket.stats().tier_hits, 1);
        Some(bytes)
    }

    fn keep_in_tier(&self, index: u32, bytes: &[u8]) {
        if let Some(tier) = self.bucket.tier()
            && tier.put(&self.tier_name(index), bytes)
        {
            RemoteStats::add(&self.bucket.stats().tier_writes, 1);
        }
    }

    /// Bytes `range` of the version opened.
    fn get(&self, range: Range<u64>) -> Result<Bytes, PageError> {
        self.bucket
            .get_range(&self.key, range, self.stamp.e_tag.as_deref())
            .map_err(|e| match e {
                RemoteError::NotFound(_) => {
                    PageError::Changed("it was deleted from the store".into())
                }
                RemoteError::Changed(_) => {
                    PageError::Changed("it was replaced in the store".into())
                }
                RemoteError::Unavailable(why) => PageError::Unavailable(why),
            })
    }
}

impl PageSource for ObjectScene {
    fn header(&self) -> &FileHeader {
        &self.header
    }

    fn directory(&self) -> &Directory {
        &self.directory
    }

    fn header_bytes(&self) -> &[u8] {
        &self.header_bytes
    }

    fn stored_len(&self) -> u64 {
        self.stamp.len
    }

    fn read_page(&self, index: u32, out: &mut Vec<u8>) -> Result<(), PageError> {
        let bytes = match self.tier_copy(index) {
            Some(bytes) => bytes,
            None => self.fetch_page(index)?,
        };
        out.extend_from_slice(&bytes);
        Ok(())
    }

    /// Neighbouring pages in one range request when their span is within
    /// the bucket's coalescing limit (read-ahead asks for a page's
    /// children, which lie side by side), else one request each; pages the
    /// second tier holds come from it, and only the span of the rest is
    /// asked for.
    fn read_pages(&self, pages: Range<u32>) -> Vec<Result<Vec<u8>, PageError>> {
        let mut found: Vec<Option<Result<Vec<u8>, PageError>>> =
            pages.clone().map(|p| self.tier_copy(p).map(Ok)).collect();
        let first = found.iter().position(Option::is_none);
        let last = found.iter().rposition(Option::is_none);
        if let (Some(first), Some(last)) = (first, last) {
            let missing = pages.start + first as u32..pages.start + last as u32 + 1;
            for (slot, read) in found[first..=last]
                .iter_mut()
                .zip(self.fetch_pages(missing))
            {
                slot.get_or_insert(read);
            }
        }
        found.into_iter().flatten().collect()
    }

    /// Always `None`: an object is never changed in place, only replaced,
    /// which the next read (by its entity tag) or the server's listing
    /// notices.
    fn changed(&self) -> Option<String> {
        None
    }

    fn stamp(&self) -> Stamp {
        Stamp::Object(self.stamp.clone())
    }

    fn location(&self) -> String {
        format!("s3://{}/{}", self.bucket.url().bucket, self.key)
    }
}
