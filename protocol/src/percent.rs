//! Percent-encoding of a URL path segment or query value (RFC 3986's
//! unreserved characters kept, every other byte as `%XX`): how a scene
//! name or an access token travels in a URL, written the same way by the
//! client (its stream URL) and the server (the links of its pages).

/// `text` with every byte but `A-Z a-z 0-9 - . _ ~` percent-encoded.
pub fn percent_encode(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    for b in text.bytes() {
        if b.is_ascii_alphanumeric() || b"-._~".contains(&b) {
            out.push(char::from(b));
        } else {
            out.push_str(&format!("%{b:02X}"));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unreserved_bytes_stay_and_the_rest_are_escaped() {
        assert_eq!(percent_encode("a-Z_0.~"), "a-Z_0.~");
        assert_eq!(percent_encode("a b/é?&"), "a%20b%2F%C3%A9%3F%26");
    }
}
