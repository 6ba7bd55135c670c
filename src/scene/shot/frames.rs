//! Frame numbers: a shot's frames are numbered from `shot.start_frame` (default 1; film
//! pipelines start at 1001) and named with `output.padding` digits (default 4). Frame number
//! `f` is the shot's 0-based frame `k = f − start_frame`, at `k / fps` seconds.
//!
//! A [`FrameSelection`] is what `--frames` takes: comma-separated items, each `A..B` (or
//! `A..=B`, inclusive either way), `A..`, `..B` or `A`, in the shot's frame numbers
//! (`1001..1010,1050`). It resolves against the shot into a sorted list without repeats.

use std::fmt::Write as _;
use std::str::FromStr;

pub use crate::scene::file::{MAX_FRAMES, MAX_PADDING};

/// One item of a selection: first and last frame (inclusive), either left open.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameSpan {
    /// First frame, or the shot's first when `None`.
    pub first: Option<u32>,
    /// Last frame (inclusive), or the shot's last when `None`.
    pub last: Option<u32>,
}

/// Frames as the command line names them (see the module doc).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct FrameSelection(pub Vec<FrameSpan>);

impl FrameSelection {
    /// The closed range `first..=last`.
    pub fn range(first: u32, last: u32) -> FrameSelection {
        FrameSelection(vec![FrameSpan {
            first: Some(first),
            last: Some(last),
        }])
    }

    /// The frame numbers selected from a shot whose frames are `first..=last`, sorted, without
    /// repeats; an error names the item that is empty or outside the shot.
    pub fn resolve(&self, first: u32, last: u32) -> Result<Vec<u32>, String> {
        let mut frames = Vec::new();
        for span in &self.0 {
            let (a, b) = (span.first.unwrap_or(first), span.last.unwrap_or(last));
            if a > b || a < first || b > last {
                return Err(format!(
                    "{}: need {first} ≤ first ≤ last ≤ {last} (the shot's frames)",
                    span_text(a, b)
                ));
            }
            frames.extend(a..=b);
        }
        frames.sort_unstable();
        frames.dedup();
        Ok(frames)
    }
}

impl FromStr for FrameSelection {
    type Err = String;

    fn from_str(s: &str) -> Result<FrameSelection, String> {
        let num = |t: &str| -> Result<Option<u32>, String> {
            let t = t.trim();
            if t.is_empty() {
                return Ok(None);
            }
            t.parse::<u32>()
                .map(Some)
                .map_err(|_| format!("'{t}' is not a frame number"))
        };
        let spans = s
            .split(',')
            .map(|item| match item.split_once("..") {
                Some((a, b)) => Ok(FrameSpan {
                    first: num(a)?,
                    last: num(b.strip_prefix('=').unwrap_or(b))?,
                }),
                None => {
                    let n = num(item)?.ok_or_else(|| format!("empty frame item in '{s}'"))?;
                    Ok(FrameSpan {
                        first: Some(n),
                        last: Some(n),
                    })
                }
            })
            .collect::<Result<Vec<_>, String>>()?;
        Ok(FrameSelection(spans))
    }
}

/// `frames` (sorted) written back as a selection: runs of consecutive numbers as `A..B`,
/// comma-separated (`1001..1010,1050`); what `--frames` reads.
pub fn selection_text(frames: &[u32]) -> String {
    let mut s = String::new();
    let mut i = 0;
    while i < frames.len() {
        let mut j = i;
        while j + 1 < frames.len() && frames[j + 1] == frames[j] + 1 {
            j += 1;
        }
        if !s.is_empty() {
            s.push(',');
        }
        let _ = write!(s, "{}", span_text(frames[i], frames[j]));
        i = j + 1;
    }
    s
}

fn span_text(a: u32, b: u32) -> String {
    if a == b {
        a.to_string()
    } else {
        format!("{a}..{b}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn selections_parse_resolve_and_print_back() {
        let sel: FrameSelection = "1001..1003,1050,1002".parse().unwrap();
        let frames = sel.resolve(1001, 1096).unwrap();
        assert_eq!(frames, vec![1001, 1002, 1003, 1050]);
        assert_eq!(selection_text(&frames), "1001..1003,1050");
        let open: FrameSelection = "..1002, 1095..".parse().unwrap();
        assert_eq!(
            open.resolve(1001, 1096).unwrap(),
            vec![1001, 1002, 1095, 1096]
        );
        let incl: FrameSelection = "3..=5".parse().unwrap();
        assert_eq!(incl.resolve(1, 10).unwrap(), vec![3, 4, 5]);
        // Outside the shot, reversed, or not numbers.
        assert!(
            "1..5"
                .parse::<FrameSelection>()
                .unwrap()
                .resolve(1001, 1096)
                .is_err()
        );
        assert!(
            "9..3"
                .parse::<FrameSelection>()
                .unwrap()
                .resolve(1, 10)
                .is_err()
        );
        assert!("a..3".parse::<FrameSelection>().is_err());
        assert!("".parse::<FrameSelection>().is_err());
        assert!("1,,2".parse::<FrameSelection>().is_err());
    }
}
