//! Where a field is written in a scene file's text, so that a value out of range is reported at
//! its `line:column` as a parse error is (`scene.ron:7:20: sun.intensity: must be ≥ 0, got -1`).
//!
//! A small RON scanner: it skips strings, raw strings, characters and comments, tracks nesting,
//! and finds each part of a dotted field (`camera.fov_deg`) as the least nested `name:` inside
//! the value of the part before (so an enum variant's wrapping, `Auto((fov_deg: 20))`, is
//! looked through). A part `name[i]` is the `i`-th element of the list `name` (`story[1].end`).
//! A field the file does not write (a default) has no place: `None`.

/// The 1-based line and column (in characters) of `field` (dotted, e.g. `cloud.noise.octaves`)
/// in RON `text`, if the text writes it.
pub fn locate(text: &str, field: &str) -> Option<(usize, usize)> {
    let tokens = tokens(text);
    let (mut from, mut to) = (0, tokens.len());
    let mut found = None;
    for part in field.split('.') {
        let (name, index) = match part.split_once('[') {
            Some((name, rest)) => (name, rest.strip_suffix(']')?.parse::<usize>().ok()),
            None => (part, None),
        };
        let at = key_in(&tokens, from, to, name)?;
        found = Some(tokens[at].offset);
        // The value runs from after `:` to the `,` or closing bracket at the key's depth.
        let depth = tokens[at].depth;
        from = at + 2;
        to = value_end(&tokens, from, to, depth);
        if let Some(i) = index {
            // The list's elements are separated by commas one level deeper than its key.
            let open = (from..to).find(|&k| tokens[k].kind == Kind::Punct('['))?;
            let mut start = open + 1;
            for _ in 0..i {
                start = value_end(&tokens, start, to, depth + 1) + 1;
            }
            if start >= to || tokens[start].depth <= depth {
                return None;
            }
            found = Some(tokens[start].offset);
            from = start;
            to = value_end(&tokens, start, to, depth + 1);
        }
    }
    found.map(|offset| line_column(text, offset))
}

/// The index of the `,` or closing bracket that ends the value starting at `from` whose key (or
/// list) is at `depth` (`to` when none before it).
fn value_end(tokens: &[Token], from: usize, to: usize, depth: usize) -> usize {
    (from..to)
        .find(|&i| {
            let t = &tokens[i];
            (t.depth == depth && t.kind == Kind::Punct(','))
                || (t.depth < depth && matches!(t.kind, Kind::Punct(')' | ']' | '}')))
        })
        .unwrap_or(to)
}

/// The least nested `part:` among `tokens[from..to]`.
pub(super) fn key_in(tokens: &[Token], from: usize, to: usize, part: &str) -> Option<usize> {
    (from..to.saturating_sub(1))
        .filter(|&i| {
            tokens[i].kind == Kind::Ident
                && tokens[i].text == part
                && tokens[i + 1].kind == Kind::Punct(':')
        })
        .min_by_key(|&i| tokens[i].depth)
}

/// What a token is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    /// A name (field, variant, `true`, ...).
    Ident,
    /// A bracket, `:` or `,`.
    Punct(char),
    /// Anything else: a number, a string, a character.
    Other,
}

/// A token with its byte offset and its nesting depth (brackets open before it).
pub(super) struct Token<'a> {
    /// What it is.
    pub(super) kind: Kind,
    /// Its text.
    pub(super) text: &'a str,
    /// Byte offset of its first character.
    pub(super) offset: usize,
    /// Brackets open before it.
    pub(super) depth: usize,
}

impl Token<'_> {
    /// Byte offset just after it.
    pub(super) fn end(&self) -> usize {
        self.offset + self.text.len()
    }
}

/// The tokens of RON `text`; comments are skipped, a string (or character) is one token.
pub(super) fn tokens(text: &str) -> Vec<Token<'_>> {
    let bytes = text.as_bytes();
    let mut out = Vec::new();
    let (mut i, mut depth) = (0, 0usize);
    while i < bytes.len() {
        let c = bytes[i];
        match c {
            b' ' | b'\t' | b'\r' | b'\n' => i += 1,
            b'/' if bytes.get(i + 1) == Some(&b'/') => {
                while i < bytes.len() && bytes[i] != b'\n' {
                    i += 1;
                }
            }
            b'/' if bytes.get(i + 1) == Some(&b'*') => {
                i += 2;
                while i + 1 < bytes.len() && !(bytes[i] == b'*' && bytes[i + 1] == b'/') {
                    i += 1;
                }
                i += 2;
            }
            b'"' | b'\'' => {
                let end = skip_quoted(bytes, i, c).min(bytes.len());
                out.push(other(text, i, end, depth));
                i = end;
            }
            b'r' if matches!(bytes.get(i + 1), Some(b'"' | b'#')) => {
                let end = skip_raw(bytes, i).min(bytes.len());
                out.push(other(text, i, end, depth));
                i = end;
            }
            b'(' | b'[' | b'{' => {
                out.push(punct(text, i, depth));
                depth += 1;
                i += 1;
            }
            b')' | b']' | b'}' => {
                depth = depth.saturating_sub(1);
                out.push(punct(text, i, depth));
                i += 1;
            }
            b':' | b',' => {
                out.push(punct(text, i, depth));
                i += 1;
            }
            c if c.is_ascii_alphabetic() || c == b'_' => {
                let start = i;
                while i < bytes.len() && (bytes[i].is_ascii_alphanumeric() || bytes[i] == b'_') {
                    i += 1;
                }
                out.push(Token {
                    kind: Kind::Ident,
                    text: &text[start..i],
                    offset: start,
                    depth,
                });
            }
            _ => {
                // Numbers, signs and other characters: one token to the next separator.
                let start = i;
                while i < bytes.len()
                    && !matches!(
                        bytes[i],
                        b' ' | b'\t'
                            | b'\r'
                            | b'\n'
                            | b'('
                            | b')'
                            | b'['
                            | b']'
                            | b'{'
                            | b'}'
                            | b':'
                            | b','
                            | b'"'
                    )
                {
                    i += 1;
                }
                i = i.max(start + 1);
                out.push(Token {
                    kind: Kind::Other,
                    text: &text[start..i.min(text.len())],
                    offset: start,
                    depth,
                });
            }
        }
    }
    out
}

fn other(text: &str, start: usize, end: usize, depth: usize) -> Token<'_> {
    Token {
        kind: Kind::Other,
        text: text.get(start..end).unwrap_or(""),
        offset: start,
        depth,
    }
}

fn punct(text: &str, i: usize, depth: usize) -> Token<'_> {
    Token {
        kind: Kind::Punct(text.as_bytes()[i] as char),
        text: &text[i..i + 1],
        offset: i,
        depth,
    }
}

/// The index after the string or character opened by `quote` at `i` (escapes skipped).
fn skip_quoted(bytes: &[u8], mut i: usize, quote: u8) -> usize {
    i += 1;
    while i < bytes.len() && bytes[i] != quote {
        i += if bytes[i] == b'\\' { 2 } else { 1 };
    }
    i + 1
}

/// The index after the raw string `r#"…"#` starting at `i`.
fn skip_raw(bytes: &[u8], mut i: usize) -> usize {
    i += 1;
    let hashes = bytes[i..].iter().take_while(|&&b| b == b'#').count();
    i += hashes + 1;
    while i < bytes.len() {
        if bytes[i] == b'"'
            && bytes[i + 1..]
                .iter()
                .take(hashes)
                .filter(|&&b| b == b'#')
                .count()
                == hashes
        {
            return i + 1 + hashes;
        }
        i += 1;
    }
    i
}

/// The 1-based line and column (characters) of byte `offset` in `text`.
pub(super) fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let column = before[before.rfind('\n').map_or(0, |n| n + 1)..]
        .chars()
        .count()
        + 1;
    (line, column)
}

#[cfg(test)]
mod tests {
    use super::*;

    const SCENE: &str = r#"// a "quoted" comment: sun: (intensity: 1.0)
Scene(
    target: Model("builtin:cumulus"), /* shot: (fps: 1) */
    sun: (direction: (1.0, -1.0, 0.0), intensity: -2.0),
    camera: Auto((azimuth_deg: 10.0, fov_deg: 200.0)),
    cloud: (noise: (octaves: 12), density: 30.0),
    output: (name: "a, b: (c)", formats: [Png, Png]),
)"#;

    #[test]
    fn fields_are_found_where_they_are_written() {
        assert_eq!(locate(SCENE, "sun.intensity"), Some((4, 40)));
        assert_eq!(locate(SCENE, "camera.fov_deg"), Some((5, 38)));
        assert_eq!(locate(SCENE, "cloud.noise.octaves"), Some((6, 21)));
        assert_eq!(locate(SCENE, "output.formats"), Some((7, 33)));
        assert_eq!(locate(SCENE, "cloud"), Some((6, 5)));
        // Not written (a default), or only inside a comment or a string.
        assert_eq!(locate(SCENE, "shot.fps"), None);
        assert_eq!(locate(SCENE, "cloud.density.x"), None);
        assert_eq!(locate(SCENE, "c"), None);
        // A key of another part is not taken for this one's.
        assert_eq!(locate(SCENE, "sun.octaves"), None);
    }

    #[test]
    fn list_elements_are_found_by_index() {
        let text = "Scene(\n  story: [\n    (target: Model(\"a\"), end: 1.0),\n    (target: Model(\"b\"), start: 0.5, end: 2.0),\n  ],\n)";
        assert_eq!(locate(text, "story[0]"), Some((3, 5)));
        assert_eq!(locate(text, "story[1]"), Some((4, 5)));
        assert_eq!(locate(text, "story[1].start"), Some((4, 26)));
        assert_eq!(locate(text, "story[0].end"), Some((3, 26)));
        assert_eq!(locate(text, "story[0].start"), None);
        assert_eq!(locate(text, "story[2]"), None);
    }
}
