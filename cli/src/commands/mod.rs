//! One module per `farfield` subcommand (the measuring ones together in
//! [`measure`]); [`crate::cli`] parses and dispatches.

pub mod compare;
pub mod demo;
pub mod measure;
pub mod path;
pub mod render;
pub mod traverse;
pub mod view;
pub mod wan;
