//! The median radius of a cloud spread over chunks, exactly, in two passes
//! and bounded memory: the in-memory build caps outliers' radii at a
//! multiple of the cloud's median ([`knn::radius_cap`]), and each chunk's
//! own median would cap differently.
//!
//! The first pass counts the radii in bins by their leading bits (which
//! order positive floats as their values); the bin holding the middle rank
//! is then read back from the chunks' radii files and the median selected
//! within it.
//!
//! [`knn::radius_cap`]: crate::spheres::knn::radius_cap

use std::fs::File;
use std::io::{self, BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

/// Leading bits of an f64 a bin is keyed by: sign, exponent and 8 bits of
/// mantissa (bins 1/256 of an octave wide).
const KEY_BITS: u32 = 20;

fn key(radius: f64) -> usize {
    (radius.to_bits() >> (64 - KEY_BITS)) as usize
}

/// Radii counted by bin, and the files they were written to.
pub(crate) struct RadiusMedian {
    bins: Vec<u64>,
    count: u64,
    files: Vec<PathBuf>,
}

impl RadiusMedian {
    pub(crate) fn new() -> Self {
        Self {
            bins: vec![0; 1 << KEY_BITS],
            count: 0,
            files: Vec::new(),
        }
    }

    /// Counts the positive radii of a chunk and writes them to `path`.
    pub(crate) fn add(&mut self, radii: &[f64], path: &Path) -> io::Result<()> {
        let mut out = BufWriter::with_capacity(1 << 16, File::create(path)?);
        for &r in radii.iter().filter(|r| **r > 0.0) {
            self.bins[key(r)] += 1;
            self.count += 1;
            out.write_all(&r.to_le_bytes())?;
        }
        out.into_inner().map_err(|e| e.into_error())?;
        self.files.push(path.to_owned());
        Ok(())
    }

    /// Counts the radii a chunk's `add` wrote to `path` before (a part of
    /// a build made elsewhere).
    pub(crate) fn add_file(&mut self, path: &Path) -> io::Result<()> {
        // As `add` counts them: positive radii (a damaged file's NaN or
        // negative values are not radii).
        for_each_radius(path, &mut |r| {
            if r.is_finite() && r > 0.0 {
                self.bins[key(r)] += 1;
                self.count += 1;
            }
        })?;
        self.files.push(path.to_owned());
        Ok(())
    }

    /// The median as the in-memory build takes it (the element of rank
    /// count / 2), or `None` when no radius is positive; the files are
    /// removed when `remove`.
    pub(crate) fn median(self, remove: bool) -> io::Result<Option<f64>> {
        if self.count == 0 {
            return Ok(None);
        }
        let rank = self.count / 2;
        let mut below = 0;
        let mut bin = 0;
        for (b, &n) in self.bins.iter().enumerate() {
            if below + n > rank {
                bin = b;
                break;
            }
            below += n;
        }
        let mut within = Vec::with_capacity(self.bins[bin] as usize);
        for path in &self.files {
            for_each_radius(path, &mut |r| {
                if key(r) == bin {
                    within.push(r);
                }
            })?;
            if remove {
                std::fs::remove_file(path)?;
            }
        }
        let at = (rank - below) as usize;
        if at >= within.len() {
            return Err(io::Error::other("the radii files changed during the build"));
        }
        Ok(Some(*within.select_nth_unstable_by(at, f64::total_cmp).1))
    }
}

/// Each radius of a radii file, in order.
fn for_each_radius(path: &Path, each: &mut dyn FnMut(f64)) -> io::Result<()> {
    let mut input = BufReader::with_capacity(1 << 16, File::open(path)?);
    let mut word = [0u8; 8];
    loop {
        match input.read_exact(&mut word) {
            Ok(()) => each(f64::from_le_bytes(word)),
            Err(e) if e.kind() == io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(e),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_median_of_many_files_is_the_median_of_all() {
        let dir = std::env::temp_dir().join(format!("farfield-median-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let mut rnd = crate::test_random(3);
        let mut all = Vec::new();
        let mut median = RadiusMedian::new();
        for f in 0..7 {
            let radii: Vec<f64> = (0..1000 + f * 37)
                .map(|_| {
                    if rnd() < 0.05 {
                        0.0
                    } else {
                        (rnd() * 10.0).exp() * 1e-3
                    }
                })
                .collect();
            all.extend(radii.iter().copied().filter(|r| *r > 0.0));
            median.add(&radii, &dir.join(format!("r{f}"))).unwrap();
        }
        let mid = all.len() / 2;
        let expected = *all.select_nth_unstable_by(mid, f64::total_cmp).1;
        // Counted again from the files, as a merge of parts does.
        let mut again = RadiusMedian::new();
        for f in 0..7 {
            again.add_file(&dir.join(format!("r{f}"))).unwrap();
        }
        assert_eq!(again.median(false).unwrap(), Some(expected));
        assert_eq!(median.median(true).unwrap(), Some(expected));
        assert!(
            std::fs::read_dir(&dir).unwrap().next().is_none(),
            "files left"
        );
        let _ = std::fs::remove_dir(&dir);
        assert_eq!(RadiusMedian::new().median(true).unwrap(), None);
    }
}
