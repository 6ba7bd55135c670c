//! The per-frame light grid, where the renderer computes how much sunlight and skylight reaches
//! each point of the cloud: optical depth toward the sun ([`SunGrid`]) and toward each sky cell
//! ([`crate::render::light::sky_cells`]) on the nodes of regular grids over the cloud, so shading a march
//! sample costs one trilinear lookup instead of secondary marches.
//!
//! In: any [`Medium`] and the sun direction. Out: [`LightGrid`], a [`ShadowDepths`] — the depths
//! anywhere (clamped to the grid). The grid may light the march through another medium than
//! the one it was built from (motion blur: one grid at the frame's time).
//!
//! The medium is sampled once, along the sun grid's light columns (through the medium's own
//! rays, [`crate::render::medium::lattice`]: only inside its intervals); the sky's coarse world grid takes its
//! extinction from those samples, prefiltered. Buffers can be handed on from frame to frame
//! ([`LightGrid::build_reusing`]). The sky's depths are swept in [`crate::render::light::sky_depth`],
//! the sun's summed along light columns in [`crate::render::light::sun_depth`].

use glam::Vec3A;
use rayon::prelude::*;

use crate::render::light::fluence::{FluenceGrid, FluenceSettings, MAX_FLUENCE_CELLS};
use crate::render::light::sky_cells::SKY_DIRECTIONS;
use crate::render::light::sky_depth::{SkyWork, block_sky, depth_of, sky_depths};
use crate::render::light::sun_depth::SunGrid;
use crate::render::light::{LightDepths, MultipleLight, ShadowDepths};
use crate::render::medium::Medium;
use crate::render::medium::lattice::{GridShape, trilinear};
use crate::render::settings::RenderSettings;
use crate::render::surfaces::Surfaces;

/// Optical depths toward the sun (on a light-aligned grid of the same spacing, `SunGrid`) and
/// toward each sky cell on a grid `SKY_SPACING` times coarser (sky light comes from a broad
/// source: its shadows are soft, and 26 sweeps at full resolution would cost more than the
/// frame).
#[derive(Clone, Debug)]
pub struct LightGrid {
    /// Depth toward the sun, on its own light-aligned grid.
    sun: SunGrid,
    sky_shape: GridShape,
    sky_inv_h: f32,
    /// [`SKY_DIRECTIONS`] depths per coarse node, node-major, as their cube roots
    /// ([`crate::render::light::sky_depth::quantize_depth`]).
    sky: Vec<u16>,
    /// Nodes of the world grid the sky's is [`SKY_SPACING`](crate::render::light::sky_depth::SKY_SPACING) times as coarse as.
    #[cfg(test)]
    world_nodes: usize,
    /// Working buffers of the sky's build, kept for the next frame's.
    work: SkyWork,
    /// The light scattered at least once (the physically based multiple scattering), when the
    /// settings ask for it ([`FluenceSettings::new`]).
    pub(in crate::render::light) fluence: Option<FluenceGrid>,
}

/// What a light grid holds, for the benchmark's work counters.
#[cfg(test)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct LightGridSize {
    /// Nodes of the world grid at the light grid's spacing (the sky's is [`SKY_SPACING`](crate::render::light::sky_depth::SKY_SPACING) times
    /// as coarse).
    pub world: usize,
    /// Nodes of the sun's grid.
    pub sun: usize,
    /// Nodes of the sky's grid (each with [`SKY_DIRECTIONS`] depths).
    pub sky: usize,
    /// Bytes the grid keeps (depths and working buffers).
    pub bytes: usize,
}

impl LightGrid {
    /// The light grid of a frame: `medium` lit by `settings.sun` at
    /// `RenderSettings::light_grid_cells` on the longest side of its bounds (the quality's
    /// `shadow_grid`, fewer for a cloud small on screen). `None` when the medium is empty.
    pub fn for_frame<M: Medium>(settings: &RenderSettings, medium: &M) -> Option<LightGrid> {
        LightGrid::for_frame_reusing(settings, medium, None)
    }

    /// [`LightGrid::for_frame`], reusing the buffers of `previous` (a shot's last grid).
    pub(crate) fn for_frame_reusing<M: Medium>(
        settings: &RenderSettings,
        medium: &M,
        previous: Option<LightGrid>,
    ) -> Option<LightGrid> {
        let sun = Vec3A::from(settings.sun.travel_dir());
        let res = settings.light_grid_cells(medium.bounds());
        let casters = settings.surfaces.as_deref().filter(|s| s.casts_shadows());
        let fluence = FluenceSettings::new(settings);
        LightGrid::build_reusing(medium, sun, res, previous, casters, fluence.as_ref())
    }

    /// Light grid for sunlight travelling along `sun_dir` (unit) through `medium`, about `res`
    /// cells on the longest side of its bounds. `None` when the medium has no bounds (empty or
    /// unbounded).
    pub fn build<M: Medium>(medium: &M, sun_dir: Vec3A, res: u32) -> Option<LightGrid> {
        LightGrid::build_reusing(medium, sun_dir, res, None, None, None)
    }

    /// [`LightGrid::build`], reusing the buffers of `previous`: a shot does not allocate and
    /// zero a few hundred megabytes every frame.
    ///
    /// The sun's depths are summed along light columns straight from the medium ([`SunGrid`]);
    /// the sky's are swept through a world grid of [`SKY_SPACING`](crate::render::light::sky_depth::SKY_SPACING) times the spacing whose
    /// extinction is the sun grid's samples, prefiltered: the medium is sampled once per frame.
    /// The shadow-casting holdouts of `casters` then take the light from the nodes they hide
    /// from the sun ([`SunGrid::block`]) and from each sky cell ([`block_sky`]). With
    /// `fluence`, the light scattered at least once is traced through the sky's coarse grid
    /// ([`FluenceGrid::build`]; a shadow-casting holdout between a photon's first collision and
    /// its light drops it).
    pub(crate) fn build_reusing<M: Medium>(
        medium: &M,
        sun_dir: Vec3A,
        res: u32,
        previous: Option<LightGrid>,
        casters: Option<&Surfaces>,
        fluence: Option<&FluenceSettings>,
    ) -> Option<LightGrid> {
        let (lo, hi) = medium.bounds()?;
        let shape = GridShape::covering(lo, hi, res);
        let (old_sun, mut sky, mut work) = match previous {
            Some(g) => (Some(g.sun), g.sky, g.work),
            None => (None, Vec::new(), SkyWork::default()),
        };
        let mut sun = SunGrid::build(medium, sun_dir, shape.h, old_sun)?;
        let sky_shape = sky_depths(&shape, &sun, &mut work, &mut sky);
        if let Some(c) = casters {
            sun.block(c);
            block_sky(&sky_shape, &work.coarse, c, &mut sky);
        }
        // After the holdouts' shadows: the cells' mean sun detail sees them as the march does.
        let fluence = fluence.map(|f| match fluence_lattice(lo, hi, &sky_shape, &sun) {
            Some((shape, sigma)) => FluenceGrid::build(&shape, &sigma, f, casters, &sun),
            None => FluenceGrid::build(&sky_shape, &work.coarse, f, casters, &sun),
        });
        // The sampled extinction served the sky's coarse grid only: not kept through the
        // march (a frame's peak memory), at the price of allocating it again next frame.
        sun.release_extinction();
        Some(LightGrid {
            sun,
            sky_inv_h: 1.0 / sky_shape.h,
            sky_shape,
            sky,
            #[cfg(test)]
            world_nodes: shape.len(),
            work,
            fluence,
        })
    }

    /// Node counts and memory (for the benchmark).
    #[cfg(test)]
    pub(crate) fn size(&self) -> LightGridSize {
        LightGridSize {
            world: self.world_nodes,
            sun: self.sun.len(),
            sky: self.sky_shape.len(),
            bytes: (self.sun.stored_values()
                + self.work.coarse.len()
                + self
                    .work
                    .sweeps
                    .iter()
                    .map(|w| w.slices[0].len() + w.slices[1].len())
                    .sum::<usize>())
                * std::mem::size_of::<f32>()
                + (self.sky.len()
                    + self
                        .work
                        .sweeps
                        .iter()
                        .map(|w| w.depths.len())
                        .sum::<usize>())
                    * std::mem::size_of::<u16>(),
        }
    }

    /// Trilinear depths at `x` (clamped to the grids; their border nodes are outside the cloud,
    /// so points outside see the border values).
    #[inline]
    pub(crate) fn lookup(&self, x: Vec3A) -> LightDepths {
        let sun = self.sun.lookup(x);
        let mut sky = [0.0f32; SKY_DIRECTIONS];
        trilinear::<SKY_DIRECTIONS, u16>(&self.sky_shape, self.sky_inv_h, &self.sky, x, &mut sky);
        // Interpolated as cube roots (`quantize_depth`: the surface's kink).
        for t in &mut sky {
            *t = depth_of(*t);
        }
        LightDepths { sun, sky }
    }
}

impl ShadowDepths for LightGrid {
    #[inline]
    fn depths(&self, x: Vec3A) -> LightDepths {
        self.lookup(x)
    }

    #[inline]
    fn multiple(&self, x: Vec3A) -> MultipleLight {
        self.fluence
            .as_ref()
            .map_or(MultipleLight::ZERO, |f| f.lookup(x))
    }
}

/// The lattice the fluence estimate is traced through when the sky's coarse grid is too coarse
/// for it (`None`: that grid, which [`FluenceGrid::build`] coarsens to
/// [`MAX_FLUENCE_CELLS`]): a small frame's light grid follows its pixels, but the scattered
/// light's cells must follow the cloud, so the estimate of a 96×54 frame is as fine as a
/// 1080p one's. Sampled from the sun grid's prefiltered extinction at twice the fluence's
/// resolution (the build then averages blocks of two).
fn fluence_lattice(
    lo: Vec3A,
    hi: Vec3A,
    sky_shape: &GridShape,
    sun: &SunGrid,
) -> Option<(GridShape, Vec<f32>)> {
    let fine = 2 * MAX_FLUENCE_CELLS - 2;
    if sky_shape.dims.iter().max().copied().unwrap_or(0) >= fine {
        return None;
    }
    // `covering` pads three nodes: `fine` nodes on the longest side.
    let shape = GridShape::covering(lo, hi, (fine - 3) as u32);
    let [nx, ny, _] = shape.dims;
    let mut sigma = vec![0.0f32; shape.len()];
    sigma
        .par_chunks_mut(nx * ny)
        .enumerate()
        .for_each(|(k, slice)| {
            for j in 0..ny {
                for i in 0..nx {
                    slice[i + nx * j] = sun.coarse_extinction(shape.node(i, j, k));
                }
            }
        });
    Some((shape, sigma))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A ball of radius 1 and extinction 3 at the origin, sampled on a 64-cell grid.
    fn ball_grid(sun: Vec3A) -> LightGrid {
        let ball = crate::render::Homogeneous {
            shape: crate::render::Shape::Ball {
                center: Vec3A::ZERO,
                radius: 1.0,
            },
            sigma_t: 3.0,
            step: 0.05,
        };
        LightGrid::build(&ball, sun, 64).expect("a bounded medium")
    }

    #[test]
    fn depths_through_a_ball_match_chords() {
        for sun in [Vec3A::NEG_Y, Vec3A::new(-0.4, -0.8, -0.3).normalize()] {
            let grid = ball_grid(sun);
            // Centre: the chord toward the sun is the radius; likewise straight up.
            let c = grid.lookup(Vec3A::ZERO);
            let (ts, tu, td) = (
                c.sun,
                c.sky[crate::render::light::sky_cells::UP],
                c.sky[crate::render::light::sky_cells::DOWN],
            );
            assert!((td / 3.0 - 1.0).abs() < 0.04, "τ_down at centre {td}");
            assert!((ts / 3.0 - 1.0).abs() < 0.04, "τ_sun at centre {ts}");
            assert!((tu / 3.0 - 1.0).abs() < 0.04, "τ_up at centre {tu}");
            // The point half-way toward the sun, and the antipode (full diameter minus ½).
            let ts = grid.lookup(-sun * 0.5).sun;
            assert!((ts / 1.5 - 1.0).abs() < 0.06, "τ_sun half-way {ts}");
            let ts = grid.lookup(sun * 0.5).sun;
            assert!((ts / 4.5 - 1.0).abs() < 0.04, "τ_sun far side {ts}");
            // Outside on the sunny side nothing is in the way.
            assert!(grid.lookup(-sun * 1.05).sun < 0.05);
        }
    }
}
