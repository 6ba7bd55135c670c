//! Byte-level helpers for the text formats: a whitespace token cursor that knows its line,
//! a line iterator, and number parsing from byte tokens (non-UTF-8 bytes are just "not a number").

/// A cursor over whitespace-separated tokens that tracks the 1-based line of each token.
pub(crate) struct Tokens<'a> {
    data: &'a [u8],
    pos: usize,
    line: usize,
    /// `#` starts a comment running to the end of the line (OFF); PLY data has none.
    hash_comments: bool,
}

impl<'a> Tokens<'a> {
    /// A cursor at the start of `data`, whose first byte is on line `first_line`.
    pub(crate) fn new(data: &'a [u8], first_line: usize, hash_comments: bool) -> Tokens<'a> {
        Tokens {
            data,
            pos: 0,
            line: first_line,
            hash_comments,
        }
    }

    /// Line of the next token (after [`Tokens::skip_blank`]) or of the cursor.
    pub(crate) fn line(&self) -> usize {
        self.line
    }

    /// Bytes not yet consumed.
    pub(crate) fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }

    /// Skip whitespace and comments, counting newlines.
    pub(crate) fn skip_blank(&mut self) {
        while let Some(&b) = self.data.get(self.pos) {
            if b == b'\n' {
                self.line += 1;
                self.pos += 1;
            } else if b.is_ascii_whitespace() {
                self.pos += 1;
            } else if b == b'#' && self.hash_comments {
                self.skip_line();
            } else {
                break;
            }
        }
    }

    /// The next token with its line, or `None` at the end of the data.
    pub(crate) fn next_token(&mut self) -> Option<(&'a [u8], usize)> {
        self.skip_blank();
        let start = self.pos;
        while let Some(&b) = self.data.get(self.pos) {
            if b.is_ascii_whitespace() || (b == b'#' && self.hash_comments) {
                break;
            }
            self.pos += 1;
        }
        (self.pos > start).then(|| (&self.data[start..self.pos], self.line))
    }

    /// Skip to just after the next newline (the rest of the current line is ignored).
    pub(crate) fn skip_line(&mut self) {
        match self.data[self.pos..].iter().position(|&b| b == b'\n') {
            Some(i) => {
                self.pos += i + 1;
                self.line += 1;
            }
            None => self.pos = self.data.len(),
        }
    }
}

/// Lines of `data` with their 1-based numbers; `\r` before `\n` is removed.
pub(crate) fn lines(data: &[u8]) -> impl Iterator<Item = (usize, &[u8])> {
    data.split(|&b| b == b'\n').enumerate().map(|(i, l)| {
        let l = l.strip_suffix(b"\r").unwrap_or(l);
        (i + 1, l)
    })
}

/// Whitespace-separated tokens of one line.
pub(crate) fn split_ws(line: &[u8]) -> impl Iterator<Item = &[u8]> {
    line.split(|b| b.is_ascii_whitespace())
        .filter(|t| !t.is_empty())
}

/// A token shown in an error message: lossy UTF-8, cut to 40 characters.
pub(crate) fn show(token: &[u8]) -> String {
    let s = String::from_utf8_lossy(token);
    if s.chars().count() > 40 {
        format!("{}...", s.chars().take(40).collect::<String>())
    } else {
        s.into_owned()
    }
}

/// Parse a decimal number (any form Rust's `f64` parser accepts, so also `nan`/`inf`: callers
/// reject non-finite coordinates with a clearer message).
pub(crate) fn parse_f64(token: &[u8]) -> Result<f64, String> {
    std::str::from_utf8(token)
        .ok()
        .and_then(|s| s.parse::<f64>().ok())
        .ok_or_else(|| format!("expected a number, found '{}'", show(token)))
}

/// Parse a signed integer.
pub(crate) fn parse_i64(token: &[u8]) -> Result<i64, String> {
    std::str::from_utf8(token)
        .ok()
        .and_then(|s| s.parse::<i64>().ok())
        .ok_or_else(|| format!("expected an integer, found '{}'", show(token)))
}

/// Parse a count or index that must be a non-negative integer fitting in `u32`.
pub(crate) fn parse_u32(token: &[u8], what: &str) -> Result<u32, String> {
    let v = parse_i64(token).map_err(|e| format!("{what}: {e}"))?;
    u32::try_from(v).map_err(|_| format!("{what} {v} is out of range (0..=4294967295)"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tokens_track_lines_and_comments() {
        let mut t = Tokens::new(b"a b # c\n\n d#e\r\nf", 1, true);
        let got: Vec<(String, usize)> = std::iter::from_fn(|| t.next_token())
            .map(|(s, l)| (show(s), l))
            .collect();
        let want = [("a", 1), ("b", 1), ("d", 3), ("f", 4)];
        assert_eq!(
            got,
            want.map(|(s, l)| (s.to_string(), l)).to_vec(),
            "comments are skipped, lines counted"
        );
    }

    #[test]
    fn numbers_reject_garbage() {
        assert_eq!(parse_f64(b"-1.5e3").unwrap(), -1500.0);
        assert!(parse_f64(b"1.2.3").is_err());
        assert!(parse_f64(&[0xff, 0x31]).is_err());
        assert!(parse_u32(b"-1", "index").is_err());
        assert!(parse_u32(b"4294967296", "index").is_err());
        assert_eq!(parse_u32(b"7", "index").unwrap(), 7);
    }
}
