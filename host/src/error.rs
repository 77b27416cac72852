//! What the library's fallible calls return: an [`Error`] whose [`ErrorKind`] says what failed
//! (the input, the options, the limits, the GPU, the output) and whose message says how, in
//! one line naming the file or the option concerned. The library prints nothing; a caller
//! decides what to show, and may act on the kind (retry on the CPU, ask for a smaller image).

use std::fmt;

/// What an [`Error`] is about.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ErrorKind {
    /// A mesh file that cannot be read, or whose contents are broken or unsupported.
    Input,
    /// Options or a camera that cannot be honoured: a depth out of range, a mode the
    /// representation lacks, a view with no direction.
    Options,
    /// What does not fit: memory, the GPU's binding limits, the grid layout's addresses.
    Limits,
    /// No GPU adapter at all (`Backend::open(BackendChoice::Auto)` takes the CPU instead).
    NoGpu,
    /// The GPU backend failed: its device, its kernels, a dispatch or a read-back.
    Gpu,
    /// An output file that cannot be written.
    Output,
}

/// A failure of the library: its kind and a one-line message.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Error {
    kind: ErrorKind,
    message: String,
}

/// The library's result type.
pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    pub fn new(kind: ErrorKind, message: impl Into<String>) -> Self {
        Error {
            kind,
            message: message.into(),
        }
    }

    pub fn kind(&self) -> ErrorKind {
        self.kind
    }

    pub fn message(&self) -> &str {
        &self.message
    }

    /// The same error with `prefix: ` before its message (a file name, say).
    pub fn prefixed(self, prefix: impl fmt::Display) -> Self {
        Error {
            message: format!("{prefix}: {}", self.message),
            ..self
        }
    }
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message)
    }
}

impl std::error::Error for Error {}

/// Returns early with an [`Error`] of kind `$kind` (an [`ErrorKind`] variant's name) and a
/// formatted message.
macro_rules! fail {
    ($kind:ident, $($message:tt)+) => {
        return Err($crate::error::Error::new($crate::error::ErrorKind::$kind, format!($($message)+)))
    };
}

/// An [`Error`] of kind `$kind` with a formatted message, for `map_err` and `ok_or_else`.
macro_rules! error {
    ($kind:ident, $($message:tt)+) => {
        $crate::error::Error::new($crate::error::ErrorKind::$kind, format!($($message)+))
    };
}

pub(crate) use {error, fail};

#[cfg(test)]
mod tests {
    use super::*;

    fn refuse(depth: u32) -> Result<()> {
        fail!(Options, "depth {depth} is too deep");
    }

    #[test]
    fn errors_carry_their_kind_and_one_line() {
        let e = refuse(9).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::Options);
        assert_eq!(e.to_string(), "depth 9 is too deep");
        let e = e.prefixed("mesh.ply");
        assert_eq!(
            (e.kind(), e.message()),
            (ErrorKind::Options, "mesh.ply: depth 9 is too deep")
        );
        // Callers using anyhow keep the message and can find the kind again.
        let any: anyhow::Error = error!(NoGpu, "no adapter").into();
        assert_eq!(any.downcast_ref::<Error>().map(Error::kind), Some(ErrorKind::NoGpu));
    }
}
