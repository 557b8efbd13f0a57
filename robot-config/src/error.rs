//! The one-line error of a configuration file: where, which key, what is wrong.

use std::fmt;

/// A refused configuration file, displayed as `<file>:<line>: <key>: <problem>`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ConfigError {
    /// The file, as the caller named it.
    pub origin: String,
    /// The line the problem is on (1-based), if the parser knows it.
    pub line: Option<usize>,
    /// The dotted key, e.g. `singularity.stiffness` (empty for the whole file).
    pub key: String,
    /// What is wrong.
    pub problem: String,
}

impl ConfigError {
    /// The error of `message` found at `key`, at byte `offset` of `text` if known. serde's
    /// "missing field `x`" and "unknown field `x`, …" become "missing key" and "unknown key" on
    /// the key `x` itself.
    pub(crate) fn new(origin: &str, text: &str, offset: Option<usize>, key: &str, message: &str) -> Self {
        let line = offset.map(|offset| text.get(..offset).unwrap_or(text).matches('\n').count() + 1);
        let (field, problem) = match named_field(message, "missing field `") {
            Some((field, _)) => (Some(field), "missing key".to_string()),
            None => match named_field(message, "unknown field `") {
                Some((field, rest)) => (Some(field), unknown_key(rest.trim_start_matches(", "))),
                None => (None, message.trim().replace('\n', " ")),
            },
        };
        let key = match field {
            Some(field) if key != field && !key.ends_with(&format!(".{field}")) => join_key(key, field),
            _ => key.to_string(),
        };
        Self { origin: origin.to_string(), line, key, problem }
    }
}

/// `(field, rest)` of a serde message `<prefix>field`rest`.
fn named_field<'m>(message: &'m str, prefix: &str) -> Option<(&'m str, &'m str)> {
    message.strip_prefix(prefix)?.split_once('`')
}

fn unknown_key(expected: &str) -> String {
    if expected.is_empty() {
        "unknown key".to_string()
    } else {
        format!("unknown key ({expected})")
    }
}

fn join_key(parent: &str, field: &str) -> String {
    if parent.is_empty() || parent == "." {
        field.to_string()
    } else {
        format!("{parent}.{field}")
    }
}

impl fmt::Display for ConfigError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.line {
            Some(line) => write!(f, "{}:{line}: ", self.origin)?,
            None => write!(f, "{}: ", self.origin)?,
        }
        if !self.key.is_empty() && self.key != "." {
            write!(f, "{}: ", self.key)?;
        }
        f.write_str(&self.problem)
    }
}

impl std::error::Error for ConfigError {}
