//! `--param key=value` pairs, parsed once and read by the generators, and
//! the `--up` axis every importer turns its input by.

use std::collections::BTreeMap;

/// The `--param key=value` pairs of a build, in the order of their keys,
/// and its `--up`.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Params {
    pairs: BTreeMap<String, String>,
    /// Which way is up in the inputs (see [`super::up`]).
    pub up: super::up::Up,
}

impl Params {
    /// Parses `key=value` strings; a later key replaces an earlier one.
    pub fn parse<S: AsRef<str>>(pairs: &[S]) -> Result<Self, String> {
        let mut map = BTreeMap::new();
        for pair in pairs {
            let pair = pair.as_ref();
            let (key, value) = pair
                .split_once('=')
                .ok_or_else(|| format!("--param '{pair}' is not of the form key=value"))?;
            if key.is_empty() {
                return Err(format!("--param '{pair}' has an empty key"));
            }
            map.insert(key.to_owned(), value.to_owned());
        }
        Ok(Self {
            pairs: map,
            up: Default::default(),
        })
    }

    /// The raw value of `key`, if given.
    pub fn get(&self, key: &str) -> Option<&str> {
        self.pairs.get(key).map(String::as_str)
    }

    /// Keys that are not in `known`, for "unknown parameter" errors.
    pub fn unknown_keys<'a>(&'a self, known: &[&str]) -> Vec<&'a str> {
        self.pairs
            .keys()
            .map(String::as_str)
            .filter(|k| !known.contains(k))
            .collect()
    }

    /// `key` parsed as `T`, or `default` when absent.
    pub fn parse_or<T: std::str::FromStr>(&self, key: &str, default: T) -> Result<T, String> {
        match self.get(key) {
            None => Ok(default),
            Some(v) => v
                .parse()
                .map_err(|_| format!("parameter {key}={v} is not a valid value")),
        }
    }

    /// Inserts or replaces one pair (used by code that builds parameter sets).
    pub fn set(&mut self, key: &str, value: impl ToString) {
        self.pairs.insert(key.to_owned(), value.to_string());
    }
}
