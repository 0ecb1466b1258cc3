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
//! reported as truncated. A panic inside the LAZ decompressor on corrupt
//! data becomes an error.

use std::fs::File;
use std::io::{BufReader, Read, Seek, SeekFrom};
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use glam::DVec3;
use las::point::Format;

use super::ImportError;
use crate::scene::{Geometry, Primitives, Scene};

/// Points decoded per batch.
const BATCH: u64 = 1 << 16;

/// Loads a LAS or LAZ file as one point cloud.
pub fn load(path: &Path) -> Result<Scene, ImportError> {
    let mut file = File::open(path).map_err(|e| ImportError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| ImportError::io(path, e))?.len();
    let (count, compressed) = precheck(path, &mut file, file_len)?;
    let mut reader = las::Reader::new(BufReader::with_capacity(1 << 20, file))
        .map_err(|e| las_error(path, "header", e))?;
    // Compressed points take at least a few bytes each, whatever the header says.
    let cap = count.min(if compressed { file_len } else { file_len / 20 }) as usize;
    let read = |reader: &mut las::Reader| read_points(path, reader, cap);
    let (positions, colors) = if compressed {
        catch_unwind(AssertUnwindSafe(|| read(&mut reader))).unwrap_or_else(|_| {
            Err(ImportError::malformed(
                path,
                "point data",
                "the LAZ data is corrupt",
            ))
        })?
    } else {
        read(&mut reader)?
    };
    let mut geometry = Geometry::new(path.display().to_string(), positions, Primitives::Points);
    geometry.colors = colors.map(|c| {
        let wide = c.iter().flatten().any(|&v| v > 255);
        let to8 = |v: u16| {
            if wide {
                ((u32::from(v) + 128) / 257) as u8
            } else {
                v as u8
            }
        };
        c.into_iter().map(|rgb| rgb.map(to8)).collect()
    });
    Ok(Scene::single(geometry))
}

type Points = (Vec<DVec3>, Option<Vec<[u16; 3]>>);

fn read_points(path: &Path, reader: &mut las::Reader, cap: usize) -> Result<Points, ImportError> {
    let mut data = las::PointDataBuilder::new()
        .for_header(reader.header())
        .build();
    let mut positions = Vec::with_capacity(cap);
    let mut colors = reader
        .header()
        .point_format()
        .has_color
        .then(|| Vec::with_capacity(cap));
    loop {
        let at = format!("point {}", positions.len());
        if reader
            .fill_points(BATCH, &mut data)
            .map_err(|e| las_error(path, at, e))?
            == 0
        {
            return Ok((positions, colors));
        }
        positions.extend(
            data.x()
                .zip(data.y())
                .zip(data.z())
                .map(|((x, y), z)| DVec3::new(x, y, z)),
        );
        if let (Some(colors), Some(rgb)) = (colors.as_mut(), data.rgb()) {
            colors.extend(rgb.map(|(r, g, b)| [r, g, b]));
        }
    }
}

/// Checks the raw header against the file size; returns the point count and
/// whether the points are compressed. Leaves the file at its start.
fn precheck(path: &Path, file: &mut File, file_len: u64) -> Result<(u64, bool), ImportError> {
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
    Ok((count, format.is_compressed))
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
        for junk in [&b"LASF"[..], b"not a las file at all", &[0u8; 400]] {
            let path = temp("las");
            std::fs::write(&path, junk).unwrap();
            assert!(load_geometry(&path).is_err());
        }
    }
}
