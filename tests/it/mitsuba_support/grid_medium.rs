//! A dense density grid as a [`Medium`]: the very grid Mitsuba renders (cell-centred trilinear,
//! clamped at the box), lit by a light grid built from it or by optical depths toward the
//! lights marched exactly through it ([`ExactLights`]).
//! Used to separate the light transport from the density's discretisation in the comparison.

use glam::Vec3A;
use nephele::export::grid::{DensityGrid, Leaf};
use nephele::render::{Frustum, Ray};
use nephele::render::{LightDepths, Medium, ShadowDepths};

/// Optical depth past which [`DenseGrid::depth`] stops marching (the transmittance is
/// `e^{-30}`, nothing any image shows).
const EXACT_DEPTH_CAP: f32 = 30.0;

/// The grid, dense over its active box.
pub struct DenseGrid {
    lo: Vec3A,
    hi: Vec3A,
    voxel: f32,
    dims: [usize; 3],
    vals: Vec<f32>,
    max: f32,
}

impl DenseGrid {
    /// `grid` made dense.
    pub fn new(grid: &DensityGrid) -> DenseGrid {
        let (lo, hi) = grid.active_index_bounds().expect("a live cloud");
        let dims: [usize; 3] = std::array::from_fn(|a| (hi[a] - lo[a] + 1) as usize);
        let mut vals = vec![0.0; dims[0] * dims[1] * dims[2]];
        for (ijk, v) in grid.leaves.iter().flat_map(Leaf::active) {
            let [x, y, z] = std::array::from_fn(|a| (ijk[a] - lo[a]) as usize);
            vals[(z * dims[1] + y) * dims[0] + x] = v;
        }
        let h = 0.5 * grid.voxel;
        let wlo = grid.world(lo).map(|c| (c - h) as f32);
        let whi = grid.world(hi).map(|c| (c + h) as f32);
        DenseGrid {
            lo: Vec3A::from(wlo),
            hi: Vec3A::from(whi),
            voxel: grid.voxel as f32,
            dims,
            max: grid.max_value(),
            vals,
        }
    }

    fn at(&self, i: usize, j: usize, k: usize) -> f32 {
        self.vals[(k * self.dims[1] + j) * self.dims[0] + i]
    }

    /// Trilinear extinction at `x` (cell centres, clamped; 0 outside the box).
    pub fn sigma(&self, x: Vec3A) -> f32 {
        if x.cmplt(self.lo).any() || x.cmpgt(self.hi).any() {
            return 0.0;
        }
        let n = Vec3A::new(
            self.dims[0] as f32 - 1.0,
            self.dims[1] as f32 - 1.0,
            self.dims[2] as f32 - 1.0,
        );
        let g = ((x - self.lo) / self.voxel - 0.5).clamp(Vec3A::ZERO, n);
        let f = g.floor();
        let w = g - f;
        let (i, j, k) = (f.x as usize, f.y as usize, f.z as usize);
        let (i1, j1, k1) = (
            (i + 1).min(self.dims[0] - 1),
            (j + 1).min(self.dims[1] - 1),
            (k + 1).min(self.dims[2] - 1),
        );
        let l = |a: f32, b: f32, t: f32| a + t * (b - a);
        let x00 = l(self.at(i, j, k), self.at(i1, j, k), w.x);
        let x10 = l(self.at(i, j1, k), self.at(i1, j1, k), w.x);
        let x01 = l(self.at(i, j, k1), self.at(i1, j, k1), w.x);
        let x11 = l(self.at(i, j1, k1), self.at(i1, j1, k1), w.x);
        l(l(x00, x10, w.y), l(x01, x11, w.y), w.z)
    }

    fn interval(&self, o: Vec3A, d: Vec3A) -> Option<(f32, f32)> {
        let inv = d.recip();
        let (a, b) = ((self.lo - o) * inv, (self.hi - o) * inv);
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element();
        (t1 > t0).then_some((t0, t1))
    }

    /// Optical depth from `x` along `dir` to the box's exit (midpoint rule, quarter-voxel steps),
    /// stopped once past [`EXACT_DEPTH_CAP`] (the light there is below 10⁻¹³: a march of
    /// the 640×360 shot's thick body in minutes, not hours).
    fn depth(&self, x: Vec3A, dir: Vec3A) -> f32 {
        let Some((t0, t1)) = self.interval(x, dir) else {
            return 0.0;
        };
        let h = 0.25 * self.voxel;
        let n = ((t1 - t0) / h).ceil().max(1.0) as usize;
        let h = (t1 - t0) / n as f32;
        let cap = EXACT_DEPTH_CAP / h;
        let mut sum = 0.0;
        for s in 0..n {
            sum += self.sigma(x + dir * (t0 + (s as f32 + 0.5) * h));
            if sum > cap {
                break;
            }
        }
        sum * h
    }
}

impl Medium for DenseGrid {
    type Scratch = Vec<[f32; 2]>;

    fn scratch(&self) -> Self::Scratch {
        Vec::with_capacity(1)
    }

    fn begin_tile(&self, _: &Frustum, _: &mut Self::Scratch) {}

    fn begin_ray(&self, ray: &Ray, s: &mut Self::Scratch) {
        s.clear();
        if let Some((a, b)) = self.interval(ray.origin, ray.dir) {
            s.push([a, b]);
        }
    }

    fn intervals<'s>(&self, s: &'s Self::Scratch) -> &'s [[f32; 2]] {
        s
    }

    fn extinction(&self, _: &mut Self::Scratch, _: f32, x: Vec3A) -> f32 {
        self.sigma(x)
    }

    fn bounds(&self) -> Option<(Vec3A, Vec3A)> {
        Some((self.lo, self.hi))
    }

    fn step(&self) -> f32 {
        self.voxel
    }

    fn max_extinction(&self) -> f32 {
        self.max
    }
}

/// Optical depths toward the lights marched exactly through a [`DenseGrid`] (slow).
pub struct ExactLights<'a> {
    grid: &'a DenseGrid,
    sun_dir: Vec3A,
    /// With [`ExactLights::cell_mean`]: per sky cell, directions spread over its solid angle.
    cells: Option<Vec<Vec<Vec3A>>>,
}

impl<'a> ExactLights<'a> {
    /// Depths through `grid` for sunlight travelling along `sun_dir`.
    pub fn new(grid: &'a DenseGrid, sun_dir: Vec3A) -> ExactLights<'a> {
        ExactLights {
            grid,
            sun_dir,
            cells: None,
        }
    }

    /// [`ExactLights::new`], each sky cell's depth the one whose transmittance is the mean
    /// transmittance over the cell's solid angle (`per_cell` directions on average, a Fibonacci
    /// sphere binned to the nearest cell): what the cell's one direction stands for.
    pub fn cell_mean(grid: &'a DenseGrid, sun_dir: Vec3A, per_cell: usize) -> ExactLights<'a> {
        let dirs = nephele::render::sky_directions();
        let n = per_cell * dirs.len();
        let mut cells = vec![Vec::new(); dirs.len()];
        let golden = std::f32::consts::PI * (3.0 - 5f32.sqrt());
        for i in 0..n {
            let y = 1.0 - 2.0 * (i as f32 + 0.5) / n as f32;
            let r = (1.0 - y * y).max(0.0).sqrt();
            let d = Vec3A::new(
                r * (golden * i as f32).cos(),
                y,
                r * (golden * i as f32).sin(),
            );
            let k = (0..dirs.len())
                .max_by(|&a, &b| dirs[a].dot(d).total_cmp(&dirs[b].dot(d)))
                .unwrap();
            cells[k].push(d);
        }
        ExactLights {
            grid,
            sun_dir,
            cells: Some(cells),
        }
    }
}

impl ShadowDepths for ExactLights<'_> {
    fn depths(&self, x: Vec3A) -> LightDepths {
        let dirs = nephele::render::sky_directions();
        let sun = self.grid.depth(x, -self.sun_dir);
        LightDepths {
            sun,
            sky: std::array::from_fn(|k| match &self.cells {
                None => self.grid.depth(x, dirs[k]),
                Some(cells) => {
                    let t: f32 = cells[k]
                        .iter()
                        .map(|&d| (-self.grid.depth(x, d)).exp())
                        .sum::<f32>()
                        / cells[k].len() as f32;
                    -t.max(1e-30).ln()
                }
            }),
        }
    }
}

/// The sun's depth marched exactly through a [`DenseGrid`], the sky's from `base` (slow).
pub struct ExactSun<'a, L> {
    /// The grid marched toward the sun.
    pub grid: &'a DenseGrid,
    /// Direction sunlight travels.
    pub sun_dir: Vec3A,
    /// Where the sky's depths come from.
    pub base: &'a L,
}

impl<L: ShadowDepths> ShadowDepths for ExactSun<'_, L> {
    fn depths(&self, x: Vec3A) -> LightDepths {
        let mut d = self.base.depths(x);
        d.sun = self.grid.depth(x, -self.sun_dir);
        d
    }
}
