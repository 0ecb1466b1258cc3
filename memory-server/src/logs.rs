//! How the binaries log: to stderr, filtered by `RUST_LOG`, with colours
//! only where stderr is a terminal. A log file, a pipe or a container's
//! log collector gets plain text: escape codes there are noise that every
//! reader has to strip (as `ls` and `git` decide colour by the terminal).

use std::io::IsTerminal;

use tracing_subscriber::EnvFilter;

/// Starts logging for a binary: `RUST_LOG`, else `default` (`None`: only
/// errors).
pub fn init(default: Option<&str>) {
    let filter = match default {
        Some(default) => {
            EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default))
        }
        None => EnvFilter::from_default_env(),
    };
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::stderr().is_terminal())
        .init();
}

#[cfg(test)]
mod tests {
    use std::sync::{Arc, Mutex};

    /// A writer into a shared buffer.
    #[derive(Clone, Default)]
    struct Buffer(Arc<Mutex<Vec<u8>>>);

    impl std::io::Write for Buffer {
        fn write(&mut self, bytes: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(bytes);
            Ok(bytes.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    fn logged(ansi: bool) -> String {
        let buffer = Buffer::default();
        let writer = buffer.clone();
        let subscriber = tracing_subscriber::fmt()
            .with_writer(move || writer.clone())
            .with_ansi(ansi)
            .finish();
        tracing::subscriber::with_default(subscriber, || tracing::warn!(page = 3, "corrupt"));
        String::from_utf8(buffer.0.lock().unwrap().clone()).unwrap()
    }

    /// Under `cargo test` stderr is captured, not a terminal: what `init`
    /// decides there is plain text, and colour would show as escapes.
    #[test]
    fn logs_to_something_other_than_a_terminal_carry_no_escape_codes() {
        use std::io::IsTerminal;
        let plain = logged(std::io::stderr().is_terminal());
        assert!(
            plain.contains("corrupt") && !plain.contains('\x1b'),
            "{plain:?}"
        );
        assert!(logged(true).contains('\x1b'), "colour on a terminal");
    }
}
