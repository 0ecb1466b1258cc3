//! `farfield path gen:NAME --out FILE`: writes a generated scene's own
//! camera path (the PLP paper's walk through the city, orbit of the cars)
//! as camera-path JSON, for `render --path`, `bench --path` and the PLP
//! bench. The keyframes come from the builder's generators, with the same
//! `--param`s as the scene, so the path always fits the scene it was
//! generated for.

use std::path::Path;

use anyhow::{Context, bail};
use farfield_builder::generate::{GENERATORS, PathKey, camera_path};
use farfield_builder::import::Params;

/// The keyframes of `input`'s path as a JSON list, one compact keyframe
/// object per line (easy to read and to diff), or an error naming the
/// generators that have a path.
pub fn path_json(input: &str, params: &[String]) -> anyhow::Result<String> {
    to_json(&keyframes(input, params)?)
}

fn to_json(keys: &[PathKey]) -> anyhow::Result<String> {
    let lines = keys
        .iter()
        .map(serde_json::to_string)
        .collect::<Result<Vec<_>, _>>()?;
    Ok(format!("[\n  {}\n]\n", lines.join(",\n  ")))
}

fn keyframes(input: &str, params: &[String]) -> anyhow::Result<Vec<PathKey>> {
    let params = Params::parse(params).map_err(anyhow::Error::msg)?;
    let Some(name) = input.strip_prefix("gen:") else {
        bail!("{input}: only generated scenes (gen:NAME) have camera paths");
    };
    match camera_path(name, &params)? {
        Some(keys) => Ok(keys),
        None => {
            let mut with = Vec::new();
            for g in GENERATORS {
                if camera_path(g, &Params::default())?.is_some() {
                    with.push(format!("gen:{g}"));
                }
            }
            bail!(
                "{input} has no camera path (generators with one: {})",
                with.join(", ")
            )
        }
    }
}

/// `farfield path`: writes the path to `out` and says how long it is.
pub fn run(input: &str, params: &[String], out: &Path) -> anyhow::Result<()> {
    let keys = keyframes(input, params)?;
    std::fs::write(out, to_json(&keys)?).with_context(|| format!("writing {}", out.display()))?;
    let seconds = keys.last().map_or(0.0, |k| k.t);
    println!(
        "{}: {} keyframes over {seconds:.2} s",
        out.display(),
        keys.len()
    );
    Ok(())
}
