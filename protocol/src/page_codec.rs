//! How a page's body (its node records, then its payload) is stored: as
//! is, or deflated after its records are split into byte planes.
//!
//! The codec was chosen by measurement on this project's own pages
//! (`farfield-server bench codecs`, docs/experiments.md): records are
//! bit-packed fixed-size words whose bytes each carry a different field
//! (a sphere's position code, its normal's cell, its color), so putting
//! byte 0 of every record together, then byte 1, and so on, gives the
//! compressor runs of like values. Deflate over those planes stores the
//! lidar cloud in 63 % of its bytes, within 6 % of zstd's best level, and
//! is decoded by a small pure-Rust crate (`miniz_oxide`) that builds for
//! the browser unchanged.
//!
//! Decoding is bounded: the page says how many bytes its body decodes to,
//! that is capped by [`MAX_DECODED_BODY_BYTES`], and the inflater stops
//! at it, so a hostile page cannot make a reader allocate more than it
//! claims, and a claim that disagrees with the stream is an error.

use crate::FormatError;

/// The most bytes one page's body may decode to (the largest built page
/// body is well under a megabyte; image-caching leaves are the largest).
pub const MAX_DECODED_BODY_BYTES: u32 = 256 << 20;

/// Deflate's level for pages: 3 stored every scene measured within 0.5 %
/// of levels 6 and 9 (image-caching pages 2 % smaller), encoding 1.8 to 3
/// times as fast; level 1 left the lidar cloud 11 % larger.
const DEFLATE_LEVEL: u8 = 3;

/// How a page's body is stored (byte 32 of the page).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PageCodec {
    /// The body as is: what a page whose bytes deflate would not shrink
    /// keeps.
    Stored = 0,
    /// Records split into byte planes, then the payload, deflated (RFC
    /// 1951, no zlib wrapper: the page's CRC-32 covers the stored bytes).
    PlanesDeflate = 1,
}

impl PageCodec {
    pub fn from_u8(code: u8, page: u32) -> Result<Self, FormatError> {
        match code {
            0 => Ok(Self::Stored),
            1 => Ok(Self::PlanesDeflate),
            other => Err(FormatError::BadPage {
                page,
                message: format!("unknown page codec {other}"),
            }),
        }
    }
}

/// Encodes a body of `records` (`node_bytes` each) and `payload`: deflated
/// planes when that is smaller, else stored.
pub fn encode_body(records: &[u8], node_bytes: usize, payload: &[u8]) -> (PageCodec, Vec<u8>) {
    encode_body_at(records, node_bytes, payload, DEFLATE_LEVEL)
}

/// [`encode_body`] at another deflate level (0 to 10): what `farfield-server
/// bench codecs` compares. Records of one byte are not split (the planes
/// are the records), which is how the bench deflates a body as it is.
pub fn encode_body_at(
    records: &[u8],
    node_bytes: usize,
    payload: &[u8],
    level: u8,
) -> (PageCodec, Vec<u8>) {
    let mut planes = split_planes(records, node_bytes);
    planes.extend_from_slice(payload);
    let deflated = miniz_oxide::deflate::compress_to_vec(&planes, level);
    if deflated.len() < records.len() + payload.len() {
        (PageCodec::PlanesDeflate, deflated)
    } else {
        let mut body = Vec::with_capacity(records.len() + payload.len());
        body.extend_from_slice(records);
        body.extend_from_slice(payload);
        (PageCodec::Stored, body)
    }
}

/// Decodes a deflated body of `decoded_len` bytes whose first
/// `record_bytes` are records of `node_bytes` split into planes.
pub fn decode_planes_deflate(
    stored: &[u8],
    decoded_len: u32,
    record_bytes: usize,
    node_bytes: usize,
    page: u32,
) -> Result<Vec<u8>, FormatError> {
    let bad = |message: String| FormatError::BadPage { page, message };
    if decoded_len > MAX_DECODED_BODY_BYTES {
        return Err(bad(format!(
            "its body claims {decoded_len} bytes decoded, over the limit of {MAX_DECODED_BODY_BYTES}"
        )));
    }
    let mut decoded =
        miniz_oxide::inflate::decompress_to_vec_with_limit(stored, decoded_len as usize).map_err(
            |e| {
                bad(format!(
                    "its deflated body does not decode ({:?})",
                    e.status
                ))
            },
        )?;
    if decoded.len() != decoded_len as usize {
        return Err(bad(format!(
            "its body decodes to {} bytes where it claims {decoded_len}",
            decoded.len()
        )));
    }
    if record_bytes > decoded.len() {
        return Err(bad(format!(
            "{} body bytes do not hold {record_bytes} bytes of records",
            decoded.len()
        )));
    }
    // The records back in place; the payload, often most of the body,
    // stays where it was inflated.
    let records = join_planes(&decoded[..record_bytes], node_bytes);
    decoded[..record_bytes].copy_from_slice(&records);
    Ok(decoded)
}

/// Byte `b` of every record, for each `b` in turn. A trailing partial
/// record (none in a valid page) is kept as it is, after the planes.
pub fn split_planes(records: &[u8], node_bytes: usize) -> Vec<u8> {
    if node_bytes <= 1 {
        return records.to_vec();
    }
    let whole = records.len() / node_bytes * node_bytes;
    let mut out = Vec::with_capacity(records.len());
    for b in 0..node_bytes {
        out.extend(records[..whole].iter().skip(b).step_by(node_bytes));
    }
    out.extend_from_slice(&records[whole..]);
    out
}

/// The inverse of [`split_planes`].
pub fn join_planes(planes: &[u8], node_bytes: usize) -> Vec<u8> {
    if node_bytes <= 1 {
        return planes.to_vec();
    }
    let count = planes.len() / node_bytes;
    let whole = count * node_bytes;
    let mut out = vec![0u8; planes.len()];
    for (b, plane) in planes[..whole].chunks_exact(count.max(1)).enumerate() {
        for (i, &byte) in plane.iter().enumerate() {
            out[i * node_bytes + b] = byte;
        }
    }
    out[whole..].copy_from_slice(&planes[whole..]);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn planes_round_trip(records in proptest::collection::vec(any::<u8>(), 0..200), node_bytes in 1usize..40) {
            prop_assert_eq!(join_planes(&split_planes(&records, node_bytes), node_bytes), records);
        }

        #[test]
        fn bodies_round_trip(
            nodes in 0usize..300,
            node_bytes in 1usize..33,
            payload in proptest::collection::vec(any::<u8>(), 0..300),
            seed in any::<u8>(),
        ) {
            // Records that repeat (compressible) or not.
            let records: Vec<u8> = (0..nodes * node_bytes)
                .map(|i| if seed % 2 == 0 { (i % 7) as u8 } else { (i as u8).wrapping_mul(seed) ^ (i >> 3) as u8 })
                .collect();
            let (codec, stored) = encode_body(&records, node_bytes, &payload);
            let decoded = match codec {
                PageCodec::Stored => stored.clone(),
                PageCodec::PlanesDeflate => decode_planes_deflate(
                    &stored,
                    (records.len() + payload.len()) as u32,
                    records.len(),
                    node_bytes,
                    0,
                ).unwrap(),
            };
            prop_assert_eq!(&decoded[..records.len()], &records[..]);
            prop_assert_eq!(&decoded[records.len()..], &payload[..]);
            prop_assert!(stored.len() <= records.len() + payload.len());
        }

        /// Whatever bytes claim to be a deflated body, decoding returns
        /// an error or a body of exactly the claimed length: no panic,
        /// and never more than the claim.
        #[test]
        fn arbitrary_streams_are_bounded(stored in proptest::collection::vec(any::<u8>(), 0..200), claim in 0u32..5000) {
            if let Ok(body) = decode_planes_deflate(&stored, claim, 0, 6, 0) {
                prop_assert_eq!(body.len(), claim as usize);
            }
        }
    }

    #[test]
    fn repetitive_records_are_deflated_and_noise_is_stored() {
        let records: Vec<u8> = (0..6000).map(|i| (i % 6) as u8).collect();
        assert_eq!(encode_body(&records, 6, &[]).0, PageCodec::PlanesDeflate);
        // A xorshift's bytes do not compress.
        let mut x = 0x2545_f491_4f6c_dd1du64;
        let noise: Vec<u8> = (0..6000)
            .map(|_| {
                x ^= x << 13;
                x ^= x >> 7;
                x ^= x << 17;
                x as u8
            })
            .collect();
        let (codec, stored) = encode_body(&noise, 6, &[]);
        assert_eq!(codec, PageCodec::Stored);
        assert_eq!(stored, noise);
    }

    #[test]
    fn a_claim_that_disagrees_with_the_stream_is_refused() {
        let records: Vec<u8> = (0..600).map(|i| (i % 6) as u8).collect();
        let (_, stored) = encode_body(&records, 6, &[]);
        for claim in [0, 599, 601, 10_000] {
            let e = decode_planes_deflate(&stored, claim, 600, 6, 7).unwrap_err();
            assert!(matches!(e, FormatError::BadPage { page: 7, .. }), "{e}");
        }
        assert!(decode_planes_deflate(&stored, MAX_DECODED_BODY_BYTES + 1, 600, 6, 7).is_err());
        assert!(decode_planes_deflate(&stored[..stored.len() / 2], 600, 600, 6, 7).is_err());
        // Records claimed past the body.
        assert!(decode_planes_deflate(&stored, 600, 606, 6, 7).is_err());
        assert_eq!(
            decode_planes_deflate(&stored, 600, 600, 6, 7).unwrap(),
            records
        );
    }
}
