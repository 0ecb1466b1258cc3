//! Builds the browser viewer into `$OUT_DIR/web` (see the crate's docs):
//! `farfield-web` for wasm32 with the `web` profile, then wasm-bindgen's
//! glue for `--target web`, then the wasm gzipped.
//!
//! It reruns when a source file the wasm was built from changes: the
//! nested build's dep-info file lists them, and each one in this
//! workspace is told to cargo.

use std::env;
use std::fs;
use std::path::{Path, PathBuf};
use std::process::Command;

const TARGET: &str = "wasm32-unknown-unknown";

fn main() {
    println!("cargo::rustc-check-cfg=cfg(farfield_viewer_embedded)");
    println!("cargo::rerun-if-env-changed=FARFIELD_WEB_EMBED");
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("set by cargo"));
    let workspace = manifest
        .parent()
        .expect("the crate is in the workspace")
        .to_owned();
    for file in ["Cargo.lock", "Cargo.toml", "web/Cargo.toml"] {
        println!("cargo::rerun-if-changed={}", workspace.join(file).display());
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("set by cargo")).join("web");
    let missing = if env::var("FARFIELD_WEB_EMBED").is_ok_and(|v| v == "0") {
        Err("FARFIELD_WEB_EMBED=0: built without the browser viewer".to_owned())
    } else {
        build(&workspace, &out)
    };
    match missing {
        Ok(()) => {
            println!("cargo::rustc-cfg=farfield_viewer_embedded");
            println!("cargo::rustc-env=FARFIELD_WEB_MISSING=");
        }
        Err(why) => {
            let why = why.replace(['\n', '\r'], " ");
            println!("cargo::warning=the browser viewer is not embedded: {why}");
            println!("cargo::rustc-env=FARFIELD_WEB_MISSING={why}");
        }
    }
}

/// The nested build, the binding and the gzip; why not, on failure.
fn build(workspace: &Path, out: &Path) -> Result<(), String> {
    let target_dir = env::var_os("CARGO_TARGET_DIR")
        .map_or_else(|| workspace.join("target"), PathBuf::from)
        .join("web-assets");
    let cargo = env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let mut command = Command::new(cargo);
    command
        .current_dir(workspace)
        .args([
            "build",
            "-p",
            "farfield-web",
            "--profile",
            "web",
            "--target",
            TARGET,
        ])
        .arg("--target-dir")
        .arg(&target_dir);
    // What the outer cargo set for this script, not for the nested build:
    // host flags, and clippy's wrapper under `cargo clippy` (it would
    // change the nested build's fingerprints, rebuilding it each time).
    for var in [
        "CARGO_ENCODED_RUSTFLAGS",
        "RUSTC_WORKSPACE_WRAPPER",
        "CARGO_TARGET_DIR",
        "CARGO_BUILD_TARGET",
    ] {
        command.env_remove(var);
    }
    let status = command
        .status()
        .map_err(|e| format!("cannot run cargo: {e}"))?;
    if !status.success() {
        return Err(format!(
            "the wasm build failed ({status}); is the wasm32 target installed? \
             (rustup target add {TARGET}; FARFIELD_WEB_EMBED=0 builds without the viewer)"
        ));
    }
    let built = target_dir.join(TARGET).join("web");
    rerun_if_sources_change(&built.join("farfield_web.d"), workspace);
    fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    wasm_bindgen_cli_support::Bindgen::new()
        .input_path(built.join("farfield_web.wasm"))
        .web(true)
        .map_err(|e| format!("wasm-bindgen: {e}"))?
        // As the command line's defaults are (`web/build`), not the
        // library's: the glue finds its wasm beside itself.
        .typescript(false)
        .omit_default_module_path(false)
        .out_name("farfield_web")
        .generate(out)
        .map_err(|e| format!("wasm-bindgen: {e:#}"))?;
    let wasm = out.join("farfield_web_bg.wasm");
    let bytes = fs::read(&wasm).map_err(|e| format!("{}: {e}", wasm.display()))?;
    fs::write(out.join("farfield_web_bg.wasm.gz"), gzip(&bytes)).map_err(|e| format!("gzip: {e}"))
}

/// `bytes` as a gzip member (RFC 1952): a header with no name or time,
/// the raw deflate stream, then the CRC-32 and length of the input.
fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut out = vec![0x1f, 0x8b, 8, 0, 0, 0, 0, 0, 2, 255];
    out.extend(miniz_oxide::deflate::compress_to_vec(bytes, 9));
    out.extend(crc32fast::hash(bytes).to_le_bytes());
    out.extend((bytes.len() as u32).to_le_bytes());
    out
}

/// Tells cargo every workspace source file the wasm was built from, as
/// the nested build's dep-info file (`target: dep dep ...`) lists them.
fn rerun_if_sources_change(dep_info: &Path, workspace: &Path) {
    let Ok(text) = fs::read_to_string(dep_info) else {
        // Without the list, any change anywhere in the web crate reruns.
        println!(
            "cargo::rerun-if-changed={}",
            workspace.join("web").display()
        );
        return;
    };
    let target = workspace.join("target");
    let first = text.lines().next().unwrap_or_default();
    let deps = first.split_once(": ").map_or("", |(_, deps)| deps);
    // Paths are separated by spaces; a space inside one is escaped.
    let deps = deps.replace("\\ ", "\u{0}");
    for dep in deps.split_whitespace() {
        let path = PathBuf::from(dep.replace('\u{0}', " "));
        if path.starts_with(workspace) && !path.starts_with(&target) {
            println!("cargo::rerun-if-changed={}", path.display());
        }
    }
}
