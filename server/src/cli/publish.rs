//! `farfield-server publish FILE s3://bucket/key.ff`: a built scene
//! uploaded to object storage, where `serve --scenes s3://bucket/prefix`
//! finds it.

use std::time::Instant;

use serde_json::json;

use super::{PublishArgs, Report};

pub fn run(args: &PublishArgs) -> anyhow::Result<Report> {
    let started = Instant::now();
    let (bucket, url) = args.store.bucket(&args.to, Default::default())?;
    anyhow::ensure!(
        !url.key.is_empty(),
        "{}: name the object to write (s3://bucket/key.ff)",
        args.to
    );
    let bytes = farfield_objects::publish(&args.file, &bucket, &url.key)?;
    let seconds = started.elapsed().as_secs_f64();
    Ok(Report {
        json: json!({ "file": args.file, "to": url.to_string(), "bytes": bytes, "seconds": seconds }),
        text: format!(
            "{}: {bytes} bytes published to {url} in {seconds:.2} s",
            args.file.display()
        ),
        exit_code: 0,
        as_json: args.json,
    })
}
