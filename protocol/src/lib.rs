//! farfield-protocol: the bytes both sides agree on.
//!
//! No async runtime, no GPU: this crate is what the server writes and the
//! client reads, plus the CPU reference decoder that traversal walks
//! (the traversals themselves are `farfield-traverse`).
//!
//! - [`file`]: the paged hierarchy file's fixed-size [`file::FileHeader`]
//!   and a page's [`file::PageEntry`] (layout in `FORMAT.md`);
//!   [`directory`]: the page directory, itself in pages reached from the
//!   header, which a client learns as it goes.
//! - [`page`]: one page's [`page::PageHeader`], checksum and the verified
//!   [`page::Page`] view a decoder reads nodes from.
//! - [`sphere_codec`]: QSplat's quantized node: position and radius relative
//!   to the parent (13 bits), normal (14 bits), cone (2 bits), 5-6-5 color.
//! - [`cube_codec`]: the color-cube octree's cell record, clustered
//!   sub-cubes and cell-relative leaf geometry (Chamberlain et al.).
//! - [`plp_codec`]: the PLP tessellation (Klosowski & Silva): the cell
//!   skeleton in page 0, each page's cells and their triangles.
//! - [`bsp_codec`]: hierarchical image caching's BSP (Shade et al.): the
//!   tree in page 0, a page per shared prototype, a page per leaf.
//! - [`shading`]: the fixed light the cube builder bakes in and the
//!   client's geometry pass repeats; [`octahedral`]: 32-bit unit normals.
//! - [`camera`]: a view with f64 frustum planes and projected-size math.
//! - [`hierarchy`]: [`hierarchy::Hierarchy`], a header plus whichever pages are
//!   resident, the one type traversal walks.
//! - [`paged_file`]: [`paged_file::PagedFile`], a whole file in memory as
//!   builders make it, and [`paged_file::read_image`], a file's bytes read
//!   into a fully resident hierarchy.
//! - [`messages`]: the websocket session's [`messages::ClientMessage`] and
//!   [`messages::ServerMessage`]; [`codec`]: their bytes (bincode 2, in one
//!   module so it can be swapped); [`percent`]: names and tokens in URLs.

pub mod auth;
pub mod bsp_codec;
pub mod camera;
pub mod codec;
pub mod cube_codec;
pub mod directory;
pub mod file;
pub mod hierarchy;
pub mod kinds;
pub mod messages;
pub mod octahedral;
pub mod page;
pub mod page_codec;
pub mod paged_file;
pub mod percent;
pub mod plp_codec;
pub mod shading;
pub mod sphere_codec;

/// Everything that can be wrong with bytes that claim to be a farfield file
/// or page. A decoder reports these; it never draws what failed a check.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum FormatError {
    #[error("not a farfield file (bad magic)")]
    BadMagic,
    #[error(
        "format version {found} is not supported (this build reads version {supported}): rebuild the scene from its inputs with `farfield-server build`"
    )]
    UnsupportedVersion { found: u32, supported: u32 },
    #[error("{what} is truncated: need {needed} bytes, have {have}")]
    Truncated {
        what: &'static str,
        needed: u64,
        have: u64,
    },
    #[error("header checksum mismatch: the header is corrupt")]
    HeaderChecksum,
    #[error(
        "page {page}: checksum mismatch (stored {stored:#010x}, computed {computed:#010x}): the page is corrupt"
    )]
    PageChecksum {
        page: u32,
        stored: u32,
        computed: u32,
    },
    #[error("page {page}: {message}")]
    BadPage { page: u32, message: String },
    #[error("header: {0}")]
    BadHeader(String),
}
