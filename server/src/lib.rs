//! farfield-server: everything between an input file and the bytes a client
//! receives.
//!
//! - [`scene`]: the in-memory [`scene::Scene`] all importers produce.
//! - [`import`]: OBJ, PLY, OFF, LAS/LAZ, PDB and the `gen:` generators.
//! - [`build`]: the QSplat bounding-sphere builder: leaf sizing, tree,
//!   quantization and the breadth-first page layout.
//! - [`cli`]: the `farfield-server` subcommands, callable in-process.
//! - [`allocator`]: the allocator the binaries use, asking for transparent
//!   huge pages on the builder's large arrays.
//! - [`store`]: writes the paged file atomically and reads it back through a
//!   memory map, verifying page checksums.
//! - [`serve`]: the memory server: HTTP and websocket streaming of pages in
//!   priority order, shared page cache, prefetch, metrics.

pub mod allocator;
pub mod build;
pub mod cli;
pub mod import;
pub mod scene;
pub mod serve;
pub mod store;
