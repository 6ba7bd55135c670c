//! Probe of the decomposition stages on a mesh (development aid): timings and distributions.
use std::time::Instant;

use nephele::decompose::{
    self, DecomposeConfig,
    select::{Coverage, VoxelGrid},
};

fn main() {
    let path = std::env::args().nth(1).expect("mesh path");
    let blobs: usize = std::env::args().nth(2).map_or(300, |s| s.parse().unwrap());
    let loaded = nephele::mesh::load(&path).unwrap();
    let mesh = &loaded.mesh;
    let d = mesh.bounds().diagonal();
    curvature_hist(mesh);
    let t = Instant::now();
    let samples = nephele::mesh::sample::sample_surface(mesh, 60_000, 1);
    eprintln!("samples {:.3}", t.elapsed().as_secs_f64());
    let cfg = DecomposeConfig {
        max_selected: blobs,
        ..Default::default()
    };
    let t = Instant::now();
    let c = decompose::grow_candidates(&cfg, mesh, &samples);
    eprintln!(
        "grow {:.3} s, {} candidates",
        t.elapsed().as_secs_f64(),
        c.len()
    );
    let stages = [1u8, 2, 3].map(|s| c.iter().filter(|x| x.stage == s).count());
    eprintln!("stages {stages:?}");
    let mut big: Vec<f64> = c
        .iter()
        .map(|x| x.ellipsoid.semi_axes.max_element() / d)
        .collect();
    big.sort_by(f64::total_cmp);
    eprintln!(
        "max semi-axis / D: median {:.3} p90 {:.3} max {:.3}",
        big[big.len() / 2],
        big[big.len() * 9 / 10],
        big[big.len() - 1]
    );
    let t = Instant::now();
    let grid = VoxelGrid::new(&mesh.bounds(), cfg.voxels);
    let cov = Coverage::new(&grid, &c);
    eprintln!(
        "rasterise {:.3} s, {} voxel entries, grid {:?}",
        t.elapsed().as_secs_f64(),
        cov.runs.iter().map(|r| r.1 as usize).sum::<usize>(),
        grid.dims
    );
    let t = Instant::now();
    let order = decompose::select_greedy(&cfg, &mesh.bounds(), &c);
    eprintln!(
        "select {:.3} s, {} selected",
        t.elapsed().as_secs_f64(),
        order.len()
    );
    let w: Vec<f64> = c.iter().map(|x| x.weight).collect();
    let mut ws = w.clone();
    ws.sort_by(f64::total_cmp);
    eprintln!(
        "weights median {:.2} max {:.2}",
        ws[ws.len() / 2],
        ws[ws.len() - 1]
    );
}

#[allow(dead_code)]
fn curvature_hist(mesh: &nephele::mesh::Mesh) {
    let d = mesh.bounds().diagonal();
    let mut h: Vec<f64> = nephele::mesh::sample::vertex_mean_curvature(mesh)
        .iter()
        .map(|h| h.abs() * d)
        .collect();
    h.sort_by(f64::total_cmp);
    let q = |f: f64| h[((h.len() - 1) as f64 * f) as usize];
    eprintln!(
        "|H|·D quantiles 10% {:.2} 50% {:.2} 90% {:.2} 99% {:.2} max {:.2}",
        q(0.1),
        q(0.5),
        q(0.9),
        q(0.99),
        q(1.0)
    );
}
