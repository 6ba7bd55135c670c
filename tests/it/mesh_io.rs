//! Mesh file formats end to end: every reader on a tiny inline cube (quads, so fan
//! triangulation and winding are checked through the signed volume), write→read round trips,
//! a bad-input corpus that must fail with located messages, the shared test models against
//! their README counts, and a seeded mutation "fuzz" run that must never panic.

#[path = "mesh_io/fixtures.rs"]
mod fixtures;
#[path = "mesh_io/mutate.rs"]
mod mutate;

use std::path::{Path, PathBuf};
use std::time::Instant;

use fixtures::{
    Ply, cube_obj, cube_off, cube_positions, cube_triangles, stl_ascii, stl_binary, temp_dir,
};
use nephele::mesh::io::{MeshFormat, parse_mesh_bytes, read_mesh, write_mesh};
use nephele::mesh::{Mesh, MeshError, load};

/// Write `bytes` as `name` in a fresh folder for `test`, returning the path.
fn file(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn assert_unit_cube(path: &Path) {
    let m = read_mesh(path).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        (m.positions.len(), m.triangles.len()),
        (8, 12),
        "{}",
        path.display()
    );
    let loaded = load(path.to_str().unwrap()).unwrap();
    assert!(
        (loaded.mesh.signed_volume() - 1.0).abs() < 1e-12,
        "{}",
        path.display()
    );
    assert_eq!(loaded.mesh.boundary_edge_count(), 0, "{}", path.display());
    assert!(
        loaded.warnings.is_empty(),
        "{}: {:?}",
        path.display(),
        loaded.warnings
    );
}

#[test]
fn every_format_reads_the_cube() {
    let dir = temp_dir("cube");
    let tris = cube_triangles();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("cube.obj", cube_obj().into_bytes()),
        ("CUBE.OBJ", cube_obj().into_bytes()),
        ("cube.off", cube_off().into_bytes()),
        ("cube_ascii.ply", Ply::cube().ascii()),
        ("cube_le.ply", Ply::cube().binary(false)),
        ("cube_be.PLY", Ply::cube().binary(true)),
        ("cube_ascii.stl", stl_ascii(&tris).into_bytes()),
        (
            "cube_binary.stl",
            stl_binary(&tris, tris.len() as u32, true),
        ),
    ];
    for (name, bytes) in cases {
        assert_unit_cube(&file(&dir, name, &bytes));
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn round_trips() {
    let dir = temp_dir("roundtrip");
    // Positions that are not exact in f32, so the OBJ path must print f64 exactly.
    let mesh = Mesh {
        positions: cube_positions()
            .iter()
            .map(|p| glam::DVec3::from_array(*p) * 0.1 + glam::DVec3::splat(1.0 / 3.0))
            .collect(),
        triangles: cube_triangles(),
    };
    let obj = dir.join("sub/m.obj");
    write_mesh(&obj, &mesh).unwrap();
    assert_eq!(read_mesh(&obj).unwrap(), mesh, "OBJ round trip is exact");
    let ply = dir.join("m.ply");
    write_mesh(&ply, &mesh).unwrap();
    let back = read_mesh(&ply).unwrap();
    assert_eq!(back.triangles, mesh.triangles);
    for (a, b) in back.positions.iter().zip(&mesh.positions) {
        assert_eq!(*a, b.as_vec3().as_dvec3(), "PLY stores f32 positions");
    }
    let bytes = std::fs::read(&ply).unwrap();
    assert!(bytes.starts_with(b"ply\nformat binary_little_endian 1.0\n"));
    for bad in ["m.stl", "m.off", "m.glb", "m"] {
        assert!(matches!(
            write_mesh(&dir.join(bad), &mesh),
            Err(MeshError::UnknownFormat { .. })
        ));
    }
    assert!(matches!(
        read_mesh(&dir.join("m.glb")),
        Err(MeshError::UnknownFormat { .. })
    ));
    assert!(matches!(
        read_mesh(&dir.join("missing.obj")),
        Err(MeshError::Io { .. })
    ));
    std::fs::remove_dir_all(dir).unwrap();
}

/// `ply` (ASCII) with the line of vertex `k` (1-based) replaced.
fn ply_vertex_line_replaced(ply: &[u8], k: usize, line: &str) -> Vec<u8> {
    let text = String::from_utf8(ply.to_vec()).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    let end = lines.iter().position(|l| *l == "end_header").unwrap();
    lines[end + k] = line;
    (lines.join("\n") + "\n").into_bytes()
}

/// Files that must not read: (name, content, substrings the message must contain).
fn bad_corpus() -> Vec<(&'static str, Vec<u8>, Vec<&'static str>)> {
    let tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    let off_head = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
    let ply_ascii = Ply::cube().ascii();
    let ply_bin = Ply::cube().binary(false);
    let text = |s: &str| s.as_bytes().to_vec();
    let cut = |b: &[u8], n: usize| b[..b.len() - n].to_vec();
    let mut garbage_body = Ply::cube().header("binary_little_endian");
    garbage_body.extend((0..400u32).map(|i| (i.wrapping_mul(2_654_435_761) >> 13) as u8));
    let claim_2g = Ply::cube_claiming(0, 2_147_483_648).header("binary_little_endian");
    let mut stl_nan = stl_binary(&[[0, 1, 2], [1, 2, 3]], 2, false);
    stl_nan[84 + 50 + 12..84 + 50 + 16].copy_from_slice(&f32::NAN.to_le_bytes());
    vec![
        ("empty.obj", vec![], vec!["empty"]),
        ("empty.ply", vec![], vec!["empty"]),
        ("blank.off", text("\n  \n"), vec!["empty"]),
        ("empty.stl", vec![], vec!["empty"]),
        (
            "nan.obj",
            text(&format!("{tri}v nan 0 0\nf 1 2 3\n")),
            vec![":4:", "non-finite"],
        ),
        (
            "inf.obj",
            text("v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n"),
            vec![":2:"],
        ),
        (
            "range.obj",
            text(&format!("{tri}f 1 2 9\n")),
            vec![":4:", "vertex 9"],
        ),
        (
            "negative.obj",
            text(&format!("{tri}f -1 -2 -4\n")),
            vec![":4:", "-4"],
        ),
        (
            "zero.obj",
            text(&format!("{tri}f 0 1 2\n")),
            vec![":4:", "index 0"],
        ),
        (
            "two.obj",
            text(&format!("{tri}f 1 2\n")),
            vec![":4:", "at least 3"],
        ),
        (
            "word.obj",
            text(&format!("{tri}f 1 two 3\n")),
            vec![":4:", "two"],
        ),
        ("short_v.obj", text("v 0 0\n"), vec![":1:", "x y z"]),
        ("nofaces.obj", text(tri), vec!["no usable triangle"]),
        (
            "garbage.obj",
            (0..=255u8).cycle().take(3000).collect(),
            vec!["garbage.obj"],
        ),
        (
            "trunc.ply",
            cut(&ply_ascii, 12),
            vec!["face 6", "vertex_index"],
        ),
        (
            "word.ply",
            ply_vertex_line_replaced(&ply_ascii, 4, "1x 7 1 2 0.5 0.25 0"),
            vec!["vertex 4", "1x"],
        ),
        (
            "trunc_bin.ply",
            cut(&ply_bin, 7),
            vec!["binary face 6", "truncated"],
        ),
        ("garbage_bin.ply", garbage_body, vec!["garbage_bin.ply"]),
        ("claims_2g.ply", claim_2g, vec!["2147483648", "face"]),
        (
            "range.ply",
            Ply::with_face(&[0, 1, 100]).binary(true),
            vec!["binary face 7", "100"],
        ),
        (
            "two.ply",
            Ply::with_face(&[0, 1]).binary(false),
            vec!["face 7", "at least 3"],
        ),
        (
            "noend.ply",
            text("ply\nformat ascii 1.0\nelement vertex 1\n"),
            vec!["end_header"],
        ),
        ("notply.ply", text("PLY?\n"), vec![":1:", "first line"]),
        (
            "format.ply",
            text("ply\nformat binary_middle_endian 1.0\nend_header\n"),
            vec![":2:"],
        ),
        (
            "noface.ply",
            text(
                "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n",
            ),
            vec!["no 'face'"],
        ),
        (
            "lies.stl",
            stl_binary(&[[0, 1, 2], [1, 2, 3]], 3, false),
            vec!["claims 3", "hold 2"],
        ),
        (
            "claims_2g.stl",
            stl_binary(&[], 2_000_000_000, false),
            vec!["claims 2000000000"],
        ),
        ("short.stl", text("nonsense!"), vec!["shorter"]),
        ("nan.stl", stl_nan, vec!["binary triangle 2", "non-finite"]),
        (
            "trunc_ascii.stl",
            text("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"),
            vec![":2:", "never closed"],
        ),
        (
            "word_ascii.stl",
            text("solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nbanana 1 0 0\n"),
            vec![":5:", "banana"],
        ),
        (
            "range.off",
            text(&format!("{off_head}3 0 1 3\n")),
            vec![":6:", "face 1", "out of range"],
        ),
        (
            "nan.off",
            text("OFF\n3 1 0\n0 0 0\n1 0 NaN\n0 1 0\n3 0 1 2\n"),
            vec![":4:", "vertex 2"],
        ),
        (
            "short_face.off",
            text(&format!("{off_head}3 0 1\n")),
            vec!["face"],
        ),
        (
            "two.off",
            text(&format!("{off_head}2 0 1\n")),
            vec![":6:", "at least 3"],
        ),
        (
            "trunc.off",
            text("OFF\n3 1 0\n0.000 0.000 0.000\n1.000 0.000 0.000\n"),
            vec!["ends early", "vertex 3"],
        ),
        (
            "claims_2g.off",
            text("OFF\n2000000000 2000000000 0\n"),
            vec!["cannot fit"],
        ),
        ("unknown.glb", text("glTF"), vec!["unknown mesh format"]),
    ]
}

#[test]
fn bad_inputs_fail_with_located_messages() {
    let dir = temp_dir("bad");
    for (name, bytes, needles) in bad_corpus() {
        let path = file(&dir, name, &bytes);
        let start = Instant::now();
        let err = read_mesh(&path).expect_err(name).to_string();
        assert!(
            start.elapsed().as_secs_f64() < 0.5,
            "{name} took {:?}",
            start.elapsed()
        );
        assert!(
            err.contains(name),
            "{name}: message does not name the file: {err}"
        );
        for n in needles {
            assert!(err.contains(n), "{name}: expected '{n}' in: {err}");
        }
        let err = load(path.to_str().unwrap()).expect_err(name).to_string();
        assert!(err.contains(name), "{err}");
    }
    std::fs::remove_dir_all(dir).unwrap();
}

#[test]
fn readable_but_unusable_meshes_fail_in_load() {
    let dir = temp_dir("unusable");
    // Collinear: parses, but has zero area.
    let p = file(&dir, "flat.obj", b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n");
    assert!(read_mesh(&p).is_ok());
    let e = load(p.to_str().unwrap()).unwrap_err().to_string();
    assert!(
        e.contains("flat.obj") && e.contains("zero surface area"),
        "{e}"
    );
    // All faces degenerate (repeated index): dropped, then nothing is left.
    let p = file(&dir, "degen.obj", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 1 2\n");
    let e = read_mesh(&p).unwrap_err().to_string();
    assert!(e.contains("no usable triangle"), "{e}");
    std::fs::remove_dir_all(dir).unwrap();
}

fn models_dir() -> Option<PathBuf> {
    let dir = PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/models"));
    if dir.join("README.md").exists() {
        Some(dir)
    } else {
        eprintln!("skipping: {} is absent", dir.display());
        None
    }
}

/// Rows `| file | vertices | faces | ...` of the models README.
fn readme_counts(dir: &Path) -> Vec<(String, usize, usize)> {
    let readme = std::fs::read_to_string(dir.join("README.md")).unwrap();
    readme
        .lines()
        .filter_map(|l| {
            let cells: Vec<&str> = l.split('|').map(str::trim).collect();
            let num = |s: &str| s.replace(',', "").parse::<usize>().ok();
            (cells.len() > 4 && cells[1].contains('.'))
                .then(|| Some((cells[1].to_string(), num(cells[2])?, num(cells[3])?)))
                .flatten()
        })
        .collect()
}

#[test]
fn shared_models_match_their_readme() {
    let Some(dir) = models_dir() else { return };
    let rows = readme_counts(&dir);
    assert!(rows.len() >= 10, "README table not understood: {rows:?}");
    for (name, vertices, faces) in rows {
        let path = dir.join(&name);
        let start = Instant::now();
        let mesh = read_mesh(&path).unwrap_or_else(|e| panic!("{e}"));
        let read_time = start.elapsed();
        assert_eq!(
            (mesh.positions.len(), mesh.triangles.len()),
            (vertices, faces),
            "{name}"
        );
        let loaded = load(path.to_str().unwrap()).unwrap();
        eprintln!(
            "{name}: {vertices} vertices, {faces} faces, read in {:.1} ms, warnings {:?}",
            read_time.as_secs_f64() * 1e3,
            loaded.warnings
        );
        assert!(loaded.mesh.signed_volume() > 0.0, "{name}");
        let flipped = loaded.warnings.iter().any(|w| w.contains("flipped"));
        assert_eq!(
            flipped,
            name == "horse.ply",
            "{name}: {:?}",
            loaded.warnings
        );
    }
}

#[test]
fn mutated_files_never_panic() {
    // NEPHELE_MUTATIONS=N runs N mutants per seed file instead of 1000 (for longer soaks).
    let per_seed = std::env::var("NEPHELE_MUTATIONS")
        .ok()
        .and_then(|n| n.parse().ok())
        .unwrap_or(1000);
    let stats = mutate::mutation_run(0x006e_6570_6865_6c65, per_seed);
    for s in &stats {
        eprintln!("{s}");
    }
}

#[test]
fn parse_mesh_bytes_matches_read_mesh() {
    let bytes = Ply::cube().binary(true);
    let m = parse_mesh_bytes(&bytes, MeshFormat::Ply, Path::new("mem.ply")).unwrap();
    assert_eq!(m.triangles.len(), 12);
    let e = parse_mesh_bytes(
        &bytes[..bytes.len() - 1],
        MeshFormat::Ply,
        Path::new("mem.ply"),
    )
    .unwrap_err()
    .to_string();
    assert!(e.starts_with("mem.ply:6: binary face 6"), "{e}");
}

/// Read speed of the two big PLY models (best of 5, release build):
/// `cargo test --release --test it -- --ignored --nocapture mesh_io::read_speed`.
#[test]
#[ignore = "timing; run alone in release"]
fn read_speed() {
    let Some(dir) = models_dir() else { return };
    for name in ["horse.ply", "armadillo.ply", "bunny-scan-open.obj"] {
        let path = dir.join(name);
        let best = (0..5)
            .map(|_| {
                let start = Instant::now();
                read_mesh(&path).unwrap();
                start.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min);
        eprintln!("{name}: best of 5 read_mesh {:.1} ms", best * 1e3);
        assert!(best < 0.2, "{name} took {best} s");
    }
}
