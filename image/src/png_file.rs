//! PNG files for rendered images: write RGBA8, read RGB8 or RGBA8.
//!
//! Rendered frames and reference images travel as PNG so they can be looked
//! at and compared later (`farfield compare`). Writing goes to a temporary
//! file in the same directory and is renamed into place, so a crash never
//! leaves half a PNG behind.

use std::fs::File;
use std::io::{BufReader, BufWriter, Write};
use std::path::{Path, PathBuf};

use thiserror::Error;

/// Why a PNG could not be written or read.
#[derive(Debug, Error)]
pub enum ImageError {
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{path}: not a readable PNG: {error}")]
    Decode {
        path: PathBuf,
        error: png::DecodingError,
    },
    #[error("{path}: could not encode PNG: {error}")]
    Encode {
        path: PathBuf,
        error: png::EncodingError,
    },
    #[error(
        "{path}: unsupported PNG format {color:?} with {depth:?} bits; expected 8-bit RGB or RGBA"
    )]
    Unsupported {
        path: PathBuf,
        color: png::ColorType,
        depth: png::BitDepth,
    },
    #[error("{path}: {len} bytes of pixels do not make a {width}x{height} RGBA image")]
    BadLength {
        path: PathBuf,
        len: usize,
        width: u32,
        height: u32,
    },
}

/// Writes tightly packed RGBA8 rows as a PNG at `path` (atomically).
pub fn write_png(
    path: impl AsRef<Path>,
    width: u32,
    height: u32,
    rgba: &[u8],
) -> Result<(), ImageError> {
    let path = path.as_ref();
    if rgba.len() != width as usize * height as usize * 4 || width == 0 || height == 0 {
        return Err(ImageError::BadLength {
            path: path.to_owned(),
            len: rgba.len(),
            width,
            height,
        });
    }
    let io = |error| ImageError::Io {
        path: path.to_owned(),
        error,
    };
    let encode = |error| ImageError::Encode {
        path: path.to_owned(),
        error,
    };
    let mut tmp_name = path.file_name().unwrap_or_default().to_owned();
    tmp_name.push(format!(".tmp{}", std::process::id()));
    let tmp = path.with_file_name(tmp_name);
    let result = (|| {
        let bytes = encode_png(width, height, rgba).map_err(encode)?;
        let mut out = BufWriter::new(File::create(&tmp).map_err(io)?);
        out.write_all(&bytes).map_err(io)?;
        out.flush().map_err(io)?;
        drop(out);
        std::fs::rename(&tmp, path).map_err(io)
    })();
    if result.is_err() {
        // Best effort: the temporary file is garbage either way.
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Tightly packed RGBA8 rows as PNG bytes (a browser's download, a file's
/// contents); `rgba` must hold `width * height * 4` bytes.
pub fn encode_png(width: u32, height: u32, rgba: &[u8]) -> Result<Vec<u8>, png::EncodingError> {
    let mut bytes = Vec::new();
    let mut encoder = png::Encoder::new(&mut bytes, width, height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(rgba)?;
    writer.finish()?;
    Ok(bytes)
}

/// Reads an 8-bit RGB or RGBA PNG as `(width, height, rgba)`; RGB gets an
/// opaque alpha channel.
pub fn read_png(path: impl AsRef<Path>) -> Result<(u32, u32, Vec<u8>), ImageError> {
    let path = path.as_ref();
    let decode = |error| ImageError::Decode {
        path: path.to_owned(),
        error,
    };
    let file = File::open(path).map_err(|error| ImageError::Io {
        path: path.to_owned(),
        error,
    })?;
    let mut decoder = png::Decoder::new(BufReader::new(file));
    decoder.set_transformations(png::Transformations::IDENTITY);
    let mut reader = decoder.read_info().map_err(decode)?;
    let (color, depth) = reader.output_color_type();
    if depth != png::BitDepth::Eight || !matches!(color, png::ColorType::Rgb | png::ColorType::Rgba)
    {
        return Err(ImageError::Unsupported {
            path: path.to_owned(),
            color,
            depth,
        });
    }
    let size = reader
        .output_buffer_size()
        .ok_or_else(|| ImageError::BadLength {
            path: path.to_owned(),
            len: usize::MAX,
            width: reader.info().width,
            height: reader.info().height,
        })?;
    let mut buf = vec![0; size];
    let info = reader.next_frame(&mut buf).map_err(decode)?;
    let (w, h) = (info.width, info.height);
    let channels = if color == png::ColorType::Rgb { 3 } else { 4 };
    let mut rgba = Vec::with_capacity(w as usize * h as usize * 4);
    for row in buf.chunks(info.line_size).take(h as usize) {
        let row = &row[..w as usize * channels];
        if channels == 4 {
            rgba.extend_from_slice(row);
        } else {
            for p in row.chunks_exact(3) {
                rgba.extend_from_slice(&[p[0], p[1], p[2], 255]);
            }
        }
    }
    Ok((w, h, rgba))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn temp(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("farfield-image-{}-{name}", std::process::id()))
    }

    #[test]
    fn rgba_round_trips() {
        let path = temp("rt.png");
        let rgba: Vec<u8> = (0..3 * 2 * 4).map(|i| (i * 11) as u8).collect();
        write_png(&path, 3, 2, &rgba).unwrap();
        assert_eq!(read_png(&path).unwrap(), (3, 2, rgba));
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn rgb_gets_opaque_alpha() {
        let path = temp("rgb.png");
        let mut enc = png::Encoder::new(BufWriter::new(File::create(&path).unwrap()), 2, 1);
        enc.set_color(png::ColorType::Rgb);
        enc.set_depth(png::BitDepth::Eight);
        enc.write_header()
            .unwrap()
            .write_image_data(&[1, 2, 3, 4, 5, 6])
            .unwrap();
        let (w, h, rgba) = read_png(&path).unwrap();
        assert_eq!((w, h), (2, 1));
        assert_eq!(rgba, [1, 2, 3, 255, 4, 5, 6, 255]);
        std::fs::remove_file(&path).unwrap();
    }

    #[test]
    fn other_formats_are_refused_clearly() {
        let path = temp("gray16.png");
        let mut enc = png::Encoder::new(BufWriter::new(File::create(&path).unwrap()), 1, 1);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::Sixteen);
        enc.write_header()
            .unwrap()
            .write_image_data(&[0, 1])
            .unwrap();
        let err = read_png(&path).unwrap_err().to_string();
        assert!(err.contains("expected 8-bit RGB or RGBA"), "{err}");
        std::fs::remove_file(&path).unwrap();
        let err = read_png(temp("missing.png")).unwrap_err().to_string();
        assert!(err.contains("missing.png"), "{err}");
    }

    #[test]
    fn wrong_length_is_refused() {
        let err = write_png(temp("bad.png"), 2, 2, &[0; 15]).unwrap_err();
        assert!(matches!(err, ImageError::BadLength { .. }));
    }
}
