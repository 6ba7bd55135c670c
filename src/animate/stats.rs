//! Statistics of the visible density of a frame's blobs, independent of the renderer's look:
//! the solid `F(x) = Σ f_i(x) − t ≥ 0` (the model's iso-surface) sampled at the centres of a
//! cubic lattice, and its 6-connected components.
//!
//! The lattice has a fixed cell (a fraction of the *target's* diagonal) and is anchored at the
//! world origin, so the voxel counts of any two frames of a shot are comparable: a frame's
//! visible volume divided by the last frame's is the "fraction of final volume". The region
//! sampled is the union of the frame's blob supports: `F ≥ 0` cannot hold outside them (the
//! threshold is positive), so a piece flying outside the target's box still counts.

use glam::DVec3;
use rayon::prelude::*;

use crate::blobby::{Blob, BlobField};
use crate::geometry::Aabb;

/// The visible solid of one frame on the lattice.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct VisibleVolume {
    /// Lattice cells whose centre has `F ≥ 0`.
    pub voxels: usize,
    /// 6-connected components of those cells.
    pub components: usize,
    /// Cells of the largest component (0 when nothing is visible).
    pub largest: usize,
}

impl VisibleVolume {
    /// Share of the visible cells held by the largest component (1 when nothing is visible, so
    /// an empty frame never fails a "one piece" check).
    pub fn largest_share(&self) -> f64 {
        share(self.largest, self.voxels)
    }
}

/// `part / whole`, or 1 when `whole` is 0 (an empty frame is "one piece").
fn share(part: usize, whole: usize) -> f64 {
    if whole == 0 {
        1.0
    } else {
        part as f64 / whole as f64
    }
}

/// A cubic lattice anchored at the world origin: cell `i` spans `[i·cell, (i+1)·cell)` per axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lattice {
    /// Edge of a cell.
    pub cell: f64,
}

impl Lattice {
    /// The lattice whose cell is `fraction` of `target`'s diagonal (`fraction` > 0).
    pub fn for_target(target: &Aabb, fraction: f64) -> Lattice {
        Lattice {
            cell: (target.diagonal() * fraction).max(f64::MIN_POSITIVE),
        }
    }
}

/// Default lattice cell as a fraction of the target's diagonal (the "≤ 1 %").
pub const DEFAULT_CELL_FRACTION: f64 = 0.01;

/// Sample the visible solid of `blobs` (iso-level `threshold` > 0) on `lattice` over the union
/// of their supports; label its 6-connected components. Deterministic at any thread count.
pub fn visible_volume(blobs: &[Blob], threshold: f64, lattice: Lattice) -> VisibleVolume {
    let field = BlobField::new(blobs, threshold);
    if field.bounds().is_empty() {
        return VisibleVolume::default();
    }
    let region = field.bounds();
    let lo = (region.min / lattice.cell).floor();
    let hi = (region.max / lattice.cell).ceil();
    let dims = [
        (hi.x - lo.x).max(1.0) as usize,
        (hi.y - lo.y).max(1.0) as usize,
        (hi.z - lo.z).max(1.0) as usize,
    ];
    let inside = sample_inside(&field, lo * lattice.cell, lattice.cell, dims);
    let (components, largest) = label_components(&inside, dims);
    VisibleVolume {
        voxels: inside.iter().filter(|&&v| v).count(),
        components,
        largest,
    }
}

/// `F ≥ 0` at the centre of every cell of the `dims` block starting at `origin`, x fastest.
fn sample_inside(field: &BlobField, origin: DVec3, cell: f64, dims: [usize; 3]) -> Vec<bool> {
    let [nx, ny, nz] = dims;
    let mut inside = vec![false; nx * ny * nz];
    inside
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(z, slab)| {
            for y in 0..ny {
                for x in 0..nx {
                    let p =
                        origin + DVec3::new(x as f64 + 0.5, y as f64 + 0.5, z as f64 + 0.5) * cell;
                    slab[x + nx * y] = field.is_inside(p);
                }
            }
        });
    inside
}

/// Number of 6-connected components of the `true` cells and the size of the largest.
pub fn label_components(inside: &[bool], dims: [usize; 3]) -> (usize, usize) {
    let [nx, ny, nz] = dims;
    debug_assert_eq!(inside.len(), nx * ny * nz);
    let mut seen = vec![false; inside.len()];
    let mut stack = Vec::new();
    let (mut count, mut largest) = (0, 0);
    for start in 0..inside.len() {
        if !inside[start] || seen[start] {
            continue;
        }
        count += 1;
        let mut size = 0;
        seen[start] = true;
        stack.push(start);
        while let Some(i) = stack.pop() {
            size += 1;
            let (x, y, z) = (i % nx, (i / nx) % ny, i / (nx * ny));
            let mut visit = |j: usize| {
                if inside[j] && !seen[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            };
            if x > 0 {
                visit(i - 1);
            }
            if x + 1 < nx {
                visit(i + 1);
            }
            if y > 0 {
                visit(i - nx);
            }
            if y + 1 < ny {
                visit(i + nx);
            }
            if z > 0 {
                visit(i - nx * ny);
            }
            if z + 1 < nz {
                visit(i + nx * ny);
            }
        }
        largest = largest.max(size);
    }
    (count, largest)
}

/// Coverage of a rendered frame: pixels whose alpha exceeds a level, and their 4-connected
/// components (edge-sharing pixels only, the stricter choice).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Coverage {
    /// Fraction of the image's pixels covered.
    pub fraction: f64,
    /// Covered pixels.
    pub pixels: usize,
    /// 4-connected components of the covered pixels.
    pub components: usize,
    /// Pixels of the largest component.
    pub largest: usize,
}

impl Coverage {
    /// Share of the covered pixels in the largest component (1 when nothing is covered).
    pub fn largest_share(&self) -> f64 {
        share(self.largest, self.pixels)
    }
}

/// Alpha level above which a pixel counts as covered.
pub const ALPHA_LEVEL: f32 = 0.05;

/// Coverage of an alpha image (`width × height`, row-major) above `level`.
pub fn coverage(alpha: &[f32], width: usize, height: usize, level: f32) -> Coverage {
    let mask: Vec<bool> = alpha.iter().map(|&a| a > level).collect();
    // A 2D image is a lattice one cell deep: 6-connectivity there is 4-connectivity.
    let (components, largest) = label_components(&mask, [width, height, 1]);
    let pixels = mask.iter().filter(|&&m| m).count();
    Coverage {
        fraction: pixels as f64 / (width * height).max(1) as f64,
        pixels,
        components,
        largest,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::animate::sphere_blob as sphere;

    #[test]
    fn two_apart_spheres_are_two_components_of_the_right_volume() {
        let blobs = [
            sphere(DVec3::ZERO, 1.0),
            sphere(DVec3::new(5.0, 0.0, 0.0), 0.5),
        ];
        let lattice = Lattice { cell: 0.05 };
        let v = visible_volume(&blobs, 1.0, lattice);
        assert_eq!(v.components, 2);
        let expect = |r: f64| 4.0 / 3.0 * std::f64::consts::PI * r * r * r / 0.05f64.powi(3);
        let big = expect(1.0);
        assert!(
            (v.largest as f64 - big).abs() < 0.03 * big,
            "{} vs {big}",
            v.largest
        );
        let total = big + expect(0.5);
        assert!((v.voxels as f64 - total).abs() < 0.03 * total);
        assert!((v.largest_share() - big / total).abs() < 0.02);
    }

    #[test]
    fn coverage_counts_four_connected_pieces() {
        // Two diagonal pixels are two pieces under 4-connectivity.
        let alpha = [1.0, 0.0, 0.0, 0.0, 1.0, 1.0, 0.0, 0.0, 0.5];
        let c = coverage(&alpha, 3, 3, ALPHA_LEVEL);
        assert_eq!((c.pixels, c.components, c.largest), (4, 2, 3));
        assert!((c.fraction - 4.0 / 9.0).abs() < 1e-12);
    }
}
