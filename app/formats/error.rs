//! The one error type of the format writers and readers, apart from them so that each format's file depends on it
//! and not on the module that names the formats.

use std::io;

/// Errors of the writers and readers.
#[derive(Debug, thiserror::Error)]
pub enum FormatError {
    #[error(transparent)]
    Io(#[from] io::Error),
    #[error("not a valid {format} file: {message}")]
    Invalid { format: &'static str, message: String },
    /// The grid does not fit the format (a schematic's sides are unsigned Shorts).
    #[error("{0}")]
    TooLarge(String),
}

pub(crate) fn invalid(format: &'static str, message: impl Into<String>) -> FormatError {
    FormatError::Invalid { format, message: message.into() }
}
