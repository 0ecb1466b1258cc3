//! How a refusal quotes what a client sent: at most a short prefix, so a
//! client that sends a 900 KB name gets a one-line answer, not its name
//! back (which once overflowed the connection's write buffer).

/// Characters of a client's text a reply quotes at most.
pub const QUOTED_CHARS: usize = 48;

/// `text`, or its first [`QUOTED_CHARS`] characters followed by `…` and
/// how long it was.
pub fn prefix(text: &str) -> String {
    match text.char_indices().nth(QUOTED_CHARS) {
        None => text.to_owned(),
        Some((end, _)) => format!("{}… ({} bytes)", &text[..end], text.len()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_texts_are_quoted_whole_and_long_ones_cut_on_a_character() {
        assert_eq!(prefix("island"), "island");
        let long = "é".repeat(100_000);
        let quoted = prefix(&long);
        assert!(quoted.starts_with(&"é".repeat(QUOTED_CHARS)), "{quoted}");
        assert!(quoted.ends_with("… (200000 bytes)"), "{quoted}");
        assert!(quoted.len() < 200, "{}", quoted.len());
    }
}
