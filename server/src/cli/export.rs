//! `farfield-server export`: a scene as plain files for a static file
//! server (nginx, say), laid out as the load test's `--static` mode asks
//! for them: `OUT/NAME/header` (the header as stored, its checksum
//! included) and `OUT/NAME/pages/N` (page id N as stored: the scene's
//! pages, then its directory pages). Every page is verified on the way
//! out, so a corrupt file exports nothing.

use anyhow::Context;
use farfield_store::{PageSource, SceneFile};
use serde_json::json;

use super::{ExportArgs, Report};

pub fn run(args: &ExportArgs) -> anyhow::Result<Report> {
    let file = SceneFile::open(&args.file)?;
    let name = match &args.name {
        Some(name) => name.clone(),
        None => args
            .file
            .file_stem()
            .and_then(|s| s.to_str())
            .context("the file has no name to export it under (give --name)")?
            .to_owned(),
    };
    anyhow::ensure!(
        !name.is_empty() && !name.contains(['/', '\\']) && name != "." && name != "..",
        "{name:?} cannot name a folder"
    );
    let dir = args.out.join(&name);
    let pages_dir = dir.join("pages");
    std::fs::create_dir_all(&pages_dir)
        .with_context(|| format!("making {}", pages_dir.display()))?;
    let mut bytes = file.header_bytes().len() as u64;
    let mut page = Vec::new();
    // The scene's pages, then the directory's (ids after them).
    let count = file.directory().id_count();
    for index in 0..count {
        page.clear();
        file.read_page(index, &mut page)
            .with_context(|| format!("page {index} of {}", args.file.display()))?;
        let path = pages_dir.join(index.to_string());
        std::fs::write(&path, &page).with_context(|| format!("writing {}", path.display()))?;
        bytes += page.len() as u64;
    }
    let header = dir.join("header");
    // Last: a folder with a header is a whole export.
    std::fs::write(&header, file.header_bytes())
        .with_context(|| format!("writing {}", header.display()))?;
    Ok(Report {
        json: json!({ "scene": name, "dir": dir, "pages": count, "bytes": bytes }),
        text: format!(
            "wrote {count} pages and the header of {name} ({bytes} bytes) into {}",
            dir.display()
        ),
        exit_code: 0,
        as_json: args.json,
    })
}
