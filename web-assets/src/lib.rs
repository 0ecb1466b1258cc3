//! The browser viewer, carried inside the binary that serves it.
//!
//! `build.rs` compiles the `farfield-web` crate for `wasm32-unknown-unknown`
//! (a nested cargo, in a target folder of its own so it never waits on the
//! outer build's lock) and binds it with wasm-bindgen as a library, so the
//! server's own `cargo build` makes the viewer: a new user needs no
//! `wasm-bindgen` command and no `web/build`. The files are embedded with
//! `include_bytes!`, the wasm also gzipped for browsers that take it.
//!
//! Where the viewer cannot be built (no wasm32 target, or
//! `FARFIELD_WEB_EMBED=0` for a quicker build), the crate still builds,
//! [`VIEWER`] is `None` and [`MISSING`] says why; the server then serves a
//! folder (`web/build`'s `web/dist`) if it finds one.

/// A built viewer's files.
#[derive(Debug, Clone, Copy)]
pub struct Viewer {
    /// `farfield_web.js`: wasm-bindgen's glue, which the page imports.
    pub js: &'static [u8],
    /// `farfield_web_bg.wasm`, which the glue fetches.
    pub wasm: &'static [u8],
    /// The same wasm, gzipped.
    pub wasm_gzip: &'static [u8],
}

/// The viewer built with this binary, if it could be.
#[cfg(farfield_viewer_embedded)]
pub const VIEWER: Option<Viewer> = Some(Viewer {
    js: include_bytes!(concat!(env!("OUT_DIR"), "/web/farfield_web.js")),
    wasm: include_bytes!(concat!(env!("OUT_DIR"), "/web/farfield_web_bg.wasm")),
    wasm_gzip: include_bytes!(concat!(env!("OUT_DIR"), "/web/farfield_web_bg.wasm.gz")),
});

/// The viewer built with this binary, if it could be.
#[cfg(not(farfield_viewer_embedded))]
pub const VIEWER: Option<Viewer> = None;

/// Why [`VIEWER`] is `None` (empty when it is not).
pub const MISSING: &str = env!("FARFIELD_WEB_MISSING");

#[cfg(test)]
mod tests {
    use super::*;

    /// The embedded files are a viewer's: wasm's magic number, the glue
    /// that fetches this wasm by name, and a gzip of the same bytes.
    #[test]
    fn an_embedded_viewer_is_whole() {
        let Some(viewer) = VIEWER else {
            assert!(!MISSING.is_empty(), "no viewer and no reason");
            // CI has every tool the viewer needs: there it may not skip.
            assert!(
                std::env::var_os("FARFIELD_REQUIRE_VIEWER_TOOLS").is_none(),
                "no embedded viewer: {MISSING}"
            );
            eprintln!("SKIPPED: no embedded viewer ({MISSING})");
            return;
        };
        assert!(MISSING.is_empty(), "{MISSING}");
        assert_eq!(&viewer.wasm[..4], b"\0asm");
        let js = std::str::from_utf8(viewer.js).expect("the glue is text");
        assert!(
            js.contains("farfield_web_bg.wasm"),
            "the glue names its wasm"
        );
        let gz = viewer.wasm_gzip;
        assert_eq!(&gz[..3], &[0x1f, 0x8b, 8], "gzip's magic number, deflate");
        assert!(gz.len() < viewer.wasm.len());
        let (body, trailer) = gz[10..].split_at(gz.len() - 18);
        let inflated = miniz_oxide::inflate::decompress_to_vec(body).expect("a deflate stream");
        assert!(inflated == viewer.wasm, "the gzip holds the wasm");
        let crc = u32::from_le_bytes(trailer[..4].try_into().unwrap());
        let len = u32::from_le_bytes(trailer[4..].try_into().unwrap());
        assert_eq!(
            (crc, len as usize),
            (crc32fast::hash(viewer.wasm), viewer.wasm.len())
        );
    }
}
