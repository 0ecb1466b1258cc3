//! The websocket frame decoders: `frame_kind`, and `decode_control` for
//! both directions. A message that decodes must encode and decode back to
//! the same bytes.
#![no_main]

use farfield_protocol::codec::{decode_control, encode_control, frame_kind};
use farfield_protocol::messages::{ClientMessage, ServerMessage};
use libfuzzer_sys::fuzz_target;
use serde::Serialize;
use serde::de::DeserializeOwned;

fn round_trip<T: Serialize + DeserializeOwned>(frame: &[u8]) {
    if let Ok(message) = decode_control::<T>(frame) {
        let encoded = encode_control(&message);
        let again: T = decode_control(&encoded).expect("a re-encoded message decodes");
        assert_eq!(encode_control(&again), encoded, "re-encoding is stable");
    }
}

fuzz_target!(|frame: &[u8]| {
    let _ = frame_kind(frame);
    round_trip::<ClientMessage>(frame);
    round_trip::<ServerMessage>(frame);
});
