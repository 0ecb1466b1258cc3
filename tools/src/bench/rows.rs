//! The bench's tidy tables and their CSV files.
//!
//! `bench.csv`, one [`Row`] per camera and setting:
//!
//! | column | meaning |
//! |---|---|
//! | `scene` | the file or server scene measured |
//! | `mode` | rendering mode (`spheres`, `cubes`, `geometry`, ...) |
//! | `param`, `value` | the swept parameter and its value for this row |
//! | `camera` | index of the camera on the path (or built-in orbit) |
//! | `rmse` | root mean square RGB difference to the reference, 0..=255 |
//! | `psnr_db` | `20 log10(255 / rmse)`; `inf` when identical |
//! | `wrong_fraction` | share of pixels with a channel off by more than 8 |
//! | `frame_ms`, `frame_ms_min`, `frame_ms_max` | median, min and max whole-frame time over the repeats |
//! | `traverse_ms`, `upload_ms`, `draw_ms` | medians of the frame's parts |
//! | `drawn` | primitives drawn (splats, faces + triangles, triangles) |
//! | `bytes` | bytes received before the measured frames (streamed), or bytes of the pages the frame touched (file) |
//! | `reference` | what the row was compared with |
//! | `reference_empty` | `true` when the reference image is all background: nothing in view, the error says nothing |
//! | `width`, `height`, `repeats` | image size and timing repeats |
//! | `coverage` | triangle kinds (PLP): the visible coverage ratio `ε`, the share of the reference's visible triangles drawn (`visible.rs`); empty for other kinds |
//!
//! `progress.csv`, one [`ProgressRow`] per frame while a streamed view
//! refines: `mode, param, value, camera, frame, ms_since_connect, bytes,
//! rmse, psnr_db, wrong_fraction, coverage`.

use std::path::Path;

use anyhow::Context;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// One camera at one setting.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Row {
    pub scene: String,
    pub mode: String,
    pub param: String,
    pub value: String,
    pub camera: u32,
    pub rmse: f64,
    #[serde(serialize_with = "psnr_out", deserialize_with = "psnr_in")]
    pub psnr_db: f64,
    pub wrong_fraction: f64,
    pub frame_ms: f64,
    pub frame_ms_min: f64,
    pub frame_ms_max: f64,
    pub traverse_ms: f64,
    pub upload_ms: f64,
    pub draw_ms: f64,
    pub drawn: u64,
    pub bytes: u64,
    pub reference: String,
    pub reference_empty: bool,
    pub width: u32,
    pub height: u32,
    pub repeats: u32,
    pub coverage: Option<f64>,
}

/// One frame of a streamed view refining.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProgressRow {
    pub mode: String,
    pub param: String,
    pub value: String,
    pub camera: u32,
    pub frame: u32,
    pub ms_since_connect: f64,
    pub bytes: u64,
    pub rmse: f64,
    #[serde(serialize_with = "psnr_out", deserialize_with = "psnr_in")]
    pub psnr_db: f64,
    pub wrong_fraction: f64,
    pub coverage: Option<f64>,
}

/// PSNR of identical images is written `inf`, never `NaN`.
fn psnr_out<S: Serializer>(v: &f64, s: S) -> Result<S::Ok, S::Error> {
    if v.is_infinite() {
        s.serialize_str("inf")
    } else {
        s.serialize_f64(*v)
    }
}

fn psnr_in<'de, D: Deserializer<'de>>(d: D) -> Result<f64, D::Error> {
    let text = String::deserialize(d)?;
    match text.as_str() {
        "inf" => Ok(f64::INFINITY),
        t => t.parse().map_err(serde::de::Error::custom),
    }
}

/// Writes rows with a header line.
pub fn write<T: Serialize>(path: &Path, rows: &[T]) -> anyhow::Result<()> {
    let mut w =
        csv::Writer::from_path(path).with_context(|| format!("creating {}", path.display()))?;
    for r in rows {
        w.serialize(r)?;
    }
    w.flush()?;
    Ok(())
}

/// Reads rows written by [`write`]; a missing file is an empty table.
pub fn read<T: for<'de> Deserialize<'de>>(path: &Path) -> anyhow::Result<Vec<T>> {
    if !path.exists() {
        return Ok(Vec::new());
    }
    let mut r =
        csv::Reader::from_path(path).with_context(|| format!("reading {}", path.display()))?;
    r.deserialize()
        .map(|row| row.with_context(|| format!("a row of {}", path.display())))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rows_round_trip_through_csv_with_infinite_psnr() {
        let row = Row {
            scene: "island, with a comma".into(),
            mode: "spheres".into(),
            param: "threshold".into(),
            value: "4".into(),
            camera: 2,
            rmse: 0.0,
            psnr_db: f64::INFINITY,
            wrong_fraction: 0.0,
            frame_ms: 12.5,
            frame_ms_min: 11.0,
            frame_ms_max: 14.0,
            traverse_ms: 1.0,
            upload_ms: 2.0,
            draw_ms: 9.5,
            drawn: 1234,
            bytes: 56789,
            reference: "spheres at 1 px".into(),
            reference_empty: false,
            width: 64,
            height: 48,
            repeats: 3,
            coverage: None,
        };
        let second = Row {
            psnr_db: 31.25,
            rmse: 7.0,
            coverage: Some(0.75),
            ..row.clone()
        };
        let dir = std::env::temp_dir().join(format!("ff-rows-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("bench.csv");
        write(&path, &[row.clone(), second.clone()]).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.starts_with("scene,mode,param,value,camera,rmse,psnr_db,"),
            "{text}"
        );
        assert!(text.contains(",inf,"), "{text}");
        let back: Vec<Row> = read(&path).unwrap();
        assert_eq!(back, vec![row, second]);
        assert!(read::<Row>(&dir.join("absent.csv")).unwrap().is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
