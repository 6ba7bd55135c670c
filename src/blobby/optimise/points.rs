//! The points the full optimisation fits: surface samples, offset sign constraints just inside
//! and outside the surface, and far-field sign constraints on a coarse grid.

use glam::DVec3;
use rayon::prelude::*;

use super::FullConfig;
use crate::mesh::sample::SurfaceSamples;
use crate::mesh::winding::WindingNumber;

/// What a constraint point wants of the field.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Kind {
    Surface,
    Inside,
    Outside,
}

/// Constraint points as SoA.
pub(super) struct Points {
    pub(super) x: Vec<DVec3>,
    pub(super) n: Vec<DVec3>,
    pub(super) kind: Vec<Kind>,
}

/// Surface samples bucketed in a uniform grid, for "is any sample within r of q?" queries.
pub(super) struct SampleGrid<'a> {
    pub(super) points: &'a [DVec3],
    pub(super) inv_cell: f64,
    /// `(cell key, sample index)` sorted by key.
    pub(super) keyed: Vec<(u64, u32)>,
}

impl<'a> SampleGrid<'a> {
    pub(super) fn new(points: &'a [DVec3], cell: f64) -> SampleGrid<'a> {
        let inv_cell = 1.0 / cell;
        let mut keyed: Vec<(u64, u32)> = points
            .iter()
            .enumerate()
            .map(|(i, &p)| (Self::key(Self::cell_of(p, inv_cell)), i as u32))
            .collect();
        keyed.sort_unstable();
        SampleGrid {
            points,
            inv_cell,
            keyed,
        }
    }

    pub(super) fn cell_of(p: DVec3, inv_cell: f64) -> [i64; 3] {
        let c = (p * inv_cell).floor();
        [c.x as i64, c.y as i64, c.z as i64]
    }

    pub(super) fn key(c: [i64; 3]) -> u64 {
        // 21 bits an axis, offset so negative cells pack too.
        let f = |v: i64| ((v + (1 << 20)) as u64) & 0x1F_FFFF;
        f(c[0]) | (f(c[1]) << 21) | (f(c[2]) << 42)
    }

    /// True when some sample lies within `r` (at most one cell) of `q`.
    pub(super) fn any_within(&self, q: DVec3, r: f64) -> bool {
        let c = Self::cell_of(q, self.inv_cell);
        for dz in -1..=1 {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let k = Self::key([c[0] + dx, c[1] + dy, c[2] + dz]);
                    let lo = self.keyed.partition_point(|e| e.0 < k);
                    let hit = self.keyed[lo..]
                        .iter()
                        .take_while(|e| e.0 == k)
                        .any(|e| self.points[e.1 as usize].distance_squared(q) < r * r);
                    if hit {
                        return true;
                    }
                }
            }
        }
        false
    }
}

/// Surface points and offset constraint points. An offset point is kept only when no surface
/// sample is nearer than 80 % of its offset (a point pushed through a thin part or into a
/// concavity would otherwise demand the wrong sign) and, given the mesh's winding number
/// `solid`, when it lies on the side it constrains (next to a scan's hole an inward offset can
/// be outside the solid).
pub(super) fn constraint_points(
    cfg: &FullConfig,
    samples: &SurfaceSamples,
    solid: Option<&WindingNumber>,
    far: &[(DVec3, bool)],
    diag: f64,
) -> Points {
    let m = samples.positions.len();
    let stride = m.div_ceil(cfg.max_points.max(1)).max(1);
    let mut pts = Points {
        x: Vec::new(),
        n: Vec::new(),
        kind: Vec::new(),
    };
    let offsets = std::iter::once((Kind::Surface, 0.0))
        .chain(cfg.inside_offsets.iter().map(|&o| (Kind::Inside, -o)))
        .chain(cfg.outside_offsets.iter().map(|&o| (Kind::Outside, o)));
    for (kind, off) in offsets {
        // Cells as wide as the clearance radius: the query then scans 27 small cells, not
        // 27 cells sized for the largest offset (that was a third of the whole fit's time).
        let r = 0.8 * off.abs() * diag;
        let grid = (off != 0.0).then(|| SampleGrid::new(&samples.positions, r));
        let candidates: Vec<(DVec3, DVec3)> = (0..m)
            .step_by(stride)
            .collect::<Vec<_>>()
            .par_iter()
            .filter_map(|&i| {
                let n = samples.normals[i];
                let x = samples.positions[i] + n * (off * diag);
                let clear = grid.as_ref().is_none_or(|g| !g.any_within(x, r));
                let side = off == 0.0 || solid.is_none_or(|w| w.inside(x) == (off < 0.0));
                (clear && side).then_some((x, n))
            })
            .collect();
        for (x, n) in candidates {
            pts.x.push(x);
            pts.n.push(n);
            pts.kind.push(kind);
        }
    }
    for &(x, inside) in far {
        pts.x.push(x);
        pts.n.push(DVec3::ZERO);
        pts.kind
            .push(if inside { Kind::Inside } else { Kind::Outside });
    }
    pts
}

/// Far-field sign constraints: points of a coarse grid over the mesh's bounds (expanded by
/// 15 % of `D`, `resolution` cells on the longest side) that lie farther than `1.5 %` of `D` from
/// the surface, each with whether it is inside the solid (winding number `solid` above ½). They
/// stop blobs from growing a spurious surface away from the mesh, where no offset sample
/// reaches, and across a scan's holes they say where the solid continues. A mesh parry cannot
/// index gives no points.
pub fn far_field_points(
    mesh: &crate::mesh::Mesh,
    solid: &WindingNumber,
    resolution: usize,
) -> Vec<(DVec3, bool)> {
    use parry3d_f64::query::PointQuery;
    use parry3d_f64::shape::{TriMesh, TriMeshFlags};
    let bounds = mesh.bounds();
    let diag = bounds.diagonal();
    let bounds = bounds.expanded(0.15 * diag);
    let Ok(tri) = TriMesh::with_flags(
        mesh.positions.clone(),
        mesh.triangles.clone(),
        TriMeshFlags::empty(),
    ) else {
        return Vec::new();
    };
    let size = bounds.size();
    let cell = size.max_element() / resolution.max(2) as f64;
    let n = [
        (size.x / cell).ceil() as usize + 1,
        (size.y / cell).ceil() as usize + 1,
        (size.z / cell).ceil() as usize + 1,
    ];
    let at = |k: usize| {
        let (i, j, l) = (k % n[0], (k / n[0]) % n[1], k / (n[0] * n[1]));
        bounds.min + DVec3::new(i as f64, j as f64, l as f64) * cell
    };
    (0..n[0] * n[1] * n[2])
        .into_par_iter()
        .filter_map(|k| {
            let x = at(k);
            let far = tri.project_local_point(x, false).point.distance(x) > 0.015 * diag;
            far.then(|| (x, solid.inside(x)))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use parry3d_f64::query::PointQuery;
    use parry3d_f64::shape::{TriMesh, TriMeshFlags};

    #[test]
    fn far_field_inside_matches_the_pseudo_normal_test_on_clean_meshes() {
        // On clean closed meshes parry's pseudo-normal test is right: the winding number must
        // agree with it everywhere (the duck's flat base is square to the grid).
        for name in ["builtin:duck", "builtin:torus-knot"] {
            let mesh = crate::mesh::load(name).unwrap().mesh;
            let tri = TriMesh::with_flags(
                mesh.positions.clone(),
                mesh.triangles.clone(),
                TriMeshFlags::ORIENTED,
            )
            .unwrap();
            let far = far_field_points(&mesh, &WindingNumber::new(&mesh), 40);
            let inside = far.iter().filter(|f| f.1).count();
            assert!(inside > 100, "{name}: {inside} inside of {}", far.len());
            for &(x, flag) in &far {
                assert_eq!(
                    flag,
                    tri.project_local_point(x, false).is_inside,
                    "{name} at {x}"
                );
            }
        }
    }
}
