//! A deforming mesh: one triangle list and the vertex positions of each frame (an animation
//! cache of fixed topology, as a rig writes it: an OBJ/PLY/OFF/STL sequence `walk_####.obj`,
//! a USD mesh with `points` time samples, or a builtin deforming shape such as
//! `builtin:waving-tube`).
//!
//! A file sequence is named with one run of `#` in its file name standing for the zero-padded
//! frame number (`####` = 4 digits, as Houdini's `$F4` and Nuke's `####`): every file of the
//! folder that matches is a frame, and the frames must run without a gap. The first frame is
//! the rest frame. Every frame must have the rest frame's vertices (count) and triangles
//! (the same indices in the same order): a deforming target moves its vertices, it does not
//! change its mesh.

use std::path::{Path, PathBuf};

use glam::DVec3;

use super::{Mesh, MeshError};

/// Whether a target's `mesh` names a file sequence (a `#` in its file name).
pub fn is_pattern(mesh: &str) -> bool {
    !mesh.starts_with("builtin:")
        && Path::new(mesh)
            .file_name()
            .is_some_and(|n| n.to_string_lossy().contains('#'))
}

/// A deforming mesh of one topology (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct MeshSequence {
    /// The triangles every frame shares.
    pub triangles: Vec<[u32; 3]>,
    /// Each frame's vertex positions (at least two frames, all of one length).
    pub frames: Vec<Vec<DVec3>>,
    /// Each frame's number, increasing: a file's frame number, a USD time code, or (for a
    /// builtin, which has no numbers of its own) `0, 1, 2, …` counted from the shot's first
    /// frame.
    pub numbers: Vec<f64>,
    /// True when [`MeshSequence::numbers`] count from the shot's first frame (a builtin).
    pub from_shot_start: bool,
    /// What it was read from (the pattern, the stage, the builtin name), for messages.
    pub source: String,
    /// The rest frame's own name (its file, or the source and its time), for messages.
    pub rest_name: String,
}

impl MeshSequence {
    /// The rest frame (the first) as a mesh.
    pub fn rest(&self) -> Mesh {
        Mesh {
            positions: self.frames[0].clone(),
            triangles: self.triangles.clone(),
        }
    }

    /// Frame `i` as a mesh.
    pub fn frame(&self, i: usize) -> Mesh {
        Mesh {
            positions: self.frames[i].clone(),
            triangles: self.triangles.clone(),
        }
    }

    /// A stable identity of the rest frame (its positions' and triangles' bits), for the fit's
    /// cache key: the fit sees only the rest frame.
    pub fn rest_identity(&self) -> Vec<u8> {
        let mut out = b"mesh sequence rest frame v1".to_vec();
        for p in &self.frames[0] {
            for v in p.to_array() {
                out.extend_from_slice(&v.to_bits().to_le_bytes());
            }
        }
        for t in &self.triangles {
            for i in t {
                out.extend_from_slice(&i.to_le_bytes());
            }
        }
        out
    }

    /// The builtin deforming shape `name` (one of [`super::builtin::DEFORMING`]).
    pub fn builtin(name: &str) -> Option<MeshSequence> {
        match name {
            "waving-tube" => {
                let (frames, triangles) = super::builtin::waving_tube_frames();
                let numbers = (0..frames.len()).map(|k| k as f64).collect();
                Some(MeshSequence {
                    triangles,
                    frames,
                    numbers,
                    from_shot_start: true,
                    source: format!("builtin:{name}"),
                    rest_name: format!("builtin:{name} (frame 0)"),
                })
            }
            _ => None,
        }
    }

    /// Check frames read from one source: at least two, each with the rest frame's vertex
    /// count and triangles, every position finite. `names[i]` names frame `i` in errors;
    /// `source` names the whole.
    pub fn from_frames(
        source: &str,
        names: &[String],
        meshes: Vec<Mesh>,
        numbers: Vec<f64>,
    ) -> Result<MeshSequence, MeshError> {
        let invalid = |path: &str, message: String| MeshError::Invalid {
            path: PathBuf::from(path),
            message,
        };
        if meshes.len() < 2 {
            return Err(invalid(
                source,
                format!(
                    "a deforming target needs at least two frames, found {}{}; for a still \
                     target name the one file",
                    meshes.len(),
                    names.first().map_or(String::new(), |n| format!(" ({n})"))
                ),
            ));
        }
        let rest = &meshes[0];
        for (i, m) in meshes.iter().enumerate() {
            if m.positions.len() != rest.positions.len() {
                return Err(invalid(
                    &names[i],
                    format!(
                        "{} vertices, but the rest frame {} has {}: every frame of a deforming \
                         target must have the same vertices in the same order (one topology)",
                        m.positions.len(),
                        names[0],
                        rest.positions.len()
                    ),
                ));
            }
            if m.triangles != rest.triangles {
                let at = m
                    .triangles
                    .iter()
                    .zip(&rest.triangles)
                    .position(|(a, b)| a != b)
                    .unwrap_or(m.triangles.len().min(rest.triangles.len()));
                return Err(invalid(
                    &names[i],
                    format!(
                        "its faces differ from the rest frame {}'s ({} triangles against {}, \
                         first different at triangle {at}): every frame of a deforming target \
                         must have one topology",
                        names[0],
                        m.triangles.len(),
                        rest.triangles.len()
                    ),
                ));
            }
            if let Some(k) = m.positions.iter().position(|p| !p.is_finite()) {
                return Err(invalid(
                    &names[i],
                    format!(
                        "vertex {k} is {:?}; positions must be finite",
                        m.positions[k]
                    ),
                ));
            }
        }
        let triangles = rest.triangles.clone();
        Ok(MeshSequence {
            triangles,
            frames: meshes.into_iter().map(|m| m.positions).collect(),
            numbers,
            from_shot_start: false,
            source: source.to_string(),
            rest_name: names[0].clone(),
        })
    }

    /// Read the file sequence `pattern` (see the module doc): every matching file, in frame
    /// order, without a gap.
    pub fn load_pattern(pattern: &str) -> Result<MeshSequence, MeshError> {
        let files = frame_files(pattern)?;
        let mut meshes = Vec::with_capacity(files.len());
        for (_, path) in &files {
            let m = super::io::read_mesh(path)?;
            m.validate(path)?;
            meshes.push(m);
        }
        let names = files
            .iter()
            .map(|(_, p)| p.display().to_string())
            .collect::<Vec<_>>();
        let numbers = files.iter().map(|&(n, _)| n as f64).collect();
        MeshSequence::from_frames(pattern, &names, meshes, numbers)
    }
}

/// The files of `pattern` (one run of `#` in the file name), by frame number; an error when
/// none match or a frame between the first and the last is missing.
pub fn frame_files(pattern: &str) -> Result<Vec<(u64, PathBuf)>, MeshError> {
    let path = Path::new(pattern);
    let invalid = |message: String| MeshError::Invalid {
        path: path.to_path_buf(),
        message,
    };
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default();
    let (Some(first), Some(last)) = (name.find('#'), name.rfind('#')) else {
        return Err(invalid("no `#` frame number in the file name".into()));
    };
    let width = last + 1 - first;
    if name[first..=last].chars().any(|c| c != '#') {
        return Err(invalid(
            "the frame number must be one run of `#` (e.g. walk_####.obj)".into(),
        ));
    }
    let (prefix, suffix) = (&name[..first], &name[last + 1..]);
    // Files are named as the pattern is (no `./` before a bare file name).
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let listed = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir.as_path()
    };
    let entries = std::fs::read_dir(listed).map_err(|e| {
        invalid(format!(
            "the sequence's folder {} cannot be read: {e}",
            listed.display()
        ))
    })?;
    let mut found = Vec::new();
    for e in entries.flatten() {
        let file = e.file_name().to_string_lossy().into_owned();
        let Some(digits) = file
            .strip_prefix(prefix)
            .and_then(|r| r.strip_suffix(suffix))
        else {
            continue;
        };
        if digits.len() < width || !digits.bytes().all(|b| b.is_ascii_digit()) {
            continue;
        }
        let Ok(n) = digits.parse::<u64>() else {
            continue;
        };
        // Only the canonical spelling (`0012` for 12 at width 4), so a number is one file.
        if format!("{n:0width$}") == digits {
            found.push((n, dir.join(&file)));
        }
    }
    found.sort();
    let spelled = |n: u64| dir.join(format!("{prefix}{n:0width$}{suffix}"));
    if found.is_empty() {
        return Err(invalid(format!(
            "no file matches the sequence (e.g. {})",
            spelled(1).display()
        )));
    }
    if let Some(w) = found.windows(2).find(|w| w[1].0 != w[0].0 + 1) {
        let (a, b) = (found[0].0, found[found.len() - 1].0);
        let (gap, end) = (w[0].0 + 1, w[1].0 - 1);
        let gap_frames = if gap == end {
            format!("frame {gap} is missing")
        } else {
            format!("frames {gap} to {end} are missing")
        };
        return Err(invalid(format!(
            "{gap_frames}: {} does not exist, but the sequence runs from {} to {}",
            spelled(gap).display(),
            spelled(a).display(),
            spelled(b).display(),
        )));
    }
    Ok(found)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn patterns_are_named_by_a_hash_in_the_file_name() {
        assert!(is_pattern("walk_####.obj"));
        assert!(is_pattern("a/b/walk.####.ply"));
        assert!(!is_pattern("builtin:waving-tube"));
        assert!(!is_pattern("a#b/walk.obj"));
    }

    #[test]
    fn builtin_sequence_has_one_topology_and_many_frames() {
        let s = MeshSequence::builtin("waving-tube").unwrap();
        assert_eq!(s.frames.len(), super::super::builtin::WAVING_FRAMES);
        assert!(s.frames.iter().all(|f| f.len() == s.frames[0].len()));
        assert_eq!(
            s.rest(),
            super::super::builtin::builtin("waving-tube").unwrap()
        );
        assert!(MeshSequence::builtin("duck").is_none());
    }
}
