//! `--file` mode: a paged file read straight from disk, every page resident.

use std::path::Path;

use anyhow::Context;
use farfield_protocol::file::FileHeader;
use farfield_protocol::hierarchy::Hierarchy;

/// Reads `path` and makes every page resident, verifying each checksum.
pub fn load_file(path: &Path) -> anyhow::Result<Hierarchy> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    let header = FileHeader::decode(&bytes).with_context(|| format!("{}", path.display()))?;
    let mut h = Hierarchy::new(header).with_context(|| format!("{}", path.display()))?;
    for i in 0..h.header.pages.len() {
        let e = h.header.pages[i];
        let start = usize::try_from(e.offset)?;
        let page = bytes
            .get(start..start + e.length as usize)
            .with_context(|| {
                format!("{}: page {i} lies past the end of the file", path.display())
            })?;
        h.insert_page(i as u32, page)
            .with_context(|| format!("{}", path.display()))?;
    }
    Ok(h)
}
