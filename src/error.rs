//! The crate's error: a parameter outside its allowed range (Python ValueError) or of the wrong kind (TypeError).

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// A parameter outside its allowed range (Python ValueError).
    Value(String),
    /// A parameter of the wrong kind, or one the callee does not take (Python TypeError).
    Type(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Value(s) | Error::Type(s) => f.write_str(s),
        }
    }
}

pub type Result<T> = std::result::Result<T, Error>;

/// Builds a ValueError message.
pub fn value_error<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::Value(msg.into()))
}

/// Builds a TypeError message.
pub fn type_error<T>(msg: impl Into<String>) -> Result<T> {
    Err(Error::Type(msg.into()))
}
