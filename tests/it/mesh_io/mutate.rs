//! Seeded mutation "fuzzing" without extra crates: small valid files of every format get a few
//! random byte edits, insertions, deletions, duplications, hostile numbers or truncations, and
//! the reader must return `Ok` (with a mesh that keeps the readers' contract) or `Err`, never
//! panic.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::Path;

use nephele::mesh::io::{MeshFormat, parse_mesh_bytes};
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64;

use super::fixtures::{Ply, cube_obj, cube_off, cube_triangles, stl_ascii, stl_binary};

/// Tokens and words that tend to break parsers.
const HOSTILE_TEXT: &[&[u8]] = &[
    b"4294967295",
    b"4294967296",
    b"2147483648",
    b"-2147483649",
    b"-1",
    b"0",
    b"nan",
    b"inf",
    b"-inf",
    b"1e999",
    b"99999999999999999999999",
    b"\n",
    b" ",
    b"#",
    b"/",
    b"//",
    b"f ",
    b"v ",
    b"facet",
    b"endfacet",
    b"vertex",
    b"end_header\n",
    b"element face 3\n",
    b"property list uchar int vertex_indices\n",
    b"\xff\xfe",
];

/// 32-bit values that tend to break binary readers (counts, indices, float NaN/inf).
const HOSTILE_WORDS: &[u32] = &[
    0,
    1,
    0xFFFF_FFFF,
    0x8000_0000,
    0x7FFF_FFFF,
    0x7FC0_0000,
    0x7F80_0000,
    0xFF,
    0xFFFF,
];

/// The valid seed files: (label, format, bytes).
fn seeds() -> Vec<(&'static str, MeshFormat, Vec<u8>)> {
    let tris = cube_triangles();
    vec![
        ("obj", MeshFormat::Obj, cube_obj().into_bytes()),
        ("off", MeshFormat::Off, cube_off().into_bytes()),
        ("ply ascii", MeshFormat::Ply, Ply::cube().ascii()),
        ("ply binary le", MeshFormat::Ply, Ply::cube().binary(false)),
        ("ply binary be", MeshFormat::Ply, Ply::cube().binary(true)),
        ("stl ascii", MeshFormat::Stl, stl_ascii(&tris).into_bytes()),
        (
            "stl binary",
            MeshFormat::Stl,
            stl_binary(&tris, tris.len() as u32, true),
        ),
    ]
}

/// Apply one random mutation to `b`.
fn mutate(rng: &mut Pcg64, b: &mut Vec<u8>) {
    let len = b.len().max(1);
    let at = rng.random_range(0..len).min(b.len());
    match rng.random_range(0..7u32) {
        0 => {
            if at < b.len() {
                b[at] = rng.random();
            }
        }
        1 => {
            let n = rng.random_range(1..=16).min(b.len() - at);
            b.drain(at..at + n);
        }
        2 => {
            let t = HOSTILE_TEXT[rng.random_range(0..HOSTILE_TEXT.len())];
            b.splice(at..at, t.iter().copied());
        }
        3 => {
            // Replace one whitespace-delimited token with a hostile one.
            let start = b[..at]
                .iter()
                .rposition(|c| c.is_ascii_whitespace())
                .map_or(0, |i| i + 1);
            let end = b[at..]
                .iter()
                .position(|c| c.is_ascii_whitespace())
                .map_or(b.len(), |i| at + i);
            let t = HOSTILE_TEXT[rng.random_range(0..11)];
            b.splice(start..end, t.iter().copied());
        }
        4 => {
            let w = HOSTILE_WORDS[rng.random_range(0..HOSTILE_WORDS.len())];
            let bytes = if rng.random::<bool>() {
                w.to_le_bytes()
            } else {
                w.to_be_bytes()
            };
            for (k, &x) in bytes.iter().enumerate() {
                if let Some(c) = b.get_mut(at + k) {
                    *c = x;
                }
            }
        }
        5 => {
            let n = rng.random_range(1..=64).min(b.len() - at);
            let chunk = b[at..at + n].to_vec();
            b.splice(at..at, chunk);
        }
        _ => b.truncate(at),
    }
}

/// What came out of one parse.
#[derive(Default)]
struct Tally {
    ok: usize,
    err: usize,
    panics: Vec<String>,
}

/// Run `per_seed` mutated variants of every seed file; return one summary line per seed.
/// Panics (after the whole run) when any variant panicked or broke the `Ok` contract; the
/// offending inputs are saved to a temp folder named in the message.
pub fn mutation_run(seed: u64, per_seed: usize) -> Vec<String> {
    let mut lines = Vec::new();
    let mut failures = Vec::new();
    let dir = super::fixtures::temp_dir("mutations");
    for (s, (label, format, base)) in seeds().into_iter().enumerate() {
        let mut rng = Pcg64::seed_from_u64(seed ^ (s as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
        let mut tally = Tally::default();
        for i in 0..per_seed {
            let mut bytes = base.clone();
            for _ in 0..rng.random_range(1..=4) {
                mutate(&mut rng, &mut bytes);
            }
            let result = catch_unwind(AssertUnwindSafe(|| {
                parse_mesh_bytes(&bytes, format, Path::new("mutant"))
            }));
            let problem = match result {
                Err(_) => Some("panicked".to_string()),
                Ok(Err(e)) => {
                    tally.err += 1;
                    (!e.to_string().starts_with("mutant"))
                        .then(|| format!("error without file name: {e}"))
                }
                Ok(Ok(m)) => {
                    tally.ok += 1;
                    contract_violation(&m)
                }
            };
            if let Some(p) = problem {
                let file = dir.join(format!("{}-{i}", label.replace(' ', "-")));
                std::fs::write(&file, &bytes).unwrap();
                tally.panics.push(format!("{}: {p}", file.display()));
            }
        }
        lines.push(format!(
            "{label}: {per_seed} mutants, {} read, {} rejected, {} failures",
            tally.ok,
            tally.err,
            tally.panics.len()
        ));
        assert!(
            tally.ok > 0 && tally.err > 0,
            "{label}: mutations never/always break it"
        );
        failures.extend(tally.panics);
    }
    assert!(
        failures.is_empty(),
        "{} failures:\n{}",
        failures.len(),
        failures.join("\n")
    );
    let _ = std::fs::remove_dir_all(dir);
    lines
}

/// Check what every successful read promises: finite positions, in-range indices, no
/// repeated index in a triangle, at least one triangle.
fn contract_violation(m: &nephele::mesh::Mesh) -> Option<String> {
    let n = m.positions.len();
    if m.triangles.is_empty() {
        return Some("Ok with no triangle".into());
    }
    if let Some(p) = m.positions.iter().find(|p| !p.is_finite()) {
        return Some(format!("Ok with non-finite position {p:?}"));
    }
    m.triangles
        .iter()
        .find(|t| {
            t.iter().any(|&v| v as usize >= n) || t[0] == t[1] || t[1] == t[2] || t[0] == t[2]
        })
        .map(|t| format!("Ok with bad triangle {t:?} ({n} vertices)"))
}
