//! One page: a header, whole sibling groups of node records, a checksum.
//!
//! The bytes of a page on disk are the bytes on the wire, so the checksum
//! travels with the page and the client verifies exactly what the builder
//! wrote. A page that fails [`Page::parse`] is reported and never decoded.

use crate::FormatError;
use crate::file::Reader;

/// The four bytes every page starts with.
pub const PAGE_MAGIC: [u8; 4] = *b"FFPG";
/// Bytes of [`PageHeader`] on disk.
pub const PAGE_HEADER_BYTES: usize = 32;
/// Bytes of the trailing checksum.
pub const PAGE_CHECKSUM_BYTES: usize = 4;

/// The self-description at the start of every page.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PageHeader {
    pub index: u32,
    /// Breadth-first index of the first node in the page.
    pub first_node: u64,
    /// Breadth-first index of the first child of the page's first parent.
    pub first_child: u64,
    pub node_count: u32,
    pub level_min: u16,
    pub level_max: u16,
}

impl PageHeader {
    fn encode_into(&self, out: &mut Vec<u8>) {
        out.extend_from_slice(&PAGE_MAGIC);
        out.extend_from_slice(&self.index.to_le_bytes());
        out.extend_from_slice(&self.first_node.to_le_bytes());
        out.extend_from_slice(&self.first_child.to_le_bytes());
        out.extend_from_slice(&self.node_count.to_le_bytes());
        out.extend_from_slice(&self.level_min.to_le_bytes());
        out.extend_from_slice(&self.level_max.to_le_bytes());
    }
}

/// The index a page's bytes claim for themselves (the second field of its
/// header), read without verifying anything: how a receiver files a page
/// before checking it. `None` when the bytes are too short to say.
pub fn claimed_index(page: &[u8]) -> Option<u32> {
    let bytes = page.get(PAGE_MAGIC.len()..PAGE_MAGIC.len() + 4)?;
    Some(u32::from_le_bytes(bytes.try_into().ok()?))
}

/// The one check of a page, for every reader (the client inserting what
/// it received, the server and the store reading what they hold): page
/// `index` of the file `header` describes exists, `bytes` agree with its
/// directory entry (length and checksum, [`check_against_entry`]) and
/// checksum themselves, parse as a page of the file's kind, and the page's
/// header says what the directory says (its first node, node count and
/// first child). What a kind's payload holds is checked where it is
/// decoded.
pub fn check_page<'a>(
    header: &crate::file::FileHeader,
    index: u32,
    bytes: &'a [u8],
) -> Result<Page<'a>, FormatError> {
    let entry = *header
        .pages
        .get(index as usize)
        .ok_or(FormatError::BadPage {
            page: index,
            message: format!("no such page ({} pages)", header.pages.len()),
        })?;
    check_against_entry(&entry, index, bytes)?;
    let page = if header.kind.pages_carry_payload() {
        Page::parse_with_payload(bytes, index, header.node_bytes)?
    } else {
        Page::parse(bytes, index, header.node_bytes)?
    };
    let h = page.header;
    if h.first_node != entry.first_node
        || h.node_count != entry.node_count
        || h.first_child != entry.first_child
    {
        return Err(FormatError::BadPage {
            page: index,
            message: "page disagrees with the directory".into(),
        });
    }
    Ok(page)
}

/// Checks that `bytes`, received or read as page `index`, are the page the
/// directory `entry` describes: its length and the checksum in its last
/// four bytes. The page's own checksum only proves the bytes agree with
/// themselves; a page edited in place with its checksum recomputed passes
/// it, but not this (the directory is covered by the header's checksum,
/// which the edit would also have to forge). Both the server, when it
/// reads a page, and the client, when it receives one, call this before
/// [`Page::parse`].
pub fn check_against_entry(
    entry: &crate::file::PageEntry,
    index: u32,
    bytes: &[u8],
) -> Result<(), FormatError> {
    if bytes.len() != entry.length as usize {
        return Err(FormatError::BadPage {
            page: index,
            message: format!(
                "{} bytes where the directory says {}",
                bytes.len(),
                entry.length
            ),
        });
    }
    let tail = bytes
        .len()
        .checked_sub(PAGE_CHECKSUM_BYTES)
        .and_then(|start| bytes.get(start..))
        .and_then(|tail| <[u8; 4]>::try_from(tail).ok())
        .ok_or_else(|| FormatError::BadPage {
            page: index,
            message: format!("{} bytes is shorter than a checksum", bytes.len()),
        })?;
    let stored = u32::from_le_bytes(tail);
    if stored != entry.checksum {
        return Err(FormatError::BadPage {
            page: index,
            message: format!(
                "its checksum {stored:#010x} is not the directory's {:#010x}: the page was replaced",
                entry.checksum
            ),
        });
    }
    Ok(())
}

/// Builds a page's bytes from its header and node records; returns the
/// bytes and their checksum (also stored in the last four bytes).
pub fn encode_page(header: &PageHeader, records: &[u8]) -> (Vec<u8>, u32) {
    encode_page_with_payload(header, records, &[])
}

/// A page whose records are followed by a payload section (the color-cube
/// octree's sub-cubes and leaf geometry, in node order).
pub fn encode_page_with_payload(
    header: &PageHeader,
    records: &[u8],
    payload: &[u8],
) -> (Vec<u8>, u32) {
    let mut out =
        Vec::with_capacity(PAGE_HEADER_BYTES + records.len() + payload.len() + PAGE_CHECKSUM_BYTES);
    header.encode_into(&mut out);
    out.extend_from_slice(records);
    out.extend_from_slice(payload);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    (out, crc)
}

/// A page whose checksum and header were verified; `records` are its nodes.
#[derive(Debug, Clone, Copy)]
pub struct Page<'a> {
    pub header: PageHeader,
    pub records: &'a [u8],
    /// Bytes after the records: empty for spheres, cells' payloads for cubes.
    pub payload: &'a [u8],
}

impl<'a> Page<'a> {
    /// Verifies and parses page `index` whose records are `node_bytes` each.
    /// A page of records only (spheres).
    pub fn parse(bytes: &'a [u8], index: u32, node_bytes: u32) -> Result<Self, FormatError> {
        let page = Self::parse_with_payload(bytes, index, node_bytes)?;
        if !page.payload.is_empty() {
            return Err(FormatError::BadPage {
                page: index,
                message: format!(
                    "{} record bytes do not hold {} nodes of {node_bytes} bytes",
                    page.records.len() + page.payload.len(),
                    page.header.node_count
                ),
            });
        }
        Ok(page)
    }

    /// A page whose records may be followed by a payload (cubes).
    pub fn parse_with_payload(
        bytes: &'a [u8],
        index: u32,
        node_bytes: u32,
    ) -> Result<Self, FormatError> {
        let min = PAGE_HEADER_BYTES + PAGE_CHECKSUM_BYTES;
        if bytes.len() < min {
            return Err(FormatError::BadPage {
                page: index,
                message: format!("{} bytes is shorter than a page header", bytes.len()),
            });
        }
        let body = &bytes[..bytes.len() - PAGE_CHECKSUM_BYTES];
        let mut tail = [0u8; 4];
        tail.copy_from_slice(&bytes[bytes.len() - PAGE_CHECKSUM_BYTES..]);
        let stored = u32::from_le_bytes(tail);
        let computed = crc32fast::hash(body);
        if stored != computed {
            return Err(FormatError::PageChecksum {
                page: index,
                stored,
                computed,
            });
        }
        let mut r = Reader::new(body, "page header");
        if r.bytes(4)? != PAGE_MAGIC {
            return Err(FormatError::BadPage {
                page: index,
                message: "bad page magic".into(),
            });
        }
        let header = PageHeader {
            index: r.u32()?,
            first_node: r.u64()?,
            first_child: r.u64()?,
            node_count: r.u32()?,
            level_min: r.u16()?,
            level_max: r.u16()?,
        };
        if header.index != index {
            return Err(FormatError::BadPage {
                page: index,
                message: format!("page says it is page {}", header.index),
            });
        }
        let rest = &body[PAGE_HEADER_BYTES..];
        let record_bytes = u64::from(header.node_count) * u64::from(node_bytes);
        if (rest.len() as u64) < record_bytes {
            return Err(FormatError::BadPage {
                page: index,
                message: format!(
                    "{} record bytes do not hold {} nodes of {node_bytes} bytes",
                    rest.len(),
                    header.node_count
                ),
            });
        }
        let (records, payload) = rest.split_at(record_bytes as usize);
        Ok(Self {
            header,
            records,
            payload,
        })
    }

    /// The raw record of the `i`th node in the page, as a little-endian u64.
    #[inline]
    pub fn record(&self, i: usize, node_bytes: usize) -> u64 {
        let start = i * node_bytes;
        let mut word = [0u8; 8];
        word[..node_bytes].copy_from_slice(&self.records[start..start + node_bytes]);
        u64::from_le_bytes(word)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample() -> Vec<u8> {
        let header = PageHeader {
            index: 3,
            first_node: 10,
            first_child: 40,
            node_count: 2,
            level_min: 2,
            level_max: 3,
        };
        encode_page(&header, &[1, 2, 3, 4, 5, 6, 7, 8]).0
    }

    #[test]
    fn round_trips() {
        let bytes = sample();
        let page = Page::parse(&bytes, 3, 4).unwrap();
        assert_eq!(page.header.first_child, 40);
        assert_eq!(
            page.record(1, 4),
            u64::from(u32::from_le_bytes([5, 6, 7, 8]))
        );
    }

    #[test]
    fn every_flipped_bit_is_caught() {
        let bytes = sample();
        for bit in 0..bytes.len() * 8 {
            let mut bad = bytes.clone();
            bad[bit / 8] ^= 1 << (bit % 8);
            assert!(
                Page::parse(&bad, 3, 4).is_err(),
                "bit {bit} flip not caught"
            );
        }
    }

    #[test]
    fn wrong_index_and_sizes_are_errors() {
        let bytes = sample();
        assert!(matches!(
            Page::parse(&bytes, 4, 4),
            Err(FormatError::BadPage { .. })
        ));
        assert!(matches!(
            Page::parse(&bytes, 3, 3),
            Err(FormatError::BadPage { .. })
        ));
        assert!(Page::parse(&bytes[..10], 3, 4).is_err());
    }
}
