//! The one writer of values into job files ([`write_value`]): checked, then quoted for their
//! [`Place`], or refused.

use std::ffi::OsString;

/// A value bound for a job file: its text, what it is, where it came from and how to fix it,
/// so that the error refusing it can say all of that.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Value {
    /// The text (a path need not be UTF-8; one that is not is refused).
    pub text: OsString,
    /// What it is, e.g. "the output folder".
    pub what: &'static str,
    /// Where it came from, e.g. "--output".
    pub from: String,
    /// How to fix it when it is refused, e.g. "rename the folder".
    pub fix: &'static str,
}

impl Value {
    /// A value from outside.
    pub fn new(
        text: impl Into<OsString>,
        what: &'static str,
        from: impl Into<String>,
        fix: &'static str,
    ) -> Value {
        Value {
            text: text.into(),
            what,
            from: from.into(),
            fix,
        }
    }

    /// Text nephele makes itself (a fixed word, a frame range, a sanitized name): it goes
    /// through the writer like any value, so that nothing reaches a job file around it.
    pub fn own(text: impl Into<String>) -> Value {
        Value::new(
            text.into(),
            "nephele's own text",
            "nephele farm",
            "this is a bug in nephele; please report it",
        )
    }

    /// The error refusing this value at `place` (a [`Place`]'s name), for `why`.
    pub(super) fn refused(&self, place: &'static str, why: impl Into<String>) -> Refused {
        Refused {
            what: self.what,
            text: self.text.to_string_lossy().into_owned(),
            from: self.from.clone(),
            place,
            why: why.into(),
            fix: self.fix,
        }
    }
}

/// Where in a job file a value is written; each place has its own quoting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Place {
    /// A word of a POSIX shell command: single-quoted.
    ShellWord,
    /// An `#SBATCH` option or option value: double-quoted unless plain.
    Sbatch,
    /// A value in an `#SBATCH` filename pattern (`--output`): as [`Place::Sbatch`], `%` written
    /// `%%`.
    SbatchPattern,
    /// A YAML string: double-quoted, JSON escapes.
    Yaml,
    /// A Kubernetes object name in YAML: plain when YAML reads it back as that very string,
    /// else as [`Place::Yaml`].
    YamlName,
    /// Text in a `#` comment line: as it is.
    Comment,
}

impl Place {
    pub(super) fn name(self) -> &'static str {
        match self {
            Place::ShellWord => "into a job script's command",
            Place::Sbatch => "on an #SBATCH line",
            Place::SbatchPattern => "into an #SBATCH file name",
            Place::Yaml | Place::YamlName => "into a YAML manifest",
            Place::Comment => "into a job file's comment line",
        }
    }
}

/// A value [`write_value`] refused: what it is, its text, where it came from, the place, why,
/// and how to fix it.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[error("{what} {text:?} (from {from}) cannot be written {place}: {why}; {fix}")]
pub struct Refused {
    /// What the value is.
    pub what: &'static str,
    /// Its text (lossy if it is not UTF-8).
    pub text: String,
    /// Where it came from.
    pub from: String,
    /// Where it was to be written ([`Place`]).
    pub place: &'static str,
    /// Why it cannot be written there.
    pub why: String,
    /// How to fix it.
    pub fix: &'static str,
}

/// The one writer of job files: `v` checked and quoted for `place`, or refused (the rule is in
/// the module documentation).
pub fn write_value(v: &Value, place: Place) -> Result<String, Refused> {
    let text = checked(v, place.name())?;
    match place {
        Place::ShellWord => Ok(shell_quote(text)),
        Place::Sbatch => sbatch_quote(text, false).map_err(|why| v.refused(place.name(), why)),
        Place::SbatchPattern => {
            sbatch_quote(text, true).map_err(|why| v.refused(place.name(), why))
        }
        Place::Yaml => Ok(yaml_string(text)),
        Place::YamlName if yaml_plain(text) => Ok(text.to_string()),
        Place::YamlName => Ok(yaml_string(text)),
        Place::Comment => Ok(text.to_string()),
    }
}

/// `v`'s text if it may be written anywhere in a job file (UTF-8, no line breaks), else its
/// refusal for being written at `place` (a [`Place`]'s name).
pub(super) fn checked<'a>(v: &'a Value, place: &'static str) -> Result<&'a str, Refused> {
    let Some(text) = v.text.to_str() else {
        return Err(v.refused(
            place,
            "it is not valid UTF-8, so it cannot be written exactly",
        ));
    };
    if let Some(c) = text.chars().find(|&c| breaks_lines(c)) {
        return Err(v.refused(
            place,
            format!(
                "it holds the control character {c:?}, and job files take none (a line break \
                 would end the line and run the rest as a shell command)"
            ),
        ));
    }
    Ok(text)
}

/// Whether `c` may not appear in a job file: control characters, and the Unicode line and
/// paragraph separators (YAML 1.1 readers, Kubernetes' among them, break lines at them).
pub(super) fn breaks_lines(c: char) -> bool {
    c.is_control() || matches!(c, '\u{2028}' | '\u{2029}')
}

/// `text` (free of control characters) for an `#SBATCH` line, which sbatch splits at
/// whitespace and where `'` and `"` quote, `\` escapes and `#` starts a comment: double-quoted
/// unless it holds only plain characters, `\` written `\\`. In a filename `pattern`, `%` is
/// written `%%`. A `"` cannot be written there; nor can a `\` in a pattern, where it turns
/// Slurm's `%` expansions off. The error is the reason.
pub(super) fn sbatch_quote(text: &str, pattern: bool) -> Result<String, String> {
    if text.contains('"') {
        return Err("a double quote cannot be written on an #SBATCH line".into());
    }
    if pattern && text.contains('\\') {
        return Err("a backslash in an #SBATCH file name turns off Slurm's %j, %A and %a".into());
    }
    let mut t = text.replace('\\', r"\\");
    if pattern {
        t = t.replace('%', "%%");
    }
    let plain = |c: char| c.is_ascii_alphanumeric() || "/._,:=+@%-".contains(c);
    Ok(if t.chars().all(plain) {
        t
    } else {
        format!("\"{t}\"")
    })
}

/// Whether YAML (1.1 or 1.2) reads `text` written plain back as that very string: lowercase
/// letters, digits and `-`, starting with a letter, and not a word read as a boolean or null.
pub(super) fn yaml_plain(text: &str) -> bool {
    text.starts_with(|c: char| c.is_ascii_lowercase())
        && text
            .chars()
            .all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '-')
        && !matches!(
            text,
            "y" | "n" | "yes" | "no" | "on" | "off" | "true" | "false" | "null"
        )
}

/// A YAML double-quoted scalar (JSON string syntax, which YAML accepts).
pub(super) fn yaml_string(s: &str) -> String {
    serde_json::to_string(s).expect("strings always serialize")
}

/// `s` single-quoted for a POSIX shell (`'` becomes `'\''`).
pub fn shell_quote(s: &str) -> String {
    format!("'{}'", s.replace('\'', r"'\''"))
}
