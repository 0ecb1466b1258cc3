//! The file's pages from the top's groups and the chunks' level files, in
//! breadth-first order, without holding any level whole.
//!
//! A level is a list of segments: a group of the top, or one chunk's whole
//! level k. Breadth-first order puts a level's nodes in the order of their
//! parents, so the next level's segments follow from this level's: a top
//! node's children are its group, a chunk root's are its chunk's level 1,
//! and a chunk's level k is followed by its level k + 1.

use std::fs::File;
use std::io::{self, BufReader, Read, Seek, SeekFrom};

use farfield_protocol::sphere_codec::NodeRecord;

use super::chunk::ChunkLevels;
use super::top::{TopLayout, TopRef};
use crate::page_writer::PageWriter;
use crate::progress::Progress;
use crate::spheres::page_cutter::{GroupSink, PageCutter};

#[derive(Debug, Clone, Copy)]
enum Segment {
    Top(usize),
    Chunk { chunk: usize, level: usize },
}

/// What the merge placed.
pub(crate) struct Merged {
    pub pages: PageWriter,
    pub levels: u32,
    pub nodes: u64,
}

/// Cuts the top's groups and the chunks' levels into pages of at most
/// `page_bytes`, written to `pages_path` as they are made. `progress`
/// counts nodes placed.
pub(crate) fn merge(
    top: &TopLayout,
    chunks: &[Option<ChunkLevels>],
    node_bytes: usize,
    page_bytes: usize,
    pages_path: &std::path::Path,
    progress: &dyn Progress,
) -> io::Result<Merged> {
    let mut pages =
        PageCutter::with_writer(page_bytes, node_bytes, PageWriter::spilling_to(pages_path)?);
    // Where each chunk's next level starts in its two files.
    let mut offsets = vec![(0u64, 0u64); chunks.len()];
    let mut next_child = 1u64;
    let mut nodes = 0u64;
    let mut level = 0u32;
    let mut segments = vec![Segment::Top(0)];
    let place = |pages: &mut PageCutter, level: u32, group: &[u8], next_child: &mut u64| {
        pages.add_group(level, group, *next_child);
        *next_child += group
            .chunks_exact(node_bytes)
            .map(|r| {
                let mut word = [0u8; 8];
                word[..node_bytes].copy_from_slice(r);
                NodeRecord::child_count(u64::from_le_bytes(word)) as u64
            })
            .sum::<u64>();
        (group.len() / node_bytes) as u64
    };
    loop {
        if level > 0 {
            pages.end_level();
        }
        let before = nodes;
        let mut next = Vec::new();
        for &segment in &segments {
            match segment {
                Segment::Top(g) => {
                    let group = &top.groups[g];
                    nodes += place(&mut pages, level, &group.records, &mut next_child);
                    for &member in &group.members {
                        match member {
                            TopRef::Node(n) => next.push(Segment::Top(top.group_of_node[n])),
                            TopRef::Chunk(c) => {
                                if chunks[c].as_ref().is_some_and(|l| !l.levels.is_empty()) {
                                    next.push(Segment::Chunk { chunk: c, level: 0 });
                                }
                            }
                        }
                    }
                }
                Segment::Chunk { chunk, level: k } => {
                    let Some(files) = &chunks[chunk] else {
                        continue;
                    };
                    let (groups, count) = files.levels[k];
                    let (at_groups, at_records) = offsets[chunk];
                    let mut sizes = vec![0u8; groups as usize];
                    let mut g = File::open(&files.groups_path)?;
                    g.seek(SeekFrom::Start(at_groups))?;
                    g.read_exact(&mut sizes)?;
                    let mut records = File::open(&files.records_path)?;
                    records.seek(SeekFrom::Start(at_records))?;
                    let mut records = BufReader::with_capacity(1 << 16, records);
                    let mut group = Vec::new();
                    for &size in &sizes {
                        group.resize(usize::from(size) * node_bytes, 0);
                        records.read_exact(&mut group)?;
                        nodes += place(&mut pages, level, &group, &mut next_child);
                    }
                    offsets[chunk] = (at_groups + groups, at_records + count * node_bytes as u64);
                    if k + 1 < files.levels.len() {
                        next.push(Segment::Chunk {
                            chunk,
                            level: k + 1,
                        });
                    }
                }
            }
        }
        progress.advance(nodes - before);
        if next.is_empty() {
            break;
        }
        segments = next;
        level += 1;
    }
    Ok(Merged {
        pages: pages.finish(),
        levels: level + 1,
        nodes,
    })
}
