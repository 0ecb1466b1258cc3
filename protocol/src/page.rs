//! One page: a header, whole sibling groups of node records (and a kind's
//! payload), compressed ([`crate::page_codec`]), then a checksum.
//!
//! The bytes of a page on disk are the bytes on the wire, so the checksum
//! travels with the page and the client verifies exactly what the builder
//! wrote; it covers the stored (compressed) bytes, so a damaged page is
//! refused before anything is inflated. A page that fails [`Page::parse`]
//! is reported and never decoded.

use std::borrow::Cow;

use crate::FormatError;
use crate::file::Reader;
use crate::page_codec::{self, PageCodec};

/// The four bytes every page starts with.
pub const PAGE_MAGIC: [u8; 4] = *b"FFPG";
/// Bytes of a page's header on disk: [`PageHeader`], then the body's
/// codec (one byte, three reserved) and its decoded length.
pub const PAGE_HEADER_BYTES: usize = 40;
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
/// it received, the store's `inspect`): [`check_stored_page`], then the
/// body decoded. What a kind's payload holds is checked where it is
/// decoded.
pub fn check_page<'a>(
    header: &crate::file::FileHeader,
    directory: &crate::directory::Directory,
    index: u32,
    bytes: &'a [u8],
) -> Result<Page<'a>, FormatError> {
    check_stored_page(header, directory, index, bytes)?.decode()
}

/// Everything [`check_page`] checks but the decoding of the body: page
/// `index` of the file `header` describes exists and `directory` knows its
/// entry, `bytes` agree with it (length and checksum, [`check_against_entry`]) and
/// checksum themselves, have a page header of the file's kind whose body
/// can hold its records, and say what the directory says (first node,
/// node count, first child). The server stops here: the checksum, matched
/// with the directory's, proves the bytes are what the builder wrote, and
/// inflating every page it reads would only repeat what the client, which
/// trusts no server, does anyway.
pub fn check_stored_page<'a>(
    header: &crate::file::FileHeader,
    directory: &crate::directory::Directory,
    index: u32,
    bytes: &'a [u8],
) -> Result<StoredPage<'a>, FormatError> {
    let entry = directory.entry(index).ok_or_else(|| FormatError::BadPage {
        page: index,
        message: if index < header.page_count {
            "its directory page has not arrived".into()
        } else {
            format!("no such page ({} pages)", header.page_count)
        },
    })?;
    check_against_entry(&entry, index, bytes)?;
    let page = StoredPage::parse(bytes, index, header.node_bytes)?;
    if !header.kind.pages_carry_payload() && page.decoded_len as usize != page.record_bytes {
        return Err(FormatError::BadPage {
            page: index,
            message: format!(
                "{} body bytes do not hold {} nodes of {} bytes",
                page.decoded_len, page.header.node_count, header.node_bytes
            ),
        });
    }
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
pub fn encode_page(header: &PageHeader, records: &[u8]) -> Result<(Vec<u8>, u32), FormatError> {
    encode_page_with_payload(header, records, &[])
}

/// A page whose records are followed by a payload section (the color-cube
/// octree's sub-cubes and leaf geometry, in node order). The body is
/// compressed when that makes it smaller ([`page_codec::encode_body`]). A
/// body over [`page_codec::MAX_DECODED_BODY_BYTES`] is an error: no reader
/// would take it.
pub fn encode_page_with_payload(
    header: &PageHeader,
    records: &[u8],
    payload: &[u8],
) -> Result<(Vec<u8>, u32), FormatError> {
    let body_bytes = records.len() + payload.len();
    let decoded_len = u32::try_from(body_bytes)
        .ok()
        .filter(|&n| n <= page_codec::MAX_DECODED_BODY_BYTES)
        .ok_or_else(|| FormatError::BadPage {
            page: header.index,
            message: format!(
                "its body is {body_bytes} bytes, over the limit of {}",
                page_codec::MAX_DECODED_BODY_BYTES
            ),
        })?;
    // Records are fixed-size, so their size follows from the count.
    let node_bytes = match header.node_count {
        0 => 1,
        n => records.len() / n as usize,
    };
    let (codec, body) = page_codec::encode_body(records, node_bytes, payload);
    let mut out = Vec::with_capacity(PAGE_HEADER_BYTES + body.len() + PAGE_CHECKSUM_BYTES);
    header.encode_into(&mut out);
    out.extend_from_slice(&[codec as u8, 0, 0, 0]);
    out.extend_from_slice(&decoded_len.to_le_bytes());
    out.extend_from_slice(&body);
    let crc = crc32fast::hash(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    Ok((out, crc))
}

/// A page whose checksum and header were verified, its body not yet
/// decoded ([`StoredPage::decode`]).
#[derive(Debug, Clone, Copy)]
pub struct StoredPage<'a> {
    pub header: PageHeader,
    pub codec: PageCodec,
    /// The body's length decoded, as the page states it.
    pub decoded_len: u32,
    /// The body as stored.
    pub stored: &'a [u8],
    record_bytes: usize,
    node_bytes: usize,
}

impl<'a> StoredPage<'a> {
    /// Verifies page `index`'s checksum and parses its header; records are
    /// `node_bytes` each. Nothing is inflated.
    pub fn parse(bytes: &'a [u8], index: u32, node_bytes: u32) -> Result<Self, FormatError> {
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
        let codec = PageCodec::from_u8(r.u8()?, index)?;
        if r.bytes(3)? != [0; 3] {
            return Err(FormatError::BadPage {
                page: index,
                message: "reserved bytes are not zero".into(),
            });
        }
        let decoded_len = r.u32()?;
        let stored = &body[PAGE_HEADER_BYTES..];
        let record_bytes = u64::from(header.node_count) * u64::from(node_bytes);
        if u64::from(decoded_len) < record_bytes {
            return Err(FormatError::BadPage {
                page: index,
                message: format!(
                    "{decoded_len} body bytes do not hold {} nodes of {node_bytes} bytes",
                    header.node_count
                ),
            });
        }
        if decoded_len > page_codec::MAX_DECODED_BODY_BYTES
            || (codec == PageCodec::Stored && stored.len() != decoded_len as usize)
        {
            return Err(FormatError::BadPage {
                page: index,
                message: format!(
                    "{} stored body bytes cannot be {decoded_len} bytes decoded",
                    stored.len()
                ),
            });
        }
        Ok(Self {
            header,
            codec,
            decoded_len,
            stored,
            record_bytes: record_bytes as usize,
            node_bytes: node_bytes as usize,
        })
    }

    /// The body decoded, bounded by the length the page states.
    pub fn decode(self) -> Result<Page<'a>, FormatError> {
        let index = self.header.index;
        let body = match self.codec {
            // `parse` checked that a stored body is as long as it claims.
            PageCodec::Stored => Cow::Borrowed(self.stored),
            PageCodec::PlanesDeflate => Cow::Owned(page_codec::decode_planes_deflate(
                self.stored,
                self.decoded_len,
                self.record_bytes,
                self.node_bytes,
                index,
            )?),
        };
        Ok(Page {
            header: self.header,
            body,
            record_bytes: self.record_bytes,
        })
    }
}

/// A page whose checksum and header were verified and whose body was
/// decoded: [`Page::records`] are its nodes.
#[derive(Debug, Clone)]
pub struct Page<'a> {
    pub header: PageHeader,
    /// Records then payload: borrowed from the page's bytes when stored
    /// as is, owned when inflated.
    body: Cow<'a, [u8]>,
    record_bytes: usize,
}

impl<'a> Page<'a> {
    /// The node records, `node_bytes` each.
    pub fn records(&self) -> &[u8] {
        &self.body[..self.record_bytes]
    }

    /// Bytes after the records: empty for spheres, cells' payloads for cubes.
    pub fn payload(&self) -> &[u8] {
        &self.body[self.record_bytes..]
    }

    /// Whether the body was stored compressed (and so inflated here).
    pub fn body_is_inflated(&self) -> bool {
        matches!(self.body, Cow::Owned(_))
    }

    /// Verifies and parses page `index` whose records are `node_bytes` each.
    /// A page of records only (spheres).
    pub fn parse(bytes: &'a [u8], index: u32, node_bytes: u32) -> Result<Self, FormatError> {
        let page = Self::parse_with_payload(bytes, index, node_bytes)?;
        if !page.payload().is_empty() {
            return Err(FormatError::BadPage {
                page: index,
                message: format!(
                    "{} record bytes do not hold {} nodes of {node_bytes} bytes",
                    page.body.len(),
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
        StoredPage::parse(bytes, index, node_bytes)?.decode()
    }

    /// The raw record of the `i`th node in the page, as a little-endian u64.
    #[inline]
    pub fn record(&self, i: usize, node_bytes: usize) -> u64 {
        let start = i * node_bytes;
        let mut word = [0u8; 8];
        word[..node_bytes].copy_from_slice(&self.records()[start..start + node_bytes]);
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
        encode_page(&header, &[1, 2, 3, 4, 5, 6, 7, 8]).unwrap().0
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

    /// A page of like records, which its encoder deflates.
    fn compressed_sample() -> (Vec<u8>, Vec<u8>) {
        let records: Vec<u8> = (0..4000u32).flat_map(|i| (i % 50).to_le_bytes()).collect();
        let header = PageHeader {
            index: 1,
            first_node: 3,
            first_child: 4003,
            node_count: 4000,
            level_min: 1,
            level_max: 1,
        };
        (encode_page(&header, &records).unwrap().0, records)
    }

    #[test]
    fn compressed_pages_round_trip_and_are_smaller() {
        let (bytes, records) = compressed_sample();
        assert_eq!(bytes[32], PageCodec::PlanesDeflate as u8);
        assert!(bytes.len() < records.len() / 4, "{} bytes", bytes.len());
        let page = Page::parse(&bytes, 1, 4).unwrap();
        assert_eq!(page.records(), &records[..]);
        assert!(page.payload().is_empty());
        assert_eq!(page.record(49, 4), 49);
    }

    /// What the checksum cannot catch, a page forged with a valid
    /// checksum over a damaged stream or a false decoded length, is
    /// refused by the decoder.
    #[test]
    fn a_forged_compressed_page_is_refused() {
        let (bytes, _) = compressed_sample();
        let reseal = |mut b: Vec<u8>| {
            let n = b.len() - PAGE_CHECKSUM_BYTES;
            let crc = crc32fast::hash(&b[..n]);
            b[n..].copy_from_slice(&crc.to_le_bytes());
            b
        };
        for at in [PAGE_HEADER_BYTES, PAGE_HEADER_BYTES + 5, bytes.len() - 6] {
            for bit in 0..8 {
                let mut bad = bytes.clone();
                bad[at] ^= 1 << bit;
                let bad = reseal(bad);
                if let Ok(page) = Page::parse(&bad, 1, 4) {
                    // A flip deflate cannot notice (a literal's value)
                    // decodes to other records, never to more or fewer.
                    assert_eq!(page.records().len(), 16_000);
                }
            }
        }
        for claim in [0u32, 15_999, 16_001, u32::MAX] {
            let mut bad = bytes.clone();
            bad[36..40].copy_from_slice(&claim.to_le_bytes());
            assert!(Page::parse(&reseal(bad), 1, 4).is_err(), "claim {claim}");
        }
        let mut bad = bytes.clone();
        bad[32] = 9;
        let e = Page::parse(&reseal(bad), 1, 4).unwrap_err();
        assert!(e.to_string().contains("codec 9"), "{e}");
        let mut bad = bytes.clone();
        bad[34] = 1;
        assert!(Page::parse(&reseal(bad), 1, 4).is_err());
        // Cut short, with its checksum fixed up.
        let mut short = bytes[..bytes.len() - 20].to_vec();
        short.extend_from_slice(&[0; 4]);
        assert!(Page::parse(&reseal(short), 1, 4).is_err());
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
