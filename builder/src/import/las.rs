//! LAS and LAZ lidar point clouds, through the `las` crate (LAZ via its
//! `laz` feature).
//!
//! Points are read in batches of [`BATCH`] into one reused
//! [`las::PointData`] slab and taken column by column: positions with the
//! file's scale and offset applied (f64), and colors when the point format
//! has RGB. LAS colors are 16-bit; a file whose channels never exceed 255
//! stored 8-bit values as they are, otherwise each channel is divided by 257.
//!
//! Before the crate sees the file, its raw header is checked against the
//! file size, because the crate would otherwise allocate from (or overflow
//! on) impossible counts; a LAS body shorter than its header promises is
//! reported as truncated. For LAZ the same goes for the chunk table's count,
//! which the `laz` crate allocates for before reading, and the laszip items'
//! sizes, which it trusts. A panic inside the LAZ decompressor on corrupt
//! data (opening the file included) becomes an error. The crate itself is a
//! patched copy (`third_party/laz`, see its PATCHED.md).

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use glam::DVec3;
use las::point::Format;

use super::ImportError;
use crate::scene::{Geometry, Primitives, Scene};

/// Points decoded per batch, at most.
const BATCH: u64 = 1 << 16;
/// Points decompressed per batch of a LAZ file read in parallel, at most:
/// LASzip's chunks hold 50,000 points, so this is about 20 of them.
const PARALLEL_BATCH: u64 = 1 << 20;

/// Bytes of decoded records per batch, at most: the slab is sized for a
/// whole batch before the points are read, and a LAZ header's point count
/// is not bounded by the file, so 65,536 records of 64 KiB each would have
/// been 4 GiB for a file of a few hundred bytes.
const BATCH_BYTES: u64 = 16 << 20;

/// Loads a LAS or LAZ file as one point cloud.
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    // Sized once from the header (a vector grown by doubling would briefly
    // hold a large cloud up to three times).
    let cap = capacity(path)?;
    let mut positions = Vec::with_capacity(cap);
    let mut colors: Option<Vec<[u16; 3]>> = None;
    let info = stream(path, &mut |batch, rgb| {
        positions.extend_from_slice(batch);
        if let Some(rgb) = rgb {
            colors
                .get_or_insert_with(|| Vec::with_capacity(cap))
                .extend_from_slice(rgb);
        }
        Ok(())
    })?;
    let mut geometry = Geometry::new(path.display().to_string(), positions, Primitives::Points);
    geometry.colors = info.has_color.then(|| {
        let colors = colors.unwrap_or_default();
        let wide = colors.iter().flatten().any(|&v| v > 255);
        colors
            .into_iter()
            .map(|rgb| rgb.map(|v| to8(v, wide)))
            .collect()
    });
    Ok(Scene::single(geometry))
}

/// Points to make room for: the header's count, bounded by what the file
/// can hold (compressed points take at least a few bytes each, whatever
/// the header says).
fn capacity(path: &Path) -> Result<usize, ImportError> {
    let mut file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| ImportError::io(path, e))?.len();
    let checked = precheck(path, &mut file, file_len)?;
    let bound = if checked.compressed {
        file_len
    } else {
        file_len / 20
    };
    Ok(checked.count.min(bound) as usize)
}

/// A 16-bit LAS color channel as 8 bits: divided by 257 when the file's
/// channels are `wide` (some exceeds 255), as they are when not.
pub(crate) fn to8(v: u16, wide: bool) -> u8 {
    if wide {
        ((u32::from(v) + 128) / 257) as u8
    } else {
        v as u8
    }
}

/// What takes a file's points a batch at a time: positions, and 16-bit
/// colors when the format has them.
pub(crate) type EachBatch<'a> =
    dyn FnMut(&[DVec3], Option<&[[u16; 3]]>) -> Result<(), ImportError> + 'a;

/// What a LAS or LAZ file's header says, checked against the file.
#[derive(Debug, Clone, Copy)]
pub(crate) struct LasInfo {
    /// Points the header promises.
    pub count: u64,
    /// Whether the point format carries RGB.
    pub has_color: bool,
    /// The header's bounds (scaled): a hint, not a promise.
    pub bounds: (DVec3, DVec3),
}

impl LasInfo {
    /// What `header` says, with the point count `precheck` found.
    fn of(header: &las::Header, count: u64) -> Self {
        let b = header.bounds();
        Self {
            count,
            has_color: header.point_format().has_color,
            bounds: (
                DVec3::new(b.min.x, b.min.y, b.min.z),
                DVec3::new(b.max.x, b.max.y, b.max.z),
            ),
        }
    }
}

/// Reads the header of a LAS or LAZ file, checked as [`load`] checks it.
pub(crate) fn survey(path: &Path) -> Result<LasInfo, ImportError> {
    let mut file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| ImportError::io(path, e))?.len();
    let count = precheck(path, &mut file, file_len)?.count;
    // Only the header is read: no decompressor is set up to run.
    let open = move || open_reader(path, file, false);
    // Opening a LAZ file decodes its chunk table.
    let reader = catch_unwind(AssertUnwindSafe(open)).unwrap_or_else(|_| {
        Err(ImportError::malformed(
            path,
            "header",
            "the LAZ data is corrupt",
        ))
    })?;
    Ok(LasInfo::of(reader.header(), count))
}

/// Reads a LAS or LAZ file's points in batches (positions with the file's
/// scale and offset applied; 16-bit colors when the format has them), each
/// handed to `each` as it is decoded, so memory does not grow with the
/// file. An error from `each` stops the reading and is returned.
pub(crate) fn stream(path: &Path, each: &mut EachBatch<'_>) -> Result<LasInfo, ImportError> {
    let mut file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| ImportError::io(path, e))?.len();
    let Checked {
        count,
        compressed,
        parallel,
    } = precheck(path, &mut file, file_len)?;
    // Opening a LAZ file decodes its chunk table, so that is inside the
    // decompressor's `catch_unwind` too.
    let read = move || {
        let mut reader = open_reader(path, file, parallel)?;
        let info = LasInfo::of(reader.header(), count);
        read_points(path, &mut reader, parallel, each)?;
        Ok(info)
    };
    if compressed {
        catch_unwind(AssertUnwindSafe(read)).unwrap_or_else(|_| {
            Err(ImportError::malformed(
                path,
                "point data",
                "the LAZ data is corrupt",
            ))
        })
    } else {
        read()
    }
}

/// Opens a reader of `file` (at its start); a LAZ file's chunks are
/// decompressed in parallel, on every core, when `parallel` (its chunk
/// table checked by [`chunks_in_bounds`]), else in order.
fn open_reader(path: &Path, file: File, parallel: bool) -> Result<las::Reader, ImportError> {
    let parallelism = if parallel {
        las::LazParallelism::Yes
    } else {
        las::LazParallelism::No
    };
    let options = las::ReaderOptions::default().with_laz_parallelism(parallelism);
    las::Reader::with_options(BufReader::with_capacity(1 << 20, file), options)
        .map_err(|e| las_error(path, "header", e))
}

fn read_points(
    path: &Path,
    reader: &mut las::Reader,
    parallel: bool,
    each: &mut EachBatch<'_>,
) -> Result<(), ImportError> {
    let mut data = las::PointDataBuilder::new()
        .for_header(reader.header())
        .build();
    let format = reader.header().point_format();
    let has_color = format.has_color;
    // LAZ chunks are decompressed in parallel within a batch: a batch of
    // many chunks keeps every core busy.
    let most = if parallel { PARALLEL_BATCH } else { BATCH };
    let batch = (BATCH_BYTES / u64::from(format.len()).max(1)).clamp(1, most);
    let mut positions = Vec::with_capacity(batch as usize);
    let mut colors = Vec::with_capacity(if has_color { batch as usize } else { 0 });
    let mut read = 0u64;
    loop {
        let at = format!("point {read}");
        let n = reader
            .fill_points(batch, &mut data)
            .map_err(|e| las_error(path, at, e))?;
        if n == 0 {
            return Ok(());
        }
        read += n;
        positions.clear();
        positions.extend(
            data.x()
                .zip(data.y())
                .zip(data.z())
                .map(|((x, y), z)| DVec3::new(x, y, z)),
        );
        colors.clear();
        if has_color && let Some(rgb) = data.rgb() {
            colors.extend(rgb.map(|(r, g, b)| [r, g, b]));
        }
        each(&positions, has_color.then_some(&colors[..]))?;
    }
}

/// Checks the raw header against the file size; returns the point count and
/// whether the points are compressed. Leaves the file at its start.
fn precheck(path: &Path, file: &mut File, file_len: u64) -> Result<Checked, ImportError> {
    let raw = las::raw::Header::read_from(&mut *file).map_err(|e| las_error(path, "header", e))?;
    let legacy = u64::from(raw.number_of_point_records);
    let count = match raw.large_file {
        Some(large) if legacy == 0 => large.number_of_point_records,
        _ => legacy,
    };
    let format =
        Format::new(raw.point_data_record_format).map_err(|e| las_error(path, "header", e))?;
    let bytes = count.checked_mul(u64::from(raw.point_data_record_length));
    let end = bytes.and_then(|b| b.checked_add(u64::from(raw.offset_to_point_data)));
    match end {
        None => {
            return Err(ImportError::malformed(
                path,
                "header",
                "the point count is impossibly large",
            ));
        }
        Some(end) if !format.is_compressed && end > file_len => {
            let msg = format!("file ends early (truncated): the header promises {count} points");
            return Err(ImportError::malformed(path, "point data", msg));
        }
        _ => {}
    }
    let mut parallel = false;
    if format.is_compressed {
        let point_data = u64::from(raw.offset_to_point_data);
        check_chunk_table(path, file, point_data, file_len)?;
        check_laszip_items(path, file, &raw, file_len)?;
        parallel = chunks_in_bounds(file, &raw, count, file_len);
    }
    if let Some(evlr) = raw.evlr {
        // The crate allocates the first EVLR's 64-bit length before reading it.
        let mut head = [0u8; 28];
        let length = file
            .seek(SeekFrom::Start(evlr.start_of_first_evlr))
            .and_then(|_| file.read_exact(&mut head))
            .map(|_| {
                head.get(20..28)
                    .and_then(|b| b.try_into().ok())
                    .map(u64::from_le_bytes)
            });
        if !matches!(length, Ok(Some(n)) if n <= file_len) {
            return Err(ImportError::malformed(
                path,
                "header",
                "the extended VLR is invalid or truncated",
            ));
        }
    }
    file.seek(SeekFrom::Start(0))
        .map_err(|e| ImportError::io(path, e))?;
    Ok(Checked {
        count,
        compressed: format.is_compressed,
        parallel,
    })
}

/// What [`precheck`] found.
struct Checked {
    /// Points the header promises.
    count: u64,
    compressed: bool,
    /// Whether the LAZ chunks may be decompressed in parallel.
    parallel: bool,
}

/// The most bytes a chunk may decode to for parallel decompression.
const MAX_PARALLEL_CHUNK_BYTES: u64 = 256 << 20;

/// Whether a LAZ file's chunk table describes chunks within the file and
/// the header's points, each of a size that may be decoded whole: the
/// parallel decompressor (the `las` crate's `laz-parallel`) allocates by
/// these counts before it reads, and the fuzzer drove it to ask for more
/// memory than there is. A file whose table fails is decompressed in order,
/// as before, which reads chunks as a stream.
fn chunks_in_bounds(file: &mut File, raw: &las::raw::Header, count: u64, file_len: u64) -> bool {
    let Some(vlr) = laszip_vlr(file, raw, file_len) else {
        return false;
    };
    let point_data = u64::from(raw.offset_to_point_data);
    let record = u64::from(raw.point_data_record_length).max(1);
    let read = || -> Option<bool> {
        let vlr = laz::LazVlr::read_from(&vlr[..]).ok()?;
        file.seek(SeekFrom::Start(point_data)).ok()?;
        let table = laz::laszip::ChunkTable::read_from(&mut *file, &vlr).ok()?;
        let entries = table.as_ref();
        let bytes = entries
            .iter()
            .try_fold(0u64, |sum, e| sum.checked_add(e.byte_count))?;
        let points = entries
            .iter()
            .try_fold(0u64, |sum, e| sum.checked_add(e.point_count))?;
        let within = |e: &laz::laszip::ChunkTableEntry| {
            e.point_count
                .checked_mul(record)
                .is_some_and(|b| b <= MAX_PARALLEL_CHUNK_BYTES)
        };
        // Fixed-size chunks all claim the VLR's size; the last may hold
        // fewer points.
        let counted = if vlr.uses_variable_size_chunks() {
            points == count
        } else {
            points >= count && points - count < u64::from(vlr.chunk_size())
        };
        Some(
            !entries.is_empty()
                && bytes <= file_len.saturating_sub(point_data)
                && counted
                && entries.iter().all(within),
        )
    };
    catch_unwind(AssertUnwindSafe(read))
        .ok()
        .flatten()
        .unwrap_or(false)
}

/// Checks the chunk count of a LAZ file's chunk table, which the `laz`
/// crate allocates for before it reads the table: every chunk takes at
/// least a byte of the file, so a count past the file's length is corrupt
/// (the fuzzer's 1 KiB file asked for 46 GB). The table is found as the
/// crate finds it: its offset is the first 8 bytes of the point data, or
/// the file's last 8 where the writer could not go back to fill those in;
/// without one the crate reads the chunks in order, allocating nothing.
fn check_chunk_table(
    path: &Path,
    file: &mut File,
    point_data: u64,
    file_len: u64,
) -> Result<(), ImportError> {
    let table_at = |b: [u8; 8]| {
        u64::try_from(i64::from_le_bytes(b))
            .ok()
            .filter(|&o| o > point_data)
    };
    let table = read_array(file, point_data)
        .and_then(table_at)
        .or_else(|| table_at(read_array(file, file_len.checked_sub(8)?)?));
    // A table that cannot be read is the crate's to report.
    if let Some(head) = table.and_then(|at| read_array::<8>(file, at)) {
        let chunks = u32::from_le_bytes([head[4], head[5], head[6], head[7]]);
        if u64::from(chunks) > file_len {
            return Err(ImportError::malformed(
                path,
                "point data",
                format!(
                    "the LAZ chunk table is corrupt: it counts {chunks} chunks in a file of {file_len} bytes"
                ),
            ));
        }
    }
    Ok(())
}

/// Checks the items of a LAZ file's laszip VLR (point, GPS time, colour,
/// ...): each must have its type's size and all together a point record's.
/// The `laz` crate cuts each record by the stated sizes and decodes by the
/// types', and panicked slicing past a record when they differed. (What it
/// once allocated from a layered chunk's layer sizes before reading them is
/// fixed in its patched copy, `third_party/laz`.) A missing VLR or an item
/// type it does not know is the crate's to report.
fn check_laszip_items(
    path: &Path,
    file: &mut File,
    raw: &las::raw::Header,
    file_len: u64,
) -> Result<(), ImportError> {
    let Some(vlr) = laszip_vlr(file, raw, file_len) else {
        return Ok(());
    };
    let u16_at = |i: usize| vlr.get(i..i + 2).map(|b| u16::from_le_bytes([b[0], b[1]]));
    let bad = |message: String| ImportError::malformed(path, "laszip VLR", message);
    let mut record = 0u64;
    for i in 0..u16_at(32).unwrap_or(0) as usize {
        let (Some(kind), Some(size)) = (u16_at(34 + 6 * i), u16_at(36 + 6 * i)) else {
            return Ok(());
        };
        // LASzip's item types: POINT10, GPSTIME11, RGB12, WAVEPACKET13,
        // POINT14, RGB14, RGBNIR14, WAVEPACKET14; BYTE (0) and BYTE14 (14)
        // hold the extra bytes, any number.
        let fixed = match kind {
            6 => Some(20),
            7 | 12 => Some(8),
            8 | 11 => Some(6),
            9 | 13 => Some(29),
            10 => Some(30),
            _ => None,
        };
        if let Some(fixed) = fixed.filter(|&f| f != size) {
            return Err(bad(format!(
                "item {i} (type {kind}) is {size} bytes, not {fixed}"
            )));
        }
        record += u64::from(size);
    }
    if record != u64::from(raw.point_data_record_length) {
        return Err(bad(format!(
            "the items make records of {record} bytes, the header's are {}",
            raw.point_data_record_length
        )));
    }
    Ok(())
}

/// The laszip VLR's data, if the file has one (user id `laszip encoded`,
/// record id 22204): compressor and coder (u16 each), version (4 bytes),
/// options and chunk size (u32 each), two i64 about special EVLRs, the
/// item count (u16), then each item's type, size and version (u16 each).
fn laszip_vlr(file: &mut File, raw: &las::raw::Header, file_len: u64) -> Option<Vec<u8>> {
    let mut at = u64::from(raw.header_size);
    for _ in 0..raw.number_of_variable_length_records {
        let head = read_array::<54>(file, at)?;
        let length = u64::from(u16::from_le_bytes([head[20], head[21]]));
        let record_id = u16::from_le_bytes([head[18], head[19]]);
        if head[2..18].starts_with(b"laszip encoded") && record_id == 22204 {
            let mut data = vec![0; length as usize];
            return read_exact_at(file, at + 54, &mut data).then_some(data);
        }
        at += 54 + length;
        if at >= file_len {
            return None;
        }
    }
    None
}

/// Reads `buf.len()` bytes at `at`; false where the file has fewer.
fn read_exact_at(file: &mut File, at: u64, buf: &mut [u8]) -> bool {
    file.seek(SeekFrom::Start(at)).is_ok() && file.read_exact(buf).is_ok()
}

fn read_array<const N: usize>(file: &mut File, at: u64) -> Option<[u8; N]> {
    let mut buf = [0u8; N];
    read_exact_at(file, at, &mut buf).then_some(buf)
}

fn las_error(path: &Path, at: impl Into<String>, e: las::Error) -> ImportError {
    let eof = match &e {
        las::Error::Io(io) => io.kind() == std::io::ErrorKind::UnexpectedEof,
        // `laz::LasZipError::IoError` has no `source()`, and `laz` is not our
        // direct dependency to match on: its Debug form names the kind.
        las::Error::LasZipError(laz) => format!("{laz:?}").contains("UnexpectedEof"),
        _ => false,
    };
    match e {
        _ if eof => ImportError::malformed(path, at, "file ends early (truncated)"),
        las::Error::Io(e) => ImportError::io(path, e),
        e => ImportError::malformed(path, at, e.to_string()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicUsize, Ordering};

    fn temp(ext: &str) -> std::path::PathBuf {
        static N: AtomicUsize = AtomicUsize::new(0);
        let n = N.fetch_add(1, Ordering::Relaxed);
        std::env::temp_dir().join(format!("ff-las-{}-{n}.{ext}", std::process::id()))
    }

    /// Writes three points with the given point format (+ compression).
    fn write(ext: &str, format: u8, color_scale: u16) -> std::path::PathBuf {
        let path = temp(ext);
        let mut builder = las::Builder::from((1, 2));
        builder.point_format = Format::new(format).unwrap();
        builder.point_format.is_compressed = ext == "laz";
        let (has_color, has_time) = (
            builder.point_format.has_color,
            builder.point_format.has_gps_time,
        );
        let mut writer = las::Writer::from_path(&path, builder.into_header().unwrap()).unwrap();
        for i in 0..3u16 {
            let color = las::Color::new(i * 100 * color_scale, 255 * color_scale, 0);
            writer
                .write_point(las::Point {
                    x: 1.5 + f64::from(i),
                    y: -2.25,
                    z: 1000.125,
                    color: has_color.then_some(color),
                    gps_time: has_time.then_some(0.5),
                    ..Default::default()
                })
                .unwrap();
        }
        writer.close().unwrap();
        path
    }

    fn load_geometry(path: &Path) -> Result<Geometry, ImportError> {
        let result = load(path);
        std::fs::remove_file(path).unwrap();
        result.map(|s| s.geometries.into_iter().next().unwrap())
    }

    #[test]
    fn las_and_laz_positions_and_colors() {
        for ext in ["las", "laz"] {
            let g = load_geometry(&write(ext, 2, 1)).unwrap();
            assert_eq!(g.primitives, Primitives::Points);
            assert_eq!(
                g.positions,
                (0..3)
                    .map(|i| DVec3::new(1.5 + f64::from(i), -2.25, 1000.125))
                    .collect::<Vec<_>>()
            );
            assert_eq!(
                g.colors.unwrap(),
                vec![[0, 255, 0], [100, 255, 0], [200, 255, 0]],
                "{ext}"
            );
        }
        let g = load_geometry(&write("las", 3, 257)).unwrap();
        assert_eq!(
            g.colors.unwrap(),
            vec![[0, 255, 0], [100, 255, 0], [200, 255, 0]]
        );
        let g = load_geometry(&write("laz", 1, 1)).unwrap();
        assert!(g.colors.is_none() && g.normals.is_none());
        assert_eq!(g.positions.len(), 3);
    }

    /// A LAZ file of many chunks (its chunk table checked, decompressed
    /// in parallel in batches of many chunks) reads as the same points as
    /// its LAS twin, in order, colors and all.
    #[test]
    fn a_laz_file_of_many_chunks_reads_as_its_las_twin() {
        let points = 230_017u32;
        let write = |ext: &str| {
            let path = temp(ext);
            let mut builder = las::Builder::from((1, 2));
            builder.point_format = Format::new(2).unwrap();
            builder.point_format.is_compressed = ext == "laz";
            let mut writer = las::Writer::from_path(&path, builder.into_header().unwrap()).unwrap();
            for i in 0..points {
                writer
                    .write_point(las::Point {
                        x: f64::from(i % 1000) * 0.01,
                        y: f64::from(i / 1000) * 0.01,
                        z: f64::from(i % 7),
                        color: Some(las::Color::new((i % 251) as u16, 7, (i % 13) as u16)),
                        ..Default::default()
                    })
                    .unwrap();
            }
            writer.close().unwrap();
            path
        };
        let (las_path, laz_path) = (write("las"), write("laz"));
        let mut file = File::open(&laz_path).unwrap();
        let len = file.metadata().unwrap().len();
        assert!(
            precheck(&laz_path, &mut file, len).unwrap().parallel,
            "a sound table"
        );
        let mut streamed = 0;
        let mut batches = 0;
        stream(&laz_path, &mut |positions, colors| {
            assert_eq!(colors.map(<[_]>::len), Some(positions.len()));
            streamed += positions.len();
            batches += 1;
            Ok(())
        })
        .unwrap();
        assert_eq!(streamed, points as usize);
        assert!(
            batches <= 2,
            "{batches} batches: too few chunks each to keep the cores busy"
        );
        let (a, b) = (
            load_geometry(&las_path).unwrap(),
            load_geometry(&laz_path).unwrap(),
        );
        assert_eq!(a.positions.len(), points as usize);
        assert!(a.positions == b.positions, "positions differ");
        assert!(a.colors == b.colors, "colors differ");
    }

    #[test]
    fn bad_inputs() {
        assert!(matches!(
            load(Path::new("/nonexistent/x.las")),
            Err(ImportError::Io { .. })
        ));
        let path = write("las", 2, 1);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 5]).unwrap();
        let e = load_geometry(&path).unwrap_err().to_string();
        assert!(
            e.ends_with("point data: file ends early (truncated): the header promises 3 points"),
            "{e}"
        );
        // A header that claims 2^32 - 1 points.
        let path = write("las", 2, 1);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[107..111].copy_from_slice(&u32::MAX.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        assert!(
            load_geometry(&path)
                .unwrap_err()
                .to_string()
                .contains("truncated")
        );
        // Corrupt and cut LAZ data: an error, never a panic.
        let path = write("laz", 2, 1);
        let mut bytes = std::fs::read(&path).unwrap();
        let n = bytes.len();
        bytes.truncate(n - 10);
        for b in &mut bytes[n - 40..] {
            *b ^= 0x5a;
        }
        std::fs::write(&path, &bytes).unwrap();
        assert!(load_geometry(&path).is_err());
        let path = write("laz", 2, 1);
        let bytes = std::fs::read(&path).unwrap();
        std::fs::write(&path, &bytes[..bytes.len() - 30]).unwrap();
        let e = load_geometry(&path).unwrap_err().to_string();
        assert!(e.ends_with("file ends early (truncated)"), "{e}");
        // Found by the `las` fuzz target: a chunk table that counts more
        // chunks than the file has bytes made the decompressor allocate
        // 16 bytes for each before reading any (an abort, not an error).
        let path = write("laz", 2, 1);
        let mut bytes = std::fs::read(&path).unwrap();
        let data = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
        let table = i64::from_le_bytes(bytes[data..data + 8].try_into().unwrap()) as usize;
        let n = bytes.len() as u32;
        for (chunks, refused) in [(n, false), (n + 1, true), (u32::MAX, true)] {
            bytes[table + 4..table + 8].copy_from_slice(&chunks.to_le_bytes());
            std::fs::write(&path, &bytes).unwrap();
            let e = load(&path).map(|_| ()).unwrap_err().to_string();
            assert_eq!(e.contains("the LAZ chunk table is corrupt"), refused, "{e}");
        }
        std::fs::remove_file(&path).unwrap();
        for junk in [&b"LASF"[..], b"not a las file at all", &[0u8; 400]] {
            let path = temp("las");
            std::fs::write(&path, junk).unwrap();
            assert!(load_geometry(&path).is_err());
        }
    }

    /// Found by the `las` fuzz target (twice: a check of the chunks' layer
    /// sizes missed chunks the decompressor reads by the chunk table's
    /// counts): a chunk of a layered LAZ file (LAS 1.4, point format 7)
    /// whose layer sizes claimed gigabytes made the decompressor zero-fill
    /// buffers of that size before reading any of it, from an 800-byte file
    /// (out of memory, not an error). The patched laz reads what is there.
    #[test]
    fn layers_larger_than_the_file_are_not_allocated() {
        let path = std::env::temp_dir().join(format!("ff-las-layers-{}.laz", std::process::id()));
        let mut builder = las::Builder::from((1, 4));
        builder.point_format = Format::new(7).unwrap();
        builder.point_format.is_compressed = true;
        let mut writer = las::Writer::from_path(&path, builder.into_header().unwrap()).unwrap();
        for i in 0..3 {
            writer
                .write_point(las::Point {
                    x: f64::from(i),
                    color: Some(las::Color::new(1, 2, 3)),
                    gps_time: Some(0.5),
                    ..Default::default()
                })
                .unwrap();
        }
        writer.close().unwrap();
        drop(writer);
        let mut bytes = std::fs::read(&path).unwrap();
        assert_eq!(load(&path).unwrap().geometries[0].positions.len(), 3);
        // The first chunk: the chunk table's offset, the first point (30
        // bytes of point, 6 of color), the point count, then the sizes of
        // the point's 9 layers and the color's.
        let data = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
        let sizes = data + 8 + 36 + 4;
        bytes[sizes + 4..sizes + 8].copy_from_slice(&u32::MAX.to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let peak_before = peak_rss_bytes();
        let e = load(&path).map(|_| ()).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(e.ends_with("point 0: file ends early (truncated)"), "{e}");
        let grown = peak_rss_bytes().saturating_sub(peak_before);
        assert!(grown < 1 << 30, "the peak grew by {} MiB", grown >> 20);
    }

    /// Where the laszip VLR's data starts in a LAZ file's bytes.
    fn laszip_data(bytes: &[u8]) -> usize {
        let user = bytes
            .windows(14)
            .position(|w| w == b"laszip encoded")
            .unwrap();
        user - 2 + 54
    }

    /// Found by the `las` fuzz target: a laszip item whose stated size was
    /// not its type's (a POINT10 of 10 bytes) made the decompressor slice
    /// past the end of a record and panic.
    #[test]
    fn laszip_items_must_have_their_types_sizes() {
        let path = write("laz", 2, 1);
        let mut bytes = std::fs::read(&path).unwrap();
        let items = laszip_data(&bytes) + 34;
        // POINT10, 20 bytes, version 2.
        assert_eq!(bytes[items..items + 4], [6, 0, 20, 0]);
        bytes[items + 2] = 10;
        std::fs::write(&path, &bytes).unwrap();
        let e = load(&path).map(|_| ()).unwrap_err().to_string();
        assert!(
            e.ends_with("laszip VLR: item 0 (type 6) is 10 bytes, not 20"),
            "{e}"
        );
        // Sizes of their types, but not those of the header's records.
        bytes[items + 2] = 20;
        bytes[105] += 1;
        std::fs::write(&path, &bytes).unwrap();
        let e = load(&path).map(|_| ()).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(
            e.ends_with("laszip VLR: the items make records of 26 bytes, the header's are 27"),
            "{e}"
        );
    }

    /// Found while fixing the one above: a LAZ header's point count is not
    /// bounded by the file, and the batch slab was sized for 65,536
    /// records before any was read, so records of 64 KiB asked for 4 GiB
    /// from a file of a few hundred bytes. Batches are now 16 MiB at most.
    #[test]
    fn a_batch_of_wide_records_is_bounded() {
        let path = temp("laz");
        let mut builder = las::Builder::from((1, 2));
        builder.point_format = Format::new(0).unwrap();
        builder.point_format.extra_bytes = 65_000;
        builder.point_format.is_compressed = true;
        let mut writer = las::Writer::from_path(&path, builder.into_header().unwrap()).unwrap();
        writer
            .write_point(las::Point {
                extra_bytes: vec![7; 65_000],
                ..Default::default()
            })
            .unwrap();
        writer.close().unwrap();
        drop(writer);
        let mut bytes = std::fs::read(&path).unwrap();
        assert_eq!(load(&path).unwrap().geometries[0].positions.len(), 1);
        bytes[107..111].copy_from_slice(&(1u32 << 20).to_le_bytes());
        std::fs::write(&path, &bytes).unwrap();
        let peak_before = peak_rss_bytes();
        let e = load(&path).map(|_| ()).unwrap_err().to_string();
        std::fs::remove_file(&path).unwrap();
        assert!(e.ends_with("point 0: file ends early (truncated)"), "{e}");
        // The process's peak (other tests run beside this one, but none
        // comes near this).
        let grown = peak_rss_bytes().saturating_sub(peak_before);
        assert!(grown < 1 << 30, "the peak grew by {} MiB", grown >> 20);
    }

    /// The process's peak resident memory so far (0 where unknown).
    fn peak_rss_bytes() -> u64 {
        #[cfg(target_os = "linux")]
        {
            // SAFETY: getrusage only writes the struct it is given.
            let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
            if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } == 0 {
                return u64::try_from(usage.ru_maxrss).unwrap_or(0) * 1024;
            }
        }
        0
    }

    /// Found by the `las` fuzz target: a chunk table whose entries do not
    /// decode made the decompressor panic while the file was being opened,
    /// before the `catch_unwind` around reading the points, so the panic
    /// ended the import (and the process) instead of becoming an error.
    #[test]
    fn a_chunk_table_that_does_not_decode_is_an_error() {
        let path = write("laz", 2, 1);
        let mut bytes = std::fs::read(&path).unwrap();
        let data = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
        let table = i64::from_le_bytes(bytes[data..data + 8].try_into().unwrap()) as usize;
        // The fuzzer's table (minimised): version, 256 chunks, then
        // entries that make the integer decoder read a symbol past 16 bits.
        bytes.truncate(table);
        bytes.extend_from_slice(&[
            0x00, 0x4d, 0x01, 0x00, 0x00, 0x01, 0x00, 0x00, 0x00, 0x83, 0x22, 0x00, 0x0c, 0x00,
            0x00, 0x00, 0x13, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,
            0x00, 0xc7, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x1e, 0xad, 0x79, 0x40, 0x00,
            0x00, 0x00, 0x00,
        ]);
        std::fs::write(&path, &bytes).unwrap();
        let e = load_geometry(&path).unwrap_err().to_string();
        // With overflow checks (a debug build) the decoder panics, caught;
        // without them (release) it reads on to the end of the file. Either
        // way a clear error, and the process goes on.
        assert!(
            e.ends_with("point data: the LAZ data is corrupt")
                || e.ends_with("header: file ends early (truncated)"),
            "{e}"
        );
    }

    /// Found by the `las` fuzz target: a GPS-time layer of 0xff bytes in a
    /// LAS 1.4 LAZ file (point format 7) decoded "switch to another
    /// sequence" over and over, and laz's decoder called itself for each:
    /// the stack overflowed and the process died (third_party/laz, patched,
    /// loops instead).
    #[test]
    fn a_gps_time_layer_that_switches_forever_cannot_overflow_the_stack() {
        let path = temp("laz");
        let mut builder = las::Builder::from((1, 4));
        builder.point_format = Format::new(7).unwrap();
        builder.point_format.is_compressed = true;
        let mut writer = las::Writer::from_path(&path, builder.into_header().unwrap()).unwrap();
        for i in 0..12 {
            writer
                .write_point(las::Point {
                    x: f64::from(i),
                    color: Some(las::Color::new(1, 2, 3)),
                    gps_time: Some(1000.0 + f64::from(i * i) * 0.37),
                    ..Default::default()
                })
                .unwrap();
        }
        writer.close().unwrap();
        drop(writer);
        let mut bytes = std::fs::read(&path).unwrap();
        // The first chunk: the chunk table's offset, the first point (30
        // bytes of point, 6 of color), the point count, the sizes of the
        // point's 9 layers (GPS time last) and the color's, the layers.
        let data = u32::from_le_bytes(bytes[96..100].try_into().unwrap()) as usize;
        let sizes_at = data + 8 + 36 + 4;
        let size = |i: usize| {
            let at = sizes_at + 4 * i;
            u32::from_le_bytes(bytes[at..at + 4].try_into().unwrap()) as usize
        };
        let gps_at = sizes_at + 40 + (0..8).map(size).sum::<usize>();
        let gps_len = size(8);
        assert!(gps_len > 0);
        bytes[gps_at..gps_at + gps_len].fill(0xff);
        std::fs::write(&path, &bytes).unwrap();
        // Whatever the points decode to, the import returns.
        let _ = load_geometry(&path);
    }
}
