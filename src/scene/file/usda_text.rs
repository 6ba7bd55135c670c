//! A text layer (`.usda`) as the `openusd` 0.6 parser can read it: that parser refuses an asset
//! path inside `timeSamples` (`asset filePath.timeSamples = { 1001: @a.vdb@ }`, as
//! `nephele usd` writes for the cloud's frame VDBs, and as any shot with per-frame caches has),
//! failing the whole stage. A camera never needs those values, so before parsing each asset
//! path inside a `timeSamples` block becomes a string literal holding the same path; everything
//! else (composition arcs' asset paths included) is passed through byte for byte.

/// `text` with the asset paths inside `timeSamples` blocks written as string literals, or
/// `None` when it has none.
pub fn asset_samples_as_strings(text: &str) -> Option<String> {
    let b = text.as_bytes();
    let mut out = String::with_capacity(text.len());
    let (mut i, mut copied, mut depth) = (0usize, 0usize, 0usize);
    // The brace depth a `timeSamples = {` block opened at, and whether one is about to open.
    let (mut samples, mut pending) = (None::<usize>, false);
    let mut changed = false;
    while i < b.len() {
        match b[i] {
            b'#' => i = skip_to_newline(b, i),
            b'"' | b'\'' => i = skip_string(b, i),
            b'{' => {
                if pending {
                    samples = Some(depth);
                    pending = false;
                }
                depth += 1;
                i += 1;
            }
            b'}' => {
                depth = depth.saturating_sub(1);
                if samples == Some(depth) {
                    samples = None;
                }
                i += 1;
            }
            b'@' => {
                let (end, path) = asset(text, i);
                if samples.is_some() {
                    out.push_str(&text[copied..i]);
                    out.push_str(&quote(&path));
                    copied = end;
                    changed = true;
                }
                i = end;
            }
            c if c.is_ascii_alphabetic() => {
                let start = i;
                while i < b.len() && (b[i].is_ascii_alphanumeric() || b[i] == b'_') {
                    i += 1;
                }
                if &text[start..i] == "timeSamples" && start > 0 && b[start - 1] == b'.' {
                    pending = true;
                }
            }
            _ => i += 1,
        }
    }
    changed.then(|| {
        out.push_str(&text[copied..]);
        out
    })
}

fn skip_to_newline(b: &[u8], mut i: usize) -> usize {
    while i < b.len() && b[i] != b'\n' {
        i += 1;
    }
    i
}

/// The index after the string literal at `i` (`"…"`, `'…'` or their tripled forms).
fn skip_string(b: &[u8], i: usize) -> usize {
    let q = b[i];
    let triple = b.len() >= i + 3 && b[i + 1] == q && b[i + 2] == q;
    let mut j = if triple { i + 3 } else { i + 1 };
    while j < b.len() {
        if b[j] == b'\\' {
            j += 2;
            continue;
        }
        if b[j] == q && (!triple || (j + 2 < b.len() && b[j + 1] == q && b[j + 2] == q)) {
            return j + if triple { 3 } else { 1 };
        }
        if !triple && b[j] == b'\n' {
            return j;
        }
        j += 1;
    }
    b.len()
}

/// The asset path literal at `i` (`@path@`, or `@@@path@@@` with `\@@@` inside and up to two
/// `@` ending the path): the index after it and the path.
fn asset(text: &str, i: usize) -> (usize, String) {
    let b = text.as_bytes();
    if text[i..].starts_with("@@@") {
        let mut j = i + 3;
        let mut path = String::new();
        while j < b.len() {
            if text[j..].starts_with("\\@@@") {
                path.push_str("@@@");
                j += 4;
            } else if text[j..].starts_with("@@@") {
                // The closing `@@@` is the last three of a run of 3 to 5.
                let mut run = 0;
                while j + run < b.len() && b[j + run] == b'@' && run < 5 {
                    run += 1;
                }
                path.push_str(&"@".repeat(run - 3));
                return (j + run, path);
            } else {
                let c = text[j..].chars().next().unwrap_or('@');
                path.push(c);
                j += c.len_utf8();
            }
        }
        (b.len(), path)
    } else {
        let end = text[i + 1..].find('@').map_or(b.len(), |k| i + 1 + k);
        (
            (end + 1).min(b.len()),
            text[i + 1..end.min(b.len())].to_string(),
        )
    }
}

/// A USD string literal of `s`.
fn quote(s: &str) -> String {
    format!("\"{}\"", s.replace('\\', "\\\\").replace('"', "\\\""))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_sampled_asset_paths_become_strings() {
        let text = "#usda 1.0\n(\n  subLayers = [@base.usda@]\n)\ndef X \"a\" (references = \
                    @r.usda@) {\n  asset f.timeSamples = {\n    1: @a/b.vdb@,\n    2: \
                    @@@o@v\\@@@x@@@@,\n  }\n  string s = \"@not@ {\"\n  asset g = @g.vdb@\n}\n";
        let fixed = asset_samples_as_strings(text).unwrap();
        assert!(fixed.contains("1: \"a/b.vdb\","), "{fixed}");
        assert!(fixed.contains("2: \"o@v@@@x@\","), "{fixed}");
        for kept in [
            "[@base.usda@]",
            "references = @r.usda@",
            "\"@not@ {\"",
            "g = @g.vdb@",
        ] {
            assert!(fixed.contains(kept), "{kept}: {fixed}");
        }
        assert_eq!(
            asset_samples_as_strings("#usda 1.0\ndef X \"a\" {}\n"),
            None
        );
    }
}
