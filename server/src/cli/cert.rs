//! `farfield-server cert --name HOST --out DIR`: a key and a self-signed
//! server certificate for TLS.
//!
//! `openssl req -x509` makes a certificate marked as an authority, which
//! a chain check refuses as a server's own (the client pins it instead);
//! this one is a plain server certificate (rcgen), for exactly the names
//! given, that the client accepts as its own authority with `--ca-cert`.
//! The key is written readable by its owner only, and both files are
//! written whole or not at all.

use std::path::Path;

use anyhow::Context;
use serde_json::json;

use super::{CertArgs, Report};

pub fn run(args: &CertArgs) -> anyhow::Result<Report> {
    let names = if args.names.is_empty() {
        vec!["localhost".to_owned(), "127.0.0.1".to_owned()]
    } else {
        args.names.clone()
    };
    let made = rcgen::generate_simple_self_signed(names.clone())
        .with_context(|| format!("a certificate for {}", names.join(", ")))?;
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let (key, cert) = (args.out.join("key.pem"), args.out.join("cert.pem"));
    write_whole(&key, made.signing_key.serialize_pem().as_bytes(), 0o600)?;
    write_whole(&cert, made.cert.pem().as_bytes(), 0o644)?;
    Ok(Report {
        json: json!({
            "names": names,
            "key": key.display().to_string(),
            "cert": cert.display().to_string(),
        }),
        text: format!(
            "wrote {} and {} for {}\nserve with: farfield-server serve --tls-cert {} --tls-key {} ...\n\
             connect with: farfield render --server https://{}:PORT --ca-cert {} ...",
            key.display(),
            cert.display(),
            names.join(", "),
            cert.display(),
            key.display(),
            names[0],
            cert.display()
        ),
        exit_code: 0,
        as_json: args.json,
    })
}

/// Writes `bytes` to a temporary file beside `path` with `mode`, then
/// renames it over `path`.
fn write_whole(path: &Path, bytes: &[u8], mode: u32) -> anyhow::Result<()> {
    use std::io::Write;
    let tmp = path.with_extension("pem.tmp");
    let result = (|| {
        let mut options = std::fs::OpenOptions::new();
        options.write(true).create(true).truncate(true);
        #[cfg(unix)]
        std::os::unix::fs::OpenOptionsExt::mode(&mut options, mode);
        #[cfg(not(unix))]
        let _ = mode;
        let mut file = options.open(&tmp)?;
        file.write_all(bytes)?;
        file.sync_all()?;
        std::fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result.with_context(|| format!("writing {}", path.display()))
}
