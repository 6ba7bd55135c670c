//! Fuzz the OBJ reader: any bytes must give `Ok` or `Err`, never a panic, a hang or a
//! huge allocation; a successful read must keep the reader's contract.
#![no_main]

use std::path::Path;

use libfuzzer_sys::fuzz_target;
use nephele::mesh::io::{MeshFormat, parse_mesh_bytes};

fuzz_target!(|data: &[u8]| {
    if let Ok(mesh) = parse_mesh_bytes(data, MeshFormat::Obj, Path::new("fuzz.obj")) {
        let n = mesh.positions.len();
        assert!(!mesh.triangles.is_empty());
        assert!(mesh.positions.iter().all(|p| p.is_finite()));
        assert!(mesh.triangles.iter().flatten().all(|&v| (v as usize) < n));
    }
});
