//! `farfield-server bench codecs`: how each candidate page codec would
//! store the pages of built scenes, and how fast it encodes and decodes
//! them on one core. The pages' decoded bodies (records, then payload) are
//! the input, so the figures are this project's own records, not a corpus.
//!
//! Candidates are deflate at several levels, over the body as is and over
//! the records split into byte planes (what the format stores), each
//! through the format's own codec (`page_codec::encode_body_at`, and
//! `decode_planes_deflate` back); the format's choice is
//! `planes+deflate3`. A general-purpose survey with zstd and LZMA, which
//! have no pure-Rust encoder, is `benches/page_codecs.py`.

use std::path::{Path, PathBuf};
use std::time::Instant;

use farfield_protocol::FormatError;
use farfield_protocol::page::{Page, check_page};
use farfield_protocol::page_codec::{PageCodec, decode_planes_deflate, encode_body_at};
use farfield_store::SceneFile;
use serde_json::json;

use crate::Measured;
use crate::stats::median;

/// One page's decoded body.
struct Body {
    bytes: Vec<u8>,
    record_bytes: usize,
    node_bytes: usize,
}

/// One candidate: whether records are split into planes, and the level.
#[derive(Clone, Copy)]
struct Candidate {
    planes: bool,
    level: u8,
}

impl Candidate {
    fn name(self) -> String {
        format!(
            "{}deflate{}",
            if self.planes { "planes+" } else { "" },
            self.level
        )
    }

    /// Records of one byte are not split: the body is deflated as it is.
    fn node_bytes(self, body: &Body) -> usize {
        if self.planes { body.node_bytes } else { 1 }
    }

    fn encode(self, body: &Body) -> (PageCodec, Vec<u8>) {
        let (records, payload) = body.bytes.split_at(body.record_bytes);
        encode_body_at(records, self.node_bytes(body), payload, self.level)
    }

    fn decode(
        self,
        body: &Body,
        (codec, stored): &(PageCodec, Vec<u8>),
    ) -> Result<Vec<u8>, FormatError> {
        match codec {
            PageCodec::Stored => Ok(stored.clone()),
            PageCodec::PlanesDeflate => decode_planes_deflate(
                stored,
                body.bytes.len() as u32,
                body.record_bytes,
                self.node_bytes(body),
                0,
            ),
        }
    }
}

const CANDIDATES: [Candidate; 8] = [
    Candidate {
        planes: false,
        level: 1,
    },
    Candidate {
        planes: false,
        level: 6,
    },
    Candidate {
        planes: false,
        level: 9,
    },
    Candidate {
        planes: true,
        level: 1,
    },
    Candidate {
        planes: true,
        level: 3,
    },
    Candidate {
        planes: true,
        level: 4,
    },
    Candidate {
        planes: true,
        level: 6,
    },
    Candidate {
        planes: true,
        level: 9,
    },
];

/// Every page of `file`, decoded.
fn bodies(file: &Path) -> anyhow::Result<(SceneFile, Vec<Body>)> {
    let scene = SceneFile::open(file)?;
    let header = scene.header.clone();
    let mut out = Vec::with_capacity(header.page_count as usize);
    let mut bytes = Vec::new();
    for index in 0..header.page_count as usize {
        bytes.clear();
        scene.read_page_into(index, &mut bytes)?;
        let page = Page::parse_with_payload(&bytes, index as u32, header.node_bytes)?;
        let mut body = page.records().to_vec();
        body.extend_from_slice(page.payload());
        out.push(Body {
            bytes: body,
            record_bytes: page.records().len(),
            node_bytes: header.node_bytes as usize,
        });
    }
    Ok((scene, out))
}

pub fn codecs(files: &[PathBuf], repeats: usize) -> anyhow::Result<Measured> {
    let mut rows = Vec::new();
    let mut text = String::new();
    for file in files {
        let (scene, pages) = bodies(file)?;
        let header = &scene.header;
        let raw: usize = pages.iter().map(|b| b.bytes.len()).sum();
        // Header and per-page framing, which no codec changes.
        let framing = scene.len() as usize - pages_stored(&scene);
        let per_input =
            |stored: usize| (framing + stored) as f64 / header.input_vertices.max(1) as f64;
        text += &format!(
            "{}: {} pages, {raw} body bytes decoded, {} inputs; {:.2} bytes/input uncompressed\n",
            file.display(),
            pages.len(),
            header.input_vertices,
            per_input(raw)
        );
        let check = check_rate(&scene, repeats)?;
        text += &format!(
            "  as stored: every page checked and decoded (check_page, as a client does) at {:.1} MB/s decoded\n",
            check / 1e6
        );
        rows.push(json!({
            "file": file,
            "codec": "as stored, check_page",
            "decoded_bytes": raw,
            "decode_bytes_per_second": check,
        }));
        for candidate in CANDIDATES {
            let (mut encode_rates, mut decode_rates) = (Vec::new(), Vec::new());
            let mut stored = Vec::new();
            for _ in 0..repeats.max(1) {
                let started = Instant::now();
                stored = pages.iter().map(|b| candidate.encode(b)).collect();
                encode_rates.push(raw as f64 / started.elapsed().as_secs_f64().max(1e-9));
                let started = Instant::now();
                for (body, s) in pages.iter().zip(&stored) {
                    std::hint::black_box(candidate.decode(body, s)?);
                }
                decode_rates.push(raw as f64 / started.elapsed().as_secs_f64().max(1e-9));
            }
            // The round trip is exact (once, outside the timing).
            for (body, s) in pages.iter().zip(&stored) {
                anyhow::ensure!(
                    candidate.decode(body, s)? == body.bytes,
                    "{} does not round-trip",
                    candidate.name()
                );
            }
            let total: usize = stored.iter().map(|(_, s)| s.len()).sum();
            let (encode, decode) = (median(&mut encode_rates), median(&mut decode_rates));
            text += &format!(
                "  {:16} {:6.3}x  {:6.2} bytes/input  encode {:7.1} MB/s  decode {:7.1} MB/s\n",
                candidate.name(),
                raw as f64 / total.max(1) as f64,
                per_input(total),
                encode / 1e6,
                decode / 1e6
            );
            rows.push(json!({
                "file": file,
                "codec": candidate.name(),
                "pages": pages.len(),
                "decoded_bytes": raw,
                "stored_bytes": total,
                "ratio": raw as f64 / total.max(1) as f64,
                "bytes_per_input": per_input(total),
                "encode_bytes_per_second": encode,
                "decode_bytes_per_second": decode,
            }));
        }
    }
    Ok(Measured {
        json: json!({ "repeats": repeats.max(1), "rows": rows }),
        text: text.trim_end().to_string(),
    })
}

/// The median rate of [`check_page`] over every page as stored (checksum,
/// header, directory and the body decoded by the file's own codec): what
/// `benches/codec_wasm/run` times in wasm.
fn check_rate(scene: &SceneFile, repeats: usize) -> anyhow::Result<f64> {
    let mut stored = Vec::new();
    for index in 0..scene.header.page_count as usize {
        let mut bytes = Vec::new();
        scene.read_page_into(index, &mut bytes)?;
        stored.push(bytes);
    }
    let mut rates = Vec::new();
    for _ in 0..repeats.max(1) {
        let started = Instant::now();
        let mut decoded = 0;
        for (index, bytes) in stored.iter().enumerate() {
            let page = check_page(&scene.header, &scene.directory, index as u32, bytes)?;
            decoded += page.records().len() + page.payload().len();
        }
        rates.push(decoded as f64 / started.elapsed().as_secs_f64().max(1e-9));
    }
    Ok(median(&mut rates))
}

/// Bytes of the file's page bodies as stored (each page less its header
/// and checksum).
fn pages_stored(scene: &SceneFile) -> usize {
    use farfield_protocol::page::{PAGE_CHECKSUM_BYTES, PAGE_HEADER_BYTES};
    scene
        .directory
        .entries()
        .map(|(_, p)| (p.length as usize).saturating_sub(PAGE_HEADER_BYTES + PAGE_CHECKSUM_BYTES))
        .sum()
}
