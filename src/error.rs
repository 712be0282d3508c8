//! The crate's error: a parameter outside its allowed range (Python ValueError), of the wrong kind (TypeError), or a
//! device that is missing or failed (RuntimeError).

use std::fmt;

#[derive(Debug, Clone, PartialEq)]
pub enum Error {
    /// A parameter outside its allowed range (Python ValueError).
    Value(String),
    /// A parameter of the wrong kind, or one the callee does not take (Python TypeError).
    Type(String),
    /// The device asked for is missing or failed (Python RuntimeError): no GPU adapter, a lost device.
    Device(String),
    /// The work was asked to stop (interrupt.rs; Python KeyboardInterrupt).
    Interrupted,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Value(s) | Error::Type(s) | Error::Device(s) => f.write_str(s),
            Error::Interrupted => f.write_str("interrupted"),
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

/// A string as Python writes it in a message: 'name'.
pub fn py(s: &str) -> String {
    format!("'{s}'")
}

/// Strings as Python writes a list of them in a message: ['a', 'b'].
pub fn py_list<S: AsRef<str>>(names: &[S]) -> String {
    format!("[{}]", names.iter().map(|n| py(n.as_ref())).collect::<Vec<_>>().join(", "))
}

/// The value of `values` whose name in `names` is `given`, or a ValueError naming `param` and its choices: the one
/// parser behind every enum that parses itself from a string (`FromStr`).
pub fn parse_choice<T: Copy>(param: &str, given: &str, names: &[&str], values: &[T]) -> Result<T> {
    match names.iter().position(|n| *n == given) {
        Some(k) => Ok(values[k]),
        None => value_error(format!("{param} must be one of {}, got {}", py_list(names), py(given))),
    }
}
