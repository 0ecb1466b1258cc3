//! `farfield compare A B`: RMSE, PSNR and wrong pixels of two PNGs.

use std::path::Path;

/// `farfield compare A B`: the error of image B against reference A.
pub fn run(a: &Path, b: &Path, tolerance: u8, json: bool) -> anyhow::Result<()> {
    let c = farfield_image::compare_files(a, b, tolerance)?;
    if json {
        println!("{}", c.metrics.to_json(c.width, c.height));
    } else {
        let (w, h, m) = (c.width, c.height, c.metrics);
        println!("{} vs {} ({w}x{h}): {m}", a.display(), b.display());
    }
    Ok(())
}
