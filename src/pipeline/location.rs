//! Where a value sits in the pipeline text: key paths (`output[2].path`), their byte spans, and
//! line and column numbers, so every error points at what the user wrote.

use std::ops::Range;

/// One segment of a key path (`output[2].path`), for locating a value in the source.
#[derive(Clone, Debug)]
pub enum Key<'a> {
    Name(&'a str),
    Index(usize),
}

/// A validation failure: the key it concerns and what is wrong.
pub(super) struct Invalid<'a> {
    pub keys: Vec<Key<'a>>,
    pub message: String,
}

pub(super) fn invalid<'a>(keys: &[Key<'a>], message: impl Into<String>) -> Invalid<'a> {
    Invalid {
        keys: keys.to_vec(),
        message: message.into(),
    }
}

/// 1-based line and column of a byte offset.
pub fn line_column(src: &str, offset: usize) -> (usize, usize) {
    let before = &src[..offset.min(src.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

/// Byte span of the value at a key path, if the source has it.
pub(super) fn locate(src: &str, keys: &[Key]) -> Option<Range<usize>> {
    let doc = toml_edit::Document::parse(src).ok()?;
    let mut item = doc.as_item();
    let mut span = None;
    for k in keys {
        item = match k {
            Key::Name(n) => item.get(*n)?,
            Key::Index(i) => item.get(*i)?,
        };
        span = item.span().or(span);
    }
    span
}
