//! Writing one override into a scene's RON text, token by token ([`super::super::locate`]'s
//! scanner): the field's written value replaced, or the field added where its parent's fields
//! are; and the check that an override's value is one value and nothing more.

use std::ops::Range;

use super::super::locate::{Kind, Token, tokens};

/// `value` is one RON value: not empty, strings and brackets closed, no comment, and no `,` or
/// `:` outside brackets (which would write other fields than the one named).
pub(super) fn check_value(value: &str) -> Result<(), String> {
    if value.is_empty() {
        return Err("the value is empty".into());
    }
    let b = value.as_bytes();
    let mut open: Vec<u8> = Vec::new();
    let mut i = 0;
    while i < b.len() {
        match b[i] {
            b'"' | b'\'' => {
                let q = b[i];
                i += 1;
                while i < b.len() && b[i] != q {
                    i += if b[i] == b'\\' { 2 } else { 1 };
                }
                if i >= b.len() {
                    return Err("a string in the value is not closed".into());
                }
            }
            b'r' if matches!(b.get(i + 1), Some(b'"' | b'#')) => {
                let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
                let close = format!("\"{}", "#".repeat(hashes));
                let body = i + 2 + hashes;
                match value.get(body..).and_then(|r| r.find(&close)) {
                    Some(p) => i = body + p + close.len() - 1,
                    None => return Err("a raw string in the value is not closed".into()),
                }
            }
            b'/' if matches!(b.get(i + 1), Some(b'/' | b'*')) => {
                return Err("a comment cannot be part of a value".into());
            }
            c @ (b'(' | b'[' | b'{') => open.push(c),
            c @ (b')' | b']' | b'}') => {
                let want = match c {
                    b')' => b'(',
                    b']' => b'[',
                    _ => b'{',
                };
                if open.pop() != Some(want) {
                    return Err(format!("unbalanced `{}` in the value", c as char));
                }
            }
            b',' | b':' if open.is_empty() => {
                return Err(format!(
                    "the value has a `{}` outside brackets; set one field per --set",
                    b[i] as char
                ));
            }
            _ => {}
        }
        i += 1;
    }
    match open.last() {
        Some(&c) => Err(format!("`{}` in the value is not closed", c as char)),
        None => Ok(()),
    }
}

/// The part of a text a [`set`] changed: bytes `old` before, `old.start..new_end` after.
pub(super) struct Change {
    /// The bytes changed, in the text before.
    pub(super) old: Range<usize>,
    /// The end of what replaced them, in the text after.
    pub(super) new_end: usize,
}

/// `text` (a RON value: the whole scene, or a field's value) with the field `parts` set to
/// `value`. `defaults` is the same value as the typed scene writes it (every field, defaults
/// included), used for parents the text does not write. `shown` is the dotted name of `text`,
/// for messages.
pub(super) fn set(
    text: &str,
    parts: &[&str],
    value: &str,
    defaults: Option<&str>,
    shown: &str,
) -> Result<(String, Change), String> {
    let Some((&part, rest)) = parts.split_first() else {
        return Ok((
            value.to_string(),
            Change {
                old: 0..text.len(),
                new_end: value.len(),
            },
        ));
    };
    let toks = tokens(text);
    let name = |p: &str| {
        if shown.is_empty() {
            p.to_string()
        } else {
            format!("{shown}.{p}")
        }
    };
    let body = body(&toks).ok_or_else(|| {
        format!(
            "{shown} is {}, not a group of fields; set it whole (--set {shown}=…)",
            text.trim()
        )
    })?;
    let default_of = |d: &str| field_value(d, part).map(|r| d[r].to_string());
    let sub_defaults = defaults.and_then(default_of);
    match field_value_in(&toks, body.depth, part) {
        Some(vr) => {
            let inner = &text[vr.clone()];
            if !rest.is_empty() && inner.trim_start().starts_with('[') {
                return Err(format!(
                    "{} is a list; set it whole (--set '{}=[…]')",
                    name(part),
                    name(part)
                ));
            }
            let (new, c) = set(inner, rest, value, sub_defaults.as_deref(), &name(part))?;
            let out = format!("{}{new}{}", &text[..vr.start], &text[vr.end..]);
            Ok((
                out,
                Change {
                    old: vr.start + c.old.start..vr.start + c.old.end,
                    new_end: vr.start + c.new_end,
                },
            ))
        }
        None => {
            let sub = match &sub_defaults {
                Some(d) => set(d, rest, value, Some(d), &name(part))?.0,
                None => nest(rest, value),
            };
            let written = format!("{part}: {sub}, ");
            let at = body.insert_at;
            let out = format!("{}{written}{}", &text[..at], &text[at..]);
            Ok((
                out,
                Change {
                    old: at..at,
                    new_end: at + written.len(),
                },
            ))
        }
    }
}

/// `(a: (b: value))` for the parts `[a, b]`; `value` for none.
fn nest(parts: &[&str], value: &str) -> String {
    match parts.split_first() {
        None => value.to_string(),
        Some((p, rest)) => format!("({p}: {})", nest(rest, value)),
    }
}

/// Where the fields of a struct-like value are: their nesting depth, and where a new field goes.
struct Body {
    depth: usize,
    insert_at: usize,
}

/// The fields of the value `toks` (a struct, a variant holding one, `Some` of one, or the
/// scene's `Scene(...)`): past names and opening brackets to the first field or an empty `()`.
/// `None` for a value that has no fields (a number, a string, a tuple, a list).
fn body(toks: &[Token]) -> Option<Body> {
    let is_key = |i: usize| {
        toks[i].kind == Kind::Ident && toks.get(i + 1).is_some_and(|t| t.kind == Kind::Punct(':'))
    };
    let mut i = 0;
    // A file's attributes first (`#![enable(implicit_some)]`): to their closing `]`.
    while toks.get(i).is_some_and(|t| t.text.starts_with('#')) {
        let depth = toks[i].depth;
        i = (i + 1..toks.len())
            .find(|&j| toks[j].depth == depth && toks[j].kind == Kind::Punct(']'))
            .map_or(toks.len(), |j| j + 1);
    }
    while i < toks.len()
        && ((toks[i].kind == Kind::Ident && !is_key(i)) || toks[i].kind == Kind::Punct('('))
    {
        i += 1;
    }
    let t = toks.get(i)?;
    if is_key(i) {
        Some(Body {
            depth: t.depth,
            insert_at: t.offset,
        })
    } else if t.kind == Kind::Punct(')') && i > 0 && toks[i - 1].kind == Kind::Punct('(') {
        Some(Body {
            depth: t.depth + 1,
            insert_at: t.offset,
        })
    } else {
        None
    }
}

/// The byte range of the value of `part` among the fields of the value `text`.
fn field_value(text: &str, part: &str) -> Option<Range<usize>> {
    let toks = tokens(text);
    let body = body(&toks)?;
    field_value_in(&toks, body.depth, part)
}

/// The byte range of the value of the field `part:` written at `depth` in `toks`.
fn field_value_in(toks: &[Token], depth: usize, part: &str) -> Option<Range<usize>> {
    let at = (0..toks.len().saturating_sub(1)).find(|&i| {
        toks[i].depth == depth
            && toks[i].kind == Kind::Ident
            && toks[i].text == part
            && toks[i + 1].kind == Kind::Punct(':')
    })?;
    let from = at + 2;
    let end = (from..toks.len())
        .find(|&i| {
            let t = &toks[i];
            (t.depth == depth && t.kind == Kind::Punct(','))
                || (t.depth < depth && matches!(t.kind, Kind::Punct(')' | ']' | '}')))
        })
        .unwrap_or(toks.len());
    if end <= from {
        let after = toks[at + 1].end();
        return Some(after..after);
    }
    Some(toks[from].offset..toks[end - 1].end())
}
