//! The one place that turns control messages into bytes and back.
//!
//! bincode 2 (pinned: version 3 does not compile) with its standard
//! configuration and a size limit, so a hostile length prefix cannot make
//! the decoder allocate without bound. Swapping the encoding means changing
//! this file only.

use serde::Serialize;
use serde::de::DeserializeOwned;

use crate::messages::{FrameKind, HEADER_PART_BYTES};

/// Largest control message accepted (pages travel outside this limit).
pub const MAX_CONTROL_BYTES: usize = 1 << 20;

/// Why a frame could not be decoded.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CodecError {
    #[error("empty frame")]
    Empty,
    #[error("unknown frame kind {0}")]
    UnknownKind(u8),
    #[error("expected a {expected:?} frame")]
    WrongKind { expected: FrameKind },
    #[error("malformed control message: {0}")]
    Malformed(String),
}

fn config() -> impl bincode::config::Config {
    bincode::config::standard().with_limit::<MAX_CONTROL_BYTES>()
}

/// A control frame: the kind byte, then the bincode message.
pub fn encode_control<T: Serialize>(message: &T) -> Vec<u8> {
    let mut out = vec![FrameKind::Control as u8];
    // Encoding our own in-memory types into a Vec cannot fail short of a
    // message over the size limit, which no message we build reaches.
    if let Ok(bytes) = bincode::serde::encode_to_vec(message, config()) {
        out.extend_from_slice(&bytes);
    }
    out
}

/// A page frame: the kind byte, then the page bytes as stored.
pub fn encode_page_frame(page: &[u8]) -> Vec<u8> {
    let mut out = page_frame_to_fill(page.len());
    out.extend_from_slice(page);
    out
}

/// A page frame with its page still to come: the kind byte, and room for
/// `page_len` bytes to be appended. The server reads a page from its file
/// straight into this, so a cached frame is sent without another copy.
pub fn page_frame_to_fill(page_len: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(page_len + 1);
    out.push(FrameKind::Page as u8);
    out
}

/// A header frame: the kind byte, then (a part of) the file header as
/// stored.
pub fn encode_header_frame(header: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(header.len() + 1);
    out.push(FrameKind::Header as u8);
    out.extend_from_slice(header);
    out
}

/// The file header as stored, cut into header frames of at most
/// [`HEADER_PART_BYTES`] each, in order (one frame for a small header).
pub fn encode_header_frames(header: &[u8]) -> Vec<Vec<u8>> {
    header
        .chunks(HEADER_PART_BYTES)
        .map(encode_header_frame)
        .collect()
}

/// Splits a frame into its kind and payload.
pub fn frame_kind(frame: &[u8]) -> Result<(FrameKind, &[u8]), CodecError> {
    let (&kind, payload) = frame.split_first().ok_or(CodecError::Empty)?;
    match kind {
        0 => Ok((FrameKind::Control, payload)),
        1 => Ok((FrameKind::Page, payload)),
        2 => Ok((FrameKind::Header, payload)),
        other => Err(CodecError::UnknownKind(other)),
    }
}

/// Decodes a control frame; any bytes that are not exactly one message are
/// an error, never a panic.
pub fn decode_control<T: DeserializeOwned>(frame: &[u8]) -> Result<T, CodecError> {
    let (kind, payload) = frame_kind(frame)?;
    if kind != FrameKind::Control {
        return Err(CodecError::WrongKind {
            expected: FrameKind::Control,
        });
    }
    let (message, used) = bincode::serde::decode_from_slice(payload, config())
        .map_err(|e| CodecError::Malformed(e.to_string()))?;
    if used != payload.len() {
        return Err(CodecError::Malformed(format!(
            "{} trailing bytes",
            payload.len() - used
        )));
    }
    Ok(message)
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::*;
    use crate::messages::{ClientMessage, PageWish, ServerMessage};

    #[test]
    fn messages_round_trip() {
        let messages = [
            ClientMessage::Hello {
                protocol_version: 1,
                max_in_flight_bytes: 1 << 20,
                allow_push: true,
            },
            ClientMessage::Request {
                pages: vec![PageWish {
                    page: 3,
                    priority: 2.5,
                }],
            },
            ClientMessage::Cancel {
                pages: vec![1, 2, 3],
            },
            ClientMessage::Received { pages: vec![] },
        ];
        for m in messages {
            assert_eq!(
                decode_control::<ClientMessage>(&encode_control(&m)).unwrap(),
                m
            );
        }
        let s = ServerMessage::Error {
            message: "bunny".into(),
            fatal: false,
        };
        assert_eq!(
            decode_control::<ServerMessage>(&encode_control(&s)).unwrap(),
            s
        );
        let header = encode_header_frame(&[5; 3]);
        assert_eq!(
            frame_kind(&header).unwrap(),
            (FrameKind::Header, &[5u8, 5, 5][..])
        );
        // A header cut into parts that join back into it.
        let long: Vec<u8> = (0..HEADER_PART_BYTES * 2 + 7).map(|i| i as u8).collect();
        let parts = encode_header_frames(&long);
        assert_eq!(parts.len(), 3);
        assert!(parts.iter().all(|p| p.len() <= HEADER_PART_BYTES + 1));
        let joined: Vec<u8> = parts
            .iter()
            .flat_map(|p| match frame_kind(p).unwrap() {
                (FrameKind::Header, body) => body.to_vec(),
                other => panic!("not a header part: {other:?}"),
            })
            .collect();
        assert_eq!(joined, long);
        assert_eq!(encode_header_frames(&[5; 3]), vec![header.clone()]);
        let page = encode_page_frame(&[9, 9]);
        assert_eq!(frame_kind(&page).unwrap(), (FrameKind::Page, &[9u8, 9][..]));
        assert!(decode_control::<ClientMessage>(&page).is_err());
    }

    proptest! {
        #[test]
        fn arbitrary_bytes_never_panic(bytes in prop::collection::vec(any::<u8>(), 0..256)) {
            let _ = decode_control::<ClientMessage>(&bytes);
            let _ = decode_control::<ServerMessage>(&bytes);
            let _ = frame_kind(&bytes);
        }

        #[test]
        fn control_frames_with_noise_never_panic(tail in prop::collection::vec(any::<u8>(), 0..64)) {
            let mut frame = vec![0u8];
            frame.extend_from_slice(&tail);
            let _ = decode_control::<ClientMessage>(&frame);
        }
    }
}
