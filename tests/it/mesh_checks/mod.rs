//! Topology checks shared by the polygonization and builtin-shape tests.
#![allow(dead_code)]

use std::collections::HashMap;

use nephele::mesh::Mesh;

/// Panics unless every directed edge appears exactly once and its reverse exactly once: closed,
/// edge-manifold (each undirected edge in exactly two faces), consistently oriented.
pub fn assert_closed_oriented(mesh: &Mesh, what: &str) {
    assert!(!mesh.triangles.is_empty(), "{what}: empty mesh");
    let mut directed: HashMap<(u32, u32), u32> = HashMap::new();
    for (t, &[a, b, c]) in mesh.triangles.iter().enumerate() {
        assert!(
            a != b && b != c && c != a,
            "{what}: triangle {t} repeats a vertex"
        );
        for e in [(a, b), (b, c), (c, a)] {
            *directed.entry(e).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "{what}: directed edge {a}->{b} used {n} times");
        assert_eq!(
            directed.get(&(b, a)).copied().unwrap_or(0),
            1,
            "{what}: edge {a}-{b} has no opposite half-edge (boundary or flipped face)"
        );
    }
    assert_eq!(mesh.boundary_edge_count(), 0, "{what}");
    assert!(
        mesh.signed_volume() > 0.0,
        "{what}: inward (volume {})",
        mesh.signed_volume()
    );
}

/// Euler characteristic `V − E + F` over the vertices used by some triangle.
pub fn euler_characteristic(mesh: &Mesh) -> i64 {
    let mut used = vec![false; mesh.positions.len()];
    let mut edges = std::collections::HashSet::new();
    for &[a, b, c] in &mesh.triangles {
        for (x, y) in [(a, b), (b, c), (c, a)] {
            used[x as usize] = true;
            edges.insert((x.min(y), x.max(y)));
        }
    }
    let v = used.iter().filter(|&&u| u).count() as i64;
    v - edges.len() as i64 + mesh.triangles.len() as i64
}

/// Number of connected components (through shared vertices).
pub fn components(mesh: &Mesh) -> usize {
    let mut parent: Vec<usize> = (0..mesh.positions.len()).collect();
    fn find(p: &mut [usize], mut x: usize) -> usize {
        while p[x] != x {
            p[x] = p[p[x]];
            x = p[x];
        }
        x
    }
    for &[a, b, c] in &mesh.triangles {
        for (x, y) in [(a, b), (b, c)] {
            let (rx, ry) = (find(&mut parent, x as usize), find(&mut parent, y as usize));
            parent[rx] = ry;
        }
    }
    let mut roots: Vec<usize> = mesh
        .triangles
        .iter()
        .map(|t| find(&mut parent, t[0] as usize))
        .collect();
    roots.sort_unstable();
    roots.dedup();
    roots.len()
}

/// Smallest triangle area relative to the mean.
pub fn min_relative_area(mesh: &Mesh) -> f64 {
    let areas: Vec<f64> = (0..mesh.triangles.len())
        .map(|t| {
            let [a, b, c] = mesh.corners(t);
            0.5 * (b - a).cross(c - a).length()
        })
        .collect();
    let mean = areas.iter().sum::<f64>() / areas.len() as f64;
    areas.iter().cloned().fold(f64::INFINITY, f64::min) / mean
}
