//! Splitting a shot's frames into contiguous chunks for a farm's job array.
//!
//! Task `I` of `N` (0-based) renders chunk `I` of the requested frames cut into `N` contiguous
//! chunks whose sizes differ by at most one, the larger ones first: `M` frames (`M = q·N + r`,
//! in the order of the list, a range or a list such as `1001..1010,1050`) give chunk `I` the
//! `q + 1` frames starting at position `I·(q + 1)` when `I < r`, else the `q` frames starting
//! at `r·(q + 1) + (I − r)·q`. The split depends only on the frame list and `N`, so every task
//! of an array computes the same split on its own, and the chunks cover the list exactly once.
//!
//! The task index comes from the command line or, with `auto`, from the job-array engine's
//! environment variable ([`ARRAY_INDEX_VARS`]).

/// Environment variables that carry a job-array task's 0-based index, in the order they are
/// consulted: Slurm job arrays, Kubernetes Indexed Jobs, AWS Batch array jobs.
pub const ARRAY_INDEX_VARS: [&str; 3] = [
    "SLURM_ARRAY_TASK_ID",
    "JOB_COMPLETION_INDEX",
    "AWS_BATCH_JOB_ARRAY_INDEX",
];

/// A `--task` request that cannot be served.
#[derive(Clone, Debug, PartialEq, Eq, thiserror::Error)]
#[non_exhaustive]
pub enum ChunkError {
    /// `N` was 0.
    #[error("--task I/0: the number of tasks N in --task I/N must be at least 1")]
    NoTasks,
    /// `I ≥ N`.
    #[error("--task {index}/{count}: task indices are 0-based, so the index must be below {count} (0..={})", count - 1)]
    IndexOutOfRange {
        /// Requested index.
        index: u32,
        /// Number of tasks.
        count: u32,
    },
    /// More tasks than frames: some chunk would be empty.
    #[error(
        "{count} tasks for {frames} frames: every task needs a frame, use at most {frames} tasks"
    )]
    MoreTasksThanFrames {
        /// Number of tasks.
        count: u32,
        /// Frames to split.
        frames: u32,
    },
    /// A chunk size of 0 or larger than the frames to render.
    #[error(
        "--chunk {chunk}: a chunk must hold 1 to {frames} frames (the frames to render); use --chunk {frames} for a single task"
    )]
    BadChunkSize {
        /// Requested frames per chunk.
        chunk: u32,
        /// Frames to split.
        frames: u32,
    },
    /// `auto` was asked but no array engine's index variable is set.
    #[error(
        "--task auto/{count}: none of {} is set (not inside a job array?); give the index yourself, e.g. --task 0/{count}",
        ARRAY_INDEX_VARS.join(", ")
    )]
    NoIndexVariable {
        /// Number of tasks.
        count: u32,
    },
    /// An index variable that is not a non-negative integer.
    #[error("--task auto: {var}={value:?} is not a task index (a non-negative integer)")]
    BadIndexVariable {
        /// The variable read.
        var: &'static str,
        /// Its value.
        value: String,
    },
}

/// Chunk `index` (0-based) of `frames` cut into `count` contiguous chunks (see the module docs
/// for the exact split).
pub fn chunk(frames: &[u32], index: u32, count: u32) -> Result<&[u32], ChunkError> {
    if count == 0 {
        return Err(ChunkError::NoTasks);
    }
    if index >= count {
        return Err(ChunkError::IndexOutOfRange { index, count });
    }
    let m = frame_count(frames);
    if count > m {
        return Err(ChunkError::MoreTasksThanFrames { count, frames: m });
    }
    let (q, r) = (m / count, m % count);
    let first = (index * q + index.min(r)) as usize;
    let len = (q + u32::from(index < r)) as usize;
    Ok(&frames[first..first + len])
}

/// The number of tasks that cut `frames` into chunks of at most `chunk` frames:
/// `ceil(M / chunk)`. Their [`chunk`]s are balanced, so none exceeds `chunk`.
pub fn task_count(frames: &[u32], chunk: u32) -> Result<u32, ChunkError> {
    let m = frame_count(frames);
    if chunk == 0 || chunk > m {
        return Err(ChunkError::BadChunkSize { chunk, frames: m });
    }
    Ok(m.div_ceil(chunk))
}

/// The task index from the first of [`ARRAY_INDEX_VARS`] that `lookup` finds set (non-empty);
/// `count` is only used in the error message.
pub fn index_from_env(
    count: u32,
    lookup: impl Fn(&str) -> Option<String>,
) -> Result<u32, ChunkError> {
    for var in ARRAY_INDEX_VARS {
        if let Some(value) = lookup(var).filter(|v| !v.trim().is_empty()) {
            return value
                .trim()
                .parse::<u32>()
                .map_err(|_| ChunkError::BadIndexVariable { var, value });
        }
    }
    Err(ChunkError::NoIndexVariable { count })
}

/// Frames in a list (a shot has at most [`super::frames::MAX_FRAMES`], so it fits `u32`).
pub fn frame_count(frames: &[u32]) -> u32 {
    frames.len() as u32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_are_balanced_contiguous_and_cover_once() {
        for m in 1..40u32 {
            let frames: Vec<u32> = (5..5 + m).collect();
            for n in 1..=m {
                let mut next = 5;
                for i in 0..n {
                    let c = chunk(&frames, i, n).unwrap();
                    assert_eq!(c[0], next, "m {m} n {n} i {i}");
                    let len = c.len() as u32;
                    assert!(len == m / n || len == m.div_ceil(n), "m {m} n {n} i {i}");
                    assert!(c.windows(2).all(|w| w[1] == w[0] + 1));
                    next = c[c.len() - 1] + 1;
                }
                assert_eq!(next, 5 + m);
            }
        }
        // The larger chunks come first.
        let ten: Vec<u32> = (1..=10).collect();
        assert_eq!(chunk(&ten, 0, 4), Ok(&[1, 2, 3][..]));
        assert_eq!(chunk(&ten, 1, 4), Ok(&[4, 5, 6][..]));
        assert_eq!(chunk(&ten, 2, 4), Ok(&[7, 8][..]));
        assert_eq!(chunk(&ten, 3, 4), Ok(&[9, 10][..]));
        // A list is cut by position: 1001..1003,1050 in two tasks.
        let list = [1001, 1002, 1003, 1050];
        assert_eq!(chunk(&list, 1, 2), Ok(&[1003, 1050][..]));
    }

    #[test]
    fn bad_requests_are_refused() {
        let shot: Vec<u32> = (1..=96).collect();
        assert_eq!(chunk(&shot, 0, 0), Err(ChunkError::NoTasks));
        assert_eq!(
            chunk(&shot, 4, 4),
            Err(ChunkError::IndexOutOfRange { index: 4, count: 4 })
        );
        assert_eq!(
            chunk(&shot[..3], 0, 4),
            Err(ChunkError::MoreTasksThanFrames {
                count: 4,
                frames: 3
            })
        );
        assert!(task_count(&shot, 0).is_err());
        assert!(task_count(&shot, 97).is_err());
        assert_eq!(task_count(&shot, 24), Ok(4));
        assert_eq!(task_count(&shot, 25), Ok(4));
        assert_eq!(task_count(&shot, 96), Ok(1));
    }

    #[test]
    fn index_comes_from_the_first_variable_set() {
        let env = |pairs: &'static [(&'static str, &'static str)]| {
            move |k: &str| pairs.iter().find(|p| p.0 == k).map(|p| p.1.to_string())
        };
        assert_eq!(
            index_from_env(4, env(&[("JOB_COMPLETION_INDEX", "2")])),
            Ok(2)
        );
        assert_eq!(
            index_from_env(
                4,
                env(&[
                    ("AWS_BATCH_JOB_ARRAY_INDEX", "1"),
                    ("SLURM_ARRAY_TASK_ID", "3")
                ])
            ),
            Ok(3)
        );
        assert_eq!(
            index_from_env(4, env(&[])),
            Err(ChunkError::NoIndexVariable { count: 4 })
        );
        assert!(matches!(
            index_from_env(4, env(&[("SLURM_ARRAY_TASK_ID", "x")])),
            Err(ChunkError::BadIndexVariable { .. })
        ));
    }
}
