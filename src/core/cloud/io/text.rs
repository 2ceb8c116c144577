//! Line splitting and number parsing shared by the text formats (XYZ/PWN, OFF, OBJ).

use super::{LoadErrorKind, Location};

/// Longest token quoted back in an error message.
const MAX_QUOTED_TOKEN: usize = 32;

/// Iterates over the lines of a text file: 1-based line number and the line's content with any
/// `#` comment and surrounding whitespace removed. Invalid UTF-8 ends the iteration with
/// [`LoadErrorKind::NotText`].
pub(super) struct TextLines<'a> {
    rest: &'a [u8],
    line: usize,
    failed: bool,
}

impl<'a> TextLines<'a> {
    pub(super) fn new(bytes: &'a [u8]) -> Self {
        Self {
            rest: bytes,
            line: 0,
            failed: false,
        }
    }

    /// Bytes not yet consumed (after the last line returned).
    pub(super) fn remaining_bytes(&self) -> usize {
        self.rest.len()
    }

    /// The next line that is not blank after removing comments.
    pub(super) fn next_content(&mut self) -> Option<Result<(usize, &'a str), LoadErrorKind>> {
        loop {
            match self.next()? {
                Ok((_, "")) => continue,
                other => return Some(other),
            }
        }
    }
}

impl<'a> Iterator for TextLines<'a> {
    type Item = Result<(usize, &'a str), LoadErrorKind>;

    fn next(&mut self) -> Option<Self::Item> {
        if self.rest.is_empty() || self.failed {
            return None;
        }
        let end = self
            .rest
            .iter()
            .position(|&b| b == b'\n')
            .unwrap_or(self.rest.len());
        let raw = &self.rest[..end];
        self.rest = self.rest.get(end + 1..).unwrap_or(&[]);
        self.line += 1;
        let Ok(text) = std::str::from_utf8(raw) else {
            self.failed = true;
            return Some(Err(LoadErrorKind::NotText { line: self.line }));
        };
        if text.contains('\0') {
            self.failed = true;
            return Some(Err(LoadErrorKind::NotText { line: self.line }));
        }
        let content = text.split('#').next().unwrap_or("").trim();
        Some(Ok((self.line, content)))
    }
}

/// Quotes a token for an error message, shortened if long.
pub(super) fn quote(token: &str) -> String {
    if token.chars().count() <= MAX_QUOTED_TOKEN {
        format!("{token:?}")
    } else {
        let head: String = token.chars().take(MAX_QUOTED_TOKEN).collect();
        format!("{head:?}…")
    }
}

/// Parses a decimal number (Rust float syntax, which includes `nan` and `inf`; those are caught
/// later by the finiteness check so the error says what is wrong).
pub(super) fn parse_number(token: &str, line: usize) -> Result<f64, LoadErrorKind> {
    token.parse::<f64>().map_err(|_| LoadErrorKind::Syntax {
        location: Location::Line(line),
        message: format!("expected a number, found {}", quote(token)),
    })
}

/// Parses a non-negative element count.
pub(super) fn parse_count(token: &str, line: usize, what: &str) -> Result<u64, LoadErrorKind> {
    token.parse::<u64>().map_err(|_| LoadErrorKind::Syntax {
        location: Location::Line(line),
        message: format!("expected the {what} count, found {}", quote(token)),
    })
}

/// Parses the first `N` numbers of `tokens`; `found` counts every token for the error message.
pub(super) fn parse_numbers<'t, const N: usize>(
    tokens: impl Iterator<Item = &'t str>,
    line: usize,
    expected: &str,
) -> Result<[f64; N], LoadErrorKind> {
    let mut out = [0.0; N];
    let mut found = 0;
    for token in tokens {
        if found < N {
            out[found] = parse_number(token, line)?;
        }
        found += 1;
    }
    if found < N {
        return Err(LoadErrorKind::ColumnCount {
            line,
            expected: expected.to_owned(),
            found,
        });
    }
    Ok(out)
}

/// Converts parsed numbers to a checked position vector.
pub(super) fn position(v: [f64; 3], line: usize) -> Result<glam::Vec3, LoadErrorKind> {
    vector(v, line, "coordinate")
}

/// Converts parsed numbers to a checked normal vector.
pub(super) fn normal(v: [f64; 3], line: usize) -> Result<glam::Vec3, LoadErrorKind> {
    vector(v, line, "normal component")
}

fn vector(v: [f64; 3], line: usize, what: &'static str) -> Result<glam::Vec3, LoadErrorKind> {
    let c = |x| super::coordinate(x, what, || Location::Line(line));
    Ok(glam::Vec3::new(c(v[0])?, c(v[1])?, c(v[2])?))
}
