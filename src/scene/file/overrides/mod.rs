//! Overrides of a scene's values from outside the file, in the scene's own dotted names:
//! `--set cloud.density=30`, `--set camera=Fixed((position: (0, 1, 5)))`, `--size 1920x1080`
//! (`kick -set`, `husk --res`). The CLI, the Python binding and the live view pass the strings;
//! the rule is here.
//!
//! An override is written into the scene's text before it is deserialised, so everything after
//! — the typed scene, its validation, the frames' provenance hashes — sees one scene: a shot
//! rendered with `--set cloud.density=30` has the bits and hashes of the same shot whose file
//! says `cloud: (density: 30)`. (RON's own value tree drops struct and enum-variant names, so it
//! cannot carry a scene back to its types; the text's tokens can.) A written field's value is
//! replaced; a field the file leaves to its default is added, inside the value its parent
//! really has (the parent's default, serialised from the typed scene, when the file does not
//! write the parent either): `--set camera.fov_deg=20` works on a scene without `camera`.
//!
//! Errors name the override as the user wrote it (`--set shot.width=abc: shot.width: expected
//! an integer`), an unknown name comes with the nearest ones, and an error the rest of the load
//! finds in an overridden value (`--set shot.width=0`) names the override, not the file.

#[cfg(test)]
mod tests;
mod text;

use std::ops::Range;
use std::path::Path;

use self::text::{check_value, set};
use super::SceneFile;
use super::locate::line_column;
use crate::file_error::FileError;
use crate::scene::SceneError;

/// One override: `key` (dotted, `cloud.density`) set to `value` (RON text, one value).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Override {
    /// The dotted field name.
    pub key: String,
    /// The value as RON text.
    pub value: String,
    /// How the user wrote it, for errors (`--set cloud.density=30`, `--size 1920x1080`).
    pub given: String,
}

impl Override {
    /// The override `KEY=VALUE` (the text of a `--set`); `given` labels it in errors.
    pub fn parse(arg: &str, given: &str) -> Result<Override, String> {
        let (key, value) = arg
            .split_once('=')
            .ok_or_else(|| format!("{given}: expected KEY=VALUE, e.g. cloud.density=30"))?;
        let o = Override {
            key: key.trim().to_string(),
            value: value.trim().to_string(),
            given: given.to_string(),
        };
        o.check().map_err(|m| format!("{given}: {m}"))?;
        Ok(o)
    }

    /// The `--set KEY=VALUE` override.
    pub fn set(arg: &str) -> Result<Override, String> {
        Override::parse(arg, &format!("--set {arg}"))
    }

    /// The two overrides `shot.width` and `shot.height` of a size `WxH` (`--size 1920x1080`).
    pub fn size(arg: &str) -> Result<[Override; 2], String> {
        let given = format!("--size {arg}");
        let (w, h) = parse_size(arg).map_err(|m| format!("{given}: {m}"))?;
        let o = |key: &str, n: u32| Override {
            key: key.to_string(),
            value: n.to_string(),
            given: given.clone(),
        };
        Ok([o("shot.width", w), o("shot.height", h)])
    }

    /// The key is dotted names, the value one RON value with nothing after it.
    fn check(&self) -> Result<(), String> {
        let name_ok = |p: &str| {
            let mut c = p.chars();
            c.next()
                .is_some_and(|f| f.is_ascii_alphabetic() || f == '_')
                && c.all(|c| c.is_ascii_alphanumeric() || c == '_')
        };
        if !self.key.split('.').all(name_ok) {
            return Err(format!(
                "{:?} is not a dotted field name such as cloud.density",
                self.key
            ));
        }
        check_value(&self.value).map_err(|m| format!("{}: {m}", self.key))
    }

    /// This override's error with `message` about `field`.
    fn error(&self, field: &str, message: String) -> SceneError {
        SceneError::Override {
            given: self.given.clone(),
            field: field.to_string(),
            message,
        }
    }

    /// True when an error about `field` is about this override's value: the same field, one
    /// inside the value it sets, or the group it is part of (`shot` for `shot.width`).
    fn concerns(&self, field: &str) -> bool {
        let (k, f) = (self.key.as_str(), field);
        k == f
            || f.strip_prefix(k).is_some_and(|r| r.starts_with(['.', '[']))
            || k.strip_prefix(f).is_some_and(|r| r.starts_with('.'))
    }
}

/// The overrides in the order they apply: the size's two (`--size`) first, then each `--set`
/// (a later one wins), for the CLI and the Python binding alike.
pub fn in_order(size: Option<&[Override; 2]>, set: &[Override]) -> Vec<Override> {
    let mut all: Vec<Override> = size.into_iter().flatten().cloned().collect();
    all.extend(set.iter().cloned());
    all
}

/// An image size `WIDTHxHEIGHT` in pixels (`1920x1080`), both positive.
pub fn parse_size(arg: &str) -> Result<(u32, u32), String> {
    let bad = || format!("{arg:?} is not WIDTHxHEIGHT in pixels, e.g. 1920x1080");
    let (w, h) = arg.split_once(['x', 'X']).ok_or_else(bad)?;
    let pixels = |s: &str| s.trim().parse::<u32>().ok().filter(|&n| n > 0);
    Ok((pixels(w).ok_or_else(bad)?, pixels(h).ok_or_else(bad)?))
}

/// One override's change of the text: bytes `old` of the text before became `start..new_end`.
#[derive(Clone, Debug)]
struct Edit {
    old: Range<usize>,
    new_end: usize,
    by: usize,
}

/// A scene's text with its overrides written in, and the scene it parses to.
#[derive(Clone, Debug)]
pub struct Overridden {
    /// The parsed scene (not yet validated).
    pub file: SceneFile,
    /// The text with the overrides written in.
    pub text: String,
    overrides: Vec<Override>,
    edits: Vec<Edit>,
}

/// Parse scene `text` (of the file `path`) with `overrides` applied in order (a later one wins,
/// and may set a field inside an earlier one's value). Errors of the file's own text are the
/// file's (located); an override that cannot be written or does not parse is its own error.
pub fn apply(path: &Path, text: &str, overrides: &[Override]) -> Result<Overridden, SceneError> {
    let mut file = super::parse(path, text)?;
    let mut out = text.to_string();
    let mut edits = Vec::new();
    for (by, o) in overrides.iter().enumerate() {
        o.check().map_err(|m| o.error(&o.key, m))?;
        // The typed scene so far, written out: the values of fields the text leaves to defaults.
        let defaults = ron::ser::to_string(&file).ok();
        let parts: Vec<&str> = o.key.split('.').collect();
        let (edited, change) =
            set(&out, &parts, &o.value, defaults.as_deref(), "").map_err(|m| o.error(&o.key, m))?;
        file = super::parse_ron(&edited)
            .map_err(|e| o.error(&o.key, describe(&e.code, &parts, &o.value)))?;
        edits.push(Edit {
            old: change.old,
            new_end: change.new_end,
            by,
        });
        out = edited;
    }
    Ok(Overridden {
        file,
        text: out,
        overrides: overrides.to_vec(),
        edits,
    })
}

impl Overridden {
    /// `e`, an error found in the overridden text, said where its cause is: an override's
    /// error when it concerns an override's field or lies in the text one wrote, else at its
    /// place in the `original` file text.
    pub fn attribute(&self, original: &str, e: SceneError) -> SceneError {
        if self.overrides.is_empty() {
            return e;
        }
        let by_field = |field: &str| self.overrides.iter().rev().find(|o| o.concerns(field));
        match e {
            SceneError::Invalid {
                path,
                field,
                message,
            } => match by_field(&field) {
                Some(o) => o.error(&field, message),
                None => SceneError::Invalid {
                    path,
                    field,
                    message,
                }
                .located(original),
            },
            SceneError::InvalidAt {
                path,
                line,
                column,
                field,
                message,
            } => {
                if let Some(o) = by_field(&field) {
                    return o.error(&field, message);
                }
                match self.origin(line, column) {
                    Err(o) => o.error(&field, message),
                    Ok(offset) => {
                        let (line, column) = line_column(original, offset);
                        SceneError::InvalidAt {
                            path,
                            line,
                            column,
                            field,
                            message,
                        }
                    }
                }
            }
            SceneError::File(FileError::Parse {
                path,
                line,
                column,
                message,
            }) => match self.origin(line, column) {
                Err(o) => {
                    let (field, message) = message
                        .split_once(": ")
                        .map_or((o.key.clone(), message.clone()), |(f, m)| {
                            (f.to_string(), m.to_string())
                        });
                    o.error(&field, message)
                }
                Ok(offset) => {
                    let (line, column) = line_column(original, offset);
                    SceneError::File(FileError::Parse {
                        path,
                        line,
                        column,
                        message,
                    })
                }
            },
            other => other,
        }
    }

    /// The byte offset in the original text of `line:column` of the overridden text, or the
    /// override that wrote the text there.
    fn origin(&self, line: usize, column: usize) -> Result<usize, &Override> {
        let mut at = offset_of(&self.text, line, column);
        for e in self.edits.iter().rev() {
            if at >= e.new_end {
                at = at - e.new_end + e.old.end;
            } else if at >= e.old.start {
                return Err(&self.overrides[e.by]);
            }
        }
        Ok(at)
    }
}

/// The byte offset of 1-based `line:column` (characters) in `text`.
fn offset_of(text: &str, line: usize, column: usize) -> usize {
    let start: usize = text
        .split_inclusive('\n')
        .take(line.saturating_sub(1))
        .map(str::len)
        .sum();
    let rest = &text[start.min(text.len())..];
    start
        + rest
            .char_indices()
            .nth(column.saturating_sub(1))
            .map_or(rest.len(), |(i, _)| i)
}

/// A parse error of an override's text in the words of the override: an unknown name with
/// the nearest known ones.
fn describe(code: &ron::Error, parts: &[&str], value: &str) -> String {
    use ron::Error as E;
    let unknown = |what: &str, found: &str, names: &[&str]| {
        let near = nearest(found, names);
        let whose = parts
            .iter()
            .position(|p| *p == found)
            .map(|i| parts[..i].join("."))
            .filter(|s| !s.is_empty())
            .map_or(String::new(), |p| format!(" in {p}"));
        let hint = if near.is_empty() {
            String::new()
        } else {
            format!("; nearest: {}", near.join(", "))
        };
        format!(
            "no {what} named `{found}`{whose}{hint} (known: {})",
            names.join(", ")
        )
    };
    match code {
        E::NoSuchStructField {
            expected, found, ..
        } => unknown("field", found, expected),
        E::NoSuchEnumVariant {
            expected, found, ..
        } => unknown("variant", found, expected),
        E::ExpectedInteger | E::InvalidIntegerDigit { .. } => {
            format!("expected an integer, got {value}")
        }
        E::IntegerOutOfBounds => format!("{value} is out of the integer's range"),
        E::ExpectedFloat => format!("expected a number, got {value}"),
        E::ExpectedBoolean => format!("expected true or false, got {value}"),
        E::ExpectedString | E::ExpectedStringEnd => {
            format!("expected a string in double quotes, got {value}")
        }
        other => {
            let m = other.to_string();
            let mut c = m.chars();
            c.next()
                .map_or(String::new(), |f| f.to_lowercase().chain(c).collect())
        }
    }
}

/// The names among `names` closest to `found` (edit distance at most a third of its length,
/// and at least 2), closest first.
fn nearest<'a>(found: &str, names: &[&'a str]) -> Vec<&'a str> {
    let limit = (found.chars().count() / 3).max(2);
    let mut near: Vec<(usize, &str)> = names
        .iter()
        .map(|n| (strsim::damerau_levenshtein(found, n), *n))
        .filter(|(d, _)| *d <= limit)
        .collect();
    near.sort();
    near.into_iter().take(3).map(|(_, n)| n).collect()
}
