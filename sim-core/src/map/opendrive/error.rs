//! What the OpenDRIVE importer refuses: a message naming the road, element and attribute at fault,
//! with the line and column of the element in the file.

use std::fmt;

/// An OpenDRIVE file that could not be imported.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct OpenDriveError {
    /// 1-based line of the offending element (0 when the problem is the file as a whole).
    pub line: u32,
    /// 1-based column of the offending element (0 with `line` 0).
    pub column: u32,
    pub message: String,
}

impl fmt::Display for OpenDriveError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.line == 0 {
            write!(f, "OpenDRIVE: {}", self.message)
        } else {
            write!(f, "OpenDRIVE line {}, column {}: {}", self.line, self.column, self.message)
        }
    }
}

impl OpenDriveError {
    pub(crate) fn at(line: u32, column: u32, message: impl Into<String>) -> Self {
        Self { line, column, message: message.into() }
    }

    pub(crate) fn whole(message: impl Into<String>) -> Self {
        Self { line: 0, column: 0, message: message.into() }
    }
}
