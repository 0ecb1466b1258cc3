//! [`StoreUrl`]: `s3://bucket/key`, parsed.

/// A bucket and a key (or key prefix) in it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct StoreUrl {
    pub bucket: String,
    /// Without leading or trailing slashes; empty for the whole bucket.
    pub key: String,
}

impl StoreUrl {
    /// Parses `s3://bucket[/key]`.
    pub fn parse(text: &str) -> Result<Self, String> {
        let rest = text
            .strip_prefix("s3://")
            .ok_or_else(|| format!("{text:?} is not an s3:// address"))?;
        let (bucket, key) = rest.split_once('/').unwrap_or((rest, ""));
        if bucket.is_empty() {
            return Err(format!("{text:?} names no bucket"));
        }
        if !bucket
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-' || c == '.')
        {
            return Err(format!(
                "{text:?}: a bucket name has lowercase letters, digits, '-' and '.' only"
            ));
        }
        Ok(Self {
            bucket: bucket.to_owned(),
            key: key.trim_matches('/').to_owned(),
        })
    }

    /// The key of `name` under this one, taken as a prefix.
    pub fn child(&self, name: &str) -> String {
        if self.key.is_empty() {
            name.to_owned()
        } else {
            format!("{}/{name}", self.key)
        }
    }
}

impl std::fmt::Display for StoreUrl {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.key.is_empty() {
            write!(f, "s3://{}", self.bucket)
        } else {
            write!(f, "s3://{}/{}", self.bucket, self.key)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buckets_and_keys_are_split_and_bad_ones_named() {
        let u = StoreUrl::parse("s3://scenes/city/v2/").unwrap();
        assert_eq!((u.bucket.as_str(), u.key.as_str()), ("scenes", "city/v2"));
        assert_eq!(u.child("a.ff"), "city/v2/a.ff");
        assert_eq!(u.to_string(), "s3://scenes/city/v2");
        let whole = StoreUrl::parse("s3://scenes").unwrap();
        assert_eq!(whole.child("a.ff"), "a.ff");
        assert!(
            StoreUrl::parse("http://x/y")
                .unwrap_err()
                .contains("not an s3://")
        );
        assert!(
            StoreUrl::parse("s3:///key")
                .unwrap_err()
                .contains("no bucket")
        );
        assert!(
            StoreUrl::parse("s3://Bad_Bucket")
                .unwrap_err()
                .contains("lowercase")
        );
    }
}
